"""OpenSCENARIO expressions (``${...}``), evaluated by a small parser of its own (never
Python's eval).

Grammar (OpenSCENARIO 1.x, lowest precedence first)::

    expr  := or ; or := and ('or' and)* ; and := not ('and' not)*
    not   := 'not' not | cmp ; cmp := sum (('=='|'!='|'<'|'<='|'>'|'>=') sum)?
    sum   := prod (('+'|'-') prod)* ; prod := unary (('*'|'/'|'%') unary)*
    unary := '-' unary | power ; power := atom ('**' unary)?
    atom  := number | 'true' | 'false' | $name | name '(' expr (',' expr)* ')' | '(' expr ')'

Functions: round, floor, ceil, sqrt, pow, sin, cos, tan, asin, acos, atan, sign, abs,
max, min. Booleans are 1.0 / 0.0 in arithmetic. Errors raise :class:`ExprError`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass

__all__ = ["ExprError", "evaluate"]

Value = float | bool | str


class ExprError(ValueError):
    """An expression that cannot be evaluated, and why."""


_TOKEN = re.compile(r"\s*(?:(\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?)"
                    r"|(\$[A-Za-z_][A-Za-z0-9_]*)|([A-Za-z_][A-Za-z0-9_]*)"
                    r"|(\*\*|==|!=|<=|>=|[-+*/%<>(),]))")


def _round(x: float) -> float:
    return float(math.floor(x + 0.5)) if x >= 0 else -float(math.floor(-x + 0.5))


def _sign(x: float) -> float:
    return 0.0 if x == 0 else math.copysign(1.0, x)


_FUNCS: dict[str, tuple[int, Callable[..., float]]] = {
    "round": (1, _round), "floor": (1, math.floor), "ceil": (1, math.ceil),
    "sqrt": (1, math.sqrt), "pow": (2, math.pow), "sin": (1, math.sin), "cos": (1, math.cos),
    "tan": (1, math.tan), "asin": (1, math.asin), "acos": (1, math.acos),
    "atan": (1, math.atan), "sign": (1, _sign), "abs": (1, abs), "max": (-2, max),
    "min": (-2, min),
}
MAX_TOKENS = 4000


def _tokens(text: str) -> list[str]:
    out: list[str] = []
    pos = 0
    text = text.rstrip()
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            raise ExprError(f"unexpected character {text[pos:].strip()[:1]!r} at {pos}")
        out.append(next(g for g in m.groups() if g is not None))
        pos = m.end()
        if len(out) > MAX_TOKENS:
            raise ExprError("expression too long")
    return out


def _num(v: Value) -> float:
    if isinstance(v, bool):
        return 1.0 if v else 0.0
    if isinstance(v, float | int):
        return float(v)
    try:
        return float(v)
    except ValueError:
        raise ExprError(f"{v!r} is not a number") from None


@dataclass
class _Parser:
    toks: list[str]
    params: Mapping[str, Value]
    i: int = 0

    def peek(self) -> str | None:
        return self.toks[self.i] if self.i < len(self.toks) else None

    def take(self, want: str | None = None) -> str:
        tok = self.peek()
        if tok is None or (want is not None and tok != want):
            raise ExprError(f"expected {want or 'more'}, got {tok or 'the end'}")
        self.i += 1
        return tok

    def parse(self) -> Value:
        v = self.or_()
        if self.peek() is not None:
            raise ExprError(f"unexpected {self.peek()!r}")
        return v

    def or_(self) -> Value:
        v = self.and_()
        while self.peek() == "or":
            self.take()
            rhs = self.and_()
            v = bool(_num(v)) or bool(_num(rhs))
        return v

    def and_(self) -> Value:
        v = self.not_()
        while self.peek() == "and":
            self.take()
            rhs = self.not_()
            v = bool(_num(v)) and bool(_num(rhs))
        return v

    def not_(self) -> Value:
        if self.peek() == "not":
            self.take()
            return not bool(_num(self.not_()))
        return self.cmp()

    def cmp(self) -> Value:
        v = self.sum_()
        op = self.peek()
        if op in ("==", "!=", "<", "<=", ">", ">="):
            self.take()
            a, b = _num(v), _num(self.sum_())
            return {"==": a == b, "!=": a != b, "<": a < b, "<=": a <= b, ">": a > b,
                    ">=": a >= b}[op]
        return v

    def sum_(self) -> Value:
        v = self.prod()
        while self.peek() in ("+", "-"):
            op = self.take()
            rhs = _num(self.prod())
            v = _num(v) + rhs if op == "+" else _num(v) - rhs
        return v

    def prod(self) -> Value:
        v = self.unary()
        while self.peek() in ("*", "/", "%"):
            op = self.take()
            a, b = _num(v), _num(self.unary())
            if op != "*" and b == 0.0:
                raise ExprError("division by zero")
            v = a * b if op == "*" else a / b if op == "/" else math.fmod(a, b)
        return v

    def unary(self) -> Value:
        if self.peek() == "-":
            self.take()
            return -_num(self.unary())
        return self.power()

    def power(self) -> Value:
        v = self.atom()
        if self.peek() == "**":
            self.take()
            return _checked(math.pow, _num(v), _num(self.unary()))
        return v

    def atom(self) -> Value:
        tok = self.take()
        if tok == "(":
            v = self.or_()
            self.take(")")
            return v
        if tok.startswith("$"):
            name = tok[1:]
            if name not in self.params:
                raise ExprError(f"unknown parameter ${name}")
            return self.params[name]
        if tok in ("true", "false"):
            return tok == "true"
        if tok in _FUNCS:
            return self.call(tok)
        if tok[0].isdigit() or tok[0] == ".":
            return float(tok)
        raise ExprError(f"unexpected {tok!r}")

    def call(self, name: str) -> float:
        arity, fn = _FUNCS[name]
        self.take("(")
        args = [_num(self.or_())]
        while self.peek() == ",":
            self.take()
            args.append(_num(self.or_()))
        self.take(")")
        if (arity > 0 and len(args) != arity) or (arity < 0 and len(args) < -arity):
            raise ExprError(f"{name}() takes {abs(arity)} argument(s), got {len(args)}")
        return _checked(fn, *args)


def _checked(fn: Callable[..., float], *args: float) -> float:
    try:
        v = float(fn(*args))
    except (ValueError, OverflowError) as exc:
        raise ExprError(f"{getattr(fn, '__name__', 'function')}{tuple(args)}: {exc}") from None
    if not math.isfinite(v):
        raise ExprError(f"{getattr(fn, '__name__', 'function')}{tuple(args)} is not finite")
    return v


def evaluate(text: str, params: Mapping[str, Value]) -> Value:
    """The value of expression ``text`` (without ``${`` ``}``) with ``params``."""
    return _Parser(_tokens(text), params).parse()
