"""The networks bundled with hwyeval (the ``sumo_nets`` package), by name."""

from __future__ import annotations

from pathlib import Path

__all__ = ["bundled_net_path", "bundled_nets"]


def bundled_nets() -> list[str]:
    """Names of the bundled nets; empty if ``sumo_nets`` is unavailable."""
    try:
        import sumo_nets
    except ImportError:
        return []
    try:
        return list(sumo_nets.available())
    except Exception:
        return []


def bundled_net_path(name: str) -> Path | None:
    """The file of the bundled net ``name``; None if there is none (or no ``sumo_nets``)."""
    try:
        import sumo_nets
    except ImportError:
        return None
    try:
        return Path(sumo_nets.net_path(name))
    except (KeyError, ValueError, FileNotFoundError):
        return None
