"""A full disk or a read-only output (#26): every report file is written atomically, so
what was there stays whole and no temporary file is left; the command exits 2 (the
environment, not a verdict) with the path and the error named, never a traceback. As
root no directory is read-only, so the OS errors are raised where the files are
renamed into place (every atomic write ends with that rename)."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest
import synthetic_runs as sr

from reports import write_reports
from reports.record.codec import write_text_atomic
from suite.cli import main


def _failing_rename(code: int):  # type: ignore[no-untyped-def]
    original = Path.replace

    def replace(self: Path, target: str | os.PathLike[str]) -> Path:
        if self.name.startswith("."):  # the temporary file of an atomic write
            raise OSError(code, os.strerror(code), str(target))
        return original(self, target)
    return replace


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EROFS])
def test_report_on_a_full_or_read_only_output_exits_2_and_keeps_the_old_files(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, code: int,
        capsys: pytest.CaptureFixture[str]) -> None:
    out = sr.make_catalog(tmp_path / "night", controllers=("ctrl_a",))
    write_reports(out)
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    monkeypatch.setattr(Path, "replace", _failing_rename(code))
    assert main(["report", str(out)]) == 2
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err and errno.errorcode[code] in captured.err
    after = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert after == before  # whole, and no temporary file beside them


def test_compare_into_a_read_only_place_exits_2_not_1(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    base = sr.make_catalog(tmp_path / "base", controllers=("ctrl_a",))
    new = sr.make_catalog(tmp_path / "new", controllers=("ctrl_a",))
    monkeypatch.setattr(Path, "replace", _failing_rename(errno.EROFS))
    assert main(["compare", str(base), str(new)]) == 2  # 1 would read as a regression


def test_an_atomic_write_that_fails_leaves_the_old_file_and_no_temporary(tmp_path: Path
                                                                         ) -> None:
    target = tmp_path / "results.csv"
    target.write_text("old")
    (tmp_path / "blocker").mkdir()
    with pytest.raises(OSError):
        write_text_atomic(tmp_path / "blocker", "new")  # renaming onto a directory fails
    write_text_atomic(target, "new")
    assert target.read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["blocker", "results.csv"]
