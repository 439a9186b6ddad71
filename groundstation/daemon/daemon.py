"""The daemon behind ``gcs run``: links, sessions, the decision core, the journal.

One root ``asyncio.TaskGroup`` holds the ticker (``Tick`` every 0.1 mission s, the world,
housekeeping), the GCS heartbeat (1 Hz of mission time, system id ``gcs_system_id``), the
embedded simulator (``sim:N``), the status display, the control API and one task per
vehicle session. Every task runs under :meth:`Daemon._supervise`: an exception is logged,
journalled (``task_error``) and the task restarted, so one vehicle's failure never takes
the others down. The decision core is driven exactly as ``gcs simulate`` drives it: events
in, commands out, plans requested on ticks and solved in a worker thread
(:class:`~groundstation.daemon.planning.SolverRunner`).
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypedDict

from domain.geodesy import GeoOrigin
from domain.modes import ArduPlaneMode
from groundstation.core import commands as cmd
from groundstation.core import events as ev
from groundstation.core.area import OperatingArea
from groundstation.core.config import CoreConfig
from groundstation.core.decision import DecisionCore
from groundstation.core.link_metrics import LinkUse, link_entries
from groundstation.core.metrics import MetricsRecorder
from groundstation.core.records import command_to_record, event_to_record
from groundstation.core.watch_metrics import WatchMetrics
from groundstation.daemon.clock import MissionClock
from groundstation.daemon.config import DaemonConfig, OnExit, OperatingCenter
from groundstation.daemon.journal import Journal
from groundstation.daemon.link_budgets import LinkBudgets
from groundstation.daemon.log_lines import describe_line, line_level
from groundstation.daemon.loop_monitor import LoopMonitor
from groundstation.daemon.planning import SolverRunner
from groundstation.daemon.reports import LinkReporter, run_summary
from groundstation.daemon.services import FnService, Service, TaskSet
from groundstation.daemon.session import VehicleSession
from groundstation.daemon.signing_gate import SigningGate
from groundstation.daemon.supervision import Supervisor
from groundstation.daemon.vehicle_files import VehicleFiles
from groundstation.daemon.vehicle_port import VehiclePort
from groundstation.daemon.world import ScenarioWorld
from groundstation.daemon.world_feed import WorldFeed
from groundstation.link import Received, Router, TlogWriter
from groundstation.link.base import Link
from groundstation.link.binding import BindingRules
from groundstation.mavlink.codec import MavlinkEncoder, mavlink2
from groundstation.mavlink.evidence import NewSystemEvidence, is_autopilot_heartbeat
from groundstation.mavlink.fence_items import FenceCircle, fence_circle, keep_in_m
from groundstation.mavlink.mission_items import MissionItem
from groundstation.vehicle.state import LinkState, VehicleState
from planner import PlanResult

__all__ = ["Daemon"]

log = logging.getLogger(__name__)
M = mavlink2
MIN_WAKE_WALL_S = 0.01
HEARTBEAT_PERIOD_S = 1.0
"""The GCS heartbeat's period, mission seconds (MAVLink's 1 Hz)."""
MAX_TICKS_PER_WAKE = 100
SIGNING_REPORT_S = 5.0
"""Mission seconds between two ``signing_rejected`` journal lines of one vehicle/link."""
LINK_REPORT_PERIOD_S = 10.0
"""At most one ``link_drops`` journal line per link per this many mission seconds."""
MISSION_MESSAGES_FROM_GCS = frozenset(
    {"MISSION_COUNT", "MISSION_CLEAR_ALL", "MISSION_ITEM", "MISSION_ITEM_INT"}
)


def expected_system_ids(config: DaemonConfig) -> frozenset[int]:
    """The vehicles floe is told about: ``sim:N``'s system ids 1..N and those of
    ``vehicle_settings``. They join on evidence alone; others are also rate-limited."""
    sim = range(1, (config.sim_count or 0) + 1)
    return frozenset((*sim, *config.fleet.settings))


@dataclass
class _Due:
    """When the ticker's periodic duties are next due (mission s): the core's ``Tick``
    (``tick_s``, every ``CoreConfig.tick_s``), the metrics sample (``sample_s``, every
    mission second), the ``track`` lines (``track_s``, every ``track_period_s``), the
    ``signing_rejected`` lines (``signing_report_s``, every ``SIGNING_REPORT_S``) and the
    ``link_drops`` check (``link_report_s``, every ``LINK_REPORT_PERIOD_S``, by
    ``link_reporter``). A fleet event sets ``kick``: the ticker wakes at once."""

    tick_s: float = 0.0
    sample_s: float = 0.0
    track_s: float = 0.0
    signing_report_s: float = 0.0
    link_report_s: float = 0.0
    link_reporter: LinkReporter = field(default_factory=LinkReporter)
    kick: asyncio.Event = field(default_factory=asyncio.Event)


@dataclass
class _RunState:
    """Whether and why the run stops, and what it cost (wall and CPU time)."""

    stop_reason: str = ""
    internal_error: str | None = None
    finished: bool = False
    """The stop line is written: the core takes nothing more."""
    stop: asyncio.Event = field(default_factory=asyncio.Event)
    wall_start: float = field(default_factory=time.perf_counter)
    cpu_start: float = field(default_factory=time.process_time)


class LastPlan(TypedDict):
    """The plan the core adopted last (the status display and the control API)."""

    t: float
    routes: dict[str, list[str]]
    status: str
    solve_time_s: float


@dataclass
class DropCounts:
    """What the daemon dropped and counted."""

    unknown_frames: int = 0
    """Frames of system ids without a session (dropped; candidates' included)."""
    detections_dropped: int = 0
    """Detections outside the operating area (camera or feed), dropped."""
    detections_no_origin: int = 0
    """Feed detections dropped because no mission origin was known yet."""


class Daemon:
    """See the module docstring. Built by :mod:`groundstation.daemon.startup`, with every
    collaborator given to the constructor (links, signing, scenario world, services)."""

    def __init__(
        self,
        config: DaemonConfig,
        core_config: CoreConfig,
        clock: MissionClock,
        run_dir: Path,
        origin: GeoOrigin | None,
        journal: Journal,
        tlog: TlogWriter | None,
        *,
        links: Sequence[Link] = (),
        out_links: Sequence[Link] = (),
        signing: SigningGate | None = None,
        world: ScenarioWorld | None = None,
        wind_fallback_source: str = "none",
        link_model: Callable[[], Mapping[int, Mapping[str, Any]]] | None = None,
    ) -> None:
        self.config = config
        self.clock = clock
        self.run_dir = run_dir
        self.origin_or_none = origin
        self.journal_file = journal
        self.core = DecisionCore(core_config)
        # every input the core sees is journalled exactly (replay feeds them again)
        self.core.on_input = lambda event: journal.write_record(event_to_record(event))
        self.encoder = MavlinkEncoder(config.links.gcs_system_id, M.MAV_COMP_ID_MISSIONPLANNER)
        self.signing = signing
        self.router = Router(
            self._on_vehicle_frame,
            self._on_out_frame,
            tlog,
            rules=BindingRules(rebind_after_s=config.links.rebind_after_s),
            now_s=clock.now_s,
            on_notice=lambda event, fields: self.journal(event, **fields),
            admit=signing.admit if signing is not None else None,
            sign=signing.sign if signing is not None else None,
            on_radio=lambda link, rx: self.budgets.on_radio_status(
                link.link_id, clock.now_s(), rx.message),
        )
        for link in links:
            self.router.add_vehicle_link(link)
        for link in out_links:
            self.router.add_out_link(link)
        self.budgets = LinkBudgets(
            links, self.router.link_for, timeout_floor_s=config.links.transfer_timeout_s,
            rates_bps=dict(config.links.link_rates()),
        )
        """Each vehicle link's traffic budget (docs/links.md, "Over a telemetry radio")."""
        self.sessions: dict[int, VehicleSession] = {}
        self.newcomers = NewSystemEvidence(expected=expected_system_ids(config))
        """Evidence before a system id gets a session (``vehicle_seen``); unexpected ones
        rate-limited per link and summarised (``unknown_systems``)."""
        self.drops = DropCounts()
        self.by_name: dict[str, VehicleSession] = {}
        self.solver = SolverRunner(
            self._on_solved,
            num_workers=config.planner.num_workers,
            seed=config.mission.seed,
            on_error=self._on_solve_error,
        )
        self.metrics = MetricsRecorder()
        self.watch_metrics = WatchMetrics()
        """The ship watch's figures (``core/watch_metrics.py``), when there is a watch."""
        self.world = world
        self.loop_monitor = LoopMonitor()
        """The event loop's worst stall (``loop_monitor.py``; in ``metrics.json``)."""
        self.control_url: str | None = None
        """The control API's address, once its server listens (the status display)."""
        self.wind_fallback_source = wind_fallback_source
        """Where the core's fallback wind came from: config, scenario or none (start-up)."""
        self.link_model = link_model
        """What a link model measured per system id (the built-in simulator's radios: their
        ``air_pct``), for the ``links`` figures; None: real links."""
        self.feed = WorldFeed(self)
        self.area = OperatingArea(
            config.mission.operating_radius_m,
            config.mission.operating_center == OperatingCenter.BOAT,
        )
        self.vehicle_files = VehicleFiles(run_dir, self.journal)
        """Each vehicle's verified missions (QGC WPL 110) and parameter snapshot (.parm)."""
        self.stopping = False
        self.last_plan: LastPlan | None = None
        self._due = _Due()
        self._state = _RunState()
        supervisor = Supervisor(clock.now_s, self.journal, self._on_bug)
        self.tasks = TaskSet(supervisor)

    # ------------------------------------------------------------------ read-outs
    @property
    def core_config(self) -> CoreConfig:
        return self.core.config

    @property
    def supervisor(self) -> Supervisor:
        return self.tasks.supervisor

    @property
    def boat_xy_m(self) -> tuple[float, float] | None:
        return self.area.boat_xy_m

    @property
    def stop_reason(self) -> str:
        return self._state.stop_reason

    @property
    def internal_error(self) -> str | None:
        """Why a bug stopped the run (None if none did)."""
        return self._state.internal_error

    @property
    def unknown_frames(self) -> int:
        return self.drops.unknown_frames

    @property
    def detections_dropped(self) -> int:
        return self.drops.detections_dropped

    @property
    def detections_no_origin(self) -> int:
        return self.drops.detections_no_origin

    # ------------------------------------------------------------------ SessionHost
    @property
    def origin(self) -> GeoOrigin:
        assert self.origin_or_none is not None
        return self.origin_or_none

    def journal(self, event: str, *, logged: bool = False, **fields: object) -> None:
        """Write a journal line, stamped now; an operator event also reaches the console,
        once.

        The rule that keeps every problem to one console line: the journal line of an
        operator event is logged at its :func:`line_level` (a problem at WARNING), unless
        its site already told the operator in its own words and passes ``logged=True``
        (supervision, the core's failure, the vehicle controller's warnings, the alerts).
        The link layer never warns of what it notifies (``link_rebound``, ``peer_rebound``):
        its notice is journalled here and told by its line."""
        self._tell(self.journal_file.write(event, **fields), logged)

    def _tell(self, line: dict[str, Any], logged: bool) -> None:
        """The console's part of :meth:`journal` for a line already written."""
        if not logged and (level := line_level(line)) >= logging.INFO:
            log.log(level, "%s", describe_line(line))

    def core_event(self, event: ev.Event) -> Sequence[cmd.Verdict]:
        """Feed the core and carry out what it says (as the offline runner does); returns
        the core's verdicts on the detections this input decided.

        A fleet event (loiter end, vehicle joined/lost...) also wakes the ticker at once, so
        the plan it triggers is asked for on the next 0.1 s tick without waiting for the
        ticker's sleep."""
        if self._state.finished or self._state.internal_error is not None:
            return ()  # the run is over, or a bug stops it: nothing more is commanded
        if not isinstance(
            event,
            ev.Tick | ev.Telemetry | ev.Detection | ev.PlanSolved | ev.BoatPosition
            | ev.WindReport | ev.BatteryReport,
        ):
            self._due.kick.set()
        elif isinstance(event, ev.Telemetry):  # the arrival-error metric follows telemetry
            self.metrics.position(event.t_s, event.vehicle, event.x_m, event.y_m)
        try:
            pending = self.core.handle(event)
        except Exception as exc:  # a bug: the one bug path (Supervisor.bug), a clean stop
            self.supervisor.bug(f"core ({type(event).__name__})", exc)
            return ()
        for command in pending:
            self._execute(command)
        return pending.verdicts

    def clip(self, x_m: float, y_m: float, loiter_radius_m: float
             ) -> tuple[float, float, bool]:
        """Clip a waypoint into the operating area, far enough inside the fence's edge for
        a loiter of ``loiter_radius_m`` there (SessionHost; ``fence_items.keep_in_m``)."""
        band_m = keep_in_m(loiter_radius_m, self.area.around_boat)
        return self.area.clip(x_m, y_m, band_m)

    def area_center(self) -> tuple[float, float]:
        return self.area.center()

    def fence(self) -> FenceCircle | None:
        """The operating area's geofence now (SessionHost; ``fence_items.fence_circle``)."""
        return fence_circle(self.area.center(), self.area.radius_m)

    def mission_verified(self, vehicle: str, purpose: str,
                         items: Sequence[MissionItem]) -> None:
        """A verified mission: its QGC WPL 110 file in the run folder (SessionHost)."""
        self.vehicle_files.mission(vehicle, purpose, items)

    def params_read(self, vehicle: str, values: dict[str, float]) -> None:
        """A vehicle's parameters: its ``.parm`` snapshot in the run folder (SessionHost)."""
        self.vehicle_files.params(vehicle, values)

    def inside_area(self, x_m: float, y_m: float) -> bool:
        return self.area.contains(x_m, y_m)

    # ------------------------------------------------------------------ core commands
    def _execute(self, command: cmd.Command) -> None:
        """Journal the decision (the same records as ``gcs simulate``), then carry it out."""
        if isinstance(command, cmd.SolveRequest):
            self.journal_file.write_record(command_to_record(command))
            self.solver.submit(command)
            return
        advisory = self.config.advisory or None
        extra = (self.feed.notes.fields(command.kind, command.target)
                 if isinstance(command, cmd.Note) else {})  # track_deleted: was it confirmed
        self._journal_command(command, advisory=advisory if isinstance(command, cmd.FlyToTarget)
                              else None, **extra)
        if isinstance(command, cmd.Note) and command.vehicle is not None and (
            command.kind in ("vehicle_recovered", "vehicle_down")
        ):
            self._watch_landing(command)
        if isinstance(command, cmd.CancelSolve):
            self.solver.cancel(command.request_id)
        elif isinstance(command, cmd.PlanAdopted):
            result = command.result
            self.metrics.plan(result.solve_time_s, result.mu, result.f1, result.f2)
            self.last_plan = {
                "t": round(command.t_s, 3),
                "routes": dict(result.routes),
                "status": result.status,
                "solve_time_s": result.solve_time_s,
            }
        elif isinstance(command, cmd.FlyToTarget):
            session = self.by_name.get(command.vehicle)
            if session is not None and not self.config.advisory:
                session.command_fly(command)
                self.metrics.fly(command.t_s, command.vehicle, command.target, command.x_m,
                                 command.y_m, command.eta_s,
                                 self.core.config.observer.fov_radius_m)
        elif isinstance(command, cmd.ReleaseVehicle | cmd.SendHome):
            self.metrics.abandoned(command.vehicle)
            session = self.by_name.get(command.vehicle)
            if session is not None:
                session.release(command.reason, home=isinstance(command, cmd.SendHome))
        elif isinstance(command, cmd.SetHome):  # to any vehicle in the air (the controller)
            session = self.by_name.get(command.vehicle)
            if session is not None:
                session.set_home(command.x_m, command.y_m)
        elif isinstance(command, cmd.LaunchVehicle):
            self.watch_metrics.launches += 1
            session = self.by_name.get(command.vehicle)
            if session is not None:
                session.want_launch(command.reason, command.relieves)

    def _watch_landing(self, note: cmd.Note) -> None:
        """A watch's landing, in figures: a recovery's charge and where the return ended
        (against the scenario's true ship where there is one, else the ship's track), or
        a vehicle down."""
        watch, vehicle = self.core.watch, note.vehicle
        record = self.core.vehicles.get(vehicle or "")
        if watch is None or vehicle is None or record is None:
            return
        if note.kind == "vehicle_down":
            self.watch_metrics.vehicle_lost(vehicle)
            return
        ship = self.world.boat_xy_m if self.world is not None else None
        if ship is None:
            predicted = watch.ship.predict(note.t_s)
            ship = predicted.xy_m if predicted is not None else None
        session = self.by_name.get(vehicle)
        snap = session.snapshot if session is not None else None
        where = ((snap.x_m, snap.y_m) if snap is not None and snap.x_m is not None
                 and snap.y_m is not None else (record.x_m, record.y_m))
        energy = watch.energy.get(vehicle)
        self.watch_metrics.landing(
            energy.remaining_pct(note.t_s) if energy is not None else float("nan"),
            None if ship is None else math.dist(ship, where))

    def _journal_command(self, command: cmd.Command, **extra: object) -> None:
        record = command_to_record(command)
        event = record.pop("event")
        record.pop("t")
        self.journal(event, logged=False, **record, **extra)

    def _on_solved(self, request: cmd.SolveRequest, result: PlanResult) -> None:
        """A solver's answer, for the core unless a newer request overtook it (the core's
        rule, applied before the answer is journalled as an input)."""
        if not self.core.wants_answer(request.request_id):
            return
        self.core_event(ev.PlanSolved(self.clock.now_s(), request.request_id, result))

    def _on_solve_error(self, request: cmd.SolveRequest, error: str) -> None:
        self.journal("plan_failed", request=request.request_id, error=error)

    # ------------------------------------------------------------------ frames
    def _on_vehicle_frame(self, rx: Received) -> None:
        msg = rx.message
        sysid = rx.system_id
        if sysid == self.config.links.gcs_system_id or self._state.finished:
            return  # floe's own id; or the run is over (its stop line written)
        session = self.sessions.get(sysid)
        if session is None:
            if (
                msg.get_type() == "GLOBAL_POSITION_INT"
                and self.origin_or_none is None
                and (msg.lat != 0 or msg.lon != 0)
            ):
                self.origin_or_none = GeoOrigin(msg.lat / 1e7, msg.lon / 1e7)
                self.journal(
                    "origin", lat_deg=msg.lat / 1e7, lon_deg=msg.lon / 1e7, source=f"system {sysid}"
                )
            self.drops.unknown_frames += 1
            if not is_autopilot_heartbeat(msg) or self.stopping:
                return
            signature = (int(msg.type), int(msg.autopilot))
            place = (rx.link_id, rx.peer)
            confirmed = self.newcomers.heartbeat(
                sysid, place, signature, int(msg.get_seq()), self.clock.now_s(), rx.link_id
            )
            if not confirmed or self.origin_or_none is None:
                return
            self.newcomers.forget(sysid)
            session = self._new_session(sysid, rx.component_id)
        try:
            session.on_message(msg)
        except Exception as exc:  # a bug in the controller: the one bug path, a clean stop
            self.supervisor.bug(f"vehicle {session.id} controller", exc)

    def _new_session(self, sysid: int, component_id: int = 1) -> VehicleSession:
        settings = self.config.settings_for(sysid)
        name = settings.name or str(sysid)
        port = VehiclePort(
            sysid,
            self.router.send_to,
            self.encoder,
            self.clock,
            timeout_s=self.config.links.transfer_timeout_s,
            retries=self.config.links.transfer_retries,
            budget=functools.partial(self.budgets.for_system, sysid),
        )
        index = sysid - 1 if self.config.sim_count else len(self.sessions)
        session = VehicleSession(
            sysid, name, index, self, self.config, settings, port, self.clock, component_id,
            planned_speed_m_s=self.core_config.speed_m_s, watch=self.core_config.watch,
        )
        self.sessions[sysid] = session
        self.by_name[name] = session
        self.journal("vehicle_seen", vehicle=name, system_id=sysid, altitude_m=session.alt_m)
        if self.tasks.group is not None:
            self.tasks.spawn(f"vehicle {name}", session.run, lambda: self._gave_up(session))
        return session

    def _on_out_frame(self, rx: Received) -> None:
        """Another ground station's traffic (through --out): its mission upload to a vehicle
        floe commands is an operator override."""
        msg = rx.message
        if rx.system_id == self.config.links.gcs_system_id:
            return
        if msg.get_type() in MISSION_MESSAGES_FROM_GCS:
            if getattr(msg, "mission_type", 0) != M.MAV_MISSION_TYPE_MISSION:
                return
            session = self.sessions.get(int(getattr(msg, "target_system", 0)))
            if session is not None and session.state is VehicleState.ACTIVE:
                session.override(
                    self.clock.now_s(), f"mission {msg.get_type()} from GCS system {rx.system_id}"
                )

    # ------------------------------------------------------------------ tasks
    def _gave_up(self, session: VehicleSession) -> None:
        """A vehicle's task failed past its restart limit: it leaves the plan (its targets go
        to the others) and floe stops commanding it."""
        if session.state is VehicleState.ACTIVE:
            self.core_event(ev.VehicleLost(self.clock.now_s(), session.id))
        session.stopping = True

    def _on_bug(self, task: str, exc: BaseException) -> None:
        """A bug (in a task, the core or a vehicle's controller): stop the daemon cleanly;
        nothing more is commanded, so the vehicles keep their missions."""
        if self._state.internal_error is None:
            self._state.internal_error = (
                f"internal error in task {task}: {type(exc).__name__}: {exc}")
        self.request_stop("internal error")

    def request_stop(self, reason: str) -> None:
        if not self._state.stop.is_set():
            self._state.stop_reason = reason
            self._state.stop.set()

    async def run(self, services: Sequence[Service] = ()) -> None:
        """Run until stopped (signal, ``--duration``, :meth:`request_stop`).

        Every task runs in the one root task group, supervised: the links first (their own
        tasks in a child group; a link that cannot start, e.g. a port in use, ends the run
        with its LinkError), then the daemon's own services (ticker, heartbeat, solver),
        the ``services`` given (built by the composition root) and the vehicle sessions.
        Stopping cancels them all."""
        start_error: BaseException | None = None
        try:
            async with asyncio.TaskGroup() as tg:
                self.tasks.group = tg
                ready: asyncio.Future[None] = asyncio.get_running_loop().create_future()
                self.tasks.spawn("links", functools.partial(self.router.serve, ready))
                try:
                    await ready
                except Exception as exc:
                    start_error = exc
                    self._cancel_tasks()
                else:
                    await self._run_tasks(services)
        finally:
            self.tasks.group = None
            self.solver.close()
            await self.router.stop()
        if start_error is not None:
            raise start_error

    async def _run_tasks(self, services: Sequence[Service]) -> None:
        self.tasks.start([
            FnService("ticker", self._tick_loop),
            FnService("heartbeat", self._heartbeat_loop),
            FnService("solver", self.solver.run),
            FnService("loop-monitor", self.loop_monitor.run),
            *services,
        ])
        for session in self.sessions.values():
            gave_up = functools.partial(self._gave_up, session)
            self.tasks.spawn(f"vehicle {session.id}", session.run, gave_up)
        await self._state.stop.wait()
        await self._shutdown()
        self._cancel_tasks()

    def _cancel_tasks(self) -> None:
        self._state.finished = True
        self.router.begin_close()  # peers closing from now on (embedded vehicles) are no loss
        self.tasks.cancel()

    async def _shutdown(self) -> None:
        """Never mid-upload: stop taking commands, wait for running exchanges, then act."""
        self.stopping = True
        for session in self.sessions.values():
            session.stopping = True
        deadline = time.monotonic() + max(2.0, min(20.0, self.clock.wall_s(30.0)))
        while any(s.port.busy for s in self.sessions.values()) and time.monotonic() < deadline:
            await asyncio.sleep(0.01)
        for session in self.sessions.values():
            if session.port.busy:
                self.journal("stop_wait_timeout", vehicle=session.id)
            if (
                self._state.internal_error is None
                and self.config.on_exit == OnExit.RTL
                and session.state is VehicleState.ACTIVE
                and not self.config.advisory
                and session.link is not LinkState.LOST
                and session.controller.may_command()  # the guard: never a disarmed one
            ):
                for _ in range(3):
                    session.port.fire_mode(ArduPlaneMode.RTL)
                self.journal("rtl", vehicle=session.id, ok=None, reason="on exit")
        for line in self.newcomers.flush():
            self.journal("unknown_systems", **line)
        # the stop line is the journal's last: from here no vehicle frame is acted on or
        # journalled (the router still records it in the tlog). Frames already read in the
        # same wake could otherwise add a loiter_end after it before the tasks are cancelled
        self._state.finished = True
        self.journal("stop", logged=False, reason=self._state.stop_reason, **self.summary())

    # ------------------------------------------------------------------ loops
    async def _heartbeat_loop(self) -> None:
        msg = M.MAVLink_heartbeat_message(
            M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, M.MAV_STATE_ACTIVE, 3
        )
        due_s = self.clock.now_s()
        while not self._state.finished:
            frame = self.encoder.encode(msg)
            self.router.broadcast(frame)
            if self.signing is not None:  # vehicles with their own key: one by one
                for sysid in self.signing.keyed_only():
                    if self.router.link_for(sysid) is not None:
                        self.router.send_to(sysid, frame)
            # 1 Hz of *mission* time: the clock may run slower than the speed-up (a loaded
            # host slows the simulator, which the mission clock follows)
            now_s = self.clock.now_s()
            due_s += HEARTBEAT_PERIOD_S
            if due_s <= now_s:  # late by a whole period: the next one a period from now
                due_s = now_s + HEARTBEAT_PERIOD_S
            while not self._state.finished and now_s < due_s:
                await asyncio.sleep(max(MIN_WAKE_WALL_S, self.clock.wall_s(due_s - now_s)))
                now_s = self.clock.now_s()

    async def _tick_loop(self) -> None:
        while not self.stopping:
            now = self.clock.now_s()
            self.tick(now)
            duration_s = self.config.mission.duration_s
            if duration_s is not None and now >= duration_s:
                self.request_stop("duration")
                return
            self._due.kick.clear()
            wake_s = max(MIN_WAKE_WALL_S, self.clock.wall_s(self.core.config.tick_s))
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(wake_s):
                    await self._due.kick.wait()

    def tick(self, now: float) -> None:
        """Everything due by ``now`` (mission s): world, ticks, metrics, housekeeping."""
        due = self._due
        tick_s = self.core.config.tick_s
        # first, and every line of the report stamped ``now``: one report is one time, and
        # reports are SIGNING_REPORT_S apart. Stamped as written they were not: a plan can
        # take 0.4 mission s at 10x, and a starved process can stop between two lines of
        # one report (4.8 s apart for a 5 s period, beside two busy loops)
        if self.signing is not None and now >= due.signing_report_s:
            due.signing_report_s = now + SIGNING_REPORT_S
            for entry in self.signing.take_report():
                self._tell(self.journal_file.write_at(now, "signing_rejected", entry),
                           logged=False)
        if due.tick_s < now - MAX_TICKS_PER_WAKE * tick_s:
            due.tick_s = now - MAX_TICKS_PER_WAKE * tick_s
        while due.tick_s <= now + 1e-9:
            t = due.tick_s
            on_second = t >= due.sample_s - 1e-9
            if self.world is not None:
                for event in self.world.step_to(t):
                    self.feed.scenario_event(event)
                self._scenario_boat(on_second)
            self.core_event(ev.Tick(t))
            if on_second:
                self.feed.sample(t)
                self.watch_metrics.sample(self.core.watch_view())
                due.sample_s += 1.0
            due.tick_s = round(due.tick_s + tick_s, 6)
        for session in self.sessions.values():
            session.check_link(now)
        if now >= due.link_report_s:
            due.link_report_s = now + LINK_REPORT_PERIOD_S
            self.report_links()
        for line in self.newcomers.reports(now):  # one line per burst of unknown systems
            self.journal("unknown_systems", **line)
        if now >= due.track_s:
            due.track_s = now + self.config.mission.track_period_s
            self.feed.journal_tracks()

    def report_links(self) -> None:
        """Journal ``link_drops`` where a link's receive trouble grew (see LinkReporter)."""
        for line in self._due.link_reporter.changes(self.router.links):
            self.journal("link_drops", **line)

    def _scenario_boat(self, on_second: bool) -> None:
        """The scenario's boat at this tick. The operating area follows it every tick; the
        core hears it (``BoatPosition``, journalled) every tick only where its priorities
        read it (``priority_gain`` > 0), else once a mission second, with its velocity on
        a watch: as ``gcs simulate`` feeds it. (Every tick cost a ship-filter update and a
        journal line each 0.1 mission s: a tenth of a paper-boat run's CPU.)"""
        assert self.world is not None
        boat = self.world.boat_xy_m
        if boat is None or self.config.ship.url is not None:
            return
        self.area.boat_xy_m = boat
        watch = self.core_config.watch is not None
        if on_second or (not watch and self.core_config.priority_gain > 0):
            self.set_boat(*boat, self.world.boat_velocity_m_s if watch else None)

    def set_boat(self, x_m: float, y_m: float,
                 velocity_m_s: tuple[float, float] | None = None) -> None:
        """Where the boat is (scenario truth or the detection feed), for the core; ignored
        when ``--ship`` gives the ship's NMEA feed, which wins (``ship_fix``)."""
        if self.config.ship.url is not None:
            return
        self.area.boat_xy_m = (x_m, y_m)
        vx, vy = velocity_m_s if velocity_m_s is not None else (None, None)
        # stamped as core.set_boat stamps it
        self.core_event(ev.BoatPosition(self.core.t_s, x_m, y_m, vx, vy, source="scenario"
                                        if velocity_m_s is not None else ""))

    def ship_fix(self, event: ev.BoatPosition) -> None:
        """A fix of the ship's NMEA feed (``daemon/ship_feed.py``), for the core."""
        self.area.boat_xy_m = (event.x_m, event.y_m)
        self.core_event(event)

    def no_origin(self) -> None:
        """A feed line dropped: no mission origin yet (FeedHost)."""
        self.drops.detections_no_origin += 1

    def add_detection(self, event: ev.Detection) -> None:
        """A camera measurement (virtual camera or detection feed) for the core."""
        if not self.feed.detection(event):
            self.drops.detections_dropped += 1

    # ------------------------------------------------------------------ reports
    def summary(self) -> dict[str, object]:
        """The run in figures (printed at the end, in ``metrics.json`` and the stop line)."""
        return run_summary(self, time.perf_counter() - self._state.wall_start,
                           time.process_time() - self._state.cpu_start)

    def metrics_dict(self) -> dict[str, object]:
        wall = time.perf_counter() - self._state.wall_start
        out = self.metrics.to_dict(wall)
        if self.core.watch is not None:
            out.update(self.watch_metrics.to_dict(self.metrics.series))
        out.update(self.loop_monitor.to_dict())
        out["links"] = self.link_figures()
        out["summary"] = self.summary()
        return out

    def link_figures(self) -> list[dict[str, object]]:
        """Each vehicle link's figures (``core/link_metrics.py``), by vehicle; a link's rate
        is its budget's configured one (``--link-rate``, a serial link's baud)."""
        model = self.link_model() if self.link_model is not None else {}
        uses = []
        for system_id, session in sorted(self.sessions.items()):
            link = self.router.link_for(system_id)
            budget = self.budgets.for_system(system_id)
            uploads = session.controller.link_uploads
            modelled = model.get(system_id, {}).get("air_pct")
            uses.append(LinkUse(
                vehicle=session.id,
                link=None if link is None else link.spec.canonical,
                uploads_ok=sum(ok for ok, _ in uploads),
                uploads_failed=sum(not ok for ok, _ in uploads),
                upload_latencies_s=[took for _, took in uploads if took is not None],
                telemetry_ages_s=session.controller.telemetry_ages_s,
                bytes_in=0 if link is None else link.counters.bytes_in,
                bytes_out=0 if link is None else link.counters.bytes_out,
                rate_bps=None if budget is None else budget.configured_bps,
                model_airtime_pct=None if modelled is None else float(modelled),
            ))  # fmt: skip
        return link_entries(uses, self.clock.now_s())
