"""The controller's state and the parts of it that jobs use (see :mod:`.controller`).

:class:`VehicleState` spells the states as the journal and the status table do;
:class:`ControllerState` holds what one vehicle's controller knows and the small
operations its jobs (:mod:`.jobs`) call back (the ``JobHost`` protocol).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import Any

from domain.modes import ArduPlaneMode
from groundstation.core import events as ev
from groundstation.mavlink.airspeed_health import AirspeedChange, AirspeedHealth
from groundstation.mavlink.evidence import LoiterEndEvidence
from groundstation.mavlink.telemetry_events import VehicleSnapshot, WindReported
from groundstation.vehicle import controller_io
from groundstation.vehicle.jobs import JobRunner
from groundstation.vehicle.settings import ControllerSettings
from groundstation.vehicle.watch import Watch

__all__ = ["ASSESSED", "IN_HAND", "ControllerState", "FlyRecord", "VehicleState"]

LAUNCHED_MARGIN_M = 15.0


class VehicleState(enum.Enum):
    CONNECTING = "connecting"
    ON_GROUND = "on_ground"
    LAUNCHING = "launching"
    JOINING = "joining"
    MANUAL = "manual"
    ACTIVE = "active"
    OVERRIDDEN = "overridden"
    HOME = "home"


S = VehicleState
IN_HAND = (S.ACTIVE, S.JOINING, S.LAUNCHING)
ASSESSED = (S.CONNECTING, S.ON_GROUND, S.MANUAL)


@dataclass
class FlyRecord:
    """The mission a vehicle was last given (for the status table and the benchmark)."""

    target: str
    x_m: float
    y_m: float
    route: tuple[str, ...] = field(default=())
    verified_t_s: float | None = None


class ControllerState:
    """What one vehicle's controller knows; its outputs; the jobs' callbacks."""

    def __init__(self, vehicle: str, system_id: int, settings: ControllerSettings) -> None:
        self.vehicle = vehicle
        self.system_id = system_id
        self.s = settings
        self.state = S.CONNECTING
        self.link = "ok"
        self.launch_requested = settings.launch
        self.has_flown = False
        """Seen flying in this session: once it comes down, floe never launches it again on
        its own initiative (only an operator's :meth:`launch` does)."""
        self.came_down: str | None = None
        """How it came down after it flew (None while it flies, or before it ever did)."""
        self._operator_launch = False  # an operator's launch request, until it flies
        self.launch_held: str | None = None
        """Why a launch floe would have started on its own is held (until the operator's)."""
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

    # ------------------------------------------------------------------ reading
    @property
    def status(self) -> str:
        return self.state.value

    @property
    def commanded(self) -> bool:
        return self.state is S.ACTIVE and not self.s.advisory and not self.stopping

    @property
    def busy(self) -> bool:
        return self._jobs.busy

    def flying(self) -> bool:
        """Sustained evidence that it flies (see ControllerSettings)."""
        return self.watch.flying.confirmed

    def may_command(self) -> bool:
        """The guard on every set-mode and upload: armed, or being launched on request."""
        if self.state is S.LAUNCHING and self.launch_requested and not self.s.advisory:
            return True
        return self.snap.armed is True and not self.snap.reboot_suspected

    def may_command_request(self, request: controller_io.Exchange) -> bool:
        return (not isinstance(request, controller_io.SetMode | controller_io.UploadMission)
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
        commanding = (controller_io.SetMode | controller_io.UploadMission | controller_io.SetCurrent
                      | controller_io.Arm)
        if not isinstance(request, commanding):
            return False
        return self.snap.reboot_suspected or self.watch.mode_change_pending

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
        cls = ev.VehicleJoined if joined else ev.Telemetry
        return cls(self.t_s, self.vehicle, s.x_m, s.y_m, heading, speed)

    def _core_pose(self) -> None:
        pose = self._pose()
        if pose is not None:
            self._core(pose)

    def _battery_low(self, t: float) -> None:
        if self._battery_reported:
            return
        self._battery_reported = True
        self.journal("battery_low", remaining_pct=self.snap.battery_remaining_pct)
        if self.state is S.ACTIVE:
            self._core(ev.BatteryLow(t, self.vehicle))

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
        target = self.fly.target if self.fly else None
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
    # ------------------------------------------------------------------ JobHost
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

    def target_failed(self, fly: controller_io.Fly) -> bool:
        """Whether to try again: not when overtaken, out of the plan or link lost."""
        self.uploads_failed += 1
        return self.target_wanted()

    def target_wanted(self) -> bool:
        """Whether the job's target still stands: commanded, not overtaken by a newer
        FlyToTarget, link up."""
        return self.commanded and self._pending_fly is None and self.link != "lost"

    def cruise_known(self, speed_m_s: float | None, source: str) -> None:
        """The cruise airspeed was read (``source`` the parameter), or not (``config``:
        the configured speed); journalled as ``cruise_speed``."""
        configured = self.s.speed_m_s or 22.0
        self.cruise_speed_m_s = configured if speed_m_s is None else speed_m_s
        self.cruise_source = source
        self.journal("cruise_speed", speed_m_s=self.cruise_speed_m_s, source=source)

    def home_done(self, ok: bool) -> None:
        self.journal("rtl", ok=ok)
        if not ok:
            self._pending_home = True
