"""report.html: the page (:mod:`reports.html.page`), its per-run sections
(:mod:`reports.html.runs`), bird's-eye views (:mod:`reports.html.birdseye`) and SVG
charts (:mod:`reports.html.charts`)."""

from reports.html.charts import MAX_POINTS, decimate
from reports.html.page import render_report, write_html

__all__ = ["MAX_POINTS", "decimate", "render_report", "write_html"]
