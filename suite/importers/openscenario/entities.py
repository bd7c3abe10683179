"""Entities: each ``ScenarioObject`` (its catalog reference already resolved) -> a
:class:`~suite.catalog.storyboard.Entity` with its box, and which one is the ego."""

from __future__ import annotations

from typing import Any

from suite.catalog.storyboard import Entity
from suite.importers.openscenario.errors import OscImportError, fail_at
from suite.importers.openscenario.position_xml import num

__all__ = ["EGO_NAMES", "read_entities"]

EGO_NAMES = ("ego", "hero", "egovehicle", "ego_vehicle")
_KINDS = {"Vehicle": "vehicle", "Pedestrian": "pedestrian", "MiscObject": "misc"}


def _entity(obj: Any, ego: bool) -> Entity:
    kids = [k for k in obj if isinstance(k.tag, str) and k.tag != "ObjectController"]
    if len(kids) != 1 or kids[0].tag not in _KINDS:
        what = kids[0].tag if kids else "nothing"
        raise fail_at(kids[0] if kids else obj, f"entity {obj.get('name')}: {what} is not "
                      f"supported (a Vehicle, Pedestrian or MiscObject)")
    el = kids[0]
    box = el.find("BoundingBox")
    if box is None or box.find("Dimensions") is None or box.find("Center") is None:
        raise fail_at(el, "a BoundingBox with Center and Dimensions is required")
    dims, centre = box.find("Dimensions"), box.find("Center")
    length, width = num(dims, "length"), num(dims, "width")
    return Entity(str(obj.get("name")), _KINDS[str(el.tag)], length, width,
                  num(centre, "x") + 0.5 * length, ego)


def read_entities(root: Any, path: str, ego_name: str | None) -> tuple[Entity, ...]:
    """The entities; the ego is ``ego_name``, else the one named like an ego
    (:data:`EGO_NAMES`, case-insensitive)."""
    ents = root.find("Entities")
    objs = [] if ents is None else list(ents.iterfind("ScenarioObject"))
    for other in ([] if ents is None else ents):
        if isinstance(other.tag, str) and other.tag != "ScenarioObject":
            raise fail_at(other, f"{other.tag} is not supported (ScenarioObjects only)")
    names = [str(o.get("name")) for o in objs]
    if ego_name is None:
        found = [n for n in names if n.lower() in EGO_NAMES]
        if len(found) != 1:
            raise OscImportError(path, "Entities", f"cannot tell the ego among {names}: "
                                 "name it with --ego")
        ego_name = found[0]
    if ego_name not in names:
        raise OscImportError(path, "Entities", f"no entity {ego_name!r} (--ego) among {names}")
    out = tuple(_entity(o, o.get("name") == ego_name) for o in objs)
    if out[names.index(ego_name)].kind != "vehicle":
        raise OscImportError(path, "Entities", f"the ego {ego_name!r} must be a Vehicle")
    return out
