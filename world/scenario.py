"""Scenarios: the world, the fleet and the ground station's policy of one experiment.

A scenario is a YAML file a user can copy and edit. The bundled ones live in
``world/scenarios/`` and are addressed by name (``paper-boat``, ``svalbard-2015``, ...);
anything else is a path. Unknown or invalid fields are errors naming the field. The fields
of discovery (``camera``, ``targets.known``, ``area``, ``prior``, ``tracker``, ``search``) are
parsed by world/discovery_spec.py.

Frames: local ENU metres around ``origin``, headings in radians counter-clockwise from east.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from domain.errors import ConfigError
from domain.fault_spec import parse_scenario_faults
from domain.geodesy import GeoOrigin
from domain.limits import (
    MAX_COORDINATE_M,
    MAX_DURATION_S,
    MAX_FLEET,
    MAX_SPEED_M_S,
    MAX_TARGETS,
    MAX_WIND_M_S,
)
from domain.radio_spec import parse_scenario_radio
from domain.yaml_fields import FieldError, Fields, check_number, load_yaml_file, load_yaml_text
from world.discovery_spec import AreaSpec, CameraSpec, PriorSpec, SearchSpec, parse_discovery
from world.model import Boat
from world.wind import WindSpec

__all__ = [
    "BoatSpec",
    "FleetSpec",
    "ObserverSpec",
    "PlannerSpec",
    "PolicySpec",
    "Scenario",
    "ScenarioError",
    "ScriptedEvent",
    "TargetSpec",
    "WatchSpec",
    "bundled_scenarios",
    "load_scenario",
    "load_scenario_data",
    "parse_scenario",
    "resolve_targets",
]

EVENT_KINDS = (
    "target_added",
    "target_removed",
    "vehicle_lost",
    "vehicle_returned",
    "vehicle_rebooted",
    "override",
    "resume",
    "battery_low",
)


class ScenarioError(ConfigError):
    """A scenario cannot be loaded; the message names the file and the field."""


@dataclass(frozen=True)
class TargetSpec:
    """One iceberg: true initial state, and what the ground station knows at first."""

    id: str
    x_m: float
    y_m: float
    vx_m_s: float = 0.0
    vy_m_s: float = 0.0
    sigma0: float | None = None
    appear_s: float = 0.0


@dataclass(frozen=True)
class RandomTargets:
    """The paper's Table 1 draw: uniform positions and velocities."""

    count: int
    x_m: tuple[float, float]
    y_m: tuple[float, float]
    vx_m_s: tuple[float, float]
    vy_m_s: tuple[float, float]


@dataclass(frozen=True)
class BoatSpec:
    """The ship at the start: where, heading, speed; ``route`` (optional): waypoints it
    then sails in a loop (``world.model.Boat``)."""

    x_m: float
    y_m: float
    heading_rad: float
    speed_m_s: float
    route: tuple[tuple[float, float], ...] = ()

    def build(self) -> Boat:
        """The world's boat at the start."""
        return Boat(self.x_m, self.y_m, self.heading_rad, self.speed_m_s, self.route)


@dataclass(frozen=True)
class FleetSpec:
    """The UAVs. ``launch`` is ``"boat"`` or a point; headings spread over [0, pi]."""

    count: int = 3
    speed_m_s: float = 22.0
    turn_radius_m: float = 105.0
    fov_radius_m: float = 150.0
    loiter_s: float = 0.0
    loiter_radius_m: float = 120.0
    arrival_radius_m: float = 30.0
    launch_x_m: float | None = None
    launch_y_m: float | None = None
    headings_rad: tuple[float, ...] | None = None

    def launch_headings_rad(self, count: int) -> list[float]:
        """Explicit headings if given (cycled), else k * pi / (K - 1): 0, pi/2, pi for 3."""
        if self.headings_rad:
            return [self.headings_rad[k % len(self.headings_rad)] for k in range(count)]
        if count == 1:
            return [0.0]
        return [k * math.pi / (count - 1) for k in range(count)]


