"""hwyeval suite: catalog, road, SUMO world, the simulation loop, executors, Rerun logs, CLI."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("hwyeval")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0+unknown"
