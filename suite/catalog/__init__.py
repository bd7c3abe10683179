"""TOML scenario catalogs: parse, validate against the road network, expand sweeps.

This file format is a public contract. A catalog looks like::

    [defaults]                      # optional, merged into every scenario
    controller = "lane_keep"        # a registered controller name, or {name = ..., options...}
    duration_s = 30.0
    step_s = 0.02
    seed = 0

    [[scenario]]
    name = "s3_stall_mid"           # unique; [a-z0-9_]+
    net = "straight_3lane"          # a bundled net, or a .net.xml path relative to this file
    route = ["e0"]                  # optional; default: the through carriageway's longest path
    ego = { lane = 1, pos_m = 50.0, speed_mps = 25.0, target_speed_mps = 25.0 }
    stalled = [ { lane = 1, pos_m = 400.0 } ]        # zero or more; pos_m along the route
    traffic = { vehicles_per_hour = 1500, seed = 7 } # optional background traffic
    ramp_traffic = [ { edge = "ramp", vehicles_per_hour = 400 } ]  # optional, on-ramps
    friction = 0.6                                   # optional road friction (default 1)
    actors = [ { id = "cutter", lane = 2, pos_m = 120.0, speed_mps = 22.0,
                 events = [ { t_s = 3.0, lane_change = -1 } ] } ]  # optional, scripted
    controller = { name = "lane_keep" }              # a table may carry options
    replay = { tracks = "s.tracks.parquet", mode = "replay" }  # optional, recorded traffic
    [scenario.sweep]                # optional: cartesian product, one scenario per combination
    "stalled.0.pos_m" = [300.0, 500.0]
    "traffic.vehicles_per_hour" = [0, 2000]

Keys of a scenario (all may also appear in ``[defaults]`` except ``name`` and ``sweep``):

=================== =========================================================================
``name``            required, ``[a-z0-9_]+``, unique (also after sweep expansion).
``net``             required; a bundled net name (``sumo_nets.available()``), else a path to a
                    ``.net.xml`` file, relative to the catalog file (or absolute).
``route``           list of edge ids, each consecutive pair connected. Default: the
                    network's longest edge path (:meth:`RoadNetwork.default_route`).
``ego``             required table: ``lane`` (int), ``pos_m``, ``speed_mps`` (required),
                    ``target_speed_mps`` (default: ``speed_mps``).
``stalled``         list of tables: ``lane``, ``pos_m`` (required), ``length_m`` (4.8),
                    ``width_m`` (1.9). Default: none.
``traffic``         table: ``vehicles_per_hour`` (required, >= 0), ``seed`` (default: the
                    scenario's ``seed``), ``speed_mps`` (default: lane speed limit),
                    ``lanes`` (default: every lane of the first route edge that admits
                    passenger cars), ``speed_factor_dev`` (0.1), ``lane_speeds_mps``
                    (table lane index -> speed [m/s] > 0, e.g. ``{ 2 = 20.0 }``: the
                    traffic of those lanes drives at most that fast and keeps its lane,
                    e.g. slower traffic in the passing lane; each lane must get traffic).
                    Default: no traffic.
``actors``          list of tables, scripted vehicles: ``id`` (required, ``[a-z0-9_]+``,
                    unique; SUMO id ``actor_<id>``), ``lane``, ``pos_m`` (front bumper,
                    along the route), ``speed_mps`` (required), ``length_m`` (4.5),
                    ``width_m`` (1.8), ``events`` (list of tables in time order: ``t_s``
                    required, run time [s]; ``lane_change`` lanes to the left > 0 or right
                    < 0 of its lane then; ``speed_mps`` a new speed reached at
                    ``accel_mps2`` (2.0) m/s² and held; at least one of the two). An actor
                    holds its speed and lane between events and brakes for what is ahead
                    of it (:mod:`suite.world.actors`). Default: none.
``ramp_traffic``    list of tables, one per on-ramp: ``edge`` (required: an edge off the
                    route whose lane connections lead onto it within 8 edges),
                    ``vehicles_per_hour`` (required, >= 0), ``speed_mps`` (departure and
                    maximum speed [m/s] > 0; default: the lanes' limits). A Poisson flow
                    enters at ``edge``, joins the route and follows it to its end; cars
                    are also spread over the ramp at t = 0. Default: none.
``replay``          table, recorded traffic around the ego (:mod:`suite.world.replay`,
                    docs/replay.md): ``tracks`` (required: a tracks file,
                    :mod:`suite.catalog.tracks`, relative to this file; read and checked
                    at load, a missing or bad file is an issue at ``replay.tracks``),
                    ``mode`` (``"replay"``: every recorded vehicle follows its recording,
                    blind to the ego; ``"reactive"``: a recorded vehicle hands over to
                    SUMO's car-following driver for good once its time gap behind the
                    ego, gap / its speed, is below ``handover_time_gap_s`` with the ego
                    in its lane or about to be, or whenever it is behind the ego in the
                    ego's lane; default ``"replay"``), ``handover_time_gap_s`` (> 0,
                    default 1.0 s), ``lane_changes`` (a handed-over vehicle's lane changes:
                    ``"none"``, ``"strategic"`` only to keep its route (default) or
                    ``"all"``, SUMO's). Recorded vehicles' SUMO ids are their track ids
                    ``rec_<id>``. ``stalled``, ``actors`` and ``traffic`` may be added
                    beside it. Default: none.
``controller``      required (usually from ``[defaults]``): a name, or a table with ``name``
                    and the controller's options.
``duration_s``      required, > 0.         ``step_s``: required, <= ``duration_s``, at least
                    0.001 s and a whole number of milliseconds (SUMO's clock).
``sumo_step_s``     SUMO's own step [s]: a whole number of milliseconds and a whole multiple
                    (1, 2, ...) of ``step_s``. Default: the largest such multiple that is at
                    most 0.1 s (0.1 for ``step_s = 0.02``; ``step_s`` when that is longer).
                    The ego's controller and plant run every ``step_s``; SUMO steps every
                    ``sumo_step_s`` with the ego's pose pushed before each of its steps;
                    between them the other vehicles are extrapolated at constant speed
                    along their heading and the geometric collision check still runs every
                    ``step_s`` (docs/performance.md). ``sumo_step_s = step_s`` runs SUMO at
                    the control rate. When SUMO's driver drives the ego (controller
                    ``sumo``) SUMO is the ego's plant and steps every ``step_s`` whatever
                    this key says.
``seed``            int in [0, 2**31 - 1]; default 0.
``allow_shoulder``  bool, default false: the ego may use a hard shoulder.
``criteria``        table name -> number or ``"off"``: pass/fail limits overriding the
                    defaults of the metrics (``reports.metrics.criteria``; a name must be
                    one of its criteria); ``"off"`` switches that criterion off (TOML has
                    no null).
``record_radius_m`` > 0, default 150: vehicles within this distance of the ego are logged.
``timeout_s``       > 0: wall-clock limit of one run. Default: none.
``friction``        tyre-road friction coefficient mu of the road, in (0, 2]; default 1.0
                    (dry asphalt; ~0.6 wet). The plant's friction limit
                    (``VehicleParams.friction_coeff``, docs/plant.md); SUMO's own driver
                    and the background traffic do not use it.
``sweep``           table dotted-path -> non-empty list (see below).
=================== =========================================================================

Every other key, anywhere, is an error. Numbers: ints or floats, never bools, finite.
Lane indices count from 0 = rightmost, as in SUMO.

Merging: ``[defaults]`` is merged into every scenario key by key; the scenario's value
replaces the default's wholesale, except ``criteria`` which is merged name by name
(defaults first, then the scenario).

Sweeps: each key of ``[scenario.sweep]`` is a dotted path into the merged scenario (list
indices numeric, e.g. ``"stalled.0.pos_m"``; unquoted dotted TOML keys work too); its
target must exist after merging, or be an optional key of an existing table (e.g.
``ego.target_speed_mps``). The scenario expands to the cartesian product of the value
lists, the first key varying slowest. Variant names are
``<name>__<short><value>[__<short><value>...]``: ``short`` is the last path component,
abbreviated (``pos_m``->``pos``, ``vehicles_per_hour``->``vph``, ``speed_mps``->``speed``,
``target_speed_mps``->``vt``, otherwise the component without its unit suffix); when two
keys of a sweep share a short, preceding components are prepended until they differ
(``ego.pos_m``->``egopos``, ``stalled.0.pos_m``->``stalled0pos``). Values: numbers compactly
(``300.0``->``300``, ``2.5``->``2p5``, ``-1``->``m1``), bools ``true``/``false``, strings as
is (characters outside ``[a-z0-9_]`` become ``_``), lists/tables by their position in the
sweep list (``v0``, ``v1``...). ``Scenario.family`` is the unexpanded name and
``Scenario.sweep_values`` maps each swept path to its value.

Validation against the network: route edges exist and connect; ``ego`` and ``stalled``
and ``actors`` positions lie in ``[0, route length)``; their lanes exist at that position
(:meth:`RoadNetwork.lanes_at`); the ego's start lane admits passenger cars, or is a hard
shoulder and ``allow_shoulder`` is true; traffic lanes exist on the first route edge and
admit passenger cars, and so do the lanes of ``traffic.lane_speeds_mps`` (which must also
get traffic); a ``ramp_traffic`` edge exists, is off the route, admits passenger cars and
leads onto the route (:func:`~suite.catalog.traffic_checks.ramp_route`).

Controllers: the name must be one of ``controllers.registry.names()``; the options are
checked by building the controller once per distinct (name, options) with
``controllers.registry.make`` (a ``ConfigError`` becomes an error at
``scenario[i].controller.<key>``). If ``known_controllers`` is given to
:func:`load_catalog`, names are checked against it instead and, **only in that case**, the
option check is skipped for a name the registry cannot build because the registry (or
``controllers.builtin``) cannot be imported or does not know that name.

All problems of a catalog are collected and raised together as one :class:`CatalogError`
(``.issues`` holds them as :class:`CatalogIssue`), one line each::

    <file>: scenario[2].stalled.0.lane (scenario 's3_stall_mid'): expected ..., got 5 [note]

naming the file, the key, the scenario (its name, or ``scenario[i]`` without a valid name)
and what was expected. Notes: ``value from [defaults]`` when the bad value was inherited;
``value from scenario[i].sweep."<key>"`` (the scenario is then the variant) when a swept
value is bad; ``all sweep variants`` for a problem shared by every variant (reported once,
under the family name). A scenario whose network or route is unusable is not checked
further against the network (no cascade of follow-up errors).

The package, one job per module: :mod:`~suite.catalog.errors` (problems and the error),
:mod:`~suite.catalog.frozen` (immutable values), :mod:`~suite.catalog.rules` (field
rules), :mod:`~suite.catalog.specs` (the resolved scenario), :mod:`~suite.catalog.keys`
(the allowed keys), :mod:`~suite.catalog.sweep` (sweep paths and names),
:mod:`~suite.catalog.nets` (bundled nets), :mod:`~suite.catalog.loader` (reading, merging,
expanding), :mod:`~suite.catalog.build` (checking and building one scenario),
:mod:`~suite.catalog.report` (where a problem is reported),
:mod:`~suite.catalog.controller_check` (controllers),
:mod:`~suite.catalog.network_checks` (the scenario against its network),
:mod:`~suite.catalog.traffic_checks` (lane speeds and on-ramp traffic against it) and
:mod:`~suite.catalog.filtering` (selecting scenarios by name).
"""

from suite.catalog.errors import CatalogError, CatalogIssue, SpecError
from suite.catalog.filtering import expand_filter
from suite.catalog.frozen import FrozenMap
from suite.catalog.loader import load_catalog
from suite.catalog.nets import bundled_nets
from suite.catalog.specs import (
    ActorEventSpec,
    ActorSpec,
    Catalog,
    ControllerSpec,
    EgoSpec,
    RampTrafficSpec,
    ReplaySpec,
    Scenario,
    StalledSpec,
    TrafficSpec,
)
from suite.catalog.sweep import format_sweep_value, sweep_name, sweep_shorts

__all__ = [
    "ActorEventSpec",
    "ActorSpec",
    "Catalog",
    "CatalogError",
    "CatalogIssue",
    "ControllerSpec",
    "EgoSpec",
    "FrozenMap",
    "RampTrafficSpec",
    "ReplaySpec",
    "Scenario",
    "SpecError",
    "StalledSpec",
    "TrafficSpec",
    "bundled_nets",
    "expand_filter",
    "format_sweep_value",
    "load_catalog",
    "sweep_name",
    "sweep_shorts",
]