@dataclass(frozen=True)
class WatchSpec:
    """A watch from the moving ship (``watch:``; docs/ship.md). ``on_station`` vehicles fly
    at once and the rest of ``fleet.count`` wait on deck as spares (None: all fly);
    ``endurance_s`` is a full battery's flight time at cruise (the simulators' battery is
    sized to it, and the ground station assumes it where a vehicle reports nothing);
    ``reserve_pct`` the charge a return must end with; ``turnaround_s`` (simulators) the
    battery swap from a recovery to a ready spare; ``recovery_radius_m`` how close to the
    ship a vehicle in RTL or LAND is recovered; ``home_update_m`` how far the ship's
    predicted position moves before homes follow; ``launch_s`` from a launch order to the
    vehicle on its way."""

    on_station: int | None = None
    endurance_s: float = 3600.0
    reserve_pct: float = 15.0
    turnaround_s: float = 600.0
    recovery_radius_m: float = 150.0
    home_update_m: float = 150.0
    launch_s: float = 60.0


@dataclass(frozen=True)
class ObserverSpec:
    model: str = "kalman"
    q_per_s: float = 0.1
    r_m2: float = 5.0
    step_s: float = 0.1
    camera_rate_hz: float = 2.0
    linear_growth_per_s: float = 1.0
    iceberg_q_per_s: float = 0.1
    priority_gain: float = 0.0
    priority_near_m: float = 300.0
    priority_far_m: float = 1500.0


@dataclass(frozen=True)
class PlannerSpec:
    """Planner settings. The default objective is ``latency`` (docs/planner.md, "Choosing
    the objective"); the paper's reproduction scenarios name ``sequence``. ``wind_aware``
    false plans and predicts as in still air whatever the wind (the wind-blind baseline).
    ``tentative_weight``: the core's ``CoreConfig.tentative_weight`` (confirmation visits
    to tentative tracks; 0: none)."""

    tau: float = 0.5
    objective: str = "latency"
    time_limit_s: float = 2.0
    min_sigma_fraction: float = 0.1
    wind_aware: bool = True
    tentative_weight: float = 0.0
    mu: float | str = "floe"
    """Eq. 18's distance weight: a number >= 0 or a rule (MU_RULE_NAMES; planner.MuRule)."""


MU_RULE_NAMES = ("floe", "paper", "unconstrained")
"""``planner.mu``'s rules (planner.problem.MuRule; world does not import the planner)."""


@dataclass(frozen=True)
class PolicySpec:
    """When to replan (``replan``: event, period or both) and whether vehicles commit."""

    replan: str = "event"
    period_s: float | None = None
    commit: bool = True
    upload_min_interval_s: float | None = None
    """At most one new mission per vehicle per this many mission s
    (``groundstation/core/uploads.py``; 0: no minimum); None: the core's default."""
    upload_budget_per_h: float | None = None
    """New missions per vehicle per hour the hourly budget allows (a token bucket; a loiter
    end's answer never waits; ``groundstation/core/uploads.py``); None: no budget."""


@dataclass(frozen=True)
class ScriptedEvent:
    t_s: float
    kind: str
    vehicle: str | None = None
    target: TargetSpec | None = None
    target_id: str | None = None


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str
    duration_s: float
    origin: GeoOrigin
    fleet: FleetSpec
    boat: BoatSpec | None
    targets: tuple[TargetSpec, ...]
    random_targets: RandomTargets | None
    observer: ObserverSpec
    planner: PlannerSpec
    policy: PolicySpec
    events: tuple[ScriptedEvent, ...] = field(default=())
    faults: tuple[str, ...] = field(default=())
    radio: tuple[str, ...] = field(default=())
    """Telemetry-radio specs for the MAVLink simulator's links (docs/sitl.md)."""
    source: str = ""
    wind: WindSpec = field(default_factory=WindSpec)
    camera: CameraSpec = field(default_factory=CameraSpec)  # world/discovery_spec.py
    targets_known: bool = True
    area: AreaSpec | None = None
    prior: PriorSpec | None = None
    tracker: dict[str, float | int | str] = field(default_factory=dict)
    search: SearchSpec | None = None
    watch: WatchSpec | None = None

    @property
    def target_count(self) -> int:
        """Targets it starts with (:func:`count_targets`), known to floe or not."""
        return count_targets(self.targets, self.random_targets)

    def launch_point(self) -> tuple[float, float]:
        """Where the UAVs start: the given point, else the boat, else the origin."""
        if self.fleet.launch_x_m is not None and self.fleet.launch_y_m is not None:
            return self.fleet.launch_x_m, self.fleet.launch_y_m
        if self.boat is not None:
            return self.boat.x_m, self.boat.y_m
        return 0.0, 0.0


