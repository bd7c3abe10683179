"""search.csv round-trips; search.html draws every run and lists the failure modes with
links to the runs that exist (self-contained: no external resource)."""

from __future__ import annotations

import math
from pathlib import Path

from reports.html.search import write_search_page
from reports.record.search import SearchRow, read_search_csv, write_search_csv


def _rows() -> list[SearchRow]:
    out = []
    for i in range(8):
        fail = i in (3, 6)
        out.append(SearchRow("fam", "trial", i, f"fam__t{i:04d}", "fail" if fail else "pass",
                             -1.5 if fail else 0.2 * i, "min_ttc_s", "min_ttc_s@left" if fail
                             else "", "fam__t0003" if i == 3 else "", "",
                             (("stalled.0.pos_m", repr(100.0 + 10 * i)),
                              ("ego.speed_mps", repr(20.0 + i)))))
    out.append(SearchRow("fam", "trial", 8, "", "refused", math.nan, "", "", "", "overlap",
                         (("stalled.0.pos_m", "55.0"), ("ego.speed_mps", "30.0"))))
    out.append(SearchRow("fam", "shrink", 3, "fam__shrink000", "pass", 0.4, "min_ttc_s", "",
                         "", "", (("stalled.0.pos_m", "120.0"), ("ego.speed_mps", "22.0"))))
    return out


def test_search_csv_round_trips(tmp_path: Path) -> None:
    rows = _rows()
    path = write_search_csv(rows, tmp_path / "search.csv")
    back = read_search_csv(path)
    assert len(back) == len(rows)
    for a, b in zip(rows, back, strict=True):
        assert (a.family, a.kind, a.trial, a.run, a.status, a.failure_mode, a.found) == \
            (b.family, b.kind, b.trial, b.run, b.status, b.failure_mode, b.found)
        assert (math.isnan(a.robustness) and math.isnan(b.robustness)) or \
            a.robustness == b.robustness
        assert a.number("stalled.0.pos_m") == b.number("stalled.0.pos_m")


def test_page_draws_runs_and_links_modes(tmp_path: Path) -> None:
    write_search_csv(_rows(), tmp_path / "search.csv")
    (tmp_path / "fam__t0003").mkdir()
    (tmp_path / "fam__t0003" / "run.rrd").write_bytes(b"")
    page = write_search_page(tmp_path).read_text()
    assert page.count("<circle") >= 2 * 8  # the chart and the pair plot
    assert "min_ttc_s@left" in page and "fam__t0003/run.rrd" in page
    assert "http://" not in page and "https://" not in page
