"""What a run tested, under which limits, on which system: the three kinds of change.

A run's set-up splits into three parts, each with its own digest (SHA-256, hex):

* **the test** (:data:`TEST_KEY`): what the world does around the ego — the net (its
  file's bytes), the route, the ego's start, the stalled cars, the scripted actors,
  the traffic, the recorded tracks (their file's bytes), duration and steps, seed,
  friction, shoulder use, recording radius: every field of the resolved scenario
  (``Scenario.as_dict()``) but :data:`NOT_TEST_FIELDS`. Written into ``run.json``'s
  ``info.scenario_spec`` by the runner (:func:`suite.run.info.scenario_info`);
* **the limits**: the criteria in force (``Verdict.criteria``, every criterion with its
  limit, ``None`` = off);
* **the system under test** (SUT): the controller's name, its resolved options
  (``RunInfo.controller_params``; the catalog's options when the controller never
  built) and the hash of its code (:data:`CONTROLLER_KEY`: a plug-in's source, or the
  ``controllers`` package for a built-in one; older runs: hwyeval's whole source,
  :data:`CODE_KEY`).

:func:`setup_of` reads the three from a run; :func:`setup_change` says what differs
between two runs of one scenario. ``compare`` compares a pair run for run whenever its
test is unchanged, whatever happened to the SUT (that is what the gate is for); a
changed test is labelled and does not gate; a changed limit is labelled and the new run
is also judged under the old limits (docs/nightly.md).

**Older run directories** carry no :data:`TEST_KEY`. When either side of a pair lacks
it, both sides' tests are compared by :attr:`Setup.test_spec`, the digest of the test
fields of the recorded ``scenario_spec`` (with the net and tracks by name: their bytes
were not recorded) or, for a run without a recorded spec, of ``RunInfo``'s own test
fields (net name, duration, step, seed, set speed, friction, shoulder).
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from reports.record import RunInfo, Verdict

__all__ = ["CHANGE_KINDS", "CODE_KEY", "CONTENT_KEY", "CONTROLLER_KEY", "LIMITS_KEY",
           "NOT_TEST_FIELDS", "SUT_KEY", "TEST_KEY", "LimitChange", "OptionChange", "Setup",
           "SetupChange", "SetupDigests", "SutChange", "digest", "flatten_options",
           "limits_sha256", "setup_change", "setup_digests", "setup_from", "setup_of",
           "sut_sha256", "test_sha256"]

CONTENT_KEY = "content_sha256"  # everything a run depends on (--resume compares it)
TEST_KEY = "test_sha256"
LIMITS_KEY = "limits_sha256"
SUT_KEY = "sut_sha256"
CODE_KEY = "code_sha256"  # hwyeval's own sources (suite.run.code_identity)
CONTROLLER_KEY = "controller_sha256"  # the controller's code (suite.run.code_identity)
HASH_KEYS = (CONTENT_KEY, TEST_KEY, LIMITS_KEY, SUT_KEY, CODE_KEY, CONTROLLER_KEY)
# The kinds of change between two runs of one scenario, in the order they are named.
CHANGE_KINDS = ("test", "limits", "sut")
# Scenario fields that are not the test: its names, where things are, the wall-clock
# budget, the system under test (controller), the limits (criteria), the expectation
# (xfail) and the groups it is reported in (labels). sweep_values repeats values of
# other fields (a swept controller option among them), so it is left out too.
NOT_TEST_FIELDS = ("name", "family", "sweep_values", "catalog_path", "net_path",
                   "timeout_s", "controller", "criteria", "xfail", "labels", *HASH_KEYS)
# RunInfo's own test fields, for a run without a recorded scenario_spec
_INFO_TEST_FIELDS = ("net_name", "duration_s", "step_s", "seed", "target_speed_mps",
                     "allow_shoulder", "friction", "record_radius_m")
MAX_OPTION_CHANGES = 6  # option changes named in a finding before "and N more"
SHORT_HASH = 10


def digest(value: Any) -> str:
    """SHA-256 (hex) of ``value`` as canonical JSON (sorted keys, no spaces; a value
    JSON cannot hold is spelt with ``str``)."""
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=True,
                      default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _test_fields(spec: Mapping[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in spec.items() if k not in NOT_TEST_FIELDS}


def test_sha256(spec: Mapping[str, Any], net_sha256: str, tracks_sha256: str | None) -> str:
    """The test's digest from a resolved scenario's fields (``Scenario.as_dict()``), the
    net file's SHA-256 and, with recorded traffic, the tracks file's."""
    content: dict[str, Any] = {"test": _test_fields(spec), "net_sha256": net_sha256}
    if tracks_sha256 is not None:
        content["tracks_sha256"] = tracks_sha256
    return digest(content)


def _limit(value: Any) -> float | None:
    """A stored limit as a float (None: off; a non-number, e.g. "off", is off too)."""
    if value is None or isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value)


def limits_sha256(criteria: Mapping[str, Any]) -> str:
    """Digest of the limits in force: criterion -> limit, the criteria that are on only
    (an off criterion limits nothing, so a new criterion that is off by default leaves
    every run's limits as they were)."""
    return digest({k: limit for k, v in criteria.items() if (limit := _limit(v)) is not None})


def sut_sha256(controller: str, params: Mapping[str, Any], code: str) -> str:
    """Digest of the system under test: controller name, resolved options (nested, as
    the controller gives them), code hash."""
    return _sut_digest(controller, flatten_options(dict(params)), code)


def _sut_digest(controller: str, flat_params: Mapping[str, str], code: str) -> str:
    return digest({"controller": controller, "params": dict(flat_params), "code": code})


def flatten_options(value: Any, prefix: str = "") -> dict[str, str]:
    """Nested options as dotted key -> canonical JSON text of the leaf."""
    if isinstance(value, Mapping) and value:
        out: dict[str, str] = {}
        for k, v in value.items():
            out.update(flatten_options(v, f"{prefix}.{k}" if prefix else str(k)))
        return out
    return {prefix: json.dumps(value, sort_keys=True, allow_nan=True, default=str)}


@dataclass(frozen=True)
class Setup:
    """A run's set-up in the three parts (module doc).

    test: the recorded test digest ('' in older runs); test_spec: the digest of the
    recorded test fields (always known; net and tracks by name); limits: criterion ->
    limit in force (None: off), sorted by name; controller: its registered name;
    params: its resolved options flattened (dotted key, JSON text), sorted; code: the
    hash of its code ('' unknown)."""

    test: str
    test_spec: str
    limits: tuple[tuple[str, float | None], ...]
    controller: str
    params: tuple[tuple[str, str], ...]
    code: str

    def __post_init__(self) -> None:
        if not self.test_spec:
            raise ValueError("Setup.test_spec must not be empty")
        if list(self.limits) != sorted(self.limits, key=lambda kv: kv[0]):
            raise ValueError("Setup.limits must be sorted by criterion")
        if list(self.params) != sorted(self.params):
            raise ValueError("Setup.params must be sorted by key")

    @property
    def limits_sha256(self) -> str:
        return limits_sha256(dict(self.limits))

    @property
    def sut_sha256(self) -> str:
        return _sut_digest(self.controller, dict(self.params), self.code)

    def limit(self, criterion: str) -> float | None:
        return dict(self.limits).get(criterion)


def setup_of(info: RunInfo, verdict: Verdict | None) -> Setup:
    """The set-up of a run from its ``run.json`` (module doc: older runs); without a
    verdict the limits in force are unknown (empty: never a limit change)."""
    return setup_from(info, verdict.criteria if verdict is not None else {})


def setup_from(info: RunInfo, criteria: Mapping[str, Any]) -> Setup:
    """:func:`setup_of` with the limits in force given (``Verdict.criteria``)."""
    spec = info.scenario_spec or {}
    fields = _test_fields(spec)
    own = {k: getattr(info, k) for k in _INFO_TEST_FIELDS}
    test_spec = digest(fields if fields else own)
    params = info.controller_params or info.controller_options
    code = str(spec.get(CONTROLLER_KEY) or spec.get(CODE_KEY) or "")
    return Setup(test=str(spec.get(TEST_KEY) or ""), test_spec=test_spec,
                 limits=tuple(sorted((k, _limit(v)) for k, v in criteria.items())),
                 controller=info.controller,
                 params=tuple(sorted(flatten_options(dict(params)).items())), code=code)


@dataclass(frozen=True)
class SetupDigests:
    """The three parts of a set-up as digests (what the history stores per run): test
    ('' when not recorded), test_spec (the fallback; '' when the recorded test made it
    unnecessary), limits, sut."""

    test: str
    test_spec: str
    limits: str
    sut: str


def setup_digests(info: RunInfo, criteria: Mapping[str, Any]) -> SetupDigests:
    """The set-up digests the history stores for a run (:class:`SetupDigests`) from its
    typed ``info`` and the limits in force (``Verdict.criteria``): the recorded test
    and system-under-test digests as they are; an older run's worked out as
    :func:`setup_from` does (the test's from its recorded fields, the fallback
    ``test_spec`` only when no test digest is recorded)."""
    setup = setup_from(info, criteria)
    recorded_sut = str((info.scenario_spec or {}).get(SUT_KEY) or "")
    return SetupDigests(test=setup.test, test_spec="" if setup.test else setup.test_spec,
                        limits=setup.limits_sha256 if criteria else "",
                        sut=recorded_sut or setup.sut_sha256)


@dataclass(frozen=True)
class LimitChange:
    """A criterion whose limit differs: ``base`` -> ``new`` (None: off)."""

    criterion: str
    base: float | None
    new: float | None

    def __post_init__(self) -> None:
        if self.base == self.new:
            raise ValueError(f"LimitChange {self.criterion}: the limit did not change")

    @property
    def waived(self) -> bool:
        """In force in base, switched off in new: a waiver (a limit change, never a fix)."""
        return self.base is not None and self.new is None

    @property
    def text(self) -> str:
        return f"{self.criterion} {_limit_text(self.base)} → {_limit_text(self.new)}"


def _limit_text(value: float | None) -> str:
    if value is None:
        return "off"
    return f"{value:g}" if math.isfinite(value) else str(value)


@dataclass(frozen=True)
class OptionChange:
    """A resolved controller option that differs (JSON text each side; '' absent)."""

    key: str
    base: str
    new: str

    @property
    def text(self) -> str:
        return f"{self.key} {self.base or '(absent)'} → {self.new or '(absent)'}"


@dataclass(frozen=True)
class SutChange:
    """What differs in the system under test: the controller (base, new names; '' when
    the same), its options (for the same controller) and its code hashes ('' each
    when the same or unknown on a side)."""

    controller_base: str = ""
    controller_new: str = ""
    options: tuple[OptionChange, ...] = ()
    code_base: str = ""
    code_new: str = ""

    def __post_init__(self) -> None:
        if not (self.controller_base or self.options or self.code_base or self.code_new):
            raise ValueError("SutChange: nothing changed")

    @property
    def text(self) -> str:
        """``controller a → b; options k 1 → 2, ...; controller code 1a2b… → 3c4d…``."""
        parts = []
        if self.controller_base:
            parts.append(f"controller {self.controller_base} → {self.controller_new}")
        if self.options:
            shown = ", ".join(o.text for o in self.options[:MAX_OPTION_CHANGES])
            more = len(self.options) - MAX_OPTION_CHANGES
            parts.append(f"options {shown}" + (f" and {more} more" if more > 0 else ""))
        if self.code_base or self.code_new:
            parts.append(f"controller code {self.code_base[:SHORT_HASH] or '?'} → "
                         f"{self.code_new[:SHORT_HASH] or '?'}")
        return "; ".join(parts)


def sut_change(base: Setup, new: Setup) -> SutChange | None:
    """What differs in the SUT of two set-ups (None: nothing known to differ)."""
    swapped = base.controller != new.controller
    options: tuple[OptionChange, ...] = ()
    if not swapped:  # a swap changes every option: the names say it
        bp, np_ = dict(base.params), dict(new.params)
        options = tuple(OptionChange(k, bp.get(k, ""), np_.get(k, ""))
                        for k in sorted(set(bp) | set(np_)) if bp.get(k) != np_.get(k))
    code = bool(base.code and new.code and base.code != new.code)
    if not (swapped or options or code):
        return None
    return SutChange(controller_base=base.controller if swapped else "",
                     controller_new=new.controller if swapped else "", options=options,
                     code_base=base.code if code else "", code_new=new.code if code else "")


@dataclass(frozen=True)
class SetupChange:
    """What differs between two runs of one scenario: the test (compared by the
    recorded digests when both have one, else by :attr:`Setup.test_spec`), the limits
    (every criterion whose limit differs) and the SUT (None: unchanged)."""

    test: bool = False
    limits: tuple[LimitChange, ...] = ()
    sut: SutChange | None = None

    @property
    def kinds(self) -> tuple[str, ...]:
        """The kinds of change (:data:`CHANGE_KINDS`) present, in that order."""
        present = {"test": self.test, "limits": bool(self.limits), "sut": self.sut is not None}
        return tuple(k for k in CHANGE_KINDS if present[k])

    @property
    def waived(self) -> tuple[LimitChange, ...]:
        return tuple(c for c in self.limits if c.waived)


def setup_change(base: Setup, new: Setup) -> SetupChange:
    """The :class:`SetupChange` from ``base`` to ``new``."""
    if base.test and new.test:
        test = base.test != new.test
    else:
        test = base.test_spec != new.test_spec
    bl, nl = dict(base.limits), dict(new.limits)
    limits = tuple(LimitChange(k, bl.get(k), nl.get(k)) for k in sorted(set(bl) | set(nl))
                   if bl.get(k) != nl.get(k)) if bl and nl else ()
    return SetupChange(test=test, limits=limits, sut=sut_change(base, new))