def count_targets(listed: Sequence[TargetSpec], random_targets: RandomTargets | None) -> int:
    """Targets a scenario starts with: those listed plus those drawn at random."""
    return len(listed) + (random_targets.count if random_targets is not None else 0)


def bundled_scenarios() -> list[str]:
    """Names of the scenarios shipped with floe."""
    folder = resources.files("world") / "scenarios"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))


def load_scenario(name_or_path: str) -> Scenario:
    """Load a bundled scenario by name, or a YAML file by path."""
    data, source = load_scenario_data(name_or_path)
    return _parse_loaded(data, source)


def load_scenario_data(name_or_path: str) -> tuple[Any, str]:
    """The raw YAML mapping of a bundled scenario (by name) or a file (by path), and its
    source (the name or the path), before validation: ``gcs campaign`` applies its
    overrides to it, then :func:`parse_scenario` checks the result."""
    if name_or_path in bundled_scenarios():
        resource = resources.files("world") / "scenarios" / f"{name_or_path}.yaml"
        text = resource.read_text(encoding="utf-8")
        try:
            return load_yaml_text(text, f"scenario {name_or_path}"), name_or_path
        except ConfigError as exc:
            raise ScenarioError(str(exc)) from None
    path = Path(name_or_path)
    if not path.is_file():
        known = ", ".join(bundled_scenarios())
        raise ScenarioError(
            f"scenario {name_or_path!r}: no such file or bundled scenario (bundled: {known})"
        )
    source = str(path)
    try:
        return load_yaml_file(path, f"scenario {source}"), source
    except ConfigError as exc:
        raise ScenarioError(str(exc)) from None


def _parse_loaded(data: Any, source: str) -> Scenario:
    try:
        return parse_scenario(data, source=source)
    except FieldError as exc:
        raise ScenarioError(f"scenario {source}: {exc}") from exc


def parse_scenario(data: Any, *, source: str = "") -> Scenario:
    """Validate a scenario mapping; raises FieldError naming the field."""
    top = Fields(data)
    name = top.string("name", Path(source).stem if source else "scenario")
    description = top.string("description", "")
    duration_s = top.number(
        "duration_s", 200.0, minimum=0.0, exclusive_minimum=True, maximum=MAX_DURATION_S
    )
    origin_f = top.sub("origin")
    lat = origin_f.number("lat_deg", 78.93, minimum=-90.0, maximum=90.0)
    lon = origin_f.number("lon_deg", 11.92, minimum=-180.0, maximum=180.0)
    alt = origin_f.number("alt_m", 0.0)
    origin_f.done()
    fleet = _parse_fleet(top.sub("fleet"))
    boat = _parse_boat(top.sub("boat")) if top.has("boat") else None
    top.raw("boat")
    targets_f = top.sub("targets")
    targets_known = targets_f.boolean("known", True)
    targets, random_targets = _parse_targets(targets_f)
    observer = _parse_observer(top.sub("observer"))
    planner = _parse_planner(top.sub("planner"))
    policy = _parse_policy(top.sub("policy"))
    events = tuple(
        _parse_event(Fields(item, f"events[{i}]")) for i, item in enumerate(top.items("events"))
    )
    faults = parse_scenario_faults(top.items("faults"))
    radio = parse_scenario_radio(top.raw("radio"))
    wind = _parse_wind(top.sub("wind"))
    watch = _parse_watch(top.sub("watch")) if top.has("watch") else None
    top.raw("watch")
    more = parse_discovery(top, count_targets(targets, random_targets))
    top.done()
    ids = [t.id for t in targets] + [e.target.id for e in events if e.target is not None]
    duplicates = sorted({i for i in ids if ids.count(i) > 1})
    if duplicates:
        raise FieldError("targets", f"duplicate target id {duplicates[0]!r}")
    if fleet.launch_x_m is None and boat is None and fleet.launch_y_m is not None:
        raise FieldError("fleet.launch", "needs both x_m and y_m")
    return Scenario(
        name=name,
        description=description,
        duration_s=duration_s,
        origin=GeoOrigin(lat, lon, alt),
        fleet=fleet,
        boat=boat,
        targets=tuple(targets),
        random_targets=random_targets,
        observer=observer,
        planner=planner,
        policy=policy,
        events=tuple(sorted(events, key=lambda e: e.t_s)),
        faults=faults,
        radio=radio,
        source=source,
        wind=wind,
        camera=more.camera,
        targets_known=targets_known,
        area=more.area,
        prior=more.prior,
        tracker=more.tracker,
        search=more.search,
        watch=watch,
    )


