"""junit.xml: one testcase per run, readable by CI JUnit parsers (Jenkins, GitLab, GitHub).

``<testsuites>`` holds one ``<testsuite>`` per controller; each run is a ``<testcase
name=scenario classname="controller.family" time=wall_s>``. A failed run carries
``<failure message=... type="criteria">`` listing the stored verdict's failures (one
line each, with the time and trace step where the criterion was violated), an error
run ``<error type="error">`` with the traceback (or why its directory cannot be read),
a timeout ``<error type="timeout">``. Key metrics go to ``<system-out>``: those with a
``junit`` rank in the metric catalogue (:mod:`reports.metrics.catalogue`), in its order.

A known failure (``xfail``, :mod:`reports.expectation`) that failed as expected is
``<skipped type="xfail" message="expected failure: <reason>">`` with its failures as
text, as pytest writes an xfail; one that passed is ``<failure type="xpass">`` ("fixed:
remove the xfail") under ``strict``, else a passing case saying so in ``<system-out>``.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path

from reports.expectation import XFAILED, XPASSED
from reports.manifest import Manifest, not_run
from reports.metrics.catalogue import JUNIT_METRICS
from reports.record import Failure
from reports.record.codec import write_text_atomic
from reports.tables import RunEntry

_INVALID_XML = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")
# the metrics of a case's <system-out>, in order: the catalogue's ``junit`` role
KEY_METRICS = JUNIT_METRICS


def xml_text(text: str) -> str:
    """Text with characters XML 1.0 forbids removed."""
    return _INVALID_XML.sub("", text)


def _time(run: RunEntry) -> str:
    wall = run.wall_s
    if math.isfinite(wall) and wall >= 0:
        return f"{wall:.3f}"
    return "0"


def failure_line(failure: Failure) -> str:
    """``metric=value>limit`` and where it was violated (or that it is an aggregate):
    :attr:`reports.record.Failure.line`."""
    return failure.line


def _safe_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_\-]+", "_", text) or "_"


def _properties(parent: ET.Element, manifest: Manifest | None) -> None:
    """``<properties>``: the catalog, git revision (and dirty), hwyeval version, host."""
    if manifest is None:
        return
    p = manifest.provenance
    props = ET.SubElement(parent, "properties")
    for name, value in (("catalog", manifest.catalog), ("git_revision", p.git_sha),
                        ("git_dirty", str(bool(p.git_dirty)).lower()),
                        ("hwyeval_version", p.hwyeval_version), ("host", p.host),
                        ("started", manifest.started)):
        ET.SubElement(props, "property", name=name, value=xml_text(str(value)))


def _not_run_suite(root: ET.Element, suite_name: str, names: Sequence[str],
                   manifest: Manifest | None) -> None:
    """The scenarios the manifest lists that were not run (an interrupted night), as
    skipped test cases: a stopped run never reads as complete and green."""
    suite = ET.SubElement(root, "testsuite", name=xml_text(f"{suite_name}.not_run"),
                          tests=str(len(names)), failures="0", errors="0",
                          skipped=str(len(names)), time="0")
    _properties(suite, manifest)
    for name in names:
        case = ET.SubElement(suite, "testcase", name=xml_text(name), classname="not_run",
                             time="0")
        ET.SubElement(case, "skipped", message="not run (the run was interrupted; "
                      "hwyeval run ... --resume runs it)")


def _outcome(case: ET.Element, run: RunEntry) -> None:
    """The case's ``<failure>``, ``<error>`` or ``<skipped>`` (module doc)."""
    seen = run.expectation
    mark = run.xfail
    if seen == XFAILED and mark is not None:
        node = ET.SubElement(case, "skipped", type="xfail",
                             message=xml_text(f"expected failure: {mark.reason}"))
        node.text = xml_text("\n".join(failure_line(f) for f in run.failures))
    elif seen == XPASSED and mark is not None and mark.strict:
        ET.SubElement(case, "failure", type="xpass", message=xml_text(
            f"unexpected pass (strict xfail: {mark.reason}): fixed: remove the xfail"))
    elif run.status == "fail":
        listing = "; ".join(f.text for f in run.failures) or "failed"
        node = ET.SubElement(case, "failure", message=xml_text(listing), type="criteria")
        node.text = xml_text("\n".join(failure_line(f) for f in run.failures))
    elif run.status == "timeout":
        first = run.error.strip().splitlines()[0] if run.error.strip() else "timeout"
        node = ET.SubElement(case, "error", message=xml_text(first), type="timeout")
        node.text = xml_text(run.error)
    elif run.status == "error":
        lines = run.error.strip().splitlines()
        node = ET.SubElement(case, "error", message=xml_text(lines[-1] if lines else "error"),
                             type="error")
        node.text = xml_text(run.error)


