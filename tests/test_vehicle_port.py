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

import pytest
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
    finally:  # a failed test may leave tasks behind: cancel them on this loop
        pending = asyncio.all_tasks(loop)
        for task in pending:
            task.cancel()
        if pending:
            loop.run_until_complete(asyncio.wait(pending))
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
        replies = self.plane.receive(msg, now)
        if kind == "COMMAND_LONG":  # DO_SET_MISSION_CURRENT: show the new item at once
            replies.append(M.MAVLink_mission_current_message(self.plane.current_seq, 5))
        return replies

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


def test_reboot_during_upload_returns_vehicle_rebooted_and_the_port_stays_usable() -> None:
    async def main() -> None:
        rig = Rig(plane=FakePlane(reboot_after_item=2), latency_s=0.05)
        task = asyncio.create_task(rig.port.upload(mission()))
        await settle(0.5)  # the plane went silent after item 2: it rebooted
        assert not task.done()
        t_reboot = rig.clock.now_s()
        rig.port.notify_rebooted()
        await settle()
        assert task.done() and task.exception() is None  # the task did not crash
        result = task.result()
        assert result.code is TransferCode.VEHICLE_REBOOTED and result.retryable
        assert rig.clock.now_s() == t_reboot  # handled on the driver's next turn, no timeout
        # the port is reusable: a fresh vehicle takes the next upload
        rig.plane.rebooted, rig.plane.reboot_after_item = False, None
        assert (await rig.port.upload(mission())).ok
        assert not rig.port.busy

    run(main())


def test_reboot_while_idle_is_not_remembered() -> None:
    async def main() -> None:
        rig = Rig()
        rig.port.notify_rebooted()
        assert (await rig.port.upload(mission())).ok
        assert await rig.port.command(M.MAV_CMD_COMPONENT_ARM_DISARM, [1.0]) == 0

    run(main())


def test_reboot_ends_command_and_param_set_promptly() -> None:
    async def main() -> None:
        rig = Rig(silent=True)
        command = asyncio.create_task(rig.port.command(M.MAV_CMD_DO_SET_MODE, [1.0, 10.0]))
        await settle(0.3)
        rig.port.notify_rebooted()
        assert await command is None
        assert rig.clock.now_s() == pytest.approx(0.3)  # not the 6 s of silence the retries allow

        param = asyncio.create_task(rig.port.param_set("WP_LOITER_RAD", 80.0))
        await settle(0.2)
        rig.port.notify_rebooted()
        assert await param is False
        assert rig.clock.now_s() == pytest.approx(0.5)
        assert rig.kinds() == ["COMMAND_LONG", "PARAM_SET"]

    run(main())


# --------------------------------------------------------------------------- after the end


def test_messages_after_the_end_are_ignored() -> None:
    async def main() -> None:
        rig = Rig()
        result = await rig.port.upload(mission())
        assert result.ok and not rig.port.busy
        sent = len(rig.sent)
        # a stray request and a heartbeat after the upload: nothing runs, nothing answers
        rig.port.deliver(from_vehicle(M.MAVLink_mission_request_message(GCS_SYS, GCS_COMP, 1)))
        rig.port.deliver(from_vehicle(M.MAVLink_heartbeat_message(1, 3, 0, 10, 4, 3)))
        await settle(1.0)
        assert len(rig.sent) == sent and rig.port.dropped == 0

    run(main())


def test_stray_request_in_the_same_turn_as_the_final_ack_is_ignored() -> None:
    """The machine finishes on the ACK while a stray request waits behind it in the queue."""

    async def main() -> None:
        rig = Rig(silent=True)
        items = mission()
        task = asyncio.create_task(rig.port.upload(items))
        await settle()
        for seq in range(len(items)):
            rig.port.deliver(from_vehicle(M.MAVLink_mission_request_message(255, 190, seq)))
        rig.port.deliver(from_vehicle(M.MAVLink_mission_ack_message(255, 190, 0)))
        rig.port.deliver(from_vehicle(M.MAVLink_mission_request_message(255, 190, 0)))
        rig.port.deliver(from_vehicle(M.MAVLink_heartbeat_message(1, 3, 0, 10, 4, 3)))
        result = await task
        assert result.ok
        assert rig.kinds().count("MISSION_ITEM_INT") == len(items)  # the stray: unanswered

    run(main())


# --------------------------------------------------------------------------- serialisation


def test_command_during_upload_waits_its_turn_and_both_succeed() -> None:
    async def main() -> None:
        rig = Rig(plane=FakePlane(), latency_s=0.05)
        items = mission(n_loiters=3)
        upload = asyncio.create_task(rig.port.upload(items))
        await settle(0.07)  # the upload is running
        command = asyncio.create_task(rig.port.command(M.MAV_CMD_DO_SET_MODE, [1.0, 10.0]))
        await settle()
        assert rig.port.busy and not command.done()
        assert "COMMAND_LONG" not in rig.kinds()  # waiting, not sent, not reading
        up = await upload
        assert up.ok and up.retries_used == 0
        assert rig.plane.mission == items
        assert await command == M.MAV_RESULT_ACCEPTED
        kinds = rig.kinds()
        # serialised: the command went out after the upload's last item
        last_item = max(i for i, k in enumerate(kinds) if k == "MISSION_ITEM_INT")
        assert kinds.index("COMMAND_LONG") > last_item
        assert kinds.count("MISSION_COUNT") == 1 and kinds.count("COMMAND_LONG") == 1
        assert not rig.port.busy

    run(main())


