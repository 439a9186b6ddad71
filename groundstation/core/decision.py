"""The decision core: given events and the time, return what to do.

Events change state and mark the plan dirty; plans are requested on the next ``Tick`` (the
frontends tick at their step, 10 Hz), so a burst of events gives one plan.

Written once and driven by three frontends (daemon, offline simulator, replay). It reads no
clock and does no I/O: every input is an :mod:`~groundstation.core.events` value carrying its
mission time, every output a :mod:`~groundstation.core.commands` value. Solving is the
frontend's job too: the core emits a :class:`SolveRequest` and receives a
:class:`PlanSolved`, so the offline runner can solve inline while the daemon solves in a
worker thread with a deadline; an answer to a request that a newer one overtook is dropped.

Which vehicles a plan may redirect is the :class:`ReplanPolicy`'s ``commit``: with commit,
only *idle* vehicles (newly joined, returned, or whose loiter ended) are planned and the
targets of *busy* vehicles count as covered; without it every active vehicle is replanned.

A vehicle flies to where its first target is predicted to be on arrival
(:mod:`~groundstation.core.intercept`); the command carries the predicted arrival ``eta``.
The planning problem is built by :mod:`~groundstation.core.planning_targets`.

Unlabelled detections are buffered per camera frame and scanned by the tracker at the next
tick (:mod:`~groundstation.core.tracking`); its births, confirmations and deletions are
``track_*`` notes; a deleted track leaves the plan like a removed target.
Search cells (``planner/search_cells.py``) are covered by ``CameraFrame`` footprints and
planned as targets at their centres.

Wind: the vehicles' ``WindReport`` inputs are combined into one estimate
(:mod:`~groundstation.core.wind_estimate`: median over the active vehicles' fresh reports,
else the configured fallback), recomputed on every report and tick once a report was kept
(before, the fallback stands unchanged: ``WindEstimator.heard``); a meaningful change is
journalled as a ``wind`` line (:class:`~groundstation.core.commands.WindEstimate`).
:meth:`DecisionCore.planning_wind_m_s` is what planning and the intercept use.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from groundstation.core.commands import (
    CancelSolve,
    Command,
    Decisions,
    FlyToTarget,
    Note,
    PlanAdopted,
    SendHome,
    SolveRequest,
    ThroughPoint,
    Verdict,
)
from groundstation.core.config import CoreConfig
from groundstation.core.events import (
    BatteryReport,
    BoatPosition,
    CameraFrame,
    Detection,
    Event,
    LoiterEnded,
    PlanSolved,
    TargetAdded,
    TargetFixed,
    TargetRemoved,
    Telemetry,
    Tick,
    VehicleJoined,
    VehicleLanded,
    VehicleOnDeck,
    WindReport,
    WindWithdrawn,
)
from groundstation.core.fleet import (
    FleetStatus,
    VehicleRecord,
    free_vehicles,
    hand_over,
    status_change,
)
from groundstation.core.intercept import intercept, travel_time_s
from groundstation.core.mission import MIN_LOITER_S
from groundstation.core.planning_targets import build_problem, search_targets, track_targets
from groundstation.core.route import moved_on, through_points
from groundstation.core.ship import ShipTrack
from groundstation.core.tracking import TrackBook, TrackerFactory
from groundstation.core.uploads import UploadRule
from groundstation.core.views import (
    CoreView,
    SearchCellView,
    TrackView,
    VehicleView,
    search_cell_view,
)
from groundstation.core.watch import WatchKeeper, WatchView
from groundstation.core.wind_estimate import WindEstimator, WindState
from groundstation.core.wind_replan import WindReplan
from observer import UNCONFIRMED, Observer, boat_priority_q
from planner import PlanningProblem, PlanResult, UavPose
from planner.problem import wind_problem
from planner.search_cells import SearchCell, SearchGrid

__all__ = ["DecisionCore", "VehicleRecord"]

ANSWER_REASON = "loiter end answer"
"""The reason of a plan asked for only to answer a loiter end (a policy without event
replanning): it plans and commands only the vehicles whose loiter ended, as with
commitment (the targets the others fly to are left out), and the others keep their legs
until the next period."""


class DecisionCore:
    """Events and time in, commands out (see module docstring)."""

    def __init__(self, config: CoreConfig, tracker_factory: TrackerFactory | None = None) -> None:
        self.config = config
        self.observer = Observer(config.observer)
        self.tracks = TrackBook(self.observer, config.tracker, tracker_factory)
        """The multi-target tracker's side (``core/tracking.py``)."""
        self.search: SearchGrid | None = None
        if config.search is not None and config.area_m is not None:
            x0, x1, y0, y1 = config.area_m
            self.search = SearchGrid(_Area(x0, x1, y0, y1), config.search)
        self._prior_points: dict[str, tuple[float, float]] = {}
        self.vehicles: dict[str, VehicleRecord] = {}
        self.t_s = 0.0
        self.last_result: PlanResult | None = None
        self.plans_adopted = 0
        self.counters: dict[str, int] = {}
        self.boat_xy_m: tuple[float, float] | None = None
        self.wind = WindEstimator(config.wind_xy_m_s)
        """The vehicles' wind estimate, combined (``core/wind_estimate.py``)."""
        self.wind_replan = WindReplan(config.wind_replan_m_s, config.wind_replan_margin_s,
                                      config.observer.fov_radius_m)
        self.uploads = UploadRule(config.upload_min_interval_s, config.retarget_m,
                                  config.revisit_growth, config.upload_budget_per_h)
        """When a vehicle is sent a new mission (``core/uploads.py``)."""
        self.ship = ShipTrack()
        """The ship's track from every ``BoatPosition`` (``core/ship.py``): the watch's
        homes and returns, the daemon's beacon and the displays read it."""
        self.watch = (WatchKeeper(config.watch, config.loiter_s, self.ship) if config.watch
                      else None)
        """The ship watch (``core/watch.py``): homes, energy, relief; None without one."""
        self._next_request_id = 1
        self._verdicts: list[Verdict] = []  # this input's, returned with its commands
        # Called with every input before it is applied (frontends journal it for replay).
        self.on_input: Callable[[Event], None] | None = None
        self._pending: SolveRequest | None = None
        self._dirty_reason: str | None = None
        self._wind_refused = False  # a wind at or above the airspeed was noted
        # the first periodic plan is due at once
        self._next_periodic_s: float | None = 0.0 if config.policy.period_s else None

    # ------------------------------------------------------------------ public API
    def handle(self, event: Event) -> Decisions:
        """Apply one event; return the commands it causes (possibly none), with the
        verdicts on the detections it decided (:class:`~groundstation.core.commands.Decisions`).

        A ``Telemetry`` (three in four inputs of a simulated run: one per vehicle and tick)
        only moves its vehicle's pose, so it is answered first, with no commands."""
        if self.on_input is not None:
            self.on_input(event)
        if event.t_s > self.t_s:
            self.t_s = event.t_s
        out = Decisions()
        if isinstance(event, Telemetry):
            self._on_pose(event.vehicle, event.t_s, event.x_m, event.y_m, event.heading_rad,
                          event.speed_m_s)
            return out
        self._verdicts = []
        if isinstance(event, Tick):
            self._on_tick(event.t_s, out)
        elif isinstance(event, Detection):
            out += self._on_detection(event)
        elif isinstance(event, CameraFrame):
            self._on_frame(event)
        elif isinstance(event, PlanSolved):
            out += self._on_solved(event)
        elif isinstance(event, BoatPosition):
            if math.isfinite(event.x_m) and math.isfinite(event.y_m):
                self.boat_xy_m = (event.x_m, event.y_m)
            if not self.ship.fix(event):
                self._count("invalid_ship_fixes")
        elif isinstance(event, BatteryReport | VehicleOnDeck | VehicleLanded):
            out += self._on_watch_input(event)
        elif isinstance(event, WindReport):
            self.wind.report(event)
            out += self._update_wind(event.t_s)
        elif isinstance(event, WindWithdrawn):
            out += self.wind.withdraw(event, {v.id for v in self.active_vehicles()})
        else:
            out += self._on_fleet_or_target_event(event)
        if self._verdicts:
            out.verdicts = tuple(self._verdicts)
        return out

    def _on_tick(self, t_s: float, out: list[Command]) -> None:
        """A ``Tick``: the scans buffered by ``t_s``, the observer predicted to it, the
        wind, the watch, the upload rule's deferrals and misses, then at most one plan
        (appended to ``out``, in that order)."""
        out += self._process_scans(t_s)
        self.observer.predict_to(t_s)
        self._apply_priority()
        out += self._update_wind(t_s)  # reports age out; before the plan uses it
        if self.watch is not None and self.watch.due(t_s):
            watch = self.watch.tick(t_s, self.vehicles.values(), self._intercept_xy)
            if any(isinstance(c, SendHome) for c in watch):
                self._mark_dirty("vehicle sent home")
            out += watch
        if self.uploads.due(t_s):
            self._mark_dirty("upload interval passed")
        if self.uploads.review(self._value_now, self._last_seen_s):
            self._mark_dirty("revisit worth it")
        # Events only mark the plan dirty; the next tick replans once for all of them,
        # so a burst (several targets added at once) gives one plan, not one each.
        out += self._maybe_replan(t_s)

    def _on_watch_input(self, event: BatteryReport | VehicleOnDeck | VehicleLanded
                        ) -> list[Command]:
        """The watch's inputs (``core/watch.py``); without a watch a battery report is
        only counted and the deck's events are ignored."""
        if self.watch is None:
            self._count("watch_inputs_ignored")
            return []
        if isinstance(event, BatteryReport):
            if not self.watch.battery(event):
                self._count("battery_reports_invalid")
            return []
        record = self.vehicles.get(event.vehicle)
        if isinstance(event, VehicleOnDeck):
            if record is None:
                ship = self.watch.ship.predict(event.t_s)
                x_m, y_m = ship.xy_m if ship is not None else (0.0, 0.0)
                record = VehicleRecord(event.vehicle, x_m, y_m, 0.0, self.config.speed_m_s,
                                       event.t_s, status=FleetStatus.DECK)
                self.vehicles[event.vehicle] = record
            changed = self.watch.on_deck(event, record)
            if changed is None:
                return []
            return [Note(event.t_s, f"vehicle_{changed}", event.vehicle,
                         detail=f"battery {event.battery_pct:.0f} %"
                         if event.battery_pct is not None else "")]
        if record is None:
            return []
        was_active = record.status is FleetStatus.ACTIVE
        note = self.watch.landed(event, record)
        if was_active:
            self._mark_dirty("vehicle landed")
        return [note]

    def _intercept_xy(self, record: VehicleRecord, xy_m: tuple[float, float],
                      v_m_s: tuple[float, float]) -> tuple[float, float, float]:
        """The intercept of a point ``xy_m`` moving at ``v_m_s`` in the planning wind."""
        return intercept(record, xy_m, v_m_s, self.planning_wind_m_s(),
                         self.config.turn_radius_m)

    def set_boat(self, x_m: float, y_m: float, t_s: float | None = None) -> None:
        """Shorthand for handling :class:`BoatPosition` (recorded like every input)."""
        self.handle(BoatPosition(self.t_s if t_s is None else t_s, x_m, y_m))

    @property
    def pending_request(self) -> SolveRequest | None:
        return self._pending

    def wants_answer(self, request_id: int) -> bool:
        """The stale-answer rule, for every frontend: only the newest request counts; an
        answer to one that a newer request overtook (or that was already answered) is
        dropped. A frontend may ask before it journals an answer; the core asks again."""
        return self._pending is not None and self._pending.request_id == request_id

    def active_vehicles(self) -> list[VehicleRecord]:
        """The vehicles in the plan (``FleetStatus.ACTIVE``), in the order they joined."""
        active = FleetStatus.ACTIVE  # once: a member's lookup is a descriptor call (3.11)
        return [v for v in self.vehicles.values() if v.status is active]

    def planning_wind_m_s(self) -> tuple[float, float]:
        """The wind (ENU m/s, towards) the planner and the intercept use: the vehicles'
        combined estimate, else the fallback ``config.wind_xy_m_s``; (0, 0) when the core
        is not ``wind_aware`` (``core/wind_estimate.py``)."""
        if not self.config.wind_aware:
            return 0.0, 0.0
        return self.wind.current.xy_m_s

    @property
    def wind_state(self) -> WindState:
        """The wind estimate for display (even when not ``wind_aware``)."""
        return self.wind.current

    def _update_wind(self, t_s: float) -> list[Command]:
        """The estimate at ``t_s``; legs it moved are replanned (``core/wind_replan.py``).
        Nothing to do before the first wind report (``WindEstimator.heard``): the estimate
        is still the fallback every leg was predicted in."""
        if not self.wind.heard:
            return []
        active = self.active_vehicles()  # the estimate's update changes no vehicle
        out = self.wind.update(t_s, {v.id for v in active})
        if self.config.wind_aware:
            state = self.wind.current
            legs = self.wind_replan.legs(t_s, state.xy_m_s, state.source, active,
                                         self._leg_time_s)
            if not legs:
                return out  # nothing moved (every tick of a steady estimate)
            notes = self.wind_replan.replan(t_s, legs, self.config.policy.commit)
            for leg in legs:  # bounded by its own rule (a 2 m/s change): not delayed
                self.uploads.reset(leg.vehicle.id, t_s)
            if notes:
                self._mark_dirty("wind changed")
                out += notes
        return out

    def _leg_time_s(self, record: VehicleRecord, aim_xy_m: tuple[float, float],
                    wind_xy_m_s: tuple[float, float] | None = None) -> float:
        """Flight time from ``record``'s pose to the fixed point ``aim_xy_m`` in
        ``wind_xy_m_s`` (None: the planning wind now)."""
        wind = self.planning_wind_m_s() if wind_xy_m_s is None else wind_xy_m_s
        return intercept(record, aim_xy_m, (0.0, 0.0), wind, self.config.turn_radius_m)[2]

    # ------------------------------------------------------------------ event handlers
    def _count(self, key: str) -> None:
        self.counters[key] = self.counters.get(key, 0) + 1

    def _on_pose(self, vehicle: str, t_s: float, x_m: float, y_m: float, heading_rad: float,
                 speed_m_s: float) -> None:
        if not (math.isfinite(x_m) and math.isfinite(y_m) and math.isfinite(heading_rad)
                and math.isfinite(speed_m_s)):
            self._count("invalid_telemetry")
            return
        record = self.vehicles.get(vehicle)
        if record is None:
            return
        record.x_m, record.y_m, record.heading_rad = x_m, y_m, heading_rad
        record.speed_m_s = speed_m_s if speed_m_s > 1.0 else self.config.speed_m_s
        record.pose_t_s = t_s

    def _verdict(self, event: Detection, accepted: bool | None, reason: str) -> None:
        self._verdicts.append(Verdict(event.t_s, event.vehicle, event.target, accepted, reason))

    def _on_detection(self, event: Detection) -> list[Command]:
        out: list[Command] = []
        if event.target is None and self._tracking():
            r_m2 = self.config.observer.r_m2 if event.r_m2 is None else event.r_m2
            reason = "buffered" if self.tracks.detection(event, r_m2) else "invalid"
            self._count(f"detections_{reason}")
            self._verdict(event, None, reason)  # decided by the next tick's scan
            return out
        if event.target is not None:
            self.tracks.labelled(event)
        if event.target is not None and event.target not in self.observer.target_ids:
            if not (math.isfinite(event.x_m) and math.isfinite(event.y_m)):
                self._count("detections_invalid")
                self._verdict(event, False, "invalid")
                return out
            self.tracks.add(event.target, event.t_s, event.x_m, event.y_m, sigma0=event.r_m2)
            self._verdict(event, False, "discovered")
            out.append(Note(event.t_s, "target_discovered", event.vehicle, event.target))
            self._mark_dirty("target discovered")
            return out
        outcome = self.observer.measure(event.t_s, event.x_m, event.y_m, event.target,
                                        r_m2=event.r_m2)
        self._verdicts.append(Verdict(event.t_s, event.vehicle, outcome.target_id,
                                      outcome.accepted, outcome.reason))
        self._count(f"detections_{outcome.reason}")
        return out

    def _on_fleet_or_target_event(self, event: Event) -> list[Command]:
        out: list[Command] = []
        if isinstance(event, TargetAdded):
            if event.target in self.observer.target_ids:
                out.append(Note(event.t_s, "duplicate_target", target=event.target))
                return out
            self.tracks.add(
                event.target, event.t_s, event.x_m, event.y_m, vx_m_s=event.vx_m_s,
                vy_m_s=event.vy_m_s, sigma0=event.sigma0, q_per_s=event.q_per_s,
                prior=event.prior is True,
            )
            if event.prior is True and self.search is not None:
                self._prior_points[event.target] = (event.x_m, event.y_m)
                self.search.set_prior_points(list(self._prior_points.values()))
            self._mark_dirty("target added")
        elif isinstance(event, TargetFixed):
            if event.target not in self.observer.target_ids:
                out.append(Note(event.t_s, "unknown_target", target=event.target))
                return out
            try:
                self.tracks.reseat(event.target, event.t_s, event.x_m, event.y_m,
                                   event.sigma0)
            except ValueError as exc:
                out.append(Note(event.t_s, "fix_refused", target=event.target,
                                detail=str(exc)))
                return out
            self.uploads.seen(event.target)
            self._mark_dirty("target fixed")
        elif isinstance(event, TargetRemoved):
            if event.target not in self.observer.target_ids:
                out.append(Note(event.t_s, "unknown_target", target=event.target))
                return out
            self.tracks.remove(event.target)
            free_vehicles(self.vehicles.values(), event.target)
            self.uploads.seen(event.target)
            self._mark_dirty("target removed")
        elif isinstance(event, VehicleJoined):
            record = self.vehicles.get(event.vehicle)
            if record is None:
                record = VehicleRecord(event.vehicle, event.x_m, event.y_m, event.heading_rad,
                                       event.speed_m_s, event.t_s)
                self.vehicles[event.vehicle] = record
            record.status, record.busy, record.target = FleetStatus.ACTIVE, False, None
            self.uploads.reset(event.vehicle, event.t_s)
            self._on_pose(event.vehicle, event.t_s, event.x_m, event.y_m, event.heading_rad,
                          event.speed_m_s)
            if self.watch is not None:
                self.watch.joined(event.t_s, event.vehicle)
            self._mark_dirty("vehicle joined")
        elif isinstance(event, LoiterEnded):
            out += self._on_loiter_ended(event)
        else:
            out += self._on_status_change(event)
        return out

    def _on_loiter_ended(self, event: LoiterEnded) -> list[Command]:
        """Without commitment the vehicle goes on along its planned sequence at once
        (the paper's UAVs pass over one target and head for the next, not waiting for the
        next sample); with commitment it becomes idle and the next tick replans it."""
        record = self.vehicles.get(event.vehicle)
        if record is None or record.status is not FleetStatus.ACTIVE or not record.busy:
            return []
        record.busy = False
        record.answer_due = True
        self._mark_dirty("loiter ended")
        if record.through:  # the mission's end: it flew through every cell (core/route.py)
            self._move_on(event.t_s, record, len(record.through), None)
        out = self._visit_ended(event.t_s, record)
        command = self._next_along_route(event.t_s, record, out)
        if command is None and record.answer_due:
            # no leg yet: the next tick plans for it, whatever the policy (a periodic-only
            # policy would otherwise leave it holding until the next period); that plan
            # answers the loiter ends only (the others keep their legs until the period)
            self._dirty_reason = self._dirty_reason or ANSWER_REASON
        return out if command is None else [*out, command]

    def _next_along_route(self, t_s: float, record: VehicleRecord, out: list[Command]
                          ) -> Command | None:
        """Without commitment, the loiter end's answer at once: the next target of its
        planned route worth a visit (or home, on a watch, when that leg is unflyable;
        appended to ``out``); None when there is none (or with commitment)."""
        if self.config.policy.commit or record.target not in record.route:
            return None
        rest = record.route[record.route.index(record.target) + 1:]
        known = self._known_targets()
        rest = tuple(t for t in rest if t in known)
        pick = self._first_worth_a_visit(record, rest)
        if pick is None:
            return None
        target, rest, leg = pick
        home = self._unflyable(t_s, record, leg)
        if home:
            record.answer_due = False
            out += home
            return None
        return self._fly(t_s, record, target, rest, leg)

    def _visit_ended(self, t_s: float, record: VehicleRecord) -> list[Command]:
        """A loiter (or pass) of ``record`` ended: if its target was not seen since the
        leg was sent, that visit missed (``core/uploads.py``); a ``visit_missed`` note."""
        target, aim, leg_t_s = record.target, record.aim_xy_m, record.leg_t_s
        if target is None or aim is None or leg_t_s is None:
            return []
        if target not in self._known_targets():
            return []
        last = self._last_seen_s(target)
        if last is not None and last >= leg_t_s:
            self.uploads.seen(target)
            return []
        value = self._value_m2(target, t_s)
        if not self.uploads.missed(t_s, record.id, target, aim, value):
            return []
        return [Note(t_s, "visit_missed", record.id, target,
                     f"not seen since {leg_t_s:.1f} s; not sent back there until it moves "
                     f"{self.config.retarget_m:.0f} m or its value grows "
                     f"{self.config.revisit_growth:g}x")]

    def _value_now(self, target: str) -> float | None:
        """A target's planning value now; None when it is gone."""
        if (self.search is not None and target in self.search) or (
                target in self.observer.target_ids):
            return self._value_m2(target, self.t_s)
        return None

    def _last_seen_s(self, target: str) -> float | None:
        """When a track was last measured or a search cell last covered (None: never)."""
        if self.search is not None and target in self.search:
            return self.search.last_covered_s(target)
        if target in self.observer.target_ids:
            return self.observer.track(target).last_seen_s
        return None

    def _value_m2(self, target: str, t_s: float) -> float:
        """A target's planning value now: a search cell's, else the track's sigma."""
        if self.search is not None and target in self.search:
            return self.search.value_m2(target, t_s)
        return self.observer.sigma(target)  # the track's snapshot's sigma, unbuilt

    def _first_worth_a_visit(self, record: VehicleRecord, route: tuple[str, ...]
                             ) -> tuple[str, tuple[str, ...], tuple[float, float, float]] | None:
        """The first target of ``route`` that ``record`` did not just miss at the same
        place (``core/uploads.py``), the route from it, and its leg; None: none is."""
        known = self._known_targets()
        for k, target in enumerate(route):
            if target not in known:
                continue
            leg = self.intercept(record, target)
            if not self.uploads.blocked(record.id, target, (leg[0], leg[1]),
                                        self._value_m2(target, self.t_s)):
                return target, route[k:], leg
        return None

    def _on_status_change(self, event: Event) -> list[Command]:
        vehicle = getattr(event, "vehicle", None)
        record = self.vehicles.get(vehicle) if isinstance(vehicle, str) else None
        if record is None:
            return []
        out, reason = status_change(record, event, self.config.battery_low_action)
        if reason is not None:
            self.uploads.reset(record.id, event.t_s)  # its next leg is not delayed
            self._mark_dirty(reason)
            if record.status is not FleetStatus.ACTIVE:
                out += self._drop_pending_with(event.t_s, record.id)
        return out

    def _drop_pending_with(self, t_s: float, vehicle: str) -> list[Command]:
        """The pending request plans ``vehicle``, which has just left the active fleet
        (lost, overridden, home...): it is cancelled, and its answer, should it still come,
        is dropped as stale (:meth:`wants_answer`), so no adopted plan names a vehicle the
        core already knew it could not fly. The replan its leaving asks for (the next
        tick's, or the next period's) plans without it."""
        pending = self._pending
        if pending is None or all(u.id != vehicle for u in pending.problem.uavs):
            return []
        self._pending = None
        return [CancelSolve(t_s, pending.request_id)]

    # ------------------------------------------------------------------ planning
    def _mark_dirty(self, reason: str) -> None:
        if self.config.policy.on_events and self._dirty_reason is None:
            self._dirty_reason = reason

    def _apply_priority(self) -> None:
        if self.config.priority_gain <= 0 or self.boat_xy_m is None:
            return
        bx, by = self.boat_xy_m
        for track in self.observer.tracks():
            q = boat_priority_q(
                self.config.observer.q_per_s, math.hypot(track.x_m - bx, track.y_m - by),
                near_m=self.config.priority_near_m, far_m=self.config.priority_far_m,
                gain=self.config.priority_gain,
            )
            self.observer.set_process_noise(track.id, q)

    def _maybe_replan(self, t_s: float) -> list[Command]:
        reason = self._dirty_reason
        period = self.config.policy.period_s
        if period is not None and self._next_periodic_s is not None and t_s >= (
            self._next_periodic_s - 1e-9
        ):
            while self._next_periodic_s <= t_s + 1e-9:
                self._next_periodic_s += period
            # a periodic plan plans everyone, so it answers a loiter end too
            reason = "period" if reason in (None, ANSWER_REASON) else reason
        if reason is None:
            return []
        self._dirty_reason = None
        return self._request_plan(t_s, reason)

    def planned_vehicles(self) -> list[VehicleRecord]:
        """Vehicles a replan may redirect under the policy."""
        if self.config.policy.commit:
            return [v for v in self.vehicles.values() if v.idle]
        return self.active_vehicles()

    def _request_plan(self, t_s: float, reason: str) -> list[Command]:
        out: list[Command] = []
        answer = reason == ANSWER_REASON  # as with commitment: the others keep their legs
        vehicles = sorted(
            (v for v in self.active_vehicles() if v.answer_due) if answer
            else self.planned_vehicles(), key=lambda v: v.id)
        self.observer.predict_to(t_s)
        covered = {
            v.target for v in self.vehicles.values()
            if v.status is FleetStatus.ACTIVE and v.busy and v.target is not None
        } if self.config.policy.commit or answer else set()
        targets = track_targets(self.observer.tracks(), self.tracks.status, covered,
                                self.config.tentative_weight, self.tracks.existence)
        if self.search is not None:
            targets += search_targets(self._search_cells(t_s, covered))
        if not vehicles or not targets:
            return out
        wind = self._problem_wind(t_s, out)
        uavs = [UavPose(v.id, v.x_m, v.y_m, v.heading_rad) for v in vehicles]
        problem = build_problem(self.config, uavs, targets, wind)
        if self._pending is not None:
            out.append(CancelSolve(t_s, self._pending.request_id))
        request = SolveRequest(t_s, self._next_request_id, problem, self._hint(problem), reason)
        self._next_request_id += 1
        self._pending = request
        out.append(request)
        return out

    def _search_cells(self, t_s: float, covered: set[str]) -> list[SearchCell]:
        """The plan's search cells: the ``max_cells`` most valuable, and (``keep_held_cells``,
        without commitment) every cell an active vehicle is flying to, so a cell does not
        leave the problem (and its vehicle turned away) only because others grew past it
        (``core/uploads.py``; on discovery seeds 0-1 it changed no upload: there a cell
        leaves the problem when its vehicle's own footprint covers it)."""
        assert self.search is not None
        cells = self.search.top(t_s, exclude=covered)
        if self.config.keep_held_cells and not self.config.policy.commit:
            held = {t for v in self.active_vehicles() if v.busy
                    for t in (v.target, *v.through) if t is not None and t in self.search}
            held -= {c.id for c in cells}
            if held:
                cells += [c for c in self.search.values(t_s) if c.id in held and c.value_m2 > 0]
        return cells

    def _problem_wind(self, t_s: float, out: list[Command]) -> tuple[float, float] | None:
        """The planning problem's wind: None in still air (the problem then reads as
        before wind existed), and None with a ``wind_refused`` note (once, until the wind
        can be flown again) when it is not below the airspeed: the planner refuses such a
        wind, so the plan is made as in still air."""
        wind = self.planning_wind_m_s()
        if wind[0] == 0.0 and wind[1] == 0.0:
            return None
        reason = wind_problem(wind, self.config.speed_m_s)
        if reason is not None:
            if not self._wind_refused:
                out.append(Note(t_s, "wind_refused", detail=f"planning as in still air: {reason}"))
            self._wind_refused = True
            return None
        self._wind_refused = False
        return wind

    def _hint(self, problem: PlanningProblem) -> dict[str, list[str]]:
        if self.last_result is None:
            return {}
        targets = {t.id for t in problem.targets}
        return {
            u.id: [t for t in self.last_result.routes.get(u.id, []) if t in targets]
            for u in problem.uavs
        }

    def _on_solved(self, event: PlanSolved) -> list[Command]:
        request = self._pending
        if request is None or not self.wants_answer(event.request_id):
            self._count("stale_plans_dropped")
            return []
        self._pending = None
        result = event.result
        self.last_result = result
        self.plans_adopted += 1
        known = self._known_targets()
        assignments: dict[str, str] = {}
        fly: list[Command] = []
        for uav in request.problem.uavs:
            record = self.vehicles.get(uav.id)
            route = result.routes.get(uav.id, [])
            first = route[0] if route else result.idle.get(uav.id)
            if record is None or first is None or first not in known:
                continue
            if record.status is not FleetStatus.ACTIVE or (
                self.config.policy.commit and record.busy
            ) or (request.reason == ANSWER_REASON and not record.answer_due):
                continue
            pick = self._first_worth_a_visit(record, tuple(route) if route else (first,))
            if pick is None:
                continue
            target, legs, leg = pick
            home = self._unflyable(event.t_s, record, leg)
            if home:
                fly += home
                continue
            assignments[uav.id] = target
            command = self._fly(event.t_s, record, target, legs if route else (), leg)
            if command is not None:
                fly.append(command)
        for uav in request.problem.uavs:  # a loiter end's answer is given once
            record = self.vehicles.get(uav.id)
            if record is not None:
                record.answer_due = False
        adopted = PlanAdopted(event.t_s, request.request_id, request.problem, result,
                              assignments, request.hint, request.reason)
        return [adopted, *fly]

    def _unflyable(self, t_s: float, record: VehicleRecord,
                   leg: tuple[float, float, float]) -> list[Command]:
        """On a watch, a ``leg`` (its aim point and flight time, :meth:`intercept`) that
        would leave ``record`` short of the charge to reach the ship with its reserve is
        not flown: the vehicle goes home instead (the planner's other vehicles are
        replanned without it). Empty: fly it."""
        if self.watch is None:
            return []
        x_m, y_m, t_arr_s = leg
        if self.watch.leg_ok(t_s, record, (x_m, y_m), t_s + t_arr_s, self._intercept_xy):
            return []
        self._mark_dirty("vehicle sent home")
        return self.watch.send_home_instead(t_s, record, self._intercept_xy)

    def _fly(self, t_s: float, record: VehicleRecord, target: str,
             route: tuple[str, ...], leg: tuple[float, float, float]) -> FlyToTarget | None:
        """Send ``record`` to ``target`` along ``leg`` (its :meth:`intercept`), when it
        matters (``core/uploads.py``): not again to the same leg without commitment, and
        not within the minimum interval (deferred: the vehicle keeps what it flies)."""
        x_m, y_m, t_arr_s = leg
        aim = (x_m, y_m)
        unchanged = self.uploads.same_leg(record.target, record.aim_xy_m, target, aim)
        if unchanged and not self.config.policy.commit:
            record.route = route
            record.busy = True
            return None
        if not self.config.policy.commit and record.busy:
            k = moved_on(record.target, record.through, target, self._seen_since_leg(record))
            if k is not None:  # along the mission it has: no new one (core/route.py)
                self._move_on(t_s, record, k, (aim, t_arr_s))
                record.route = route
                return None
        # a vehicle on a routed pass (``core/route.py``) is redirected at most once per
        # route interval, whether points of its route are still ahead (it keeps flying
        # them meanwhile) or only the repeats of its head: between neighbouring cells the
        # plan's head flips with every periodic replan (issue 28: 60-68 uploads per vehicle
        # per hour on discovery's seeds 4 and 7 from heads re-sent 15 s apart)
        routed = record.busy and bool(record.through)
        if not record.answer_due and self.uploads.too_soon(
                record.id, t_s, self.config.route_min_interval_s if routed else None):
            return None  # deferred; a loiter end's answer never is (core/uploads.py)
        record.route = route
        record.busy = True
        record.answer_due = False
        self.uploads.sent(record.id, t_s)
        record.leg_t_s = t_s
        record.target, record.aim_xy_m, record.eta_s = target, aim, t_s + t_arr_s
        record.leg_wind_xy_m_s = self.planning_wind_m_s()
        record.leg_wind_source = self.wind.current.source
        through = self._through(route, aim, t_arr_s)
        record.through = tuple(c.target for c in through)
        return FlyToTarget(t_s, record.id, target, aim[0], aim[1], self.config.loiter_s,
                           self.config.loiter_radius_m, route, eta_s=t_s + t_arr_s,
                           through=through)

    def _through(self, route: tuple[str, ...], aim_xy_m: tuple[float, float],
                 t_arr_s: float) -> tuple[ThroughPoint, ...]:
        """The targets a pass to ``route[0]`` (at ``aim_xy_m``, ``t_arr_s`` s from now)
        flies through after it (``core/route.py``); none when the visit loiters, routes
        are off, or the run has no search cells (tracking alone, e.g. paper-boat's 5 s
        sample-based replanning of 3 m/s icebergs, keeps one target per mission). Always
        ``route_cells`` points, the last one (or the head) repeated when the route has
        fewer: ArduPlane reaches a repeated point at once, and the mission's length never
        changes between uploads (``vehicle/jobs.py``)."""
        if (self.search is None or self.config.loiter_s >= MIN_LOITER_S or not route
                or not self.config.route_cells):
            return ()
        points = through_points(route, self.config.route_cells, aim_xy_m, t_arr_s,
                                self.config.speed_m_s, self._where)
        last = points[-1] if points else ThroughPoint(route[0], *aim_xy_m)
        return points + (last,) * (self.config.route_cells - len(points))

    def _where(self, target: str) -> tuple[tuple[float, float], tuple[float, float]] | None:
        """A target's position and drift velocity now (None: gone)."""
        if self.search is not None and target in self.search:
            return self.search.centre(target), (0.0, 0.0)
        if target in self.observer.target_ids:
            track = self.observer.track(target)
            return (track.x_m, track.y_m), (track.vx_m_s, track.vy_m_s)
        return None

    def _seen_since_leg(self, record: VehicleRecord) -> Callable[[str], bool]:
        """Whether a target was seen since ``record``'s mission was sent (a target that is
        gone counts as seen: nothing is left to look at)."""
        def seen(target: str) -> bool:
            if target not in self._known_targets():
                return True
            last = self._last_seen_s(target)
            return last is not None and record.leg_t_s is not None and last >= record.leg_t_s
        return seen

    def _move_on(self, t_s: float, record: VehicleRecord, k: int,
                 leg: tuple[tuple[float, float], float] | None) -> None:
        """``record`` moved on to item ``k`` of its mission's ``through`` cells: its target
        and aim are that cell's (``leg``: its aim and flight time; None: the vehicle is
        there), the cells before it are done."""
        target = record.through[k - 1]
        record.through = record.through[k:]
        if leg is None:
            where = self._where(target)
            aim = where[0] if where is not None else record.aim_xy_m
            t_arr_s = 0.0
        else:
            aim, t_arr_s = leg
        record.target, record.aim_xy_m, record.eta_s = target, aim, t_s + t_arr_s
        self._count("route_moved_on")

    def travel_time_s(self, record: VehicleRecord, x_m: float, y_m: float) -> float:
        """Predicted time (s) for ``record`` to fly from its pose to (x_m, y_m) in still air
        (:func:`~groundstation.core.intercept.travel_time_s`)."""
        return travel_time_s(record, x_m, y_m, self.config.turn_radius_m)

    def intercept(self, record: VehicleRecord, target: str) -> tuple[float, float, float]:
        """(x_m, y_m, t_arr_s): the aim point for ``target`` and the flight time to it
        (:func:`~groundstation.core.intercept.intercept`)."""
        if self.search is not None and target in self.search:
            xy, v = self.search.centre(target), (0.0, 0.0)  # a search cell does not move
        else:
            track = self.observer.track(target)
            xy, v = (track.x_m, track.y_m), (track.vx_m_s, track.vy_m_s)
        return intercept(record, xy, v, self.planning_wind_m_s(), self.config.turn_radius_m)

    # ------------------------------------------------------------------ tracks, search
    def _tracking(self) -> bool:
        """Unlabelled detections go to the tracker (Kalman tracks); the field test's linear
        model keeps the observer's nearest-track association."""
        return self.config.observer.model == "kalman"

    def _on_frame(self, event: CameraFrame) -> None:
        if not self.tracks.frame(event):
            self._count("frames_invalid")
            return
        if self.search is not None:
            self.search.cover(event.t_s, event.x_m, event.y_m, event.radius_m)

    def _process_scans(self, t_s: float) -> list[Command]:
        """Buffered scans due by ``t_s`` through the tracker; its events become notes, a
        confirmation or deletion marks the plan dirty, a deleted track (already gone from
        the observer: the tracker removes it) frees its vehicles (as ``TargetRemoved``), or,
        deleted by coalescence, hands them over to the track that goes on with its estimate
        (``fleet.hand_over``: a new id alone sends no new mission).
        An unconfirmed deletion (mostly clutter) that no vehicle's route held asks for
        no plan (on ``discovery`` seed 6 they were 903 of 1 078 plans, each a chance to
        turn a vehicle away from the track it was about to reach).
        The search cells' prior weights stay those of the prior as listed."""
        out: list[Command] = []
        for scan, events, hits in self.tracks.process(t_s):
            self._count("scans")
            self._verdicts += [Verdict(scan.t_s, scan.vehicle, track, True, "assigned")
                               for track in hits]
            for ev in events:
                out.append(Note(ev.t_s, f"track_{ev.kind}", scan.vehicle or None, ev.track_id,
                                ev.reason))
                if ev.kind == "confirmed":
                    self._mark_dirty("track confirmed")
                elif ev.kind == "deleted" and ev.successor is not None:
                    # coalescence: the same estimate under the successor's id
                    hand_over(self.vehicles.values(), ev.track_id, ev.successor)
                    self._mark_dirty("track deleted")
                elif ev.kind == "deleted":  # the tracker removed it from the observer
                    held = any(ev.track_id in v.route for v in self.vehicles.values())
                    freed = free_vehicles(self.vehicles.values(), ev.track_id)
                    self.uploads.seen(ev.track_id)
                    if freed or held or ev.reason != UNCONFIRMED:
                        self._mark_dirty("track deleted")
        return out

    def _known_targets(self) -> set[str]:
        """Ids a plan may send a vehicle to: the tracks, and the search cells."""
        known = set(self.observer.target_ids)
        if self.search is not None:
            known.update(self.search.ids)
        return known

    def view(self) -> CoreView:
        """The core's read model now (``core/views.py``): what frontends and displays read."""
        vehicles = tuple(
            VehicleView(v.id, v.status, v.x_m, v.y_m, v.heading_rad, v.target, v.route, v.busy)
            for v in self.vehicles.values()
        )
        watch = self.watch_view()
        return CoreView(self.t_s, tuple(self.track_views()), tuple(self.search_view()),
                        self.search is not None, self.wind.current, vehicles,
                        dict(self.observer.counters), self.wind.flagged, self.plans_adopted,
                        watch)

    def watch_view(self) -> WatchView | None:
        """The ship watch now (``CoreView.watch``) without the rest of the view; None
        without a watch."""
        if self.watch is None:
            return None
        return self.watch.view(self.t_s, self.vehicles.values(), self._intercept_xy)

    def track_views(self) -> list[TrackView]:
        """Every track with its status (``core/views.py``), sorted by id."""
        status, existence = self.tracks.status, self.tracks.existence
        return [
            TrackView(tr.id, status(tr.id), tr.x_m, tr.y_m, tr.sigma, existence(tr.id), tr.t_s,
                      tr.vx_m_s, tr.vy_m_s, tr.cov_xy, tr.lost, tr.last_seen_s)
            for tr in self.observer.tracks()
        ]

    def search_view(self) -> list[SearchCellView]:
        """Every search cell with its value now (empty when search is off)."""
        if self.search is None:
            return []
        return [search_cell_view(c) for c in self.search.values(self.t_s)]

    def snapshot_assignments(self) -> Mapping[str, str | None]:
        return {v.id: v.target for v in self.vehicles.values()}


@dataclass(frozen=True)
class _Area:
    x_min_m: float
    x_max_m: float
    y_min_m: float
    y_max_m: float
