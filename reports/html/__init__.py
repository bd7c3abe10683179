"""report.html and the run pages: the index (:mod:`reports.html.page`) with the failures
list (:mod:`reports.html.failures`), one page per run (:mod:`reports.html.run_page`)
with its charts (:mod:`reports.html.runs`, :mod:`reports.charts`) and bird's-eye
views (:mod:`reports.html.birdseye`); relative links (:mod:`reports.html.links`)."""

from reports.charts import MAX_POINTS, decimate
from reports.html.links import RUN_PAGES, Links
from reports.html.page import render_index
from reports.html.run_page import render_run_page

__all__ = ["MAX_POINTS", "RUN_PAGES", "Links", "decimate", "render_index", "render_run_page"]
