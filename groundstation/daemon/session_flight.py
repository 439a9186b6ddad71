"""Taking a vehicle over and flying it: the session's mission side (see ``session.py``).

:class:`FlightMixin` holds the exchanges that change what a vehicle flies: assessing a
newly heard vehicle (join, park, launch), the verified mission upload (upload ->
download -> compare -> set current -> AUTO) and the mission for a target. It is mixed into
:class:`~groundstation.daemon.session.VehicleSession`, which owns the state it uses.
"""

from __future__ import annotations

import asyncio
import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from groundstation.core.commands import FlyToTarget
from groundstation.daemon.clock import MissionClock
from groundstation.daemon.config import DaemonConfig, VehicleSettings
from groundstation.daemon.vehicle_port import VehiclePort
from groundstation.mavlink.codec import mavlink2
from groundstation.mavlink.mission_items import (
    LoiterTime,
    LoiterUnlimited,
    MissionItem,
    MissionStep,
    Takeoff,
    Waypoint,
    build_mission_items,
)
from groundstation.mavlink.mission_verify import compare_missions
from groundstation.mavlink.telemetry import LoiterEndDetector, MissionItemReached

if TYPE_CHECKING:
    from groundstation.core import events as ev
    from groundstation.daemon.session import SessionHost

__all__ = ["AUTO", "GUIDED", "RTL", "TAKEN_MODES", "FlightMixin", "FlyRecord"]

M = mavlink2
AUTO, RTL, GUIDED = 10, 11, 15
TAKEN_MODES = frozenset({AUTO, GUIDED})
LAUNCH_TIMEOUT_S = 180.0
RETRY_PAUSE_S = 1.0
EXPECT_MODE_S = 15.0


@dataclass
class FlyRecord:
    """The mission a vehicle was last given (for the status table and the benchmark)."""

    target: str
    x_m: float
    y_m: float
    route: tuple[str, ...] = field(default=())
    verified_t_s: float | None = None