def _system_out(case: ET.Element, run: RunEntry) -> None:
    if run.verdict is None or not run.verdict.metrics:
        return
    values = run.verdict.values()
    out = ET.SubElement(case, "system-out")
    note = ""
    if run.expectation == XPASSED and run.xfail is not None and not run.xfail.strict:
        note = f"\nunexpected pass (xfail: {run.xfail.reason}): fixed: remove the xfail"
    out.text = xml_text("\n".join(f"{k}={values[k]:.6g}" for k in KEY_METRICS if k in values)
                        + f"\nrun_dir={run.run_dir}" + note)


def junit_tree(runs: Sequence[RunEntry], suite_name: str = "hwyeval",
               manifest: Manifest | None = None) -> ET.ElementTree:
    """The JUnit XML tree for the runs, with the manifest's provenance as properties and
    the scenarios it lists that have no run as skipped cases."""
    root = ET.Element("testsuites", name=xml_text(suite_name))
    by_controller: dict[str, list[RunEntry]] = {}
    for run in runs:
        by_controller.setdefault(run.controller, []).append(run)
    totals = {"tests": 0, "failures": 0, "errors": 0, "skipped": 0, "time": 0.0}
    for controller in sorted(by_controller):
        members = by_controller[controller]
        expected = sum(1 for r in members if r.expectation == XFAILED)
        failures = sum(1 for r in members if r.fails_night and r.status in ("fail", "pass"))
        errors = sum(1 for r in members if r.status in ("error", "timeout"))
        time_s = sum(float(_time(r)) for r in members)
        suite = ET.SubElement(root, "testsuite", name=xml_text(f"{suite_name}.{controller}"),
                              tests=str(len(members)), failures=str(failures),
                              errors=str(errors), skipped=str(expected), time=f"{time_s:.3f}")
        _properties(suite, manifest)
        for run in members:
            case = ET.SubElement(suite, "testcase", name=xml_text(run.scenario),
                                 classname=f"{_safe_name(run.controller)}."
                                           f"{_safe_name(run.family)}",
                                 time=_time(run))
            _outcome(case, run)
            _system_out(case, run)
        totals["tests"] += len(members)
        totals["failures"] += failures
        totals["errors"] += errors
        totals["skipped"] += expected
        totals["time"] += time_s
    skipped = not_run(manifest, [n for r in runs for n in (r.scenario, r.run_id)])
    if skipped:
        _not_run_suite(root, suite_name, skipped, manifest)
    root.set("tests", str(int(totals["tests"]) + len(skipped)))
    root.set("skipped", str(int(totals["skipped"]) + len(skipped)))
    root.set("failures", str(int(totals["failures"])))
    root.set("errors", str(int(totals["errors"])))
    root.set("time", f"{totals['time']:.3f}")
    ET.indent(root)
    return ET.ElementTree(root)


def write_junit(runs: Sequence[RunEntry], path: str | Path,
                manifest: Manifest | None = None) -> Path:
    """Write junit.xml; returns its path."""
    path = Path(path)
    root = junit_tree(runs, manifest=manifest).getroot()
    if root is None:  # junit_tree always builds a <testsuites> root
        raise ValueError("junit_tree built no root element")
    text = ET.tostring(root, encoding="unicode")
    write_text_atomic(path, "<?xml version='1.0' encoding='utf-8'?>\n" + text)
    return path
