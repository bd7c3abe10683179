"""The Ray executor's own lines on stderr (a lost worker, a node's other code)."""

from __future__ import annotations

import sys

__all__ = ["say"]


def say(line: str) -> None:
    """``hwyeval: ray: <line>`` on stderr, flushed."""
    sys.stderr.write(f"hwyeval: ray: {line}\n")
    sys.stderr.flush()
