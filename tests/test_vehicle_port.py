"""VehiclePort unit tests: fake clock, fake frames, no sockets.

The port runs on an event loop whose clock is virtual (:class:`VirtualTimeLoop`: a wait
advances time instead of sleeping), and the port's mission clock is :class:`FakeClock`, the
loop's virtual time times a speed-up. So every timeout is exact and every assertion is on
mission time and events, never on how busy the host is.
"""

from __future__ import annotations

import asyncio
import selectors
from collections.abc import Coroutine
from typing import Any, TypeVar

from test_mission_transfer_fake import GCS_COMP, GCS_SYS, VEH_COMP, VEH_SYS, FakePlane, mission

from groundstation.daemon.vehicle_port import VehiclePort
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_transfer import TransferCode

M = mavlink2
T = TypeVar("T")


# --------------------------------------------------------------------------- virtual time


class _InstantSelector(selectors.DefaultSelector):
    """A selector that never blocks: a wait for ``timeout`` advances the virtual clock."""

    def __init__(self) -> None:
        super().__init__()
        self.virtual_s = 0.0

    def select(self, timeout: float | None = None) -> list[Any]:
        ready = super().select(0)
        if ready:
            return ready
        if timeout is None:
            raise RuntimeError("deadlock: the event loop would wait forever")
        self.virtual_s += max(0.0, timeout)
        return ready


class VirtualTimeLoop(asyncio.SelectorEventLoop):
    """An event loop whose ``time()`` only moves when every task waits."""

    def __init__(self) -> None:
        self._instant = _InstantSelector()
        super().__init__(self._instant)

    def time(self) -> float:
        return self._instant.virtual_s


def run(coro: Coroutine[Any, Any, T]) -> T:
    loop = VirtualTimeLoop()
    try:
        return loop.run_until_complete(coro)
    finally:
        loop.close()


class FakeClock:
    """MissionClock-compatible: mission seconds = virtual loop seconds x ``speedup``."""

    def __init__(self, speedup: float = 1.0) -> None:
        self.speedup = speedup

    def now_s(self) -> float:
        return asyncio.get_running_loop().time() * self.speedup

    def wall_s(self, mission_s: float) -> float:
        return max(0.0, mission_s / self.speedup)


# --------------------------------------------------------------------------- fake vehicle


def from_vehicle(msg: MAVLinkMessage, sysid: int = VEH_SYS, compid: int = VEH_COMP) -> Any:
    """``msg`` as the port receives it: encoded by the vehicle, decoded by the ground station."""
    (decoded,) = MavlinkDecoder().feed(MavlinkEncoder(sysid, compid).encode(msg))
    return decoded


class Rig:
    """A port wired to a scripted vehicle (FakePlane plus COMMAND_LONG and PARAM_SET)."""

    def __init__(
        self,
        plane: FakePlane | None = None,
        *,
        latency_s: float = 0.02,
        speedup: float = 1.0,
        silent: bool = False,
        **port_kw: Any,
    ) -> None:
        self.clock = FakeClock(speedup)
        self.plane = plane or FakePlane()
        self.latency_s = latency_s
        self.silent = silent
        self.command_result = M.MAV_RESULT_ACCEPTED
        self.params: dict[str, float] = {}
        self.sent: list[tuple[float, Any]] = []
        self._decoder = MavlinkDecoder()
        self.port = VehiclePort(
            VEH_SYS, self._send_frame, MavlinkEncoder(GCS_SYS, GCS_COMP), self.clock, **port_kw
        )

    def _send_frame(self, sysid: int, frame: bytes) -> bool:
        assert sysid == VEH_SYS
        loop = asyncio.get_running_loop()
        for msg in self._decoder.feed(frame):
            now = self.clock.now_s()
            self.sent.append((now, msg))
            if self.silent:
                continue
            for reply in self._replies(msg, now):
                loop.call_later(
                    self.clock.wall_s(self.latency_s), self.port.deliver, from_vehicle(reply)
                )
        return True

    def _replies(self, msg: Any, now: float) -> list[Any]:
        kind = msg.get_type()
        if kind == "COMMAND_LONG" and msg.command != M.MAV_CMD_DO_SET_MISSION_CURRENT:
            return [M.MAVLink_command_ack_message(msg.command, self.command_result, 0, 0, 255, 190)]
        if kind == "PARAM_SET":
            name = msg.param_id
            self.params[name] = msg.param_value
            return [
                M.MAVLink_param_value_message(
                    name.encode(), msg.param_value, M.MAV_PARAM_TYPE_REAL32, 1, 0
                )
            ]
        return self.plane.receive(msg, now)

    def kinds(self) -> list[str]:
        return [m.get_type() for _, m in self.sent]


async def settle(mission_s: float = 0.0) -> None:
    """Let every ready task run, then let ``mission_s`` of virtual time pass (speed-up 1)."""
    for _ in range(20):
        await asyncio.sleep(0)
    if mission_s:
        await asyncio.sleep(mission_s)


# --------------------------------------------------------------------------- reboots


def test_queued_message_then_reboot_ends_with_vehicle_rebooted() -> None:
    """The fuzz crash: a message queued for the exchange, then a reboot in the same turn.

    The old port finished the machine from ``notify_rebooted`` and the drive loop then fed
    it the queued message: ``LocalProtocolError: receive() after it finished``.
    """

    async def main() -> None:
        rig = Rig(silent=True)
        task = asyncio.create_task(rig.port.upload(mission()))
        await settle()
        assert rig.kinds() == ["MISSION_COUNT"]
        # the session's on_message: deliver the message, then handle its Rebooted event
        rig.port.deliver(from_vehicle(M.MAVLink_mission_request_message(GCS_SYS, GCS_COMP, 0)))
        rig.port.notify_rebooted()
        result = await task
        assert result.code is TransferCode.VEHICLE_REBOOTED and result.retryable
        assert rig.kinds() == ["MISSION_COUNT"]  # the queued request was not answered
        assert not rig.port.busy
        assert rig.clock.now_s() < 0.01

    run(main())