class FlightMixin:
    """The mission side of a vehicle session (state lives in VehicleSession)."""

    system_id: int
    id: str
    host: SessionHost
    config: DaemonConfig
    settings: VehicleSettings
    port: VehiclePort
    clock: MissionClock
    alt_m: float
    status: str
    link: str
    launch_requested: bool
    fly: FlyRecord | None
    uploads_ok: int
    uploads_failed: int
    upload_delays_s: list[float]
    upload_delays_wall_s: list[float]
    _pending_fly: FlyToTarget | None
    _wanted: FlyToTarget | None
    _detector: LoiterEndDetector | None
    _expected_modes: dict[int, float]
    _retry_at_s: float
    _wp_loiter_rad: float | None
    _loiter_end_pending_s: float | None
    _loiter_end_wall: float

    if TYPE_CHECKING:  # provided by VehicleSession; declared here for the type checker only

        @property
        def snapshot(self) -> Any: ...

        @property
        def commanded(self) -> bool: ...

        def _journal(self, event: str, **fields: Any) -> None: ...

        def _flying(self) -> bool: ...

        def _pose_event(self, t_s: float, joined: bool = False) -> ev.Event | None: ...

        def _on_event(self, event: Any) -> None: ...

    def _expect(self, mode: int) -> None:
        self._expected_modes[mode] = self.clock.now_s() + EXPECT_MODE_S

    async def _assess(self, t_s: float) -> None:
        s = self.snapshot
        if s.mode is None or s.armed is None:
            return
        if self._flying():
            if s.mode not in TAKEN_MODES:
                if self.status != "manual":
                    self.status = "manual"
                    self._journal(
                        "waiting", reason=f"flying in {s.mode_name}: waiting for AUTO or GUIDED"
                    )
                return
            if s.x_m is None:
                return
            if s.mode == GUIDED or self.config.advisory:
                self._join(t_s, "guided" if s.mode == GUIDED else "advisory")
                return
            await self._park(t_s)
            return
        if self.status != "on_ground":
            self.status = "on_ground"
            self._journal("on_ground", prearm_ok=s.prearm_ok)
        if self.launch_requested and s.prearm_ok and not self.config.advisory:
            await self._launch(t_s)

    def _join(self, t_s: float, how: str) -> None:
        self.status = "active"
        self._journal("vehicle_joined", how=how, system_id=self.system_id, altitude_m=self.alt_m)
        joined = self._pose_event(t_s, joined=True)
        if joined is not None:
            self.host.core_event(joined)

    async def _park(self, t_s: float) -> None:
        """Join a vehicle flying in AUTO: directly if it holds an unlimited loiter, else
        park it on one where it is."""
        self.status = "joining"
        s = self.snapshot
        result = await self.port.download()
        items = result.items or ()
        seq = s.mission_current_seq
        if (
            result.ok
            and seq is not None
            and 0 < seq < len(items)
            and (items[seq].command == M.MAV_CMD_NAV_LOITER_UNLIM)
            and seq == len(items) - 1
        ):
            self._join(self.clock.now_s(), "holding")
            return
        radius = self.settings.loiter_radius_m or 120.0
        ok = await self._mission(
            [LoiterUnlimited(s.x_m, s.y_m, self.alt_m, radius)], 1, purpose="park"
        )
        if ok:
            self._join(self.clock.now_s(), "parked")
        else:
            self.status = "connecting"
            self._retry_at_s = self.clock.now_s() + 5.0

    async def _launch(self, t_s: float) -> None:
        s = self.snapshot
        self.status = "launching"
        self._journal("launch", altitude_m=self.alt_m)
        heading = s.heading_rad or 0.0
        x0, y0 = s.x_m or 0.0, s.y_m or 0.0
        radius = self.settings.loiter_radius_m or 120.0
        steps: list[MissionStep] = [
            Takeoff(self.alt_m),
            LoiterUnlimited(
                x0 + 400 * math.cos(heading), y0 + 400 * math.sin(heading), self.alt_m, radius
            ),
        ]
        ok = await self._mission(steps, None, purpose="takeoff")
        if ok:
            result = await self.port.arm()
            ok = result == M.MAV_RESULT_ACCEPTED
            if not ok:
                self._journal("arm", ok=False, result=result)
        if ok:
            await self.port.set_current(1, self.snapshot.mission_current_seq)
            self._expect(AUTO)
            ok = await self.port.set_mode(AUTO)
        if not ok:
            self.status = "on_ground"
            self._retry_at_s = self.clock.now_s() + 5.0
            return
        deadline = self.clock.now_s() + LAUNCH_TIMEOUT_S
        while self.clock.now_s() < deadline:
            s = self.snapshot
            if s.alt_m is not None and s.alt_m >= self.alt_m - 15.0:
                self._join(self.clock.now_s(), "launched")
                return
            if self.status != "launching":
                return
            await asyncio.sleep(max(0.005, self.clock.wall_s(0.5)))
        self._journal("launch_timeout", altitude_m=self.snapshot.alt_m)
        self.status = "connecting"

    # ------------------------------------------------------------------ missions
    async def _upload_verified(self, items: list[MissionItem]) -> tuple[bool, int, str]:
        """Upload then read back until they match; (ok, retries, last failure)."""
        retries = 0
        last = ""
        for attempt in range(self.config.transfer_retries + 1):
            if attempt:
                retries += 1
                await asyncio.sleep(self.clock.wall_s(RETRY_PAUSE_S))
            if self.link == "lost":
                return False, retries, "link lost"
            up = await self.port.upload(items)
            retries += up.retries_used
            if not up.ok and not up.maybe_stored:
                last = f"upload {up.code.value}: {up.message}"
                if not up.retryable:
                    return False, retries, last
                continue
            down = await self.port.download()
            retries += down.retries_used
            if not down.ok or down.items is None:
                last = f"download {down.code.value}: {down.message}"
                continue
            diff = compare_missions(items, down.items)
            if diff:
                last = f"verify: {diff[0]}"
                continue
            return True, retries, ""
        return False, retries, last

    async def _mission(
        self, steps: list[MissionStep], current: int | None, purpose: str, target: str | None = None
    ) -> bool:
        """Upload ``steps`` verified; then set ``current`` and make sure of AUTO.

        The loiter-end detector of a target mission is armed as soon as the mission is
        verified, before the set-current, so a short item cannot end unseen. A set-current
        whose ACK came but whose MISSION_CURRENT never showed ``current`` because the vehicle
        already moved past it (a waypoint passed at once) counts as done."""
        try:
            items = build_mission_items(steps, self.host.origin)
        except ValueError as exc:
            self._journal("upload", ok=False, purpose=purpose, target=target, error=str(exc))
            return False
        self._detector = None
        ok, retries, error = await self._upload_verified(items)
        if ok and current is not None:
            if purpose == "target":
                self._detector = LoiterEndDetector(current)
            before = self.snapshot.mission_current_seq
            result = await self.port.set_current(current, before)
            retries += result.retries_used
            ok = result.ok
            now_seq = self.snapshot.mission_current_seq
            if (
                not ok
                and "ACCEPTED" in result.message
                and now_seq is not None
                and (current < now_seq < len(items))
            ):
                ok = True  # ACK seen, and the vehicle is already on a later item of ours
            error = "" if ok else f"set current {result.code.value}: {result.message}"
            if ok and self._detector is not None:
                self._rearm_detector(current)
            if ok and self.snapshot.mode != AUTO:
                self._expect(AUTO)
                ok = await self.port.set_mode(AUTO)
                error = "" if ok else "mode AUTO refused"
            if not ok:
                self._detector = None
        self._journal(
            "upload",
            ok=ok,
            purpose=purpose,
            target=target,
            retries=retries,
            items=len(items),
            error=error or None,
        )
        return ok

    def _rearm_detector(self, seq: int) -> None:
        """After a confirmed set-current: MISSION_CURRENT may not have *changed* (the
        vehicle was already on ``seq`` of its previous mission), so tell the detector where
        the vehicle is; if it is already past ``seq`` (a short item ended while its
        MISSION_ITEM_REACHED was lost), the item has ended."""
        current = self.snapshot.mission_current_seq
        if current is not None and current > seq:
            self._on_event(MissionItemReached(self.clock.now_s(), seq))
            return
        self._detector = LoiterEndDetector(seq, current_seq=current)

    async def _fly(self, command: FlyToTarget) -> None:
        x_m, y_m, clipped = self.host.clip(command.x_m, command.y_m)
        radius = self.settings.loiter_radius_m or command.loiter_radius_m
        first: MissionStep
        if command.loiter_s >= 1.0:
            first = LoiterTime(x_m, y_m, self.alt_m, round(command.loiter_s))
            if self._wp_loiter_rad != radius:
                if await self.port.param_set("WP_LOITER_RAD", radius):
                    self._wp_loiter_rad = radius
                else:
                    self._journal("param_set", ok=False, name="WP_LOITER_RAD", value=radius)
        else:
            first = Waypoint(x_m, y_m, self.alt_m)
        steps: list[MissionStep] = [first, LoiterUnlimited(x_m, y_m, self.alt_m, radius)]
        self.fly = FlyRecord(command.target, x_m, y_m, command.route)
        while self.commanded:
            ok = await self._mission(steps, 1, purpose="target", target=command.target)
            if ok:
                now = self.clock.now_s()
                self.fly.verified_t_s = now
                self.uploads_ok += 1
                if self._wanted is command:
                    self._wanted = None
                if self._loiter_end_pending_s is not None:
                    self.upload_delays_s.append(now - self._loiter_end_pending_s)
                    self.upload_delays_wall_s.append(time.monotonic() - self._loiter_end_wall)
                    self._loiter_end_pending_s = None
                if clipped:
                    self._journal("clipped", target=command.target, x_m=x_m, y_m=y_m)
                return
            self.uploads_failed += 1
            if self._pending_fly is not None or self.link == "lost":
                return  # overtaken by a newer command, or out of the plan
            await asyncio.sleep(self.clock.wall_s(RETRY_PAUSE_S))
