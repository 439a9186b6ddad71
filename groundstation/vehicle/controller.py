"""One vehicle's policy, sans-IO: inputs (:mod:`.io`) in, outputs out.

States (:class:`VehicleState`, spelt as in the journal and the status table):
``connecting`` (not assessed yet), ``on_ground`` (not flying; launched only when asked),
``launching``, ``joining`` (being parked), ``manual`` (flying in a mode floe does not
take: waits for AUTO/GUIDED), ``active`` (in the plan, commanded), ``overridden`` (someone
else has it), ``home`` (sent home). The link (``ok``/``degraded``/``lost``) is apart.

Rules (each decision needs evidence over several frames, :mod:`.evidence`):

* Join / rejoin / resume only a *flying* vehicle: armed, above ``flying_alt_m``, faster
  than ``flying_speed_m_s``, not landed (EXTENDED_SYS_STATE), sustained. Flying in GUIDED
  (or advisory) joins at once; in AUTO it is parked first (:func:`~.jobs.park_job`); on the
  ground it is launched only when asked. Before it is first assessed, its cruise airspeed
  is read (:func:`~.jobs.cruise_job`; advisory: the configured one): the speed the core
  plans it with.
* An active vehicle leaves the plan when it is on the ground (``landed``), when it makes no
  progress to its aim point for ``progress_timeout_s`` (``no_progress``: core VehicleLost,
  re-assessed after that long again), on a confirmed reboot, a lost link, a sustained mode
  change out of AUTO/GUIDED that is not floe's (after ``override_grace_s``: the autopilot's
  battery failsafe or mission end, else an override), or a confirmed low battery.
* After a link restore nothing is commanded until the vehicle was watched for
  ``restore_settle_s`` (a reboot during the silence shows then).
* Guard: no set-mode or upload goes to a vehicle that is not armed, unless it is being
  launched at the operator's request.
* One exchange at a time; a newer FlyToTarget overtakes a pending one; the mission owed when
  the link went is sent again when it is back.
"""

from __future__ import annotations

import math
from typing import Any

from domain.modes import TAKEN_MODES, ArduPlaneMode
from groundstation.core import events as ev
from groundstation.mavlink.telemetry_events import (
    Armed,
    Disarmed,
    MissionItemReached,
    ModeChanged,
    PrearmChanged,
    Rebooted,
    StatusText,
    TelemetryEvent,
    WindReported,
)
from groundstation.vehicle import controller_io
from groundstation.vehicle.jobs import (
    Job,
    cruise_job,
    home_job,
    launch_job,
    park_job,
    target_job,
)
from groundstation.vehicle.state import (
    ASSESSED,
    IN_HAND,
    LAUNCHED_MARGIN_M,
    ControllerState,
    FlyRecord,
    VehicleState,
)

__all__ = ["FlyRecord", "VehicleController", "VehicleState"]

S = VehicleState


