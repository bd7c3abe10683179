"""Parameters: ``ParameterDeclarations``, ``$name`` references and ``${...}`` expressions
in attribute values, and the declarations' constraint groups.

A declaration's value may refer to parameters declared before it. Constraint groups
(``ConstraintGroup`` of ``ValueConstraint``) are alternatives (one group must hold);
inside a group every constraint must hold. A violation is an error naming the
parameter unless constraints are ignored (``--ignore-constraints``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from suite.catalog.storyboard import RULES, compare
from suite.importers.openscenario.errors import OscImportError, fail_at
from suite.importers.openscenario.expr import ExprError, Value, evaluate

__all__ = ["declare", "resolve_text", "resolve_tree"]

_TYPES = ("int", "double", "string", "boolean", "unsignedInt", "unsignedShort", "dateTime")


def resolve_text(text: str, params: Mapping[str, Value]) -> Value:
    """An attribute's value: ``${expr}`` evaluated, ``$name`` looked up, else itself
    (:class:`~suite.importers.openscenario.expr.ExprError` when it cannot be)."""
    t = text.strip()
    if t.startswith("${") and t.endswith("}"):
        return evaluate(t[2:-1], params)
    if t.startswith("$"):
        name = t[1:]
        if name not in params:
            raise ExprError(f"unknown parameter ${name}")
        return params[name]
    return text


def _typed(value: Value, kind: str) -> Value:
    if kind in ("int", "unsignedInt", "unsignedShort"):
        f = float(value) if not isinstance(value, bool) else float(value)
        if f != int(f) or (kind != "int" and f < 0):
            raise ExprError(f"{value!r} is not an {kind}")
        return float(int(f))
    if kind == "double":
        return float(value)
    if kind == "boolean":
        return value if isinstance(value, bool) else str(value).strip().lower() == "true"
    return value if isinstance(value, str) else _fmt(value)


def _fmt(value: Value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and value == int(value):
        return str(int(value))
    return str(value)


def declare(root: Any, overrides: Mapping[str, str] | None = None,
            ignore_constraints: bool = False) -> dict[str, Value]:
    """The parameters of ``root``'s top-level ``ParameterDeclarations`` (``overrides``
    by name replace declared values), constraints checked."""
    params: dict[str, Value] = {}
    overrides = dict(overrides or {})
    decls = root.find("ParameterDeclarations")
    for d in ([] if decls is None else decls.findall("ParameterDeclaration")):
        name, kind = d.get("name", ""), d.get("parameterType", "string")
        if not name or kind not in _TYPES:
            raise fail_at(d, f"a declaration needs a name and a parameterType of {_TYPES}")
        raw = overrides.pop(name, d.get("value", ""))
        try:
            params[name] = _typed(resolve_text(str(raw), params), kind)
        except (ExprError, ValueError) as exc:
            raise fail_at(d, f"parameter {name}: {exc}") from None
    if overrides:
        raise OscImportError(str(root.getroottree().docinfo.URL), "ParameterDeclarations",
                             f"parameter(s) {sorted(overrides)} are set but not declared")
    if not ignore_constraints and decls is not None:
        for d in decls.findall("ParameterDeclaration"):
            _check_constraints(d, params)
    return params


def _check_constraints(decl: Any, params: Mapping[str, Value]) -> None:
    groups = decl.findall("ConstraintGroup")
    if not groups:
        return
    name = decl.get("name")
    value = params[name]
    failed: list[str] = []
    for g in groups:
        ok = True
        for c in g.findall("ValueConstraint"):
            rule, raw = c.get("rule", ""), c.get("value", "")
            try:
                bound = resolve_text(raw, params)
            except ExprError as exc:
                raise fail_at(c, f"parameter {name}: constraint value {raw!r}: {exc}") from None
            if not _holds(value, rule, bound):
                ok = False
                failed.append(f"{rule} {_fmt(bound)}")
        if ok:
            return
    path = decl.getroottree().docinfo.URL
    raise OscImportError(str(path), f"parameter {name}", f"value {_fmt(value)} violates its "
                         f"constraints ({'; '.join(failed)}); --ignore-constraints to run "
                         "it anyway", int(decl.sourceline or 0))


def _holds(value: Value, rule: str, bound: Value) -> bool:
    if rule not in RULES:
        return False
    if isinstance(value, str) or isinstance(bound, str):
        a, b = _fmt(value), _fmt(bound)
        try:
            return compare(float(a), rule, float(b))
        except ValueError:
            return (a == b) if rule == "equalTo" else (a != b) if rule == "notEqualTo" else False
    return compare(float(value), rule, float(bound))


def resolve_tree(root: Any, params: Mapping[str, Value]) -> None:
    """Every attribute of ``root``'s elements (but the declarations' own) resolved in
    place; an unresolvable one is an error naming its element and line."""
    for el in root.iter():
        if not isinstance(el.tag, str) or el.tag in ("ParameterDeclaration", "ValueConstraint"):
            continue
        for key, raw in el.attrib.items():
            if "$" not in raw:
                continue
            try:
                el.set(key, _fmt(resolve_text(raw, params)))
            except (ExprError, ValueError) as exc:
                raise fail_at(el, f"attribute {key}={raw!r}: {exc}") from None