def resolve_targets(scenario: Scenario, rng: np.random.Generator) -> list[TargetSpec]:
    """The scenario's listed targets plus its random draw, as every frontend draws them:
    ids T1, T2, ... after the listed ones; per target x, y, vx, vy uniform in that order.
    One seed gives the same icebergs in ``gcs simulate``, ``gcs sitl`` and ``gcs run``."""
    targets = list(scenario.targets)
    spec = scenario.random_targets
    if spec is not None:
        taken = {t.id for t in targets}
        k = 1
        for _ in range(spec.count):
            while f"T{k}" in taken:
                k += 1
            targets.append(TargetSpec(
                id=f"T{k}",
                x_m=float(rng.uniform(*spec.x_m)),
                y_m=float(rng.uniform(*spec.y_m)),
                vx_m_s=float(rng.uniform(*spec.vx_m_s)),
                vy_m_s=float(rng.uniform(*spec.vy_m_s)),
            ))
            taken.add(f"T{k}")
    return targets


def _parse_watch(f: Fields) -> WatchSpec:
    on_station: int | None = None
    if f.has("on_station"):
        on_station = f.integer("on_station", minimum=1, maximum=MAX_FLEET)
    else:
        f.raw("on_station")
    endurance = f.number("endurance_s", 3600.0, minimum=60.0, maximum=86_400.0)
    reserve = f.number("reserve_pct", 15.0, minimum=0.0, maximum=90.0)
    turnaround = f.number("turnaround_s", 600.0, minimum=0.0, maximum=MAX_DURATION_S)
    recovery = f.number("recovery_radius_m", 150.0, minimum=1.0, maximum=10_000.0)
    home_update = f.number("home_update_m", 150.0, minimum=1.0, maximum=100_000.0)
    launch = f.number("launch_s", 60.0, minimum=0.0, maximum=3_600.0)
    f.done()
    return WatchSpec(on_station, endurance, reserve, turnaround, recovery, home_update, launch)


def _parse_fleet(f: Fields) -> FleetSpec:
    count = f.integer("count", 3, minimum=1, maximum=MAX_FLEET)
    speed = f.number(
        "speed_m_s", 22.0, minimum=0.0, exclusive_minimum=True, maximum=MAX_SPEED_M_S
    )
    turn = f.number(
        "turn_radius_m", 105.0, minimum=0.0, exclusive_minimum=True, maximum=MAX_COORDINATE_M
    )
    fov = f.number(
        "fov_radius_m", 150.0, minimum=0.0, exclusive_minimum=True, maximum=MAX_COORDINATE_M
    )
    loiter_s = f.number("loiter_s", 0.0, minimum=0.0, maximum=MAX_DURATION_S)
    loiter_r = f.number(
        "loiter_radius_m", 120.0, minimum=0.0, exclusive_minimum=True, maximum=MAX_COORDINATE_M
    )
    arrival = f.number("arrival_radius_m", 30.0, minimum=0.0, exclusive_minimum=True)
    launch_x: float | None = None
    launch_y: float | None = None
    launch = f.raw("launch")
    if launch is not None and launch != "boat":
        lf = Fields(launch, f.path_of("launch"))
        launch_x = lf.number("x_m", minimum=-MAX_COORDINATE_M, maximum=MAX_COORDINATE_M)
        launch_y = lf.number("y_m", minimum=-MAX_COORDINATE_M, maximum=MAX_COORDINATE_M)
        lf.done()
    headings: tuple[float, ...] | None = None
    if f.has("headings_rad"):
        values = f.items("headings_rad")
        if not values:
            raise FieldError(f.path_of("headings_rad"), "must not be empty")
        headings = tuple(
            check_number(f"{f.path_of('headings_rad')}[{i}]", v) for i, v in enumerate(values)
        )
    else:
        f.raw("headings_rad")
    f.done()
    return FleetSpec(count, speed, turn, fov, loiter_s, loiter_r, arrival, launch_x, launch_y,
                     headings)


