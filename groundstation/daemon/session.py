"""One vehicle's session: telemetry -> core events, core commands -> MAVLink exchanges.

State (``status``): ``connecting`` (not assessed yet), ``on_ground`` (never armed unless a
launch is asked for), ``launching``, ``joining`` (being parked), ``manual`` (flying in a mode
floe does not take: waits for AUTO/GUIDED), ``active`` (in the plan, commanded),
``overridden`` (someone else has it: not commanded until AUTO again or ``vehicle resume``),
``home`` (sent home on low battery). The link state (``ok``/``degraded``/``lost``) is kept
apart: a lost active vehicle leaves the plan and is taken back when heard again.

Takeover: armed and flying in GUIDED -> joins at once; in AUTO -> its mission is read back and
it joins if it holds an unlimited loiter, else it is first parked on one (upload, verify,
set current); on the ground -> launched only when asked (``--launch``, ``vehicle launch``):
wait for the pre-arm bit, upload [home, takeoff, unlimited loiter], verify, arm, AUTO, join
once up. A mission for a target is [home, NAV_LOITER_TIME at the aim point (a waypoint for
0 s), NAV_LOITER_UNLIM there], WP_LOITER_RAD set by PARAM_SET; upload -> download-verify ->
set current 1 -> MISSION_CURRENT confirmed, retried on the mission clock until verified or
overtaken by a newer command.

Mode changes: the daemon's own (expected for a while after it asked) are told apart from
the autopilot's (battery failsafe, RTL at mission end: a STATUSTEXT says why within
``override_grace_s``) and from an operator's (anything else out of AUTO/GUIDED): override.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import logging
import math
import time
from typing import Any, Protocol

from domain.geodesy import GeoOrigin
from groundstation.core import events as ev
from groundstation.core.commands import FlyToTarget
from groundstation.daemon.clock import MissionClock
from groundstation.daemon.config import DaemonConfig, VehicleSettings
from groundstation.daemon.session_flight import (
    AUTO,
    RTL,
    TAKEN_MODES,
    FlightMixin,
    FlyRecord,
)
from groundstation.daemon.vehicle_port import VehiclePort
from groundstation.mavlink.codec import MAVLinkMessage
from groundstation.mavlink.telemetry import (
    Armed,
    BatteryLow,
    Disarmed,
    LoiterEndDetector,
    MissionCurrentChanged,
    MissionItemReached,
    ModeChanged,
    PrearmChanged,
    Rebooted,
    StatusText,
    VehicleTelemetry,
)

__all__ = ["SessionHost", "VehicleSession"]

log = logging.getLogger(__name__)
FLYING_ALT_M = 10.0
RATES_EVERY_S = 30.0
CLOCK_CHECK_S = 30.0


class SessionHost(Protocol):
    """What a session needs from the daemon."""

    @property
    def origin(self) -> GeoOrigin: ...

    def core_event(self, event: ev.Event) -> None: ...

    def journal(self, event: str, **fields: Any) -> None: ...

    def clip(self, x_m: float, y_m: float) -> tuple[float, float, bool]: ...


class VehicleSession(FlightMixin):
    """See the module docstring."""

    def __init__(
        self,
        system_id: int,
        name: str,
        index: int,
        host: SessionHost,
        config: DaemonConfig,
        settings: VehicleSettings,
        port: VehiclePort,
        clock: MissionClock,
    ) -> None:
        self.system_id = system_id
        self.id = name
        self.index = index
        self.host = host
        self.config = config
        self.settings = settings
        self.port = port
        self.clock = clock
        self.telemetry = VehicleTelemetry(
            system_id, host.origin, battery_low_pct=config.battery_low_pct
        )
        self.alt_m = settings.altitude_m or config.altitude_m + config.altitude_step_m * index
        self.status = "connecting"
        self.link = "ok"
        self.launch_requested = bool(config.launch)
        self.fly: FlyRecord | None = None
        self.track: collections.deque[tuple[float, float]] = collections.deque(maxlen=60)
        self.last_loiter_end_s: float | None = None
        self.uploads_ok = 0
        self.uploads_failed = 0
        self.upload_delays_s: list[float] = []
        self.upload_delays_wall_s: list[float] = []
        self._loiter_end_pending_s: float | None = None
        self._loiter_end_wall = 0.0
        self._wake = asyncio.Event()
        self._pending_fly: FlyToTarget | None = None
        self._wanted: FlyToTarget | None = None
        self._pending_home = False
        self._detector: LoiterEndDetector | None = None
        self._expected_modes: dict[int, float] = {}
        self._pending_override: tuple[float, int, str] | None = None
        self._texts: collections.deque[tuple[float, str]] = collections.deque(maxlen=20)
        self._battery_reported = False
        self._rates_at_s = -math.inf
        self._retry_at_s = 0.0
        self._wp_loiter_rad: float | None = None
        self._last_track_s = -math.inf
        self.stopping = False
        self._clock_ref: tuple[float, int] | None = None
        self._clock_checked = False

    # ------------------------------------------------------------------ helpers
    @property
    def snapshot(self) -> Any:
        return self.telemetry.snapshot()

    @property
    def commanded(self) -> bool:
        return self.status == "active" and not self.config.advisory and not self.stopping

    def wake(self) -> None:
        self._wake.set()

    def _journal(self, event: str, **fields: Any) -> None:
        self.host.journal(event, vehicle=self.id, **fields)

    def _flying(self) -> bool:
        s = self.snapshot
        return bool(s.armed) and s.alt_m is not None and s.alt_m > FLYING_ALT_M

    def _pose_event(self, t_s: float, joined: bool = False) -> ev.Event | None:
        s = self.snapshot
        if s.x_m is None or s.y_m is None:
            return None
        heading = s.heading_rad if s.heading_rad is not None else 0.0
        speed = s.airspeed_m_s or s.speed_m_s or self.settings.speed_m_s or 22.0
        cls = ev.VehicleJoined if joined else ev.Telemetry
        return cls(t_s, self.id, s.x_m, s.y_m, heading, speed)

    # ------------------------------------------------------------------ incoming
    def on_message(self, msg: MAVLinkMessage) -> None:
        """Every message from this vehicle (called on the event loop by the router)."""
        t_s = self.clock.now_s()
        events = self.telemetry.receive(msg, t_s)
        self.port.deliver(msg)
        if self.link == "lost" and self.snapshot.last_heard_s == t_s:
            self.link = "ok"
            self._journal("link_restored")
            if self.status == "active" and self._wanted is not None and not self._pending_fly:
                # the mission it was being given when the link went is still owed: the
                # core will not send it again if it plans the same target
                self._pending_fly = self._wanted
                self.wake()
            if self.status == "active":
                pose = self._pose_event(t_s)
                if pose is not None:
                    self.host.core_event(pose)
                self.host.core_event(ev.VehicleReturned(t_s, self.id))
        for event in events:
            self._on_event(event)
        if msg.get_type() == "GLOBAL_POSITION_INT":
            s = self.snapshot
            if s.x_m is not None and s.y_m is not None:
                if t_s - self._last_track_s >= 5.0:
                    self.track.append((s.x_m, s.y_m))
                    self._last_track_s = t_s
                if self.status == "active":
                    pose = self._pose_event(t_s)
                    if pose is not None:
                        self.host.core_event(pose)
        if self.status in ("connecting", "on_ground", "manual"):
            self.wake()

    def _on_event(self, event: Any) -> None:
        t_s = event.t_s
        if isinstance(event, ModeChanged):
            self._on_mode(event)
        elif isinstance(event, MissionItemReached | MissionCurrentChanged):
            detector = self._detector
            if detector is not None and detector.feed(event):
                self._detector = None
                self.last_loiter_end_s = t_s
                self._loiter_end_pending_s = t_s
                self._loiter_end_wall = time.monotonic()
                self._journal(
                    "loiter_end",
                    target=self.fly.target if self.fly else None,
                    how=detector.ended_by,
                )
                if self.status == "active":
                    self.host.core_event(ev.LoiterEnded(t_s, self.id))
        elif isinstance(event, StatusText):
            self._texts.append((t_s, event.text))
            self._journal("statustext", severity=event.severity, text=event.text)
        elif isinstance(event, Rebooted):
            self._journal(
                "reboot",
                previous_time_boot_ms=event.previous_time_boot_ms,
                time_boot_ms=event.time_boot_ms,
            )
            self.port.notify_rebooted()
            self._detector = None
            self._wp_loiter_rad = None
            self._rates_at_s = -math.inf
            if self.status in ("active", "joining", "launching"):
                self.host.core_event(ev.VehicleLost(t_s, self.id))
            if self.status not in ("overridden", "home"):
                self.status = "connecting"
            self.wake()
        elif isinstance(event, BatteryLow):
            self._on_battery_low(t_s, event.remaining_pct)
        elif isinstance(event, Armed | Disarmed):
            self._journal("armed", armed=isinstance(event, Armed))
        elif isinstance(event, PrearmChanged):
            self.wake()

    def _on_battery_low(self, t_s: float, pct: float | None) -> None:
        if self._battery_reported:
            return
        self._battery_reported = True
        self._journal("battery_low", remaining_pct=pct)
        if self.status == "active":
            self.host.core_event(ev.BatteryLow(t_s, self.id))

    def _on_mode(self, event: ModeChanged) -> None:
        t_s = event.t_s
        expected = self._expected_modes.pop(event.new, None)
        ours = expected is not None and expected >= t_s
        cause = "floe" if ours else ("initial" if event.old is None else "vehicle")
        self._journal("mode", old=event.old_name, mode=event.new_name, cause=cause)
        if ours or event.old is None:
            return
        if event.new in TAKEN_MODES:
            self._pending_override = None
            if self.status == "overridden" and event.new == AUTO:
                self.resume(t_s, "mode AUTO")
            elif self.status in ("manual", "connecting"):
                self.wake()
            return
        if self.status in ("active", "joining", "launching"):
            self._pending_override = (t_s, event.new, event.new_name)
            self.wake()

    def _resolve_override(self, t_s: float) -> None:
        pending = self._pending_override
        if pending is None or t_s - pending[0] < self.config.override_grace_s:
            return
        self._pending_override = None
        if self.status not in ("active", "joining", "launching"):
            return  # already out of floe's hands (sent home, released, lost)
        since, mode, name = pending
        texts = " | ".join(text.lower() for tt, text in self._texts if tt >= since - 3.0)
        s = self.snapshot
        low = s.battery_remaining_pct is not None and (
            s.battery_remaining_pct <= self.config.battery_low_pct
        )
        if mode == RTL and ("battery" in texts or low):
            self._journal("autopilot_mode", mode=name, reason="battery failsafe")
            self._on_battery_low(t_s, s.battery_remaining_pct)
            return
        if mode == RTL and "mission complete" in texts and self.status == "active":
            # our missions end in an unlimited loiter: a mission that ran off its end is
            # taken back with a fresh mission (the core replans it as idle)
            self._journal("autopilot_mode", mode=name, reason="mission end")
            self.host.core_event(ev.VehicleRebooted(t_s, self.id))
            return
        reason = "failsafe" if "failsafe" in texts else f"mode {name}"
        self.override(t_s, reason)

    # ------------------------------------------------------------------ decisions
    def override(self, t_s: float, reason: str) -> None:
        """Someone else took the vehicle: stop commanding it, replan the others."""
        if self.status == "overridden":
            return
        was_planned = self.status == "active"
        self.status = "overridden"
        self._pending_fly = None
        self._wanted = None
        self._detector = None
        self._journal("override", reason=reason)
        if was_planned:
            self.host.core_event(ev.OperatorOverride(t_s, self.id))

    def resume(self, t_s: float, reason: str) -> bool:
        """An operator gave the vehicle back to floe."""
        if self.status not in ("overridden", "home"):
            return False
        self._journal("resume", reason=reason)
        self._battery_reported = False if self.status == "home" else self._battery_reported
        self.status = "active"
        pose = self._pose_event(t_s)
        if pose is not None:
            self.host.core_event(pose)
        self.host.core_event(ev.OperatorResume(t_s, self.id))
        return True

    def release(self, reason: str, home: bool = False) -> None:
        """Core said: stop commanding (ReleaseVehicle) or go home (SendHome)."""
        self._pending_fly = None
        self._wanted = None
        self._detector = None
        if home:
            self.status = "home"
            self._pending_home = True
            self.wake()
        elif self.status != "overridden":
            self.status = "overridden"
        self._journal("released", reason=reason, home=home)

    def command_fly(self, command: FlyToTarget) -> None:
        """Core said: fly to a target (the newest command overtakes a pending one); it is
        owed (``_wanted``) until a verified upload carried it out."""
        self._pending_fly = command
        self._wanted = command
        self.wake()

    def request_launch(self) -> tuple[bool, str]:
        if self.status not in ("on_ground", "connecting"):
            return False, f"vehicle {self.id} is {self.status}, not on the ground"
        self.launch_requested = True
        self.wake()
        return True, ""

    def check_link(self, t_s: float) -> None:
        """Housekeeping: declare the link lost after ``lost_after_s`` of silence; flush
        incomplete STATUSTEXTs; check the mission clock against the vehicle's clock."""
        if self.snapshot.last_heard_s is None:
            return
        for event in self.telemetry.tick(t_s):
            self._on_event(event)
        self._check_clock(t_s)
        state = self.telemetry.link_status(t_s, self.config.lost_after_s)
        if state == "lost" and self.link != "lost":
            self.link = "lost"
            self._journal("link_lost", silent_s=round(t_s - self.snapshot.last_heard_s, 2))
            self._pending_fly = None
            if self.status == "active":
                self.host.core_event(ev.VehicleLost(t_s, self.id))
        elif state != "lost":
            self.link = state
        if self._pending_override is not None:
            self.wake()

    def _check_clock(self, t_s: float) -> None:
        """The mission clock must run at the rate of the vehicle's ``time_boot_ms``
        (design.md); a speed-up that does not match the vehicles' is reported once."""
        boot_ms = self.snapshot.time_boot_ms
        if boot_ms is None or self._clock_checked:
            return
        if self._clock_ref is None or boot_ms < self._clock_ref[1]:
            self._clock_ref = (t_s, boot_ms)
            return
        dt = t_s - self._clock_ref[0]
        if dt < CLOCK_CHECK_S:
            return
        ratio = (boot_ms - self._clock_ref[1]) / 1000.0 / dt
        self._clock_checked = True
        self._journal(
            "clock_check", vehicle_s_per_mission_s=round(ratio, 3), ok=abs(ratio - 1.0) <= 0.2
        )
        if abs(ratio - 1.0) > 0.2:
            log.warning(
                "vehicle %s: its clock runs %.2f x the mission clock: is --speedup right?",
                self.id,
                ratio,
            )

    # ------------------------------------------------------------------ the worker
    async def run(self) -> None:
        """The session's task: assess, launch, park, fly, go home (one exchange at a time)."""
        while not self.stopping:
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(0.2):
                    await self._wake.wait()
            self._wake.clear()
            await self.step()

    async def step(self) -> None:
        t_s = self.clock.now_s()
        self._resolve_override(t_s)
        if self.stopping:
            return
        if self.link == "lost" or self.snapshot.last_heartbeat_s is None:
            return
        if not self.config.advisory and t_s - self._rates_at_s >= RATES_EVERY_S:
            self._rates_at_s = t_s
            self.port.request_rates(self.config.telemetry_rate_hz)
        if self.status in ("connecting", "on_ground", "manual") and t_s >= self._retry_at_s:
            await self._assess(t_s)
        if self._pending_home and not self.config.advisory:
            self._pending_home = False
            self._expect(RTL)
            if not await self.port.set_mode(RTL):
                self._journal("rtl", ok=False)
                self._pending_home = True
            else:
                self._journal("rtl", ok=True)
        command = self._pending_fly
        if command is not None and self.commanded:
            self._pending_fly = None
            await self._fly(command)
        elif command is not None and self.config.advisory:
            self._pending_fly = None
