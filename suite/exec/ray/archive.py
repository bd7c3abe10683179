"""A run directory as it travels back from a Ray worker: a gzipped tar archive, unpacked
on the driver into a staging directory (links and paths out of it refused:
``tarfile``'s ``data`` filter) and published atomically, replacing an older one."""

from __future__ import annotations

import io
import tarfile
from pathlib import Path

from reports.record.run import publish_run_dir, remove_path, staging_dir
from suite.exec.jobs import RunJob

__all__ = ["COMPRESS_LEVEL", "pack_run", "unpack_run"]

COMPRESS_LEVEL = 1  # gzip level of the archive: Parquet and .rrd are compressed already


def pack_run(run_dir: Path, name: str) -> bytes:
    """The run directory ``run_dir`` as a gzipped tar archive holding ``name/``."""
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w:gz", compresslevel=COMPRESS_LEVEL) as tar:
        tar.add(run_dir, arcname=name)
    return buf.getvalue()


def unpack_run(archive: bytes, job: RunJob) -> None:
    """Unpack a shipped run directory into a staging directory and publish it as the
    job's run directory (replacing an older one; nothing outside the staging directory
    is ever written)."""
    stage = staging_dir(job.out_dir, job.name)
    try:
        with tarfile.open(fileobj=io.BytesIO(archive), mode="r:gz") as tar:
            tar.extractall(stage, filter="data")
        run = stage / job.name
        if run.is_symlink() or not run.is_dir():
            raise ValueError(f"the shipped archive of {job.name} holds no directory {job.name}/")
        publish_run_dir(run, job.run_dir)
    finally:
        remove_path(stage)