def _parse_boat(f: Fields) -> BoatSpec:
    boat = BoatSpec(
        x_m=f.number("x_m", minimum=-MAX_COORDINATE_M, maximum=MAX_COORDINATE_M),
        y_m=f.number("y_m", minimum=-MAX_COORDINATE_M, maximum=MAX_COORDINATE_M),
        heading_rad=f.number("heading_rad", 0.0),
        speed_m_s=f.number("speed_m_s", 0.0, minimum=0.0, maximum=MAX_SPEED_M_S),
        route=_parse_route(f),
    )
    f.done()
    return boat


def _parse_route(f: Fields) -> tuple[tuple[float, float], ...]:
    if not f.has("route"):
        f.raw("route")
        return ()
    points = []
    for i, item in enumerate(f.items("route")):
        path = f"{f.path_of('route')}[{i}]"
        if not isinstance(item, list | tuple) or len(item) != 2:
            raise FieldError(path, f"must be a point [x_m, y_m], got {item!r}")
        points.append((check_number(f"{path}[0]", item[0], minimum=-MAX_COORDINATE_M,
                                    maximum=MAX_COORDINATE_M),
                       check_number(f"{path}[1]", item[1], minimum=-MAX_COORDINATE_M,
                                    maximum=MAX_COORDINATE_M)))
    if len(points) < 2:
        raise FieldError(f.path_of("route"), "needs at least two waypoints")
    return tuple(points)


def _parse_target(f: Fields) -> TargetSpec:
    target = TargetSpec(
        id=f.string("id"),
        x_m=f.number("x_m", minimum=-MAX_COORDINATE_M, maximum=MAX_COORDINATE_M),
        y_m=f.number("y_m", minimum=-MAX_COORDINATE_M, maximum=MAX_COORDINATE_M),
        vx_m_s=f.number("vx_m_s", 0.0, minimum=-MAX_SPEED_M_S, maximum=MAX_SPEED_M_S),
        vy_m_s=f.number("vy_m_s", 0.0, minimum=-MAX_SPEED_M_S, maximum=MAX_SPEED_M_S),
        sigma0=f.optional_number("sigma0", minimum=0.0),
        appear_s=f.number("appear_s", 0.0, minimum=0.0, maximum=MAX_DURATION_S),
    )
    if not target.id:
        raise FieldError(f.path_of("id"), "must not be empty")
    f.done()
    return target


def _parse_targets(f: Fields) -> tuple[list[TargetSpec], RandomTargets | None]:
    listed = [
        _parse_target(Fields(item, f"{f.path_of('list')}[{i}]"))
        for i, item in enumerate(f.items("list"))
    ]
    random_targets: RandomTargets | None = None
    if f.has("random"):
        rf = f.sub("random")
        random_targets = RandomTargets(
            count=rf.integer("count", minimum=0, maximum=MAX_TARGETS),
            x_m=rf.range_pair("x_m", (0.0, 1500.0), limit=MAX_COORDINATE_M),
            y_m=rf.range_pair("y_m", (0.0, 1500.0), limit=MAX_COORDINATE_M),
            vx_m_s=rf.range_pair("vx_m_s", (-3.0, 3.0), limit=MAX_SPEED_M_S),
            vy_m_s=rf.range_pair("vy_m_s", (-3.0, 3.0), limit=MAX_SPEED_M_S),
        )
        rf.done()
    else:
        f.raw("random")
    total = count_targets(listed, random_targets)
    if total > MAX_TARGETS:
        raise FieldError(
            f.path_of("list"), f"{total} targets in all; floe's limit is {MAX_TARGETS}"
        )
    f.done()
    return listed, random_targets


