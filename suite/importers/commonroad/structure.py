"""The file's structure, read with ElementTree before commonroad-io reads it: what
commonroad-io drops silently, or fails on without naming the element, is an
:class:`~suite.importers.commonroad.errors.ImportFailure` naming it.

* Well-formed XML (else ``XML line L column C``), a ``<commonRoad>`` root, a
  ``planningProblem`` and a ``lanelet``.
* **Unique ids.** A CommonRoad file's lanelets, obstacles (``obstacle`` of 2018b,
  ``dynamicObstacle``, ``staticObstacle``, ``environmentObstacle``, ``phantomObstacle``),
  traffic signs and lights and intersections share one id space (commonroad-io's
  ``Scenario``), planning problems another. Two lanelets with one id: commonroad-io keeps
  the first and drops the second with a warning, so the road silently lost a lane; two
  obstacles: it fails with ``ID 373 is already used``. Both name the second element
  (``lanelet 2``, ``obstacle 373``) and the first one's kind.
* **Goal lanelets.** Every ``goalState/position/lanelet ref`` of a planning problem is a
  lanelet of the file (commonroad-io fails with an ``AttributeError`` on a missing one):
  else ``planningProblem <id> goalState`` names the missing lanelet.

One parse of the file with ElementTree: ~30 ms for a 600 kB file (commonroad-io's own
read takes ~150 ms, the whole import ~1 s).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from suite.importers.commonroad.errors import ImportFailure

__all__ = ["OBSTACLE_TAGS", "check_structure"]

OBSTACLE_TAGS = ("obstacle", "dynamicObstacle", "staticObstacle", "environmentObstacle",
                 "phantomObstacle")
"""The elements that are obstacles (2018b's ``obstacle`` and the later formats')."""


def _parse(path: Path) -> ET.Element:
    try:
        return ET.parse(path).getroot()
    except ET.ParseError as exc:
        line, col = exc.position
        raise ImportFailure(str(path), f"XML line {line} column {col}",
                            f"not well-formed XML ({exc})") from exc
    except OSError as exc:
        raise ImportFailure(str(path), "file", f"cannot be read ({exc})") from exc


def _check_root(path: Path, root: ET.Element) -> None:
    if root.tag != "commonRoad":
        raise ImportFailure(str(path), f"<{root.tag}>", "expected a <commonRoad> root element")
    if root.find("planningProblem") is None:
        raise ImportFailure(str(path), "planningProblem",
                            "no planning problem: the ego's initial state is needed")
    if root.find("lanelet") is None:
        raise ImportFailure(str(path), "lanelet", "no lanelets: a road is needed")


def _kind(tag: str) -> str:
    """What an element is called in a message: ``obstacle`` for every obstacle tag."""
    return "obstacle" if tag in OBSTACLE_TAGS else tag


def _id(text: str) -> int | str:
    """An id as its integer (``"07"`` is 7, as commonroad-io reads it), else as written."""
    try:
        return int(text)
    except ValueError:
        return text


def _check_ids(path: Path, root: ET.Element) -> set[int | str]:
    """Refuse an id given twice (module docstring); the lanelets' ids."""
    seen: dict[tuple[str, int | str], str] = {}
    lanelets: set[int | str] = set()
    for el in root:
        text = el.get("id")
        if text is None:
            continue
        ident = _id(text.strip())
        key = ("problem" if el.tag == "planningProblem" else "scenario", ident)
        kind = _kind(el.tag)
        if key in seen:
            raise ImportFailure(str(path), f"{kind} {text}", f"its id is also that of "
                                f"{seen[key]} {text} earlier in the file (ids must be "
                                "unique: commonroad-io would drop or refuse one of them)")
        seen[key] = kind
        if el.tag == "lanelet":
            lanelets.add(ident)
    return lanelets


def _check_goals(path: Path, root: ET.Element, lanelets: set[int | str]) -> None:
    for problem in root.findall("planningProblem"):
        for ref in problem.findall("goalState/position/lanelet"):
            text = (ref.get("ref") or "").strip()
            if _id(text) not in lanelets:
                raise ImportFailure(str(path), f"planningProblem {problem.get('id')} goalState",
                                    f"its goal lanelet {text or '(no ref)'} is not a lanelet "
                                    "of the file")


def check_structure(path: Path) -> None:
    """Parse ``path`` and check its structure (module docstring); ImportFailure names
    the file and the element."""
    root = _parse(path)
    _check_root(path, root)
    _check_goals(path, root, _check_ids(path, root))