def test_exchanges_run_in_the_order_they_were_asked_for() -> None:
    async def main() -> None:
        rig = Rig(plane=FakePlane(mission=mission()))
        down, param, current, arm = await asyncio.gather(
            rig.port.download(),
            rig.port.param_set("WP_LOITER_RAD", 80.0),
            rig.port.set_current(2, 1),
            rig.port.arm(),
        )
        assert down.ok and param is True and current.ok and arm == M.MAV_RESULT_ACCEPTED
        firsts = [k for k in rig.kinds() if k != "MISSION_REQUEST_INT" and k != "MISSION_ACK"]
        assert firsts == ["MISSION_REQUEST_LIST", "PARAM_SET", "COMMAND_LONG", "COMMAND_LONG"]
        assert rig.params == {"WP_LOITER_RAD": 80.0}

    run(main())


# --------------------------------------------------------------------------- cancellation


def test_cancel_mid_upload_sends_the_cancel_and_leaves_the_port_reusable() -> None:
    async def main() -> None:
        rig = Rig(silent=True)
        task = asyncio.create_task(rig.port.upload(mission()))
        await settle(0.7)
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
        assert task.cancelled()
        last = rig.sent[-1][1]
        assert last.get_type() == "MISSION_ACK"
        assert last.type == M.MAV_MISSION_OPERATION_CANCELLED
        assert not rig.port.busy
        rig.silent = False
        assert await rig.port.command(M.MAV_CMD_COMPONENT_ARM_DISARM, [1.0]) == 0
        assert (await rig.port.upload(mission())).ok

    run(main())


def test_cancel_while_waiting_for_the_turn_sends_nothing() -> None:
    async def main() -> None:
        rig = Rig(latency_s=0.05)
        upload = asyncio.create_task(rig.port.upload(mission()))
        await settle()
        command = asyncio.create_task(rig.port.command(M.MAV_CMD_DO_SET_MODE, [1.0, 10.0]))
        await settle()
        command.cancel()
        await asyncio.gather(command, return_exceptions=True)
        assert (await upload).ok
        assert "COMMAND_LONG" not in rig.kinds() and not rig.port.busy

    run(main())


# --------------------------------------------------------------------------- queue, timing


def test_full_queue_drops_the_oldest_message() -> None:
    async def main() -> None:
        rig = Rig(silent=True, queue_size=4)
        items = mission()
        task = asyncio.create_task(rig.port.upload(items))
        await settle()
        for _ in range(9):
            rig.port.deliver(from_vehicle(M.MAVLink_heartbeat_message(1, 3, 0, 10, 4, 3)))
        # the newest message, a request, survives the overflow
        rig.port.deliver(from_vehicle(M.MAVLink_mission_request_message(255, 190, 0)))
        assert rig.port.dropped == 6
        await settle()
        assert rig.kinds() == ["MISSION_COUNT", "MISSION_ITEM_INT"]
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)

    run(main())


def test_timeouts_are_in_mission_seconds() -> None:
    """At a 20x speed-up the vehicle still sees 1.5 s between MISSION_COUNTs."""

    async def main() -> None:
        rig = Rig(silent=True, speedup=20.0, timeout_s=1.5, retries=2)
        result = await rig.port.upload(mission())
        assert result.code is TransferCode.TIMEOUT
        counts = [t for t, m in rig.sent if m.get_type() == "MISSION_COUNT"]
        assert counts == pytest.approx([0.0, 1.5, 3.0])
        assert rig.clock.now_s() == pytest.approx(4.5)
        assert asyncio.get_running_loop().time() == pytest.approx(4.5 / 20.0)

    run(main())


def test_telemetry_flood_does_not_starve_the_timeout() -> None:
    """Messages that are not for the exchange never postpone its deadline."""

    async def main() -> None:
        rig = Rig(silent=True, timeout_s=1.0, retries=1)
        loop = asyncio.get_running_loop()
        heartbeat = from_vehicle(M.MAVLink_heartbeat_message(1, 3, 0, 10, 4, 3))
        for i in range(1, 400):
            loop.call_later(i * 0.01, rig.port.deliver, heartbeat)
        result = await rig.port.param_set("WP_LOITER_RAD", 80.0, timeout_s=1.0, retries=1)
        assert result is False
        assert [round(t, 6) for t, _ in rig.sent] == [0.0, 1.0]
        assert rig.clock.now_s() == pytest.approx(2.0)

    run(main())


# --------------------------------------------------------------------------- set-current


def test_set_current_is_confirmed_by_item_reached_delivered_to_the_port() -> None:
    """The session delivers every autopilot frame to the port; MISSION_ITEM_REACHED of the
    item after the ACK reaches the running set-current and confirms it, a stale later
    MISSION_CURRENT before it does not (issue 11 follow-up)."""

    async def main() -> None:
        rig = Rig(silent=True)
        task = asyncio.create_task(rig.port.set_current(1, 2))
        await settle(0.05)
        ack = M.MAVLink_command_ack_message(
            M.MAV_CMD_DO_SET_MISSION_CURRENT, M.MAV_RESULT_ACCEPTED, 0, 0, GCS_SYS, GCS_COMP
        )
        rig.port.deliver(from_vehicle(ack))
        rig.port.deliver(from_vehicle(M.MAVLink_mission_current_message(2, 3)))  # stale
        await settle(0.5)
        assert not task.done()
        rig.port.deliver(from_vehicle(M.MAVLink_mission_item_reached_message(1)))
        result = await task
        assert result.ok and result.retries_used == 0
        assert "MISSION_ITEM_REACHED 1" in result.message
        assert rig.clock.now_s() == pytest.approx(0.55)

    run(main())
