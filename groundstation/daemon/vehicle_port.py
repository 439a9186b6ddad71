"""Talking to one vehicle: the sans-IO transfer machines driven on the mission clock.

A :class:`VehiclePort` sends the daemon's messages to one system id (through the router)
and runs one exchange at a time: mission upload / download / set current
(``groundstation.mavlink``'s state machines), COMMAND_LONG with its COMMAND_ACK, PARAM_SET
with its PARAM_VALUE. Every timeout is in mission seconds (``MissionClock.wall_s`` turns a
wait into wall time), so at a 50x speed-up the vehicle sees the same 1.5 s timeouts it
would see at 1x. Messages of the vehicle reach the running exchange through
:meth:`deliver`; nothing is queued while no exchange runs.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import Callable, Sequence
from typing import Any, Protocol

from groundstation.daemon.clock import MissionClock
from groundstation.mavlink.codec import MavlinkEncoder, MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_commands import SetCurrent
from groundstation.mavlink.mission_download import MissionDownload
from groundstation.mavlink.mission_items import MissionItem
from groundstation.mavlink.mission_transfer import Finished, Send, TransferResult
from groundstation.mavlink.mission_upload import MissionUpload

__all__ = ["VehiclePort"]

M = mavlink2
_QUEUE = 512


class _Machine(Protocol):
    @property
    def done(self) -> bool: ...

    @property
    def result(self) -> TransferResult | None: ...

    def start(self, now_s: float) -> list[Any]: ...

    def receive(self, msg: MAVLinkMessage, now_s: float) -> list[Any]: ...

    def poll(self, now_s: float) -> list[Any]: ...

    def cancel(self, now_s: float) -> list[Any]: ...

    def next_deadline_s(self) -> float | None: ...

    def notify_vehicle_rebooted(self, now_s: float) -> list[Any]: ...


class VehiclePort:
    """One vehicle's outgoing messages and running exchange (see module docstring)."""

    def __init__(
        self,
        system_id: int,
        send_frame: Callable[[int, bytes], bool],
        encoder: MavlinkEncoder,
        clock: MissionClock,
        *,
        timeout_s: float = 1.5,
        retries: int = 5,
        component_id: int = 1,
    ) -> None:
        self.system_id = system_id
        self.component_id = component_id
        self._send_frame = send_frame
        self.encoder = encoder
        self.clock = clock
        self.timeout_s = timeout_s
        self.retries = retries
        self._queue: asyncio.Queue[MAVLinkMessage] | None = None
        self._machine: _Machine | None = None
        self.busy = False
        self.sent = 0

    # ------------------------------------------------------------------ plumbing
    def send(self, msg: MAVLinkMessage) -> bool:
        """Encode ``msg`` with the GCS identity and send it to this vehicle."""
        try:
            frame = self.encoder.encode(msg)
        except Exception:  # a message that cannot be packed is a local bug: dropped
            return False
        self.sent += 1
        return self._send_frame(self.system_id, frame)

    def deliver(self, msg: MAVLinkMessage) -> None:
        """A message of this vehicle arrived (called by the session)."""
        if self._queue is not None and not self._queue.full():
            self._queue.put_nowait(msg)

    def notify_rebooted(self) -> None:
        """The vehicle rebooted: the running transfer ends with VEHICLE_REBOOTED."""
        machine = self._machine
        if machine is not None and not machine.done:
            for action in machine.notify_vehicle_rebooted(self.clock.now_s()):
                if isinstance(action, Send):
                    self.send(action.msg)

    async def _next(self, deadline_s: float | None) -> MAVLinkMessage | None:
        assert self._queue is not None
        if not self._queue.empty():
            return self._queue.get_nowait()
        now = self.clock.now_s()
        wait_mission = 0.5 if deadline_s is None else max(0.0, deadline_s - now)
        wall = max(0.002, self.clock.wall_s(wait_mission))
        try:
            async with asyncio.timeout(wall):
                return await self._queue.get()
        except TimeoutError:
            return None

    async def run(self, machine: _Machine) -> TransferResult:
        """Drive ``machine`` to its end; cancelling the task cancels the transfer politely."""
        self._queue = asyncio.Queue(_QUEUE)
        self._machine = machine
        self.busy = True
        try:
            actions = machine.start(self.clock.now_s())
            while True:
                for action in actions:
                    if isinstance(action, Send):
                        self.send(action.msg)
                    elif isinstance(action, Finished):
                        return action.result
                if machine.done:
                    assert machine.result is not None
                    return machine.result
                msg = await self._next(machine.next_deadline_s())
                now = self.clock.now_s()
                actions = machine.receive(msg, now) if msg is not None else machine.poll(now)
        except asyncio.CancelledError:
            with contextlib.suppress(Exception):
                for action in machine.cancel(self.clock.now_s()):
                    if isinstance(action, Send):
                        self.send(action.msg)
            raise
        finally:
            self._queue = None
            self._machine = None
            self.busy = False

    # ------------------------------------------------------------------ missions
    @property
    def _own_system(self) -> int:
        return self.encoder.system_id

    @property
    def _own_component(self) -> int:
        return self.encoder.component_id

    async def upload(self, items: Sequence[MissionItem]) -> TransferResult:
        return await self.run(
            MissionUpload(
                self.system_id,
                self.component_id,
                items,
                timeout_s=self.timeout_s,
                retries=self.retries,
                own_system=self._own_system,
                own_component=self._own_component,
            )
        )

    async def download(self) -> TransferResult:
        return await self.run(
            MissionDownload(
                self.system_id,
                self.component_id,
                timeout_s=self.timeout_s,
                retries=self.retries,
                own_system=self._own_system,
                own_component=self._own_component,
            )
        )

    async def set_current(self, seq: int, known_current_seq: int | None) -> TransferResult:
        return await self.run(
            SetCurrent(
                self.system_id,
                self.component_id,
                seq,
                known_current_seq=known_current_seq,
                timeout_s=max(1.0, self.timeout_s * 2 / 3),
                retries=self.retries,
                own_system=self._own_system,
                own_component=self._own_component,
            )
        )

    # ------------------------------------------------------------------ commands
    async def command(
        self, command: int, params: Sequence[float], timeout_s: float = 1.0, retries: int = 5
    ) -> int | None:
        """COMMAND_LONG until its COMMAND_ACK; the MAV_RESULT, or None on silence."""
        p = [float(x) for x in params] + [0.0] * (7 - len(params))
        self._queue = asyncio.Queue(_QUEUE)
        self.busy = True
        try:
            for confirmation in range(retries + 1):
                self.send(
                    M.MAVLink_command_long_message(
                        self.system_id, self.component_id, command, min(confirmation, 255), *p
                    )
                )
                deadline = self.clock.now_s() + timeout_s
                while self.clock.now_s() < deadline:
                    msg = await self._next(deadline)
                    if msg is None:
                        continue
                    if msg.get_type() == "COMMAND_ACK" and int(msg.command) == command:
                        target = getattr(msg, "target_system", 0)
                        if target in (0, self.encoder.system_id):
                            result = int(msg.result)
                            if result != M.MAV_RESULT_IN_PROGRESS:
                                return result
            return None
        finally:
            self._queue = None
            self.busy = False

    async def set_mode(self, mode: int) -> bool:
        result = await self.command(
            M.MAV_CMD_DO_SET_MODE, [M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, mode]
        )
        return result == M.MAV_RESULT_ACCEPTED

    async def arm(self) -> int | None:
        return await self.command(M.MAV_CMD_COMPONENT_ARM_DISARM, [1.0], retries=2)

    async def param_set(
        self, name: str, value: float, timeout_s: float = 1.0, retries: int = 5
    ) -> bool:
        """PARAM_SET until PARAM_VALUE echoes ``value``."""
        self._queue = asyncio.Queue(_QUEUE)
        self.busy = True
        try:
            for _ in range(retries + 1):
                self.send(
                    M.MAVLink_param_set_message(
                        self.system_id,
                        self.component_id,
                        name.encode("ascii"),
                        float(value),
                        M.MAV_PARAM_TYPE_REAL32,
                    )
                )
                deadline = self.clock.now_s() + timeout_s
                while self.clock.now_s() < deadline:
                    msg = await self._next(deadline)
                    if msg is None or msg.get_type() != "PARAM_VALUE":
                        continue
                    pid = msg.param_id
                    if isinstance(pid, bytes):
                        pid = pid.decode("ascii", "replace")
                    if str(pid).rstrip("\x00") == name and math.isclose(
                        float(msg.param_value), float(value), rel_tol=1e-6, abs_tol=1e-6
                    ):
                        return True
            return False
        finally:
            self._queue = None
            self.busy = False

    def request_rates(self, position_hz: float) -> None:
        """Ask for the telemetry the daemon needs (fire and forget; repeated by the session).

        REQUEST_DATA_STREAM for the groups (older autopilots, ArduPilot's SRx) and
        SET_MESSAGE_INTERVAL for the position, which the planner and the camera need most.
        """
        groups = (
            (M.MAV_DATA_STREAM_EXTENDED_STATUS, 1),
            (M.MAV_DATA_STREAM_EXTRA1, 1),
            (M.MAV_DATA_STREAM_EXTRA2, 1),
            (M.MAV_DATA_STREAM_EXTRA3, 1),
            (M.MAV_DATA_STREAM_POSITION, max(1, round(position_hz))),
        )
        for stream_id, rate in groups:
            self.send(
                M.MAVLink_request_data_stream_message(
                    self.system_id, self.component_id, stream_id, rate, 1
                )
            )
        self.send(
            M.MAVLink_command_long_message(
                self.system_id,
                self.component_id,
                M.MAV_CMD_SET_MESSAGE_INTERVAL,
                0,
                M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
                1e6 / position_hz,
                0,
                0,
                0,
                0,
                0,
            )
        )

    def fire_mode(self, mode: int) -> None:
        """Send a mode change once without waiting (used on exit)."""
        self.send(
            M.MAVLink_command_long_message(
                self.system_id,
                self.component_id,
                M.MAV_CMD_DO_SET_MODE,
                0,
                M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                mode,
                0,
                0,
                0,
                0,
                0,
            )
        )
