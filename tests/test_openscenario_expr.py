"""OpenSCENARIO expressions and parameters (suite.importers.openscenario.expr, .params):
known values, precedence, functions, booleans, and refusals (never Python's eval)."""

from __future__ import annotations

import math

import pytest

from suite.importers.openscenario.expr import ExprError, evaluate
from suite.importers.openscenario.params import resolve_text

P: dict[str, float | bool | str] = {"a": -5.0, "b": 5.0, "v": 60.0, "flag": True,
                                   "name": "car"}


@pytest.mark.parametrize(("text", "value"), [
    ("1 + 2 * 3", 7.0), ("(1 + 2) * 3", 9.0), ("2 ** 3 ** 2", 512.0), ("-2 ** 2", -4.0),
    ("7 % 4", 3.0), ("10 / 4", 2.5), ("-$a", 5.0), ("$v / 3.6", 60.0 / 3.6),
    ("2 * sqrt( $a * $a ) / ($b / 3.6)", 2 * 5.0 / (5.0 / 3.6)),
    ("round(2.5) + round(-2.5)", 0.0), ("floor(-1.5) + ceil(1.2)", 0.0),
    ("pow(2, 10)", 1024.0), ("abs($a) + sign($a)", 4.0), ("max(1, 4, 2) - min(3, 2)", 2.0),
    ("sin(0) + cos(0) + tan(0) + asin(0) + acos(1) + atan(0)", 1.0), ("1.5e2", 150.0),
    (".5 + 1.", 1.5),
])
def test_arithmetic(text: str, value: float) -> None:
    assert evaluate(text, P) == pytest.approx(value)


@pytest.mark.parametrize(("text", "value"), [
    ("1 < 2", True), ("2 <= 1", False), ("3 == 3", True), ("3 != 3", False),
    ("not true", False), ("true and false or true", True), ("not (1 > 2) and $flag", True),
    ("1 + 1 == 2 and 2 >= 2", True),
])
def test_comparisons_and_logic(text: str, value: bool) -> None:
    assert evaluate(text, P) is value


@pytest.mark.parametrize(("text", "why"), [
    ("$missing + 1", "unknown parameter"), ("1 / 0", "division by zero"),
    ("sqrt(-1)", "sqrt"), ("max(1)", "argument"), ("(1 + 2", "expected"),
    ("1 + ", "expected"), ("__import__('os')", "unexpected"), ("1 ; 2", "unexpected"),
    ("$name * 2", "not a number"), ("pow(10, 400)", "pow"),
])
def test_refusals(text: str, why: str) -> None:
    with pytest.raises(ExprError, match=why):
        evaluate(text, P)


def test_attribute_values() -> None:
    assert resolve_text("${$v / 3.6}", P) == pytest.approx(60.0 / 3.6)
    assert resolve_text("$name", P) == "car"
    assert resolve_text("12.5", P) == "12.5"
    assert math.isclose(float(resolve_text("${-$a}", P)), 5.0)
    with pytest.raises(ExprError, match="unknown"):
        resolve_text("$nope", P)
