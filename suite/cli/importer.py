"""``hwyeval import commonroad FILE.xml [FILE ...] --out DIR``: recorded CommonRoad
scenarios -> a SUMO net, a tracks file and a ``catalog.toml`` scenario per file
(docs/recorded.md; :mod:`suite.importers.commonroad`).

One line per file (what was built, lanes/edges, tracks kept/dropped, corrections), the
warnings on stderr. Exit codes: 0 every file imported; 2 bad input (a file that cannot
be imported, named with its element; commonroad-io missing; an --out the import may not
write: :mod:`suite.importers.common.out_guard`, refused before anything is written).
The files that did import keep their outputs and are listed in DIR/catalog.toml even
when another file failed.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from suite.cli.common import (
    EXIT_INPUT,
    EXIT_OK,
    Output,
    add_import_output,
    err,
    whole_number,
    writing_to,
)
from suite.cli.import_openscenario import add_openscenario_parser


def _metres(text: str) -> float:
    """A road length [m] in (0, net_build.MAX_EXTENSION_M] (it sizes a run's memory)."""
    from suite.importers.commonroad.net_build import MAX_EXTENSION_M

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a length in metres > 0, got {text!r}") \
            from None
    if not 0.0 < value <= MAX_EXTENSION_M:
        raise argparse.ArgumentTypeError(f"expected a length in metres > 0 and at most "
                                         f"{MAX_EXTENSION_M:g}, got {text}")
    return value


def _obstacle_id(text: str) -> int:
    return whole_number(text, 0, "an obstacle id (an integer)")


def add_import_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The ``import`` sub-command and its formats (``commonroad``, ``openscenario``)."""
    s = sub.add_parser("import", help="import scenarios (CommonRoad recordings, OpenSCENARIO "
                                      "files) into a catalog folder")
    fmt = s.add_subparsers(dest="format", required=True)
    c = fmt.add_parser("commonroad", help="CommonRoad XML files -> nets, tracks, catalog.toml")
    c.add_argument("files", nargs="+", metavar="FILE.xml")
    add_import_output(c, "docs/recorded.md")
    c.add_argument("--extension-m", type=_metres, default=None, metavar="M",
                   help="straight road added where the recorded road ends (default 1000)")
    c.add_argument("--approach-m", type=_metres, default=None, metavar="M",
                   help="straight road added where it begins (default 200)")
    c.add_argument("--ego-obstacle", type=_obstacle_id, default=None, metavar="ID",
                   help="make the recorded vehicle (dynamic obstacle) ID the ego: its first "
                   "state is the ego's start, its track the ego's recorded trajectory "
                   "(controller 'recorded'); one FILE only (docs/recorded.md)")
    c.set_defaults(func=cmd_import_commonroad)
    add_openscenario_parser(fmt)


def _line(r: object) -> str:
    from suite.importers.commonroad import FileResult

    if not isinstance(r, FileResult):  # pragma: no cover - typed by the caller
        raise TypeError(type(r).__name__)
    dropped = ", ".join(f"{len(v)} {k}" for k, v in sorted(r.dropped.items()) if v)
    step = (f"dt corrected {r.step.header_dt_s:g} -> {r.step.dt_s:g} s" if r.step.corrected
            else f"dt {r.step.dt_s:g} s")
    extra = [step]
    if r.uncertain_states:
        extra.append(f"{r.uncertain_states} uncertain states -> centres")
    if r.stalled:
        extra.append(f"{r.stalled} stalled")
    return (f"{r.source.name} -> {r.name}: {r.net_path.name} ({r.recorded_edges} recorded + "
            f"{r.edges - r.recorded_edges} extension edges, {r.lanes} lanes, extended "
            f"{r.extension_m:g} m), {r.tracks_path.name} ({r.kept} vehicles kept, "
            f"{dropped or 'none'} dropped), ego lane {r.ego_lane} at {r.ego_pos_m:.1f} m "
            f"({r.ego_lateral_m:+.2f} m off its centre)"
            f"{f', recorded ego {r.ego_track}' if r.ego_track else ''}, "
            f"{r.duration_s:g} s; {'; '.join(extra)} [{r.wall_s:.2f} s]")


def cmd_import_commonroad(args: argparse.Namespace) -> int:
    """The import under DIR's lock (suite.exec.out_lock): another command writing DIR is
    refused (exit 2) before anything is read or written."""
    with writing_to(Path(args.out)):
        return _import_commonroad(args)


def _import_commonroad(args: argparse.Namespace) -> int:
    from suite.importers.commonroad import ImportParams, OutputRefused, import_files
    from suite.importers.commonroad.net_build import NetParams

    net = NetParams()
    net = NetParams(downstream_extension_m=args.extension_m or net.downstream_extension_m,
                    upstream_extension_m=args.approach_m or net.upstream_extension_m,
                    speed_limit_mps=net.speed_limit_mps)
    out = Output()
    if args.ego_obstacle is not None and len(args.files) != 1:
        err(f"--ego-obstacle {args.ego_obstacle}: expected one FILE (obstacle ids are a "
            f"file's own), got {len(args.files)}")
        return EXIT_INPUT
    try:
        outcome = import_files([Path(f) for f in args.files], Path(args.out),
                               ImportParams(net=net, ego_obstacle=args.ego_obstacle),
                               overwrite=args.overwrite)
    except (ImportError, OutputRefused) as exc:  # commonroad-io missing; --out refused
        err(str(exc))
        return EXIT_INPUT
    for r in outcome.results:
        out.line(_line(r))
        for note in r.notes:
            if note.startswith("WARNING"):
                err(f"warning: {r.source.name}: {note[len('WARNING '):]}")
    for f in outcome.failures:
        err(str(f))
    if outcome.catalog is not None:
        out.line(f"catalog: {outcome.catalog}")
    return EXIT_INPUT if outcome.failures else EXIT_OK
