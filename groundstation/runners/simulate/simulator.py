"""The offline simulator behind ``gcs simulate``: the decision core against the world model.

Virtual time advances in fixed steps of the core's tick (``CoreConfig.tick_s``: the
scenario's ``observer.step_s``, 0.1 s in the paper). Each step, in order:

1. scripted events due by now (targets appearing, vehicles lost, overrides...) reach the
   world and the core;
2. the core gets a ``Tick`` and may ask for a plan; requests are solved inline (the same
   planner the daemon runs in a worker thread) and the answer goes back as ``PlanSolved``;
3. the vehicles fly what they were told for one step, at their airspeed in the scenario's
   wind (``WindField(scenario.wind, seed)``, sampled at the middle of the step and held
   over it); loiter ends become events;
4. the world moves (icebergs, boat); the camera measures what lies in a UAV's field of
   view at its rate, and the measurements reach the core as ``Detection`` events;
5. every second of mission time the metrics are sampled.

The core hears each vehicle's pose and airspeed (as ArduPlane's telemetry tells them) and,
in wind, each flying vehicle's wind estimate once a second (``WindReport``); the
arrival-error metric follows the vehicles' true positions (:mod:`groundstation.core.arrivals`).

No clock is read except to report the wall time the run took.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from groundstation.core.area import OperatingArea
from groundstation.core.commands import (
    Command,
    FlyToTarget,
    LaunchVehicle,
    PlanAdopted,
    ReleaseVehicle,
    SendHome,
    SetHome,
    SolveRequest,
)
from groundstation.core.config import config_to_dict
from groundstation.core.decision import DecisionCore
from groundstation.core.events import (
    BatteryLow,
    BatteryReport,
    BoatPosition,
    Detection,
    Event,
    LoiterEnded,
    OperatorOverride,
    OperatorResume,
    PlanSolved,
    TargetAdded,
    TargetRemoved,
    Telemetry,
    Tick,
    VehicleJoined,
    VehicleLanded,
    VehicleLost,
    VehicleOnDeck,
    VehicleRebooted,
    VehicleReturned,
    WindReport,
)
from groundstation.core.link_metrics import offline_link_entries
from groundstation.core.metrics import MetricsRecorder
from groundstation.core.mission import target_mission
from groundstation.core.records import (
    command_to_record,
    event_to_record,
    search_record,
    track_records,
    truth_records,
)
from groundstation.core.scenario_config import core_config_for
from groundstation.core.watch_metrics import WatchMetrics
from groundstation.runners.simulate.deck import Deck, DeckState
from groundstation.runners.simulate.discovery import Discovery
from groundstation.runners.simulate.vehicle import OfflineVehicle
from planner import solve_plan
from world.discovery_spec import discovery_mode, scenario_camera
from world.dynamics import UavState
from world.model import Iceberg, World
from world.scenario import Scenario, ScriptedEvent, resolve_targets
from world.wind import WindField, WindSpec

__all__ = ["PlanRecord", "SimulationOptions", "SimulationRun", "run_simulation", "wind_record"]


@dataclass(frozen=True)
class SimulationOptions:
    seed: int = 0
    uavs: int | None = None
    duration_s: float | None = None
    num_workers: int = 1
    deterministic: bool = True
    objective: str | None = None
    snapshot_times_s: tuple[float, ...] = ()
    progress: Callable[[float, float], None] | None = None
    journal: bool = False
    operating_radius_m: float | None = None
    """The operating area around the launch origin (``core/area.py``): announced targets
    outside it are refused, detections outside it dropped, aim points clipped onto it.
    None (the default): no area."""


@dataclass
class MapSnapshot:
    t_s: float
    uav_xy_m: dict[str, tuple[float, float]]
    routes: dict[str, list[str]]
    estimates: dict[str, tuple[float, float, float]]
    truth: dict[str, tuple[float, float]]
    boat_xy_m: tuple[float, float] | None


@dataclass(frozen=True)
class PlanRecord:
    """One adopted plan, as ``gcs campaign`` keeps it (``plans.parquet``): when, the
    planner's figures (``objective_value`` is the objective's value, ``objective`` its
    name), and the size of the problem it solved."""

    t_s: float
    mu: float
    f1: float
    f2: float
    objective_value: float
    objective: str
    status: str
    solver: str
    solve_time_s: float
    bound: float | None
    gap: float | None
    targets: int
    uavs_planned: int


@dataclass
class SimulationRun:
    """Everything a run produced: metrics and the history the plots draw."""

    scenario: Scenario
    options: SimulationOptions
    metrics: dict[str, Any]
    uav_tracks: dict[str, list[tuple[float, float, float]]] = field(default_factory=dict)
    target_truth: dict[str, list[tuple[float, float, float]]] = field(default_factory=dict)
    target_estimates: dict[str, list[tuple[float, float, float, float]]] = field(
        default_factory=dict
    )
    boat_track: list[tuple[float, float, float]] = field(default_factory=list)
    snapshots: list[MapSnapshot] = field(default_factory=list)
    events: list[dict[str, Any]] = field(default_factory=list)
    journal: list[dict[str, Any]] = field(default_factory=list)
    plans: list[PlanRecord] = field(default_factory=list)
    interrupted_at_s: float | None = None
    """Mission time a Ctrl-C stopped the run at (its metrics cover up to there); None: it
    ran its whole duration."""


class _Simulation:
    def __init__(self, scenario: Scenario, options: SimulationOptions) -> None:
        self.scenario = scenario
        self.options = options
        self.rng = np.random.default_rng(options.seed)
        self.duration_s = options.duration_s or scenario.duration_s
        self.core = DecisionCore(core_config_for(scenario, options.objective))
        self.dt_s = self.core.config.tick_s  # the scenario's observer.step_s
        self.area = OperatingArea(options.operating_radius_m, False)
        self.metrics = MetricsRecorder()
        self.fov_radius_m = self.core.config.observer.fov_radius_m
        self.wind = WindField(scenario.wind, options.seed)
        self.run = SimulationRun(scenario, options, metrics={})
        targets = resolve_targets(scenario, self.rng)
        self.discovery = (Discovery(scenario, options.seed, targets)
                          if discovery_mode(scenario) else None)
        boat = scenario.boat
        camera = scenario_camera(scenario)
        self.world = World(
            [], boat.build() if boat else None,
            camera, self.rng,
        )
        count = options.uavs or scenario.fleet.count
        x0, y0 = scenario.launch_point()
        fleet = scenario.fleet
        self.deck: Deck | None = None
        """The ship's deck and the planes' batteries on a watch (``deck.py``)."""
        self.watch_metrics = WatchMetrics()
        if scenario.watch is not None and self.world.boat is not None:
            self.deck = Deck(scenario.watch, fleet, self.world.boat)
        self.vehicles = {
            str(k + 1): OfflineVehicle(
                str(k + 1), UavState(x0, y0, heading, fleet.speed_m_s), fleet.turn_radius_m,
                fleet.arrival_radius_m, loiter_radius_m=fleet.loiter_radius_m,
            )
            for k, heading in enumerate(fleet.launch_headings_rad(count))
        }
        self.script: list[ScriptedEvent] = [
            ScriptedEvent(t.appear_s, "target_added", target=t) for t in targets
        ] + list(scenario.events)
        self.script.sort(key=lambda e: e.t_s)
        self.script_index = 0
        self.snapshot_times = sorted(options.snapshot_times_s)
        if options.journal:
            self.core.on_input = lambda event: self.run.journal.append(event_to_record(event))
            self.run.journal.append({
                "event": "start", "t": 0.0, "frontend": "simulate", "scenario": scenario.name,
                "seed": options.seed, "uavs": len(self.vehicles),
                "policy": self.core.config.policy.describe(),
                "objective": self.core.config.objective,
                "duration_s": self.duration_s,
                "wind": wind_record(scenario.wind),
                "core_config": config_to_dict(self.core.config),
            })

    # --------------------------------------------------------------- core plumbing
    def feed(self, event: Event) -> None:
        """Feed the core and carry out what it decides; the detections it accepted (a
        labelled one now, an unlabelled frame's at the tick that scans it) count as visits."""
        pending = self.core.handle(event)
        for verdict in pending.verdicts:
            if verdict.accepted and verdict.target is not None:
                self.metrics.seen(verdict.t_s, verdict.vehicle, verdict.target)
        while pending:
            command = pending.pop(0)
            pending.extend(self.execute(command))

    def execute(self, command: Command) -> list[Command]:
        if self.options.journal:
            self.run.journal.append(command_to_record(command))
        if isinstance(command, SolveRequest):
            result = solve_plan(
                command.problem, command.hint, num_workers=self.options.num_workers,
                random_seed=self.options.seed, deterministic=self.options.deterministic,
            )
            return self.core.handle(PlanSolved(command.t_s, command.request_id, result))
        if isinstance(command, PlanAdopted):
            result = command.result
            self.metrics.plan(result.solve_time_s, result.mu, result.f1, result.f2)
            self.run.plans.append(_plan_record(command))
        elif isinstance(command, FlyToTarget):
            vehicle = self.vehicles[command.vehicle]
            if vehicle.commanded:
                x_m, y_m, _ = self.area.clip(command.x_m, command.y_m)
                mission = target_mission(command, (x_m, y_m))
                through = tuple(self.area.clip(*xy)[:2] for xy in mission.through)
                vehicle.command_fly(replace(mission, through=through))
                self.metrics.fly(command.t_s, command.vehicle, command.target, command.x_m,
                                 command.y_m, command.eta_s, self.fov_radius_m)
        elif isinstance(command, SendHome):
            vehicle = self.vehicles[command.vehicle]
            vehicle.commanded = False
            self.metrics.abandoned(command.vehicle)
            home = (self.deck.rtl(command.vehicle) if self.deck is not None
                    else self.scenario.launch_point())
            vehicle.command_hold(*home, vehicle.loiter_radius_m)
            self.log(command.t_s, "send_home", vehicle=command.vehicle)
        elif isinstance(command, SetHome) and self.deck is not None:
            self.deck.set_home(command.vehicle, command.x_m, command.y_m)
        elif isinstance(command, LaunchVehicle) and self.deck is not None:
            if not self.deck.launch(command.t_s, command.vehicle):
                self.log(command.t_s, "launch_refused", vehicle=command.vehicle,
                         reason=f"not a ready spare ({self.deck.state(command.vehicle)})")
        elif isinstance(command, ReleaseVehicle):
            vehicle = self.vehicles[command.vehicle]
            vehicle.commanded = False
            self.metrics.abandoned(command.vehicle)
            vehicle.command_hold(vehicle.state.x_m, vehicle.state.y_m, vehicle.loiter_radius_m)
            self.log(command.t_s, "release", vehicle=command.vehicle, reason=command.reason)
        return []

    def log(self, t_s: float, event: str, **fields: Any) -> None:
        self.run.events.append({"t_s": round(t_s, 3), "event": event, **fields})
        if self.options.journal:
            self.run.journal.append({"event": event, "t": t_s, **fields})

    # --------------------------------------------------------------- scripted events
    def apply_script(self, t_s: float) -> None:
        while self.script_index < len(self.script) and self.script[self.script_index].t_s <= (
            t_s + 1e-9
        ):
            item = self.script[self.script_index]
            self.script_index += 1
            self.apply_scripted(t_s, item)

    def apply_scripted(self, t_s: float, item: ScriptedEvent) -> None:
        self.log(t_s, item.kind, vehicle=item.vehicle,
                 target=item.target.id if item.target else item.target_id)
        if item.kind == "target_added" and item.target is not None:
            spec = item.target
            self.world.add_iceberg(Iceberg(spec.id, spec.x_m, spec.y_m, spec.vx_m_s,
                                           spec.vy_m_s, self.scenario.observer.iceberg_q_per_s))
            if not self.scenario.targets_known:
                return  # the ground station learns of it from the camera (and the prior)
            self.announce(TargetAdded(t_s, spec.id, spec.x_m, spec.y_m, spec.vx_m_s,
                                      spec.vy_m_s, spec.sigma0))
            return
        if item.kind == "target_removed" and item.target_id is not None:
            if item.target_id in self.world.icebergs:
                self.world.remove_iceberg(item.target_id)
            self.feed(TargetRemoved(t_s, item.target_id))
            return
        vehicle_id = item.vehicle or ""
        vehicle = self.vehicles.get(vehicle_id)
        if vehicle is None:
            self.log(t_s, "script_error", detail=f"no vehicle {vehicle_id!r}")
            return
        if item.kind == "vehicle_lost":
            vehicle.lost = True
            self.feed(VehicleLost(t_s, vehicle_id))
        elif item.kind == "vehicle_returned":
            vehicle.lost = False
            self.feed(self.telemetry(t_s, vehicle))
            self.feed(VehicleReturned(t_s, vehicle_id))
        elif item.kind == "vehicle_rebooted":
            vehicle.command_hold(vehicle.state.x_m, vehicle.state.y_m, vehicle.loiter_radius_m)
            self.feed(VehicleRebooted(t_s, vehicle_id))
        elif item.kind == "override":
            vehicle.commanded = False
            self.feed(OperatorOverride(t_s, vehicle_id))
        elif item.kind == "resume":
            vehicle.commanded = True
            self.feed(OperatorResume(t_s, vehicle_id))
        elif item.kind == "battery_low":
            self.feed(BatteryLow(t_s, vehicle_id))

    def announce(self, event: TargetAdded) -> None:
        """A target (or prior entry) for the core, unless outside the operating area."""
        if not self.area.contains(event.x_m, event.y_m):
            self.log(event.t_s, "target_refused", target=event.target,
                     reason="outside the operating area")
            return
        self.feed(event)

    def feed_observed(self, event: Event) -> None:
        """A camera input to the core (a detection outside the operating area is dropped);
        a detection is journalled."""
        if isinstance(event, Detection) and not self.area.contains(event.x_m, event.y_m):
            return
        if self.options.journal and isinstance(event, Detection):
            self.run.journal.append({"event": "detection", "t": event.t_s,
                                     "vehicle": event.vehicle, "target": event.target,
                                     "x_m": event.x_m, "y_m": event.y_m})
        self.feed(event)

    def report_wind(self, t_s: float) -> None:
        """Each flying, commanded vehicle's WIND at 1 Hz, as ArduPlane sends it (EXTRA3):
        its estimate is taken to be the wind it flies in (the core's settling rule skips
        the first seconds, when a real autopilot's estimate is still converging). Calm
        runs send none, so their journals stay as they were."""
        wx, wy = self.wind.at(t_s)
        for vehicle in self.vehicles.values():
            if not vehicle.lost and vehicle.commanded:
                self.feed(WindReport(t_s, vehicle.id, wx, wy))

    @staticmethod
    def telemetry(t_s: float, vehicle: OfflineVehicle) -> Telemetry:
        s = vehicle.state
        return Telemetry(t_s, vehicle.id, s.x_m, s.y_m, s.heading_rad, s.speed_m_s)

    # --------------------------------------------------------------- the loop
    def execute_run(self) -> SimulationRun:
        wall_start = time.perf_counter()
        if self.deck is not None:
            self.feed(self.ship_fix(0.0))
        for vehicle in self.vehicles.values():
            s = vehicle.state
            if self.deck is not None:
                self.deck.add(vehicle.id)
                self.feed(VehicleOnDeck(0.0, vehicle.id, True, 100.0))
                continue
            self.feed(VehicleJoined(0.0, vehicle.id, s.x_m, s.y_m, s.heading_rad, s.speed_m_s))
        for added in self.discovery.prior_events() if self.discovery else []:
            self.announce(added)
        steps = round(self.duration_s / self.dt_s)
        next_sample_s = 0.0
        t_s = 0.0
        # fixed for the run, read once: each step reads them for every vehicle
        vehicles = list(self.vehicles.values())
        deck, world, feed, dt_s = self.deck, self.world, self.feed, self.dt_s
        boat_fixes = self.core.config.priority_gain > 0  # and a boat: the core steers by it
        windy = not self.scenario.wind.calm
        try:
            for k in range(steps + 1):
                t_s = k * dt_s
                self.apply_script(t_s)
                if deck is not None:
                    self.deck_step(t_s)
                for vehicle in vehicles:
                    if deck is not None and deck.on_deck(vehicle.id):
                        continue
                    s = vehicle.state
                    self.metrics.position(t_s, vehicle.id, s.x_m, s.y_m)
                    if not vehicle.lost:
                        feed(self.telemetry(t_s, vehicle))
                if boat_fixes and world.boat is not None:
                    feed(BoatPosition(t_s, world.boat.x_m, world.boat.y_m))
                on_second = t_s >= next_sample_s - 1e-9
                if on_second and deck is not None:
                    feed(self.ship_fix(t_s))
                if on_second and windy:
                    self.report_wind(t_s)
                feed(Tick(t_s))
                if on_second:
                    self.sample(t_s)
                    next_sample_s += 1.0
                    if self.options.progress is not None:
                        self.options.progress(t_s, self.duration_s)
                if k == steps:
                    break
                wind_xy_m_s = self.wind.at(t_s + 0.5 * dt_s)
                for vehicle in vehicles:
                    if deck is not None and not self.fly_on_watch(t_s, vehicle, wind_xy_m_s):
                        continue
                    if vehicle.step(t_s, dt_s, wind_xy_m_s) and not vehicle.lost and (
                        vehicle.commanded
                    ):
                        if self.options.journal:
                            self.run.journal.append({"event": "loiter_end", "t": t_s + dt_s,
                                                     "vehicle": vehicle.id})
                        feed(LoiterEnded(t_s + dt_s, vehicle.id))
                world.step(dt_s)
                if not world.frames_due():
                    continue  # no camera frame this step
                positions = {v.id: (v.state.x_m, v.state.y_m) for v in vehicles}
                if self.discovery is not None:
                    for event in self.discovery.observe(world, positions,
                                                        lambda v: self.vehicles[v].lost):
                        self.feed_observed(event)
                    continue
                for m in world.observe(positions):
                    if self.vehicles[m.vehicle].lost:
                        continue
                    self.feed_observed(Detection(m.t_s, m.vehicle, m.target, m.x_m, m.y_m, m.r_m2))
        except KeyboardInterrupt:
            # Ctrl-C: the run so far is a run of that length (metrics, journal); the
            # frontend keeps it and says so
            self.run.interrupted_at_s = t_s
            self.duration_s = max(t_s, self.dt_s)
        wall = time.perf_counter() - wall_start
        metrics = self.metrics.to_dict(wall)
        metrics["realtime_factor"] = self.duration_s / wall if wall > 0 else math.inf
        metrics["scenario"] = self.scenario.name
        metrics["uavs"] = len(self.vehicles)
        metrics["seed"] = self.options.seed
        metrics["duration_s"] = self.duration_s
        if self.run.interrupted_at_s is not None:
            metrics["interrupted_at_s"] = self.run.interrupted_at_s
        metrics["policy"] = self.core.config.policy.describe()
        metrics["objective"] = self.core.config.objective
        metrics["wind"] = wind_record(self.scenario.wind)
        metrics["observer_counters"] = dict(self.core.view().observer_counters)
        metrics["links"] = offline_link_entries(
            sorted(self.vehicles), self.metrics.uploads, self.duration_s
        )
        if self.discovery is not None:
            metrics.update(self.discovery.metrics(self.duration_s))
        if self.deck is not None:
            self.watch_metrics.launches = self.deck.launches
            metrics.update(self.watch_metrics.to_dict(self.metrics.series))
        self.run.metrics = metrics
        return self.run

    # --------------------------------------------------------------- the watch's deck
    def ship_fix(self, t_s: float) -> BoatPosition:
        """The ship's own fix (its GPS: position, course and speed over ground)."""
        boat = self.world.boat
        assert boat is not None
        vx, vy = boat.velocity_m_s
        return BoatPosition(t_s, boat.x_m, boat.y_m, vx, vy, boat.heading_rad, None,
                            "scenario")

    def deck_step(self, t_s: float) -> None:
        """Planes on deck stand on the ship; launches, battery swaps and reports fall due."""
        assert self.deck is not None and self.world.boat is not None
        boat = self.world.boat
        for vehicle in self.vehicles.values():
            vid = vehicle.id
            if self.deck.on_deck(vid):
                vehicle.state = UavState(boat.x_m, boat.y_m, boat.heading_rad,
                                         self.scenario.fleet.speed_m_s)
            if self.deck.ready_due(t_s, vid):
                self.log(t_s, "battery_swapped", vehicle=vid)
                self.feed(VehicleOnDeck(t_s, vid, True, self.deck.battery_pct(vid)))
            if self.deck.airborne_due(t_s, vid):
                vehicle.lost, vehicle.commanded = False, True
                vehicle.phase, vehicle.aim_xy_m, vehicle.target = "free", None, None
                self.log(t_s, "launched", vehicle=vid)
                s = vehicle.state
                self.feed(VehicleJoined(t_s, vid, s.x_m, s.y_m, s.heading_rad, s.speed_m_s))
            pct = self.deck.report_due(t_s, vid)
            if pct is not None and not vehicle.lost:
                plane = self.deck.planes[vid]
                self.feed(BatteryReport(t_s, vid, pct, plane.battery.current_a,
                                        plane.battery.voltage_v))

    def fly_on_watch(self, t_s: float, vehicle: OfflineVehicle,
                     wind_xy_m_s: tuple[float, float]) -> bool:
        """Drain, fall, recover: False when the plane does not fly this step."""
        assert self.deck is not None
        vid = vehicle.id
        if self.deck.on_deck(vid) or self.deck.state(vid) is DeckState.FALLEN:
            return False
        t_next = t_s + self.dt_s
        if self.deck.drain(vid, self.dt_s, vehicle.state.speed_m_s, math.hypot(*wind_xy_m_s)):
            vehicle.lost, vehicle.commanded = True, False
            self.watch_metrics.vehicle_lost(vid)
            self.log(t_next, "vehicle_fell", vehicle=vid, reason="battery empty")
            s = vehicle.state
            self.feed(VehicleLost(t_next, vid))
            self.feed(VehicleLanded(t_next, vid, s.x_m, s.y_m))
            return False
        s = vehicle.state
        if self.deck.check_return(t_next, vid, s.x_m, s.y_m, vehicle.loiter_radius_m):
            landing = self.deck.landings[-1]
            self.watch_metrics.landing(landing.battery_pct, landing.return_end_m)
            vehicle.commanded = False
            self.log(t_next, "vehicle_recovered", vehicle=vid,
                     battery_pct=round(landing.battery_pct, 1),
                     return_end_m=round(landing.return_end_m, 1))
            self.feed(VehicleLanded(t_next, vid, s.x_m, s.y_m))
            self.feed(VehicleOnDeck(t_next, vid, False, landing.battery_pct))
            return False
        return True

    def sample(self, t_s: float) -> None:
        """Metrics, plots and journal once a mission second; the uncertainty is over the
        confirmed and prior tracks (tentative ones are candidates, not icebergs)."""
        view = self.core.view()
        self.watch_metrics.sample(view.watch)
        tracks = view.firm_tracks()
        truth = self.world.true_positions()
        self.metrics.sample_tracks(t_s, tracks, truth)
        if self.discovery is not None:
            self.discovery.sample(t_s, view, truth)
        for tr in tracks:
            self.run.target_estimates.setdefault(tr.id, []).append((t_s, tr.x_m, tr.y_m,
                                                                    tr.sigma))
        for target, (x, y) in truth.items():
            self.run.target_truth.setdefault(target, []).append((t_s, x, y))
        if self.options.journal:
            self.run.journal += track_records(t_s, view)
            if self.discovery is not None and self.discovery.search_due(t_s, view):
                self.run.journal.append(search_record(t_s, view))
            self.run.journal += truth_records(t_s, truth)
            if self.world.boat is not None:
                self.run.journal.append({"event": "boat", "t": t_s, "x_m": self.world.boat.x_m,
                                         "y_m": self.world.boat.y_m})
        for vehicle in self.vehicles.values():
            self.run.uav_tracks.setdefault(vehicle.id, []).append(
                (t_s, vehicle.state.x_m, vehicle.state.y_m)
            )
        boat = self.world.boat
        if boat is not None:
            self.run.boat_track.append((t_s, boat.x_m, boat.y_m))
        while self.snapshot_times and self.snapshot_times[0] <= t_s + 1e-9:
            self.snapshot_times.pop(0)
            self.run.snapshots.append(MapSnapshot(
                t_s=t_s,
                uav_xy_m={v.id: (v.state.x_m, v.state.y_m) for v in self.vehicles.values()},
                routes={v.id: list(v.route) for v in view.vehicles},
                estimates={tr.id: (tr.x_m, tr.y_m, tr.sigma) for tr in tracks},
                truth=dict(truth),
                boat_xy_m=(boat.x_m, boat.y_m) if boat else None,
            ))


def wind_record(spec: WindSpec) -> dict[str, float]:
    """The run's wind as metrics.json and the journal's ``start`` line give it."""
    return {"speed_m_s": spec.speed_m_s, "from_deg": spec.from_deg, "gust_m_s": spec.gust_m_s}


def _plan_record(adopted: PlanAdopted) -> PlanRecord:
    result, problem = adopted.result, adopted.problem
    return PlanRecord(
        t_s=float(adopted.t_s), mu=float(result.mu), f1=float(result.f1),
        f2=float(result.f2), objective_value=float(result.objective),
        objective=str(problem.objective), status=str(result.status), solver=result.solver,
        solve_time_s=float(result.solve_time_s),
        bound=None if result.bound is None else float(result.bound),
        gap=None if result.gap is None else float(result.gap), targets=len(problem.targets),
        uavs_planned=len(problem.uavs),
    )


def run_simulation(scenario: Scenario, options: SimulationOptions | None = None) -> SimulationRun:
    """Run ``scenario`` in virtual time and return its metrics and history."""
    options = options or SimulationOptions()
    if options.uavs is not None and options.uavs < 1:
        raise ValueError("the fleet needs at least one UAV")
    if options.duration_s is not None and not options.duration_s > 0:
        raise ValueError("duration must be > 0 s")
    if not options.snapshot_times_s:
        duration = options.duration_s or scenario.duration_s
        options = replace(options, snapshot_times_s=(duration / 4, duration / 2, duration))
    return _Simulation(scenario, options).execute_run()
