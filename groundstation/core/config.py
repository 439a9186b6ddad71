"""Configuration of the decision core: replan policy, planner settings, loiter, observer."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from groundstation.core.mission import ROUTE_POINTS_MAX
from observer import ObserverConfig, TrackerConfig
from planner import MuRule, Objective, ProblemError, parse_mu
from planner.search_cells import SearchConfig

__all__ = [
    "BatteryAction",
    "CoreConfig",
    "ReplanPolicy",
    "WatchConfig",
    "config_from_dict",
    "config_to_dict",
]


class BatteryAction(StrEnum):
    """What a low battery leads to: send the vehicle home, or stop commanding it."""

    RTL = "rtl"
    RELEASE = "release"


@dataclass(frozen=True)
class ReplanPolicy:
    """When the core replans, and which vehicles a replan may redirect.

    * ``on_events``: replan when something changes (a loiter ended, a target appeared or
      went, a vehicle joined, was lost, came back, was taken over or given back). The
      daemon's default.
    * ``period_s``: also replan every ``period_s`` mission seconds (the paper's 5 s
      sample-based replanning). ``None``: never on time alone.
    * ``commit``: True keeps a vehicle on its target until its loiter ends, and its target
      counts as covered (only idle vehicles are planned); False lets every replan redirect
      every vehicle (the paper's simulation).
    """

    on_events: bool = True
    period_s: float | None = None
    commit: bool = True

    def __post_init__(self) -> None:
        if self.period_s is not None and not self.period_s > 0:
            raise ValueError(f"period_s must be > 0, got {self.period_s}")
        if not self.on_events and self.period_s is None:
            raise ValueError("a replan policy needs events, a period, or both")

    @classmethod
    def from_names(cls, replan: str, period_s: float | None, commit: bool) -> ReplanPolicy:
        """Build from a scenario/config ``replan`` name: event, period or both."""
        if replan == "event":
            return cls(on_events=True, period_s=period_s, commit=commit)
        if replan == "period":
            return cls(on_events=False, period_s=period_s, commit=commit)
        if replan == "both":
            return cls(on_events=True, period_s=period_s, commit=commit)
        raise ValueError(f"replan must be event, period or both, got {replan!r}")

    def describe(self) -> str:
        parts = []
        if self.on_events:
            parts.append("event")
        if self.period_s is not None:
            parts.append(f"every {self.period_s:g} s")
        return f"{' + '.join(parts)}, {'commit' if self.commit else 'no commit'}"


@dataclass(frozen=True)
class WatchConfig:
    """A watch from a moving ship (docs/ship.md): endurance, relief, homes on the ship.

    * ``on_station``: vehicles flying at once; the rest of the fleet are spares on deck,
      launched to relieve a vehicle before it must go home. None: every vehicle flies.
    * ``endurance_s``: a full battery's flight time, used where a vehicle reports nothing
      useful about its battery (and as the energy model's prior).
    * ``reserve_pct``: the charge a vehicle must still hold when its return ends.
    * ``home_update_m``: a vehicle's home is moved when the ship's predicted position for
      it moved farther than this.
    * ``recovery_radius_m``: a vehicle that comes down this close to the ship's predicted
      position was recovered (else it is down).
    * ``launch_s``: from a launch order to the vehicle in the plan (catapult, climb-out).
    * ``ready_pct``: a spare on deck is ready when its battery holds at least this.
    """

    on_station: int | None = None
    endurance_s: float = 3600.0
    reserve_pct: float = 15.0
    home_update_m: float = 150.0
    recovery_radius_m: float = 150.0
    launch_s: float = 60.0
    ready_pct: float = 95.0

    def __post_init__(self) -> None:
        if self.on_station is not None and (
            isinstance(self.on_station, bool) or not isinstance(self.on_station, int)
            or self.on_station < 1
        ):
            raise ValueError(f"on_station must be a whole number >= 1, got {self.on_station!r}")
        for name, low, high in (("endurance_s", 60.0, 86_400.0), ("reserve_pct", 0.0, 90.0),
                                ("home_update_m", 1.0, 100_000.0),
                                ("recovery_radius_m", 1.0, 10_000.0),
                                ("launch_s", 0.0, 3_600.0), ("ready_pct", 1.0, 100.0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not (
                math.isfinite(value) and low <= value <= high
            ):
                raise ValueError(f"{name} must be a number in [{low:g}, {high:g}], got {value!r}")
            object.__setattr__(self, name, float(value))


@dataclass(frozen=True)
class CoreConfig:
    """Everything the decision core needs to decide; no I/O settings here."""

    policy: ReplanPolicy = field(default_factory=ReplanPolicy)
    observer: ObserverConfig = field(default_factory=ObserverConfig)
    turn_radius_m: float = 105.0
    speed_m_s: float = 22.0
    loiter_s: float = 30.0
    loiter_radius_m: float = 120.0
    tau: float = 0.5
    objective: Objective = Objective.LATENCY  # docs/planner.md, "Choosing the objective"
    time_limit_s: float = 2.0
    min_sigma_fraction: float = 0.1
    mu: float | MuRule = MuRule.FLOE
    """Eq. 18's distance weight: a number >= 0, or the rule that computes it per plan
    (``floe``, ``paper``, ``unconstrained``: planner.problem.MuRule, docs/planner.md "mu").
    Journals written before the setting read as ``floe`` (the rule they ran)."""
    retarget_threshold_m: float | None = None
    """A vehicle flying to a target is sent there again only when the aim point moved
    farther than this (m); None: the loiter radius (``core/uploads.py``). Journals written
    before the upload rule hold 50."""
    upload_min_interval_s: float | None = 15.0
    """At most one FlyToTarget (a mission upload) per vehicle per this many mission s; a
    sooner one is deferred and replanned when the interval has passed. Safety commands are
    never delayed (``core/uploads.py``). None: no minimum (journals written before the rule
    read as None, so they replay as they ran)."""
    keep_held_cells: bool = True
    """Without commitment, a search cell an active vehicle flies to stays in the planning
    problem even when it is no longer among the ``max_cells`` most valuable
    (``core/uploads.py``). False: journals written before (they replay as they ran)."""
    route_cells: int | None = 3
    """A mission flies through up to this many search cells of the vehicle's planned route
    after its head (plain waypoints); the vehicle moving on to the next of them needs no
    new mission (``core/route.py``). None or 0: a mission ends at its head (journals
    written before routes read as None, so they replay as they ran)."""
    route_min_interval_s: float | None = 60.0
    """The minimum interval for a vehicle flying a routed pass (it keeps flying its route,
    or holds over its head, while a new head waits; ``core/route.py``); at least
    ``upload_min_interval_s``. None: that interval for every vehicle (journals before)."""
    upload_budget_per_h: float | None = None
    """FlyToTargets per vehicle per hour the hourly budget refills (a token bucket holding
    two; a loiter end's answer is never delayed, a redirect waits for a token;
    ``core/uploads.py``). None: no budget (the default: the paper's 5 s replanning sends
    paper-boat's vehicles 200-300 an hour; ``discovery`` sets 50)."""
    revisit_growth: float | None = 2.0
    """A target a vehicle's visit did not see is not given to that vehicle again at the same
    place until its value (sigma, m^2) grew by this factor or its aim moved farther than the
    retarget threshold (``core/uploads.py``). None: off (journals written before the rule)."""
    battery_low_action: BatteryAction = BatteryAction.RTL
    priority_gain: float = 0.0
    priority_near_m: float = 300.0
    priority_far_m: float = 1500.0
    wind_xy_m_s: tuple[float, float] = (0.0, 0.0)
    """The fallback wind (the config's or the scenario's), ENU m/s the air moves towards:
    what the core plans with while no vehicle reports its own (``core/wind_estimate.py``)."""
    wind_aware: bool = True
    """False: plan and predict as in still air even in wind (the wind-blind baseline)."""
    wind_replan_m_s: float | None = 2.0
    """A committed leg predicted before the first wind estimate, or in a wind that has since
    changed by more than this (m/s, vector difference), is predicted again, and replanned
    if its arrival moved by more than ``wind_replan_margin_s`` (``core/wind_replan.py``;
    docs/wind.md, "The first leg"). None: never (journals written before the rule existed
    read as None, so they replay as they ran)."""
    wind_replan_margin_s: float = 5.0
    """See ``wind_replan_m_s`` (s)."""
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    """The multi-target tracker's settings (used only once unlabelled detections, camera
    frames or prior targets arrive: ``core/tracking.py``)."""
    search: SearchConfig | None = None
    """Search cells over ``area_m`` (``planner/search_cells.py``); None: no search."""
    area_m: tuple[float, float, float, float] | None = None
    """The operating area (x_min, x_max, y_min, y_max), m; search needs it."""
    tentative_weight: float = 0.0
    """A tentative track's planning value is ``tentative_weight * existence * max(sigma,
    mean sigma of the confirmed and prior tracks)`` (``core/planning_targets.py``; a
    scenario's ``planner.tentative_weight``). 0 (measured best: a real iceberg is
    confirmed within the pass that found it, M of N frames, so what is left tentative is
    mostly clutter, and visits to it are lost): paper-boat-clutter, 3 UAVs, seeds 0-19,
    mean uncertainty 4 932 +- 973 m^2 (13/20 bounded) at 0 against 6 127 +- 1 766
    (11/20) at 1; discovery, seeds 0-9, true icebergs confirmed at the end 0.979 at 0
    against 0.972 at 1, which costs 5x the CPU (170 against 34 s a run)."""

    watch: WatchConfig | None = None
    """The ship watch (endurance, relief, moving homes: ``core/energy.py``,
    ``core/relief.py``, ``core/ship.py``). None: none of it (the paper's runs; journals
    written before the watch existed read as None, so they replay as they ran)."""

    def __post_init__(self) -> None:
        if self.turn_radius_m <= 0:
            raise ValueError("turn_radius_m must be > 0")
        if self.speed_m_s <= 0:
            raise ValueError("speed_m_s must be > 0")
        if self.loiter_s < 0:
            raise ValueError("loiter_s must be >= 0")
        # plain strings (a journal's start line, a scenario) become the enums
        if self.battery_low_action not in tuple(BatteryAction):
            raise ValueError("battery_low_action must be rtl or release")
        if self.objective not in tuple(Objective):
            raise ValueError(f"objective must be one of {', '.join(Objective)}")
        object.__setattr__(self, "battery_low_action", BatteryAction(self.battery_low_action))
        object.__setattr__(self, "objective", Objective(self.objective))
        try:
            mu_value, mu_rule = parse_mu(self.mu)
        except ProblemError as exc:
            raise ValueError(str(exc)) from None
        object.__setattr__(self, "mu", mu_rule if mu_value is None else mu_value)
        # a journal's start line holds the wind as a JSON list
        try:
            wind = tuple(float(c) for c in self.wind_xy_m_s)
        except (TypeError, ValueError):
            wind = ()
        if len(wind) != 2 or not all(math.isfinite(c) for c in wind):
            raise ValueError(f"wind_xy_m_s must be two finite numbers, got {self.wind_xy_m_s!r}")
        object.__setattr__(self, "wind_xy_m_s", (wind[0], wind[1]))
        if not isinstance(self.wind_aware, bool):
            raise ValueError(f"wind_aware must be true or false, got {self.wind_aware!r}")
        for name, value, optional in (("wind_replan_m_s", self.wind_replan_m_s, True),
                                      ("wind_replan_margin_s", self.wind_replan_margin_s, False)):
            if value is None and optional:
                continue
            if isinstance(value, bool) or not isinstance(value, int | float) or not (
                math.isfinite(value) and value >= 0
            ):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
            object.__setattr__(self, name, float(value))
        for name, value, low in (("retarget_threshold_m", self.retarget_threshold_m, 0.0),
                                 ("upload_min_interval_s", self.upload_min_interval_s, 0.0),
                                 ("route_min_interval_s", self.route_min_interval_s, 0.0),
                                 ("upload_budget_per_h", self.upload_budget_per_h, 0.0),
                                 ("revisit_growth", self.revisit_growth, 1.0)):
            if value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, int | float) or not (
                math.isfinite(value) and value >= low
            ):
                raise ValueError(f"{name} must be a finite number >= {low:g} or null, "
                                 f"got {value!r}")
            object.__setattr__(self, name, float(value))
        if self.route_cells is not None and (
                isinstance(self.route_cells, bool) or not isinstance(self.route_cells, int)
                or not 0 <= self.route_cells <= ROUTE_POINTS_MAX):
            raise ValueError(f"route_cells must be a whole number in [0, {ROUTE_POINTS_MAX}] "
                             f"or null, "
                             f"got {self.route_cells!r}")
        if not isinstance(self.keep_held_cells, bool):
            raise ValueError(f"keep_held_cells must be true or false, got "
                             f"{self.keep_held_cells!r}")
        if self.area_m is not None:
            try:
                area = tuple(float(c) for c in self.area_m)
            except (TypeError, ValueError):
                area = ()
            if len(area) != 4 or not all(math.isfinite(c) for c in area) or not (
                area[1] > area[0] and area[3] > area[2]
            ):
                raise ValueError("area_m must be x_min < x_max, y_min < y_max (finite), "
                                 f"got {self.area_m!r}")
            object.__setattr__(self, "area_m", area)
        if self.search is not None and self.area_m is None:
            raise ValueError("search needs area_m (the operating area)")
        w = self.tentative_weight
        if isinstance(w, bool) or not isinstance(w, (int, float)) or not (
            math.isfinite(w) and w >= 0
        ):
            raise ValueError(f"tentative_weight must be finite and >= 0, got {w!r}")

    @property
    def retarget_m(self) -> float:
        """The same-leg threshold in force: ``retarget_threshold_m``, else the loiter
        radius."""
        if self.retarget_threshold_m is None:
            return self.loiter_radius_m
        return self.retarget_threshold_m

    @property
    def tick_s(self) -> float:
        """Mission seconds between two ``Tick`` inputs, in every frontend (the daemon's
        ticker, ``gcs simulate``'s step, a bare tlog's replay): the observer's prediction
        grid, ``observer.max_step_s`` (0.1 s), so a tick never falls between grid points."""
        return self.observer.max_step_s


def config_to_dict(config: CoreConfig) -> dict[str, Any]:
    """The core configuration as plain JSON/YAML data (journalled at start for replay)."""
    out = dataclasses.asdict(config)
    out["objective"] = str(config.objective)
    out["mu"] = str(config.mu) if isinstance(config.mu, MuRule) else config.mu
    out["battery_low_action"] = str(config.battery_low_action)
    out["wind_xy_m_s"] = list(config.wind_xy_m_s)
    if config.area_m is not None:
        out["area_m"] = list(config.area_m)
    return out


def config_from_dict(data: Mapping[str, Any]) -> CoreConfig:
    """Inverse of :func:`config_to_dict`; raises ValueError naming an unknown or bad key."""
    known = {f.name for f in dataclasses.fields(CoreConfig)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ValueError(f"core config: unknown key {unknown[0]!r}")
    values = dict(data)
    values.setdefault("wind_replan_m_s", None)  # written before the rule: it was off
    values.setdefault("upload_min_interval_s", None)  # likewise (core/uploads.py)
    values.setdefault("revisit_growth", None)
    values.setdefault("keep_held_cells", False)
    values.setdefault("route_cells", None)  # written before routes (core/route.py)
    values.setdefault("route_min_interval_s", None)
    values.setdefault("upload_budget_per_h", None)  # written before the budget
    values.setdefault("retarget_threshold_m", 50.0)  # the default before the rule
    try:
        if "policy" in values:
            values["policy"] = ReplanPolicy(**values["policy"])
        if "observer" in values:
            values["observer"] = ObserverConfig(**values["observer"])
        if "tracker" in values:
            values["tracker"] = TrackerConfig(**values["tracker"])
        if values.get("search") is not None:
            values["search"] = SearchConfig(**values["search"])
        if values.get("watch") is not None:
            values["watch"] = WatchConfig(**values["watch"])
        return CoreConfig(**values)
    except TypeError as exc:
        raise ValueError(f"core config: {exc}") from exc