def _parse_observer(f: Fields) -> ObserverSpec:
    spec = ObserverSpec(
        model=f.string("model", "kalman", choices=("kalman", "linear")),
        q_per_s=f.number("q_per_s", 0.1, minimum=0.0),
        r_m2=f.number("r_m2", 5.0, minimum=0.0, exclusive_minimum=True),
        step_s=f.number("step_s", 0.1, minimum=0.0, exclusive_minimum=True, maximum=5.0),
        camera_rate_hz=f.number("camera_rate_hz", 2.0, minimum=0.0, exclusive_minimum=True),
        linear_growth_per_s=f.number("linear_growth_per_s", 1.0, minimum=0.0),
        iceberg_q_per_s=f.number("iceberg_q_per_s", 0.1, minimum=0.0),
        priority_gain=f.number("priority_gain", 0.0, minimum=0.0),
        priority_near_m=f.number("priority_near_m", 300.0, minimum=0.0),
        priority_far_m=f.number("priority_far_m", 1500.0, minimum=0.0),
    )
    if spec.priority_far_m <= spec.priority_near_m and spec.priority_gain > 0:
        raise FieldError(f.path_of("priority_far_m"), "must be above priority_near_m")
    f.done()
    return spec


def _parse_planner(f: Fields) -> PlannerSpec:
    spec = PlannerSpec(
        tau=f.number("tau", 0.5, minimum=0.0, maximum=1.0),
        objective=f.string("objective", "latency", choices=("sequence", "arrival", "latency")),
        time_limit_s=f.number("time_limit_s", 2.0, minimum=0.0, exclusive_minimum=True),
        min_sigma_fraction=f.number("min_sigma_fraction", 0.1, minimum=0.0, maximum=1.0),
        wind_aware=f.boolean("wind_aware", True),
        tentative_weight=f.number("tentative_weight", 0.0, minimum=0.0, maximum=1e6),
        mu=_parse_mu(f),
    )
    f.done()
    return spec


def _parse_mu(f: Fields) -> float | str:
    """``mu``: a rule name (MU_RULE_NAMES) or a number >= 0; absent or null: ``floe``."""
    raw = f.raw("mu")
    if raw is None:
        return "floe"
    if isinstance(raw, str):
        if raw not in MU_RULE_NAMES:
            raise FieldError(f.path_of("mu"), f"must be a number >= 0 or one of "
                             f"{', '.join(MU_RULE_NAMES)}, got {raw!r}")
        return raw
    return f.number("mu", 0.0, minimum=0.0)


def _parse_policy(f: Fields) -> PolicySpec:
    replan = f.string("replan", "event", choices=("event", "period", "both"))
    period = f.optional_number("period_s", minimum=0.0, exclusive_minimum=True)
    if replan in ("period", "both") and period is None:
        raise FieldError(f.path_of("period_s"), f"is required when replan is {replan!r}")
    commit = f.boolean("commit", replan == "event")
    interval = f.optional_number("upload_min_interval_s", minimum=0.0)
    budget = f.optional_number("upload_budget_per_h", minimum=0.0, exclusive_minimum=True)
    f.done()
    return PolicySpec(replan=replan, period_s=period, commit=commit,
                      upload_min_interval_s=interval, upload_budget_per_h=budget)


def _parse_wind(f: Fields) -> WindSpec:
    """``wind: {speed_m_s, from_deg, gust_m_s, gust_tau_s}`` (world/wind.py); absent: calm."""
    spec = WindSpec(
        speed_m_s=f.number("speed_m_s", 0.0, minimum=0.0, maximum=MAX_WIND_M_S),
        from_deg=f.number("from_deg", 0.0, minimum=0.0, maximum=360.0) % 360.0,
        gust_m_s=f.number("gust_m_s", 0.0, minimum=0.0, maximum=MAX_WIND_M_S),
        gust_tau_s=f.number("gust_tau_s", 5.0, minimum=0.0, exclusive_minimum=True,
                            maximum=MAX_DURATION_S),
    )
    f.done()
    return spec


def _parse_event(f: Fields) -> ScriptedEvent:
    t_s = f.number("t_s", minimum=0.0, maximum=MAX_DURATION_S)
    kind = f.string("kind", choices=EVENT_KINDS)
    vehicle: str | None = None
    target: TargetSpec | None = None
    target_id: str | None = None
    if kind == "target_added":
        target = _parse_target(f.sub("target"))
        target = TargetSpec(target.id, target.x_m, target.y_m, target.vx_m_s, target.vy_m_s,
                            target.sigma0, t_s)
    elif kind == "target_removed":
        target_id = f.string("target")
    else:
        vehicle = f.string("vehicle")
    f.done()
    return ScriptedEvent(t_s=t_s, kind=kind, vehicle=vehicle, target=target, target_id=target_id)
