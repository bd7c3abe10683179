"""Reading XML safely: lxml with no entity resolution, no network, no DTD loading and
no huge trees; a document type declaring entities (external or internal: the way to an
entity bomb) is refused."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from lxml import etree

from suite.importers.openscenario.errors import OscImportError

__all__ = ["read_xml"]

MAX_BYTES = 64 * 1024 * 1024  # a larger scenario or road file is refused [bytes]


def _parser() -> Any:
    return etree.XMLParser(resolve_entities=False, no_network=True, huge_tree=False,
                           load_dtd=False, dtd_validation=False, remove_comments=True,
                           remove_pis=True)


def read_xml(path: Path) -> Any:
    """The parsed tree of ``path`` (:class:`OscImportError` when unreadable, malformed,
    too large or declaring entities)."""
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise OscImportError(str(path), "file", f"cannot read it: {exc}") from None
    if size > MAX_BYTES:
        raise OscImportError(str(path), "file", f"{size} bytes, more than {MAX_BYTES}")
    try:
        tree = etree.parse(str(path), _parser())
    except etree.XMLSyntaxError as exc:
        raise OscImportError(str(path), "file", f"not well-formed XML: {exc}",
                             int(getattr(exc, "lineno", 0) or 0)) from None
    dtd = tree.docinfo.internalDTD
    if dtd is not None and (list(dtd.iterentities()) or tree.docinfo.system_url):
        raise OscImportError(str(path), "DOCTYPE", "a document type declaring entities "
                             "(external entities, entity expansion) is refused")
    if tree.docinfo.system_url or tree.docinfo.public_id:
        raise OscImportError(str(path), "DOCTYPE", "an external document type is refused")
    _refuse_entity_refs(tree, path)
    return tree


def _refuse_entity_refs(tree: Any, path: Path) -> None:
    """An unresolved entity reference left in the tree is refused too."""
    for el in tree.iter():
        if isinstance(el, etree._Entity):
            raise OscImportError(str(path), "DOCTYPE", f"entity reference &{el.name}; "
                                 "refused", int(el.sourceline or 0))