class VehicleController(ControllerState):
    """See the module docstring. ``handle(input) -> outputs``; never raises on telemetry."""

    # ------------------------------------------------------------------ the entry point
    def handle(self, inp: controller_io.Input) -> list[controller_io.Output]:
        if isinstance(inp, controller_io.ForeignFrame):  # changes nothing: no work per frame
            self.foreign_frames += 1
            return []
        self.t_s = max(self.t_s, inp.t_s)
        if isinstance(inp, controller_io.Frame):
            self._on_frame(inp)
        elif isinstance(inp, controller_io.Tick):
            self._on_tick(inp.t_s)
        elif isinstance(inp, controller_io.ExchangeDone):
            self._on_done(inp)
        elif isinstance(inp, controller_io.Fly):
            self._pending_fly = self._wanted = inp
        elif isinstance(inp, controller_io.Release):
            self._release(inp.reason, inp.home)
        elif isinstance(inp, controller_io.Stop):
            self.stopping = True
        self._advance()
        out, self._out = self._out, []
        return out

    def take_outputs(self) -> list[controller_io.Output]:
        """Outputs of direct calls (:meth:`resume`, :meth:`override`, :meth:`launch`)."""
        self._advance()
        out, self._out = self._out, []
        return out

    # ------------------------------------------------------------------ telemetry
    def _on_frame(self, frame: controller_io.Frame) -> None:
        self.snap = s = frame.snapshot
        t = frame.t_s
        if self.link == "lost":
            self.link = "ok"
            self.journal("link_restored")
            self._restore = [t, 0.0]
        for event in frame.events:
            self._on_event(event)
        kind = frame.kind
        if kind == "SYS_STATUS" and s.sensors is not None:
            self._airspeed(self.airspeed.sys_status(*s.sensors, t))
        grounded = False
        if kind in ("HEARTBEAT", "GLOBAL_POSITION_INT", "EXTENDED_SYS_STATE"):
            grounded = self.watch.flight(s, t)
            self._track_flight(grounded)
        if grounded and self.state is S.ACTIVE:
            self._leave("landed", t, S.ON_GROUND, alt_m=s.alt_m, armed=s.armed)
        if kind == "HEARTBEAT":
            self._on_heartbeat(t)
        elif kind in ("SYS_STATUS", "BATTERY_STATUS"):
            self.watch.battery.reading(s.battery_remaining_pct, t)
            if self.watch.battery.confirmed(t):
                self._battery_low(t)
        elif kind == "MISSION_CURRENT" and s.mission_current_seq is not None:
            self.watch.mission_current(s.mission_current_seq, s.mission_state)
            loiter = self._loiter
            if loiter is not None and loiter.observe_current(s.mission_current_seq, t):
                self._loiter_ended(t, loiter)
        elif kind == "GLOBAL_POSITION_INT" and self.state is S.ACTIVE and self._restore is None:
            self._core_pose()
            fly = self.fly
            if fly is not None and fly.verified_t_s is not None:
                near_m = self.loiter_radius_m() + self.s.progress_margin_m
                self.watch.position(s, (fly.x_m, fly.y_m), near_m, t)
        up = s.alt_m is not None and s.alt_m >= self.alt_m - LAUNCHED_MARGIN_M
        if self.state is S.LAUNCHING and self._launch_deadline_s is not None and up:
            self._launch_deadline_s = None
            self.joined("launched")

    def _track_flight(self, grounded: bool) -> None:
        """Whether it has flown, and how it came down after it did (before the state
        changes on this frame: the state says whose it was when it came down)."""
        if self.watch.flying.confirmed:
            self.has_flown = True
            self.came_down = None
            self._operator_launch = False
        elif grounded and self.has_flown and self.came_down is None:
            mode = self.snap.mode_name or "?"
            self.came_down = {
                S.ACTIVE: f"came down in {mode} while floe flew it",
                S.JOINING: f"came down in {mode} while floe was taking it",
                S.LAUNCHING: f"came down in {mode} while floe launched it",
                S.OVERRIDDEN: f"came down in {mode} while the operator had it",
                S.MANUAL: f"came down in {mode}, not floe's",
                S.HOME: f"came down in {mode} after floe sent it home",
            }.get(self.state, f"came down in {mode}")

    def _on_event(self, event: TelemetryEvent) -> None:
        t = event.t_s
        if isinstance(event, ModeChanged):
            expected = self._expected.pop(event.new, None)
            ours = expected is not None and expected >= t
            cause = "floe" if ours else ("initial" if event.old is None else "vehicle")
            self.journal("mode", old=event.old_name, mode=event.new_name, cause=cause)
            self._own_mode = event.new if ours else None
        elif isinstance(event, MissionItemReached):
            self.watch.item_reached(event.seq, t)
            loiter = self._loiter
            if loiter is not None and loiter.observe_reached(event.seq, t):
                self._loiter_ended(t, loiter)
        elif isinstance(event, StatusText):
            self.watch.texts.append((t, event.text))
            self.journal("statustext", severity=event.severity, text=event.text)
            self._airspeed(self.airspeed.text(event.text, t))
        elif isinstance(event, Rebooted):
            self._on_reboot(event)
        elif isinstance(event, Armed | Disarmed):
            self.journal("armed", armed=isinstance(event, Armed))
        elif isinstance(event, PrearmChanged):
            self._retry_at_s = min(self._retry_at_s, t)
        elif isinstance(event, WindReported):
            self._on_wind(event)

    def _on_heartbeat(self, t: float) -> None:
        s = self.snap
        if self._restore is not None:
            self._restore[1] += 1
            since, beats = self._restore
            if (
                t - since >= self.s.restore_settle_s
                and beats >= self.s.evidence_frames
                and not s.reboot_suspected
            ):
                self._restored(t)
        mode = s.mode
        ours = mode is not None and self._own_mode == mode
        given_back = self.watch.heartbeat(s, t, ours, self.state in IN_HAND)
        self._resolve_mode_change(t)
        if mode is not None and mode not in TAKEN_MODES:
            self._left_taken = True
        # taken back: switched (back) to AUTO after the override, and kept there
        auto = mode == ArduPlaneMode.AUTO
        if given_back and self.state is S.OVERRIDDEN and auto and self._left_taken:
            self.resume(t, "mode AUTO")
        if mode in TAKEN_MODES and self.state in (S.MANUAL, S.CONNECTING):
            self._retry_at_s = min(self._retry_at_s, t)

    def _resolve_mode_change(self, t: float) -> None:
        """A mode change out of AUTO/GUIDED that lasted ``override_grace_s``
        (:meth:`Watch.mode_change` says whose it was)."""
        change = self.watch.mode_change(self.snap, t, self.state is S.ACTIVE)
        if change is None or self.state not in IN_HAND:
            return
        if change.kind == "battery":
            self.journal(
                "autopilot_mode", mode=change.name, reason=change.reason, evidence=change.evidence
            )
            self._own_mode = change.mode  # accounted for (the core sends it home)
            self._battery_low(t)
        elif change.kind == "mission_end":
            # our missions end in an unlimited loiter: one that ran off its end (a mission
            # cut short by a failed upload) is taken back with a fresh one (the core replans
            # it as idle)
            self.journal(
                "autopilot_mode", mode=change.name, reason=change.reason, evidence=change.evidence
            )
            # the autopilot's RTL is accounted for until floe's fresh mission changes the mode
            # (a pilot's switch to another mode is still theirs)
            self._own_mode = change.mode
            self._core(ev.VehicleRebooted(t, self.vehicle))
        else:
            self.override(t, change.reason, change.name)

    def _on_reboot(self, event: Rebooted) -> None:
        self.journal(
            "reboot", previous_time_boot_ms=event.previous_time_boot_ms,
            time_boot_ms=event.time_boot_ms,
        )  # fmt: skip
        self._out.append(controller_io.NotifyRebooted())
        self._airspeed_rebooted()
        self._abort_job()
        self._loiter = None
        self.wp_loiter_rad_m = None
        self._rates_at_s = -math.inf
        self.watch.reset_clock()
        if self.state in IN_HAND:
            self._core(ev.VehicleLost(event.t_s, self.vehicle))
        if self.state not in (S.OVERRIDDEN, S.HOME):
            self.state = S.CONNECTING
            self._retry_at_s = event.t_s

    # ------------------------------------------------------------------ time
    def _on_tick(self, t: float) -> None:
        last = self.snap.last_heard_s
        if last is None:
            return
        self._check_clock(t)
        silent_s = t - last
        if silent_s > self.s.lost_after_s:
            if self.link != "lost":
                self.link = "lost"
                self.journal("link_lost", silent_s=round(silent_s, 2))
                self._pending_fly = None
                self._restore = None
                self._abort_job(cancel=True)
                if self.state is S.ACTIVE:
                    self._core(ev.VehicleLost(t, self.vehicle))
                elif self.state in (S.JOINING, S.LAUNCHING):
                    self.state = S.CONNECTING
        else:
            self.link = "degraded" if silent_s > min(2.5, self.s.lost_after_s / 2.0) else "ok"
        self._resolve_mode_change(t)
        progress = self.watch.stalled(t)
        if (
            self.state is S.ACTIVE
            and progress is not None
            and self._restore is None
            and self.link != "lost"
        ):
            self._leave(
                "no_progress", t, S.CONNECTING, target=self.fly.target if self.fly else None,
                distance_m=round(progress[0], 1), since_s=round(progress[1], 2), logged=True,
            )  # fmt: skip
            self._hold_until_s = t + self.s.progress_timeout_s
            self._out.append(
                controller_io.Warn(
                    f"vehicle {self.vehicle}: no progress towards its aim point for "
                    f"{self.s.progress_timeout_s:g} s: taken out of the plan"
                )
            )
        if (
            self.state is S.LAUNCHING
            and self._launch_deadline_s is not None
            and t >= self._launch_deadline_s
        ):
            self._launch_deadline_s = None
            self.journal("launch_timeout", altitude_m=self.snap.alt_m)
            self.state = S.CONNECTING

    def _check_clock(self, t: float) -> None:
        checked = self.watch.clock(self.snap, t)
        if checked is None:
            return
        ratio, ok = checked
        self.journal("clock_check", vehicle_s_per_mission_s=round(ratio, 3), ok=ok,
                     logged=not ok)  # a failed check: the controller_io.Warn below tells it
        if not ok:
            self._out.append(
                controller_io.Warn(
                    f"vehicle {self.vehicle}: its clock runs {ratio:.2f} x the mission clock: "
                    "is --speedup right?"
                )
            )

    # ------------------------------------------------------------------ decisions
    def _leave(self, event: str, t: float, state: VehicleState, **fields: Any) -> None:
        """Take an active vehicle out of the plan (the core hands its targets to others)."""
        self.journal(event, **fields)
        self._core(ev.VehicleLost(t, self.vehicle))
        self.state = state
        self._pending_fly = self._wanted = None
        self._loiter = None
        self.watch.reset_progress()
        self._abort_job(cancel=True)

    def _restored(self, t: float) -> None:
        """The vehicle was watched long enough after a link restore: carry on, or not."""
        self._restore = None
        if self.state is not S.ACTIVE:
            return
        if not self.flying():
            self._leave("landed", t, S.ON_GROUND, alt_m=self.snap.alt_m, armed=self.snap.armed)
            return
        if self._wanted is not None and self._pending_fly is None:
            self._pending_fly = self._wanted  # owed: the core will not send it again
        self.watch.reset_progress()
        self._core_pose()
        self._core(ev.VehicleReturned(t, self.vehicle))

    def override(self, t: float, reason: str, mode: str | None = None) -> None:
        """Someone else took the vehicle (``mode``: the mode it was switched to, when that
        is how): stop commanding it until it is given back, replan the others."""
        if self.state is S.OVERRIDDEN:
            return
        was_planned = self.state is S.ACTIVE
        self.state = S.OVERRIDDEN
        self._left_taken = self.snap.mode is not None and self.snap.mode not in TAKEN_MODES
        self._pending_fly = self._wanted = None
        self._loiter = None
        self.watch.reset_progress()
        self._abort_job(cancel=True)
        self.journal("override", reason=reason, mode=mode or self.snap.mode_name)
        if was_planned:
            self._core(ev.OperatorOverride(t, self.vehicle))

    def resume(self, t: float, reason: str) -> bool:
        """An operator gave the vehicle back: taken back only if it flies (else it is on
        the ground, and joins again once it flies)."""
        if self.state not in (S.OVERRIDDEN, S.HOME):
            return False
        if not self.flying():
            self.journal("resume_refused", reason=reason, why="not flying")
            self.state = S.ON_GROUND
            self._retry_at_s = t
            return False
        self.journal("resume", reason=reason)
        if self.state is S.HOME:
            self._battery_reported = False
            self.watch.battery.reset()
        self.state = S.ACTIVE
        # the mode it is given back in (RTL, FBWA... through the API) is floe's to change:
        # not a new operator's change. A switch to another one after this is.
        self._own_mode = self.snap.mode
        self.watch.forget_mode_change()
        self.watch.reset_progress()
        self._core_pose()
        self._core(ev.OperatorResume(t, self.vehicle))
        return True

    def _release(self, reason: str, home: bool) -> None:
        """Core said: stop commanding (ReleaseVehicle) or go home (SendHome)."""
        self._pending_fly = self._wanted = None
        self._loiter = None
        self.watch.reset_progress()
        self._abort_job()
        if home:
            self.state = S.HOME
            self._pending_home = True
        elif self.state is not S.OVERRIDDEN:
            self.state = S.OVERRIDDEN
        self.journal("released", reason=reason, home=home)

    def _launch_request(self) -> None:
        self.launch_requested = True
        self._retry_at_s = min(self._retry_at_s, self.t_s)

    def launch(self) -> tuple[bool, str]:
        """An operator asks for a launch: of a vehicle on the ground, the only way to launch
        one that came down after it flew (also one taken over or sent home that came down
        there: its state then says ``on_ground``)."""
        down = self.state in (S.OVERRIDDEN, S.HOME) and self.watch.grounded.confirmed
        if self.state not in (S.ON_GROUND, S.CONNECTING) and not down:
            return False, f"vehicle {self.vehicle} is {self.status}, not on the ground"
        if down:
            self.state = S.ON_GROUND
            self._pending_home = False
        self._operator_launch = True
        self.launch_held = None
        self.journal("launch_request", by="operator", came_down=self.came_down)
        self._launch_request()
        return True, ""

    def _hold_launch(self) -> None:
        """A launch floe would start on its own (``--launch``) of a vehicle that came down
        after it flew: never. Said once per landing; the operator's launch lifts it."""
        self.launch_requested = False
        why = self.launch_held = self.came_down or "came down after it flew"
        self.journal("launch_held", reason=why, logged=True)
        self._out.append(
            controller_io.Warn(
                f"vehicle {self.vehicle}: {why}; floe will not launch it again on its own "
                f"('gcs vehicle launch {self.vehicle}' launches it)"
            )
        )

    def _assess(self) -> None:
        s = self.snap
        if s.mode is None or s.armed is None or s.reboot_suspected:
            return
        if self.flying():
            if s.mode not in TAKEN_MODES:
                if self.state is not S.MANUAL:
                    self.state = S.MANUAL
                    self.journal(
                        "waiting", reason=f"flying in {s.mode_name}: waiting for AUTO or GUIDED"
                    )
                return
            if s.x_m is None:
                return
            if s.mode == ArduPlaneMode.GUIDED or self.s.advisory:
                self.joined("guided" if s.mode == ArduPlaneMode.GUIDED else "advisory")
                return
            self.state = S.JOINING
            self._start(park_job(self))
            return
        if self.watch.flying.holding:
            return  # may be flying: wait for the evidence either way
        if self.state is not S.ON_GROUND:
            self.state = S.ON_GROUND
            self.journal("on_ground", prearm_ok=s.prearm_ok)
        if self.launch_requested and self.has_flown and not self._operator_launch:
            self._hold_launch()
            return
        if self.launch_requested and s.prearm_ok and not self.s.advisory:
            self.state = S.LAUNCHING
            # the mode it waited in on the ground (MANUAL...) is floe's own while launching,
            # not an operator's change: the launch exchanges may outlast the override grace
            # (several mission s at 200x). Any mode change floe did not ask for ends that
            # (_on_event); so does the launch once AUTO is accepted (launched()).
            self._own_mode = s.mode
            self.journal("launch", altitude_m=self.alt_m)
            self._start(launch_job(self, s.heading_rad or 0.0))

    # ------------------------------------------------------------------ jobs
    def _advance(self) -> None:
        """Start or step the job, one exchange at a time."""
        for _ in range(8):  # a job that finishes may let another start
            if self._jobs.running is not None or self.stopping:
                return
            if self._jobs.job is not None:
                if not self._jobs.ready(self.t_s):
                    return
                self._send(self._jobs.step())
                continue
            if not self._pick():
                return

    def _pick(self) -> bool:
        t = self.t_s
        if self.link == "lost" or self.snap.last_heartbeat_s is None or self._restore is not None:
            return False
        if not self.s.advisory and t - self._rates_at_s >= self.s.rates_every_s:
            self._rates_at_s = t
            self._out.append(controller_io.RequestRates(self.s.telemetry_rate_hz))
        if self.cruise_source is None and self.state in ASSESSED:
            if self.s.advisory:  # sends nothing but heartbeats: the configured speed
                self.cruise_known(None, "config")
            else:
                self._start(cruise_job(self))  # before it can join (docs/daemon.md)
                return True
        if self.state in ASSESSED and t >= max(self._retry_at_s, self._hold_until_s):
            self._assess()
            if self._jobs.job is not None:
                return True
        if self._pending_home and not self.s.advisory:
            self._pending_home = False
            self._start(home_job(self))
            return True
        fly = self._pending_fly
        if fly is not None and self.commanded:
            self._pending_fly = None
            self.fly = FlyRecord(fly.command.target, fly.x_m, fly.y_m, fly.command.route)
            self._start(target_job(self, fly))
            return True
        if fly is not None and self.s.advisory:
            self._pending_fly = None
        return False

    def _start(self, job: Job) -> None:
        self._jobs.start(job)

    def _send(self, request: controller_io.Exchange | None) -> None:
        if request is not None:
            self._out.append(request)

    def wants(self, request: controller_io.Exchange) -> bool:
        """Whether the driver should still run (or retry) ``request``: False once its job
        was aborted (a reboot, a release, an override, the link lost, leaving the plan)."""
        return self._jobs.wants(request)

    def _on_done(self, done: controller_io.ExchangeDone) -> None:
        self._send(self._jobs.done(done.request, done.result, self.stopping))

    def _abort_job(self, cancel: bool = False) -> None:
        if self._jobs.abort() and cancel:
            self._out.append(controller_io.CancelExchange())
