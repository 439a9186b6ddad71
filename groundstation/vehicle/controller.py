"""One vehicle's policy, sans-IO: inputs (:mod:`.io`) in, outputs out.

States (:class:`VehicleState`, spelt as in the journal and the status table):
``connecting`` (not assessed yet), ``on_ground`` (not flying; launched only when asked),
``launching``, ``joining`` (being parked), ``manual`` (flying in a mode floe does not
take: waits for AUTO/GUIDED), ``active`` (in the plan, commanded), ``overridden`` (someone
else has it), ``home`` (sent home). The link (:class:`LinkState`: ``ok``, ``degraded``,
``lost``) is apart.

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
* The ship watch (docs/ship.md): the battery goes to the core as ``BatteryReport``
  (at most every ``battery_report_s``, at once on a ``battery_report_pct`` move); a vehicle
  standing disarmed on the ground is ``VehicleOnDeck`` (when its readiness changes); one
  that flew and came down is ``VehicleLanded`` once (the evidence that sets ``came_down``).
  The core's SetHome is one verified DO_SET_HOME (:func:`~.jobs.set_home_job`), to any
  vehicle in the air, also one taken over or sent home; a newer one supersedes it. The
  core's LaunchVehicle launches a spare with ``launch`` (``--launch``), else asks the
  operator; with ``launch_on_order`` nothing else is launched on floe's own.
"""

from __future__ import annotations

import math
from typing import Any

from domain.modes import TAKEN_MODES, ArduPlaneMode
from groundstation.core import events as ev
from groundstation.core.mission import target_mission
from groundstation.mavlink.airspeed_health import AirspeedChange, AirspeedHealth
from groundstation.mavlink.evidence import LoiterEndEvidence
from groundstation.mavlink.fence_items import FenceCircle
from groundstation.mavlink.telemetry_events import (
    Armed,
    Disarmed,
    MissionItemReached,
    ModeChanged,
    PrearmChanged,
    Rebooted,
    StatusText,
    TelemetryEvent,
    VehicleSnapshot,
    WindReported,
)
from groundstation.vehicle import controller_io
from groundstation.vehicle.freshness import Freshness, PredictedPose
from groundstation.vehicle.jobs import (
    Job,
    JobRunner,
    cruise_job,
    fence_job,
    home_job,
    launch_job,
    params_job,
    park_job,
    set_home_job,
    target_job,
)
from groundstation.vehicle.settings import ControllerSettings
from groundstation.vehicle.state import (
    ASSESSED,
    IN_HAND,
    LAUNCHED_MARGIN_M,
    FlyRecord,
    LinkState,
    VehicleState,
)
from groundstation.vehicle.watch import Watch

__all__ = ["FlyRecord", "LinkState", "VehicleController", "VehicleState"]

S = VehicleState



FENCE_TRIES = 3
"""Failed fence jobs for one fence before floe stops trying (until it moves or a reboot)."""
PARAMS_TRIES = 3
"""Parameter downloads tried per session before the snapshot is given up (journalled)."""
_POSE_STATES = (S.ACTIVE, S.HOME, S.OVERRIDDEN)
"""Whose position the core hears: in the plan, sent home, or taken over (the ship watch
aims the homes and returns of all three; ``core/watch.py``)."""

