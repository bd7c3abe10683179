"""Catalog references: ``CatalogLocations`` (directories relative to the scenario file)
and every ``CatalogReference`` replaced by a copy of its entry (Vehicle, Pedestrian,
MiscObject, Controller, Maneuver, ...), the entry's own parameters set from the
reference's ``ParameterAssignments`` and resolved in it."""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from suite.importers.openscenario.errors import fail_at
from suite.importers.openscenario.params import declare, resolve_tree
from suite.importers.openscenario.xml_safe import read_xml

__all__ = ["CatalogIndex", "resolve_references"]


@dataclass
class CatalogIndex:
    """Catalog directories by kind (``VehicleCatalog`` ...) and the catalogs read so far
    (name -> entry name -> element)."""

    base: Path
    dirs: dict[str, list[Path]] = field(default_factory=dict)
    catalogs: dict[str, dict[str, Any]] = field(default_factory=dict)
    _read: set[Path] = field(default_factory=set)

    @classmethod
    def of(cls, root: Any, scenario: Path) -> CatalogIndex:
        index = cls(scenario.parent)
        locs = root.find("CatalogLocations")
        for kind in ([] if locs is None else list(locs)):
            d = kind.find("Directory")
            if d is None or not d.get("path"):
                raise fail_at(kind, "a catalog location needs a Directory path")
            index.dirs.setdefault(str(kind.tag), []).append(
                (index.base / d.get("path")).resolve())
        return index

    def _load_all(self) -> None:
        for paths in self.dirs.values():
            for d in paths:
                for f in sorted(d.glob("*.xosc")) if d.is_dir() else []:
                    self._load(f)

    def _load(self, path: Path) -> None:
        if path in self._read:
            return
        self._read.add(path)
        cat = read_xml(path).getroot().find("Catalog")
        if cat is None:
            return
        entries = self.catalogs.setdefault(cat.get("name", ""), {})
        for entry in cat:
            if isinstance(entry.tag, str) and entry.get("name"):
                entries[entry.get("name")] = entry

    def entry(self, ref: Any) -> Any:
        """The entry a CatalogReference names (error naming the reference if none)."""
        if not self.catalogs:
            self._load_all()
        cname, ename = ref.get("catalogName", ""), ref.get("entryName", "")
        entry = self.catalogs.get(cname, {}).get(ename)
        if entry is None:
            raise fail_at(ref, f"no entry {ename!r} in catalog {cname!r} (catalog "
                          f"directories: {[str(p) for v in self.dirs.values() for p in v]})")
        return entry


def _instance(ref: Any, entry: Any) -> Any:
    """A copy of ``entry`` with the reference's parameter assignments resolved in it."""
    inst = copy.deepcopy(entry)
    assigns = {a.get("parameterRef", ""): a.get("value", "")
               for a in ref.iterfind("ParameterAssignments/ParameterAssignment")}
    params = declare(inst, assigns)
    resolve_tree(inst, params)
    decls = inst.find("ParameterDeclarations")
    if decls is not None:
        inst.remove(decls)
    return inst


def resolve_references(root: Any, index: CatalogIndex) -> None:
    """Replace every CatalogReference under ``root`` by its resolved entry, in place."""
    for ref in list(root.iter("CatalogReference")):
        parent = ref.getparent()
        inst = _instance(ref, index.entry(ref))
        inst.tail = ref.tail
        parent.replace(ref, inst)