class VehicleController:
    """See the module docstring. ``handle(input) -> outputs``; never raises on telemetry.

    What one vehicle's controller knows, the policy on it, and the small operations its
    jobs (:mod:`.jobs`) call back (the ``JobHost`` protocol): one state machine, one class."""

    def __init__(self, vehicle: str, system_id: int, settings: ControllerSettings) -> None:
        self.vehicle = vehicle
        self.system_id = system_id
        self.s = settings
        self.state = S.CONNECTING
        self.link: LinkState = LinkState.OK
        self.launch_requested = settings.launch and not settings.launch_on_order
        """Launch it once it may be (``--launch``; with a watch's ``on_station`` only on the
        core's LaunchVehicle or the operator's request)."""
        self.has_flown = False
        """Seen flying in this session: once it comes down, floe never launches it again on
        its own initiative (only an operator's :meth:`launch` does)."""
        self.came_down: str | None = None
        """How it came down after it flew (None while it flies, or before it ever did)."""
        self.released_by_operator = False
        self._released_mode: int | None = None  # its mode when the operator released it
        """Overridden because the operator released it through floe (status ``released``)."""
        self._operator_launch = False  # an operator's launch request, until it flies
        self.launch_held: str | None = None
        """Why a launch floe would have started on its own is held (until the operator's)."""
        self.launch_wanted: controller_io.LaunchWanted | None = None
        """The core's LaunchVehicle for this vehicle, until it flies (the API shows it)."""
        self._spare_launch = False  # the core's launch of a fresh spare, until it flies
        self._fresh_boot = True  # booted since it last came down (or never flew)
        self._down_in_rtl = False  # it came down in an RTL (floe's, or a failsafe's)
        self._battery_sent: tuple[float, float | None] | None = None  # (t_s, pct) last sent
        self._deck_sent: bool | None = None  # the last VehicleOnDeck's ready (None: none)
        self._new_home: controller_io.NewHome | None = None  # the core's SetHome, to send
        self._home_req: controller_io.NewHome | None = None  # the one being sent
        self._home_job: Job | None = None
        self.home_xy_m: tuple[float, float] | None = None
        """The home the vehicle last confirmed after a SetHome (local ENU m)."""
        self._home_warned: str | None = None  # the failure last told (until a success)
        self.stopping = False
        self.snap = VehicleSnapshot(system_id=system_id)
        self.t_s = 0.0
        self.alt_m = settings.altitude_m
        self.retry_pause_s = settings.retry_pause_s
        self.wp_loiter_rad_m: float | None = None
        self.cruise_speed_m_s: float | None = None
        """The airspeed floe plans this vehicle with (:meth:`cruise_known`; None until read)."""
        self.cruise_source: str | None = None
        """Where it came from: ``AIRSPEED_CRUISE``, ``TRIM_ARSPD_CM`` or ``config``."""
        self.fly: FlyRecord | None = None
        self.uploads_ok = 0
        self.uploads_failed = 0
        self.upload_retries = 0
        """Retries of every upload job (transfers and set-currents), for the table."""
        self.upload_delays_s: list[float] = []
        self.link_uploads: list[tuple[bool, float | None]] = []
        """Every mission upload of the vehicle (any purpose): verified, and the mission
        seconds from its first MISSION_COUNT to the verdict of its verifying download (None:
        not timed) (the ``links`` figures)."""
        self.telemetry_ages_s: list[float] = []
        """Its newest position's age, sampled once a mission second while it had one."""
        self._age_sampled_s = -math.inf
        self.last_loiter_end_s: float | None = None
        self.foreign_frames = 0
        self._out: list[controller_io.Output] = []
        self.watch = Watch(settings)
        self._jobs = JobRunner(self.may_command_request, self._refused, self.must_wait)
        self._pending_fly: controller_io.Fly | None = None
        self._wanted: controller_io.Fly | None = None
        self._pending_home = False
        self._loiter: LoiterEndEvidence | None = None
        self._loiter_end_pending_s: float | None = None
        self._expected: dict[int, float] = {}
        # the mode floe put the vehicle in (or, while launching, the one it waited in on the
        # ground): a heartbeat in it is no operator's change. None: none is floe's.
        self._own_mode: int | None = None
        self._left_taken = False  # seen out of AUTO/GUIDED since the override
        self._battery_reported = False
        self._rates_at_s = -math.inf
        self._retry_at_s = 0.0
        self._hold_until_s = 0.0  # no re-assessment before (after no_progress)
        self._launch_deadline_s: float | None = None
        self._restore: list[float] | None = None  # [since_s, heartbeats] after a link restore
        self._wind_sent_s = -math.inf
        self._wind_since_s: float | None = None  # active and reporting since
        self.airspeed = AirspeedHealth(settings.evidence_frames, settings.evidence_span_s)
        self.fresh = Freshness(settings.lag_threshold_s, loiter_margin_m=settings.progress_margin_m)
        """Its telemetry's age against its own clock, lagging, predictions (:mod:`.freshness`)."""
        self._predicted_at_s = -math.inf  # when the core was last given a predicted pose
        self.fence_wanted: FenceCircle | None = None
        """The operating area's fence (the daemon's FenceWanted; None: no area)."""
        self.fence_held: FenceCircle | None = None
        """The fence the vehicle was last verified to hold, enabled (None: none yet)."""
        self._fence_retry_at_s = 0.0  # no new fence job before (after a failed one)
        self._fence_failures = 0  # failed jobs for the fence wanted now
        self._fence_failed: FenceCircle | None = None  # the fence those failures were for
        self.params_snapshot = False
        """Its parameters were read once (the ``.parm`` snapshot is written)."""
        self._params_tries = 0
        self._params_retry_at_s = 0.0
        self._params_job: Job | None = None

    # ------------------------------------------------------------------ reading
    @property
    def status(self) -> str:
        """The state's name; ``released`` for one the operator released through floe
        (:meth:`operator_release`: the state is ``overridden``, floe no longer commands it)."""
        if self.state is S.OVERRIDDEN and self.released_by_operator:
            return "released"
        return self.state.value

    @property
    def commanded(self) -> bool:
        return self.state is S.ACTIVE and not self.s.advisory and not self.stopping

    @property
    def busy(self) -> bool:
        return self._jobs.busy

    @property
    def telemetry_age_s(self) -> float | None:
        """How old its newest position is now, against its own clock (None: not known)."""
        return self.fresh.fix_age_s(self.snap, self.t_s)

    @property
    def lagging(self) -> bool:
        """Its frames arrive, but its newest position is older than ``lag_threshold_s``."""
        return self.fresh.lagging

    def prediction(self) -> PredictedPose | None:
        """Where it is predicted to be now, while its newest fix is too old to plan from
        (None: the fix is fresh): towards the aim point of floe's verified mission, else
        dead reckoning (:meth:`.freshness.Freshness.predict`)."""
        fly = self.fly
        aim = fly.aim_now(None) if (fly is not None and fly.verified_t_s is not None
                                    and self.state is S.ACTIVE) else None  # a route's point
        return self.fresh.predict(self.snap, self.t_s, aim, self.loiter_radius_m())

    def flying(self) -> bool:
        """Sustained evidence that it flies (see ControllerSettings)."""
        return self.watch.flying.confirmed

    def may_command(self) -> bool:
        """The guard on every set-mode and upload: armed, or being launched on request."""
        if self.state is S.LAUNCHING and self.launch_requested and not self.s.advisory:
            return True
        return self.snap.armed is True and not self.snap.reboot_suspected

    def may_command_request(self, request: controller_io.Exchange) -> bool:
        return (not isinstance(request, controller_io.SetMode | controller_io.UploadMission
                               | controller_io.UploadFence | controller_io.FenceParam)
                or self.may_command())

    def must_wait(self, request: controller_io.Exchange) -> bool:
        """A command waits while a reboot is suspected (a ``time_boot_ms`` that went back,
        not yet confirmed or cleared by the next frames): one stray frame must not cost
        the vehicle its mission, nor may a command reach a vehicle that may have
        rebooted. A confirmed reboot aborts the job; a cleared suspicion lets it go on.

        It also waits while a mode change out of AUTO/GUIDED is not yet attributed
        (``override_grace_s``): a pilot's RTL seen just before floe's next upload or its
        switch to AUTO must not be undone by them. An override aborts the job; a battery
        failsafe or a mission end of the autopilot's own lets it go on."""
        if isinstance(request, controller_io.MoveHome):  # changes no mode: no grace to wait
            return self.snap.reboot_suspected or self.link is not LinkState.OK
        commanding = (controller_io.SetMode | controller_io.UploadMission | controller_io.SetCurrent
                      | controller_io.Arm | controller_io.UploadFence | controller_io.FenceParam)
        if not isinstance(request, commanding):
            return False
        return self.snap.reboot_suspected or self.watch.mode_change_pending

    # ------------------------------------------------------------------ the entry point
    def handle(self, inp: controller_io.Input) -> list[controller_io.Output]:
        if isinstance(inp, controller_io.ForeignFrame):  # changes nothing: no work per frame
            self.foreign_frames += 1
            return []
        self.t_s = max(self.t_s, inp.t_s)
        if isinstance(inp, controller_io.AutopilotFrame):
            self._on_frame(inp)
        elif isinstance(inp, controller_io.TimePassed):
            self._on_tick(inp.t_s)
        elif isinstance(inp, controller_io.ExchangeDone):
            self._on_done(inp)
        elif isinstance(inp, controller_io.Fly):
            self._pending_fly = self._wanted = inp
        elif isinstance(inp, controller_io.Release):
            self._release(inp.reason, inp.home)
        elif isinstance(inp, controller_io.Stop):
            self.stopping = True
        elif isinstance(inp, controller_io.NewHome):
            self._on_new_home(inp)
        elif isinstance(inp, controller_io.LaunchWanted):
            self._on_launch_wanted(inp)
        elif isinstance(inp, controller_io.FenceWanted):
            if inp.fence is None or inp.fence.moved(self._fence_failed):
                self._fence_failures = 0  # another fence than the one refused: afresh
            self.fence_wanted = inp.fence
        self._advance()
        out, self._out = self._out, []
        return out

    def take_outputs(self) -> list[controller_io.Output]:
        """Outputs of direct calls (:meth:`resume`, :meth:`override`, :meth:`launch`)."""
        self._advance()
        out, self._out = self._out, []
        return out

    # ------------------------------------------------------------------ telemetry
    def _on_frame(self, frame: controller_io.AutopilotFrame) -> None:
        self.snap = s = frame.snapshot
        t = frame.t_s
        if any(isinstance(event, Rebooted) for event in frame.events):
            self.fresh.reset()  # its clock started again: this frame starts the new one
        if frame.time_boot_ms is not None:
            self.fresh.frame(frame.time_boot_ms, t)
        if self.link is LinkState.LOST:
            self.link = LinkState.OK
            self.journal("link_restored")
            self._restore = [t, 0.0]
        for event in frame.events:
            self._on_event(event)
        kind = frame.kind
        if kind == "SYS_STATUS" and s.sensors is not None:
            self._airspeed(self.airspeed.sys_status(*s.sensors, t))
        grounded = came_down = False
        if kind in ("HEARTBEAT", "GLOBAL_POSITION_INT", "EXTENDED_SYS_STATE"):
            grounded = self.watch.flight(s, t)
            came_down = self._track_flight(grounded)
        if grounded and self.state is S.ACTIVE:
            self._leave("landed", t, S.ON_GROUND, alt_m=s.alt_m, armed=s.armed)
        if came_down:
            self._landed(t)
        if kind == "HEARTBEAT":
            self._on_heartbeat(t)
        elif kind in ("SYS_STATUS", "BATTERY_STATUS"):
            self.watch.battery.reading(s.battery_remaining_pct, t)
            if self.watch.battery.confirmed(t):
                self._battery_low(t)
            self._report_battery(t)
        elif kind == "MISSION_CURRENT" and s.mission_current_seq is not None:
            self.watch.mission_current(s.mission_current_seq, s.mission_state)
            loiter = self._loiter
            if loiter is not None and loiter.observe_current(s.mission_current_seq, t):
                self._loiter_ended(t, loiter)
        elif kind == "GLOBAL_POSITION_INT" and self.state in _POSE_STATES and (
            self._restore is None
        ):  # sent home or taken over too: the watch aims homes and returns from it
            self._core_pose()
            fly = self.fly
            if fly is not None and fly.verified_t_s is not None:
                near_m = self.loiter_radius_m() + self.s.progress_margin_m
                item = fly.item
                aim = fly.aim_now(s.mission_current_seq)  # a route: the point it flies to
                if fly.item != item:  # on to the next point: progress towards it afresh
                    self.watch.reset_progress()
                self.watch.position(s, aim, near_m, t)
        up = s.alt_m is not None and s.alt_m >= self.alt_m - LAUNCHED_MARGIN_M
        if self.state is S.LAUNCHING and self._launch_deadline_s is not None and up:
            self._launch_deadline_s = None
            self.joined("launched")
        if kind in ("HEARTBEAT", "GLOBAL_POSITION_INT", "EXTENDED_SYS_STATE", "SYS_STATUS",
                    "BATTERY_STATUS"):
            self._deck(t)

    def _track_flight(self, grounded: bool) -> bool:
        """Whether it has flown, and how it came down after it did (before the state
        changes on this frame: the state says whose it was when it came down). True on
        the frame it is found down after it flew (once per landing)."""
        if self.watch.flying.confirmed:
            self.has_flown = True
            self.came_down = None
            self._operator_launch = False
            self._spare_launch = False
            self._fresh_boot = False
            self._down_in_rtl = False
            self.launch_wanted = None
            if self.s.launch_on_order:
                self.launch_requested = False  # one order, one flight
        elif grounded and self.has_flown and self.came_down is None:
            self._down_in_rtl = self.snap.mode == ArduPlaneMode.RTL or self.state is S.HOME
            mode = self.snap.mode_name or "?"
            self.came_down = {
                S.ACTIVE: f"came down in {mode} while floe flew it",
                S.JOINING: f"came down in {mode} while floe was taking it",
                S.LAUNCHING: f"came down in {mode} while floe launched it",
                S.OVERRIDDEN: f"came down in {mode} while the operator had it",
                S.MANUAL: f"came down in {mode}, not floe's",
                S.HOME: f"came down in {mode} after floe sent it home",
            }.get(self.state, f"came down in {mode}")
            return True
        return False

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
        if self.released_by_operator and mode is not None and mode != self._released_mode:
            # released, then switched by someone else: a pilot's (or the autopilot's) mode
            # change, final as for any vehicle a pilot took
            self.released_by_operator = False
            self.journal("override", reason="mode change after a release", mode=s.mode_name)
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
        # a vehicle that came down and powers up again (a battery swap on deck) is not a
        # problem; one that reboots in flight, or unexplained, is
        self.journal(
            "power_up" if self.came_down is not None and not self.flying() else "reboot",
            previous_time_boot_ms=event.previous_time_boot_ms,
            time_boot_ms=event.time_boot_ms,
        )  # fmt: skip
        self._out.append(controller_io.NotifyRebooted())
        if self.came_down is not None:
            self._fresh_boot = True  # powered up again after it came down (battery swap)
        self._airspeed_rebooted()
        self._abort_job()
        self._loiter = None
        self.wp_loiter_rad_m = None
        self.fence_held = None  # read back and enabled again once it is floe's again
        self._fence_failures = 0
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
            if self.link is not LinkState.LOST:
                self.link = LinkState.LOST
                self.journal("link_lost", silent_s=round(silent_s, 2))
                if self._deck_sent:  # a spare it cannot hear is no ready spare
                    self._core(ev.VehicleOnDeck(t, self.vehicle, False,
                                                self._battery_pct()))
                self._deck_sent = None
                self._pending_fly = None
                self._restore = None
                self._abort_job(cancel=True)
                if self.state is S.ACTIVE:
                    self._core(ev.VehicleLost(t, self.vehicle))
                elif self.state in (S.JOINING, S.LAUNCHING):
                    self.state = S.CONNECTING
        else:
            degraded = silent_s > min(2.5, self.s.lost_after_s / 2.0)
            self.link = LinkState.DEGRADED if degraded else LinkState.OK
        self._freshness(t)
        self._resolve_mode_change(t)
        progress = self.watch.stalled(t)
        if (
            self.state is S.ACTIVE
            and progress is not None
            and self._restore is None
            and self.link is not LinkState.LOST
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

    def _freshness(self, t: float) -> None:
        """Lagging starts or ends (one journal line and one console line each); while it
        lasts the core gets the predicted pose now and then, positions or not."""
        if t - self._age_sampled_s >= 1.0:
            age = self.fresh.fix_age_s(self.snap, t)
            if age is not None and self.link is not LinkState.LOST:
                self.telemetry_ages_s.append(age)
                self._age_sampled_s = t
        change = self.fresh.assess(self.snap, t, self.link is LinkState.LOST)
        if change is not None and change.lagging:
            self.journal("telemetry_lagging", age_s=round(change.age_s, 2), logged=True)
            self._out.append(controller_io.Warn(
                f"vehicle {self.vehicle}: telemetry lagging: its newest position is "
                f"{change.age_s:.1f} s old although its frames keep arriving; planned from "
                "a prediction until it is fresh"
            ))  # fmt: skip
        elif change is not None:
            self.journal("telemetry_fresh", age_s=round(change.age_s, 2),
                         lagged_s=round(change.lagged_s, 2),
                         worst_age_s=round(change.worst_age_s, 2), logged=True)
            self._out.append(controller_io.Warn(
                f"vehicle {self.vehicle}: telemetry fresh again ({change.age_s:.1f} s old) "
                f"after {change.lagged_s:.1f} s lagging (worst {change.worst_age_s:.1f} s)"
            ))  # fmt: skip
        if (self.fresh.lagging and self.state in _POSE_STATES and self._restore is None
                and self.link is not LinkState.LOST and self.fresh.stale(self.snap, t)):
            self._core_pose()  # a prediction (a fresh fix goes to the core as it comes)

    def _check_clock(self, t: float) -> None:
        if self.fresh.lagging:  # late frames would make its clock look slow: check later
            return
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

    def override(self, t: float, reason: str, mode: str | None = None, *,
                 released: bool = False) -> None:
        """Someone else took the vehicle (``mode``: the mode it was switched to, when that
        is how): stop commanding it until it is given back, replan the others.
        ``released``: the operator released it through floe (journalled ``released``)."""
        if self.state is S.OVERRIDDEN:
            return
        was_planned = self.state is S.ACTIVE
        self.state = S.OVERRIDDEN
        self.released_by_operator = released
        self._released_mode = self.snap.mode
        self._left_taken = self.snap.mode is not None and self.snap.mode not in TAKEN_MODES
        self._pending_fly = self._wanted = None
        self._loiter = None
        self.watch.reset_progress()
        self._abort_job(cancel=True)
        if released:
            self.journal("released", reason=reason, home=False, by="operator",
                         mode=self.snap.mode_name)
        else:
            self.journal("override", reason=reason, mode=mode or self.snap.mode_name)
        if was_planned:
            self._core(ev.OperatorOverride(t, self.vehicle))

    def resume(self, t: float, reason: str) -> bool:
        """An operator gave the vehicle back: taken back only if it flies (else it is on
        the ground, and joins again once it flies)."""
        if self.state not in (S.OVERRIDDEN, S.HOME):
            return False
        if not self.flying():
            # Refused only on evidence that it is down; with no sustained evidence either
            # way yet (climbing out, a gap in telemetry) it is assessed as any vehicle
            # seen anew and joins once it flies: said as such, not as a refusal.
            down = self.watch.grounded.confirmed
            self.journal("resume_refused" if down else "resume_deferred", reason=reason,
                         why="not flying" if down else "waiting for evidence that it flies")
            self.state = S.ON_GROUND
            self._retry_at_s = t
            return False
        self.released_by_operator = False
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

    def operator_resume(self, t: float, reason: str) -> tuple[bool, str]:
        """An operator's resume (API, page, CLI): :meth:`resume` with its answer, ``(ok,
        what happened)``. The same rule as AUTO: taken back only if it flies."""
        before = self.status
        if self.state is S.ACTIVE:
            return False, f"vehicle {self.vehicle} is already active (floe flies it)"
        if self.state not in (S.OVERRIDDEN, S.HOME):
            return False, f"vehicle {self.vehicle} is {before}, not overridden, released or home"
        if self.resume(t, reason):
            return True, f"vehicle {self.vehicle} resumed: floe flies it again (was {before})"
        if self.watch.grounded.confirmed:
            return False, (f"vehicle {self.vehicle} is not flying (it came down): floe does "
                           "not relaunch it; 'launch' does")
        return True, (f"vehicle {self.vehicle} resume deferred: no sustained evidence yet "
                      "that it flies; it joins once it does")

    def operator_release(self, t: float, reason: str) -> tuple[bool, str]:
        """An operator releases the vehicle: floe stops commanding it (it flies on in its
        mode and mission), journalled as ``released`` (not an override); the core hands its
        targets to the others. ``(ok, what happened)``."""
        if self.state is not S.ACTIVE:
            return False, f"vehicle {self.vehicle} is {self.status}, not active"
        self.override(t, reason, released=True)
        return True, (f"vehicle {self.vehicle} released: floe stops commanding it; it flies "
                      f"on in {self.snap.mode_name or 'its mode'}")

    def operator_rtl(self, t: float, reason: str) -> tuple[bool, str]:
        """An operator sends the vehicle home (RTL to the home it has, the ship's when floe
        moved it): floe stops planning it, as when the core sends it home. Refused for a
        vehicle a pilot took (their mode change is final) or one not flying."""
        if self.state is S.HOME:
            return True, f"vehicle {self.vehicle} is already on its way home"
        if self.state is S.OVERRIDDEN and not self.released_by_operator:
            return False, (f"vehicle {self.vehicle} is overridden: its pilot has it (their "
                           "mode change is final)")
        if self.state not in (S.ACTIVE, S.OVERRIDDEN) or not self.flying():
            return False, f"vehicle {self.vehicle} is {self.status}, not flying under floe"
        if self.s.advisory:
            return False, "advisory mode: floe commands no vehicle"
        was_planned = self.state is S.ACTIVE
        self._release(reason, home=True)
        self.released_by_operator = False
        if was_planned:  # the core frees its targets; its ReleaseVehicle finds it home
            self._core(ev.OperatorOverride(t, self.vehicle))
        return True, f"vehicle {self.vehicle} sent home (RTL); 'resume' gives it back to floe"

    def _release(self, reason: str, home: bool) -> None:
        """Core said: stop commanding (ReleaseVehicle) or go home (SendHome). A release
        of a vehicle floe already stopped commanding (taken over, released or sent home by
        the operator: the core's answer to ``OperatorOverride``) changes nothing and is not
        journalled again."""
        if not home and self.state in (S.OVERRIDDEN, S.HOME):
            return
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
        if (self.launch_requested and self.has_flown and not self._operator_launch
                and not self._spare_launch):
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
        if self._params_yield():
            self._abort_job(cancel=True)  # not a try: read again when nothing else waits
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
        silent = self.link is LinkState.LOST or self.snap.last_heartbeat_s is None
        if silent or self._restore is not None:
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
        # a new home before the RTL: ArduPlane fixes the RTL's target when it enters RTL
        if self._new_home is not None and self._start_home_set():
            return True
        if self._pending_home and not self.s.advisory:
            self._pending_home = False
            self._start(home_job(self))
            return True
        if self._fence_due():
            assert self.fence_wanted is not None
            self._start(fence_job(self, self.fence_wanted))
            return True
        fly = self._pending_fly
        if fly is not None and self.commanded:
            self._pending_fly = None
            through = fly.command.through
            self.fly = FlyRecord(fly.command.target, fly.x_m, fly.y_m, fly.command.route,
                                 through=target_mission(fly.command).through,
                                 route_end=through[-1].target if through else None)
            self._start(target_job(self, fly))
            return True
        if fly is not None and self.s.advisory:
            self._pending_fly = None
        if self._params_due():
            self._params_job = params_job(self)
            self._start(self._params_job)
            return True
        return False

    def _params_yield(self) -> bool:
        """The parameter snapshot's download is running while a job that starts at once
        waits: an RTL, the fence, a target mission. It gives way (:meth:`_params_due`: the
        lowest priority of all); what may wait on its own (a join's assessment, a home set
        for a vehicle not yet flying) does not cancel it, or the two would take turns."""
        if self._params_job is None or self._jobs.job is not self._params_job:
            return False
        return (self._pending_home or self._fence_due()
                or (self._pending_fly is not None and self.commanded))

    def _params_due(self) -> bool:
        """The parameter snapshot is read once the vehicle was assessed (its cruise speed
        known), when nothing else waits: the lowest priority of all, so a target mission
        is never queued behind it. Reading commands nothing, so it is read in any state
        (a vehicle its pilot flies included); not in advisory mode (floe sends nothing but
        heartbeats there). A failed download is tried again ``fence_retry_s`` later, at
        most :data:`PARAMS_TRIES` times."""
        return (self.s.params_snapshot and not self.params_snapshot and not self.s.advisory
                and self.cruise_source is not None and self._params_tries < PARAMS_TRIES
                and self.t_s >= self._params_retry_at_s)

    def _fence_due(self) -> bool:
        """The area's fence goes to a vehicle floe commands (joined, in the plan, not
        advisory) that does not hold it yet, or holds one the area has moved away from
        (:meth:`FenceCircle.moved`); after a failure, again ``fence_retry_s`` later, at
        most :data:`FENCE_TRIES` times for one fence (an autopilot without the fence
        parameters is not asked every 30 s for the whole run; a reboot or a moved area
        tries again). Never to a vehicle its pilot took over, sent home or not yet joined:
        floe uploads and enables nothing there, as it uploads no mission."""
        want = self.fence_wanted
        return (want is not None and self.commanded and self.t_s >= self._fence_retry_at_s
                and self._fence_failures < FENCE_TRIES and want.moved(self.fence_held))

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
        if self._home_job is not None and self._jobs.job is self._home_job:
            # a home set cut short (reboot, link lost, override) is sent again when it may
            # be, unless a newer one is waiting
            if self._new_home is None:
                self._new_home = self._home_req
            self._home_job = self._home_req = None
        if self._jobs.abort() and cancel:
            self._out.append(controller_io.CancelExchange())

    # ------------------------------------------------------------------ outputs
    def journal(self, event: str, *, logged: bool = False, **fields: Any) -> None:
        """``logged``: an ``controller_io.Warn`` of this step says it to the operator."""
        self._out.append(controller_io.JournalLine(event, fields, logged))

    def _core(self, event: ev.Event) -> None:
        self._out.append(controller_io.CoreEvent(event))

    def _pose(self, joined: bool = False) -> ev.Event | None:
        """The core's pose event. Its speed is the cruise airspeed the vehicle will fly
        (read at join, :func:`~.jobs.cruise_job`, else the configured one), never the one
        measured now: ArduPlane climbs out at ~28 m/s and then cruises at AIRSPEED_CRUISE
        (docs/wind.md, "The first leg")."""
        s = self.snap
        if s.x_m is None or s.y_m is None:
            return None
        heading = s.heading_rad if s.heading_rad is not None else 0.0
        speed = self.cruise_speed_m_s or self.s.speed_m_s or 22.0
        # a fix older than lag_threshold_s is never planned from as it is: predicted to now
        p = self.prediction()
        if p is None:
            cls = ev.VehicleJoined if joined else ev.Telemetry
            return cls(self.t_s, self.vehicle, s.x_m, s.y_m, heading, speed)
        if joined:
            return ev.VehicleJoined(self.t_s, self.vehicle, p.x_m, p.y_m, p.heading_rad, speed)
        return ev.Telemetry(self.t_s, self.vehicle, p.x_m, p.y_m, p.heading_rad, speed,
                            fix_age_s=p.fix_age_s, sigma_m=p.sigma_m)

    def _core_pose(self) -> None:
        """The pose for the core: a fix as it comes; a prediction (from a stale fix) at
        most every ``lag_pose_every_s``, so a backlog drained at once is not a burst."""
        pose = self._pose()
        if pose is None:
            return
        if isinstance(pose, ev.Telemetry) and pose.fix_age_s is not None:
            if self.t_s - self._predicted_at_s < self.s.lag_pose_every_s - 1e-9:
                return
            self._predicted_at_s = self.t_s
        self._core(pose)

    def _battery_low(self, t: float) -> None:
        if self._battery_reported:
            return
        self._battery_reported = True
        self.journal("battery_low", remaining_pct=self.snap.battery_remaining_pct)
        if self.state is S.ACTIVE:
            self._core(ev.BatteryLow(t, self.vehicle))

    # ------------------------------------------------------------------ the ship watch
    def _battery_pct(self) -> float | None:
        return _reading(self.snap.battery_remaining_pct, 0.0, 100.0)

    def _report_battery(self, t: float) -> None:
        """``BatteryReport`` for the core's energy model: at most every
        ``battery_report_s``, or at once when the remaining charge moved by
        ``battery_report_pct``. What is not a reading (NaN, out of range, ArduPilot's
        "unknown") is None; nothing at all is sent while nothing is known."""
        s = self.snap
        pct = self._battery_pct()
        current_a = _reading(s.battery_current_a, -1000.0, 1000.0)
        voltage_v = _reading(s.battery_voltage_v, 0.0, 100.0)
        if pct is None and current_a is None and voltage_v is None:
            return
        last = self._battery_sent
        if last is not None and t - last[0] < self.s.battery_report_s - 1e-9:
            moved = pct is not None and (
                last[1] is None or abs(pct - last[1]) >= self.s.battery_report_pct - 1e-9)
            if not moved:
                return
        self._battery_sent = (t, pct)
        self._core(ev.BatteryReport(t, self.vehicle, pct, current_a, voltage_v))

    def _spare_ok(self) -> bool:
        """Whether floe may launch it on the core's order: it never flew; or (only with a
        watch configured: the relief's opt-in) it came down in an RTL, floe's or a
        failsafe's, and has since been booted again with at least ``ready_pct``. Any
        other vehicle that came down after it flew is never launched on floe's own."""
        if not self.has_flown:
            return True
        ready_pct, pct = self.s.ready_pct, self._battery_pct()
        return (ready_pct is not None and self.came_down is not None and self._fresh_boot
                and self._down_in_rtl and pct is not None and pct >= ready_pct)

    def _deck(self, t: float) -> None:
        """``VehicleOnDeck`` when a vehicle standing disarmed on the ground changes
        readiness (ready: floe may launch it, :meth:`_spare_ok`, with at least
        ``ready_pct`` of charge when a watch is configured)."""
        s = self.snap
        on_deck = (s.armed is False and self.watch.grounded.confirmed and not self.flying()
                   and not s.reboot_suspected and self.link is not LinkState.LOST
                   and self.state is not S.LAUNCHING)
        if not on_deck:
            self._deck_sent = None
            return
        pct = self._battery_pct()
        ready_pct = self.s.ready_pct
        charged = ready_pct is None or (pct is not None and pct >= ready_pct)
        ready = charged and self._spare_ok()
        if ready != self._deck_sent:
            self._deck_sent = ready
            self._core(ev.VehicleOnDeck(t, self.vehicle, ready, pct))

    def _landed(self, t: float) -> None:
        """It flew and is found on the ground (the evidence behind ``came_down``): once."""
        s = self.snap
        if s.x_m is None or s.y_m is None:
            self.journal("landed_unplaced", reason=self.came_down)
            return
        self._core(ev.VehicleLanded(t, self.vehicle, s.x_m, s.y_m))

    def _on_new_home(self, new: controller_io.NewHome) -> None:
        """The core's SetHome: the newest one wins; a home set still running for an older
        one is cancelled (it is one command: nothing is half done)."""
        if not (math.isfinite(new.x_m) and math.isfinite(new.y_m)):
            self.journal("home_set_failed", x_m=new.x_m, y_m=new.y_m, reason="not a position")
            return
        self._new_home = new
        if self._home_job is not None and self._jobs.job is self._home_job:
            self._home_job = self._home_req = None
            self._abort_job(cancel=True)

    def _start_home_set(self) -> bool:
        """Start the waiting home set if the vehicle is in the air (whoever has it: moving
        the home changes no mode); drop it for one on the ground; else let it wait."""
        new = self._new_home
        assert new is not None
        if self.s.advisory:  # advisory commands nothing (the core's set_home line stays)
            self._new_home = None
            return False
        if not self.flying():
            if self.state is not S.LAUNCHING and self.watch.grounded.confirmed:
                self._new_home = None  # moot, not a failure: it landed (or was recovered)
                self.journal("home_set_skipped", x_m=new.x_m, y_m=new.y_m,
                             reason="on the ground (its home is where it is armed)")
            return False
        self._new_home = None
        self._home_req = new
        self._home_job = set_home_job(self, new.x_m, new.y_m)
        self._start(self._home_job)
        return True

    def _on_launch_wanted(self, order: controller_io.LaunchWanted) -> None:
        """The core's LaunchVehicle: with ``--launch`` floe launches the spare if it may
        (:meth:`_spare_ok`, on the ground); otherwise the operator is asked (console,
        journal, the API's ``launch_wanted`` and the live map's button)."""
        self.launch_wanted = order
        what = (f"relief of {order.relieves}" if order.relieves is not None
                else order.reason)
        down = self.state in (S.OVERRIDDEN, S.HOME) and self.watch.grounded.confirmed
        grounded = self.state in (S.ON_GROUND, S.CONNECTING) or down
        if self.state is S.LAUNCHING or self.flying():
            self.journal("launch_wanted", reason=order.reason, relieves=order.relieves,
                         action="none", why=f"already {self.status}")
            return
        if self.s.launch and not self.s.advisory and grounded and self._spare_ok():
            self.journal("launch_wanted", reason=order.reason, relieves=order.relieves,
                         action="launch")
            if down:
                self.state = S.ON_GROUND
                self._pending_home = False
            self._spare_launch = True
            self.launch_held = None
            self._launch_request()
            return
        why = ("floe launches only with --launch" if not self.s.launch or self.s.advisory
               else "not on the ground" if not grounded
               else self.came_down or "came down after it flew")
        self.journal("launch_wanted", reason=order.reason, relieves=order.relieves,
                     action="ask", why=why, logged=True)
        self._out.append(controller_io.Warn(
            f"launch vehicle {self.vehicle} ({what}): catapult it, or "
            f"'gcs vehicle launch {self.vehicle}'"
        ))  # fmt: skip

    def _on_wind(self, event: WindReported) -> None:
        """The vehicle's accepted wind estimate goes to the core (``WindReport``) while it
        is active in the plan (on the ground, or taken over, it says nothing about the air
        floe flies in) and has been for ``wind_settle_s`` (the autopilot's estimate
        converges in flight), at most once per ``wind_report_min_s``; never while its
        airspeed sensor is failed (:meth:`_airspeed`)."""
        if self.state is not S.ACTIVE or self._restore is not None or self.airspeed.failed:
            self._wind_since_s = None
            return
        if self._wind_since_s is None:
            self._wind_since_s = event.t_s
        if event.t_s - self._wind_since_s < self.s.wind_settle_s - 1e-9:
            return
        if event.t_s - self._wind_sent_s < self.s.wind_report_min_s:
            return
        self._wind_sent_s = event.t_s
        self._core(ev.WindReport(event.t_s, self.vehicle, event.wx_m_s, event.wy_m_s))

    def _airspeed(self, change: AirspeedChange | None) -> None:
        """The airspeed sensor's verdict changed (:mod:`groundstation.mavlink.airspeed_health`).
        Failed: ArduPlane's wind estimate without airspeed is wrong (40-60 % of the wind),
        so the core forgets this vehicle's reports at once (``WindWithdrawn``, when any were
        sent) and none is sent until the sensor is back; then the estimate settles again
        for ``wind_settle_s`` first."""
        if change is None:
            return
        self._wind_since_s = None
        if not change.failed:
            self.journal("airspeed_recovered", how=change.how, detail=change.detail)
            return
        self.journal("airspeed_failed", how=change.how, detail=change.detail, logged=True)
        self._out.append(controller_io.Warn(
            f"vehicle {self.vehicle}: airspeed sensor failed (ArduPlane: {change.detail}): "
            "its wind estimate is ignored until the sensor recovers"
        ))  # fmt: skip
        if self._wind_sent_s > -math.inf:
            self._core(ev.WindWithdrawn(change.t_s, self.vehicle, "airspeed sensor failed"))

    def _airspeed_rebooted(self) -> None:
        """A reboot: ArduPlane uses its sensor again (the health check's ARSPD_USE 0 is not
        saved), and the evidence starts again."""
        if self.airspeed.failed:
            self.journal("airspeed_recovered", how="reboot",
                         detail="the autopilot rebooted and uses its sensor again")
        self.airspeed.reset()

    def _loiter_ended(self, t: float, loiter: LoiterEndEvidence) -> None:
        self._loiter = None
        self.last_loiter_end_s = t
        self._loiter_end_pending_s = t
        target = self.fly.end_target if self.fly else None
        self.journal("loiter_end", target=target, how=loiter.ended_by)
        if self.state is S.ACTIVE:
            self._core(ev.LoiterEnded(t, self.vehicle))

    def _refused(self, request: controller_io.Exchange) -> None:
        """The guard stopped ``request``: the job ended; assess again later."""
        self.journal(
            "command_refused", request=type(request).__name__, state=self.status,
            armed=self.snap.armed, reason="not armed",
        )  # fmt: skip
        if self.state in (S.JOINING, S.LAUNCHING):
            self.state = S.CONNECTING
        self._retry_at_s = self.t_s + self.s.retry_assess_s

    # ---------------------------------------------------------- the jobs' callbacks (JobHost)
    def mission_seq(self) -> int | None:
        return self.snap.mission_current_seq

    def mode(self) -> int | None:
        return self.snap.mode

    def position(self) -> tuple[float, float, float]:
        s = self.snap
        return s.x_m or 0.0, s.y_m or 0.0, s.heading_rad or 0.0

    def loiter_radius_m(self, fallback_m: float | None = None) -> float:
        return self.s.loiter_radius_m or fallback_m or self.s.default_loiter_radius_m

    def expect_mode(self, mode: int) -> None:
        self._expected[mode] = self.t_s + self.s.expect_mode_s

    def arm_loiter_end(self, seq: int) -> None:
        current = self.snap.mission_current_seq
        loiter = LoiterEndEvidence(seq, current_seq=current)
        if current is not None and current > seq:
            loiter.ended_by = "mission_current"  # ended while the set-current was confirmed
            self._loiter_ended(self.t_s, loiter)
            return
        self._loiter = loiter

    def disarm_loiter_end(self) -> None:
        self._loiter = None

    def joined(self, how: str) -> None:
        self.state = S.ACTIVE
        self.watch.reset_progress()
        self.journal("vehicle_joined", how=how, system_id=self.system_id, altitude_m=self.alt_m)
        pose = self._pose(joined=True)
        if pose is not None:
            self._core(pose)

    def park_failed(self) -> None:
        if self.state is S.JOINING:
            self.state = S.CONNECTING
        self._retry_at_s = self.t_s + self.s.retry_assess_s

    def launch_failed(self) -> None:
        if self.state is S.LAUNCHING:
            self.state = S.ON_GROUND
        self._retry_at_s = self.t_s + self.s.retry_assess_s

    def launched(self) -> None:
        """AUTO was accepted: from now on the mode it waited in on the ground is not floe's
        (an operator who switches back to MANUAL before a heartbeat shows AUTO overrides)."""
        self._launch_deadline_s = self.t_s + self.s.launch_timeout_s
        if self._own_mode != ArduPlaneMode.AUTO:
            self._own_mode = None

    def target_verified(self, fly: controller_io.Fly) -> bool:
        if self.fly is not None:
            self.fly.verified_t_s = self.t_s
        self.uploads_ok += 1
        self.watch.reset_progress()
        if self._wanted is fly:
            self._wanted = None
        if self._loiter_end_pending_s is not None:
            self.upload_delays_s.append(self.t_s - self._loiter_end_pending_s)
            self._loiter_end_pending_s = None
        if fly.clipped:
            self.journal("clipped", target=fly.command.target, x_m=fly.x_m, y_m=fly.y_m)
        return True

    def count_retries(self, retries: int) -> None:
        self.upload_retries += retries

    def upload_done(self, ok: bool, took_s: float | None) -> None:
        self.link_uploads.append((ok, took_s))

    def target_failed(self, fly: controller_io.Fly) -> bool:
        """Whether to try again: not when overtaken, out of the plan or link lost."""
        self.uploads_failed += 1
        return self.target_wanted()

    def target_wanted(self) -> bool:
        """Whether the job's target still stands: commanded, not overtaken by a newer
        FlyToTarget, link up."""
        return self.commanded and self._pending_fly is None and self.link is not LinkState.LOST

    def cruise_known(self, speed_m_s: float | None, source: str) -> None:
        """The cruise airspeed was read (``source`` the parameter), or not (``config``:
        the configured speed); journalled as ``cruise_speed``."""
        configured = self.s.speed_m_s or 22.0
        self.cruise_speed_m_s = configured if speed_m_s is None else speed_m_s
        self.cruise_source = source
        self.journal("cruise_speed", speed_m_s=self.cruise_speed_m_s, source=source)

    def home_moved(self, x_m: float, y_m: float, outcome: controller_io.HomeOutcome) -> None:
        """A home set ended: ``home_set`` with where the vehicle says its home is and how
        far that is from the request, or ``home_set_failed`` (a warning once per cause
        until one succeeds, and none when a newer SetHome is already waiting)."""
        self._home_job = self._home_req = None
        if outcome.ok:
            self._home_warned = None
            if outcome.x_m is not None and outcome.y_m is not None:
                self.home_xy_m = (outcome.x_m, outcome.y_m)
            self.journal("home_set", x_m=outcome.x_m, y_m=outcome.y_m, requested_x_m=x_m,
                         requested_y_m=y_m, error_m=outcome.error_m, retries=outcome.retries)
            return
        # told once per cause until a home set succeeds: a vehicle that does not support
        # DO_SET_HOME would warn at every step of the ship (the journal has every one)
        warn = self._new_home is None and outcome.error != self._home_warned
        self.journal("home_set_failed", x_m=x_m, y_m=y_m, reason=outcome.error,
                     retries=outcome.retries, logged=True)
        if warn:
            self._home_warned = outcome.error
            self._out.append(controller_io.Warn(
                f"vehicle {self.vehicle}: its home could not be moved ({outcome.error}); "
                "an RTL now goes to its old home"
            ))  # fmt: skip

    def home_done(self, ok: bool) -> None:
        self.journal("rtl", ok=ok)
        if not ok:
            self._pending_home = True

    def params_read(self, values: dict[str, float] | None) -> None:
        self._params_tries += 1
        if values is None:
            self._params_retry_at_s = self.t_s + self.s.fence_retry_s
            return
        self.params_snapshot = True
        self._out.append(controller_io.ParamsRead(values))

    def fence_done(self, fence: FenceCircle, ok: bool) -> None:
        """The fence job's end: held (verified and enabled), or tried again
        ``fence_retry_s`` later (its ``fence`` journal line, ``ok: false``, is the
        operator's warning)."""
        if ok:
            self.fence_held = fence
            self._fence_failures = 0
        else:
            self._fence_failures += 1
            self._fence_failed = fence
            self._fence_retry_at_s = self.t_s + self.s.fence_retry_s


def _reading(value: float | None, low: float, high: float) -> float | None:
    """A battery value as the core is told it: None unless a finite number in [low, high]."""
    if value is None or isinstance(value, bool) or not isinstance(value, int | float):
        return None
    value = float(value)
    return value if math.isfinite(value) and low <= value <= high else None
