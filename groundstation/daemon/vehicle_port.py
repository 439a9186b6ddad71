"""Talking to one vehicle: the sans-IO transfer machines driven on the mission clock.

A :class:`VehiclePort` sends the daemon's messages to one system id (through the router)
and runs its exchanges: mission upload / download / set current, COMMAND_LONG with its
COMMAND_ACK, DO_SET_HOME with its COMMAND_ACK and HOME_POSITION, PARAM_SET and
PARAM_REQUEST_READ with their PARAM_VALUE, each one a
:class:`~groundstation.mavlink.mission_transfer.TransferBase` machine. Every timeout is in
mission seconds (``clock.wall_s`` turns a wait into wall time), so at a 50x speed-up the
vehicle sees the same 1.5 s timeouts it would see at 1x.

Rules (docs/protocol.md, "Driving transfers in the daemon"):

* **One owner per exchange.** Only the driver (:meth:`VehiclePort.run`) calls the running
  machine. :meth:`deliver` only queues a message and :meth:`notify_rebooted` only sets a
  flag; both wake the driver, which handles them on its next turn. After every ``await``
  the driver looks again at ``done``, the reboot flag, the queue and the deadline, in that
  order, so nothing reaches a finished machine.
* **A reboot is a flag.** The driver calls ``machine.notify_vehicle_rebooted``, sends what
  it returns and returns the VEHICLE_REBOOTED result (``command()`` returns None,
  ``param_set()`` False, ``param_read()`` None). A reboot seen while no exchange runs is
  forgotten: the next exchange starts against the rebooted vehicle, which is what it must
  talk to.
* **Exchanges are serialised** (an :class:`asyncio.Lock`, first come first served): a
  COMMAND_LONG asked for during an upload waits for the upload's end; it never sees the
  upload's messages. Messages delivered while no exchange runs are dropped.
* The queue of the running exchange is bounded (``queue_size``); when full, the *oldest*
  message is dropped and counted in :attr:`VehiclePort.dropped`: the newest is the one
  that says where the vehicle is now.
* Cancelling a caller's task cancels its exchange politely (the machine's ``cancel``
  actions are sent, e.g. MISSION_ACK OPERATION_CANCELLED) and leaves the port reusable.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
from collections.abc import AsyncIterator, Callable, Sequence
from typing import Any, Protocol

from groundstation.mavlink.codec import MavlinkEncoder, MAVLinkMessage, mavlink2
from groundstation.mavlink.link_budget import (
    MAX_HOLD_S,
    LinkBudget,
    StreamPlan,
    ack_retries,
    stream_plan,
)
from groundstation.mavlink.mission_commands import MissionSetCurrent
from groundstation.mavlink.mission_download import MissionDownload
from groundstation.mavlink.mission_items import MissionItem
from groundstation.mavlink.mission_transfer import (
    Action,
    Finished,
    Send,
    TransferBase,
    TransferResult,
)
from groundstation.mavlink.mission_upload import MissionUpload
from groundstation.mavlink.param_list import ParamList
from groundstation.mavlink.vehicle_commands import CommandLong, HomeSet, ParamRead, ParamSet

__all__ = ["PortClock", "VehiclePort"]

M = mavlink2
QUEUE_SIZE = 512
"""Messages one exchange may have waiting (a few seconds of full-rate telemetry)."""
_IDLE_WAIT_S = 0.5
"""Mission seconds to wait when the machine has no deadline (it always has one while
running; this only bounds a wait should a machine ever lack one)."""
_MIN_WALL_WAIT_S = 0.001
"""Shortest wall-clock wait, so a deadline a rounding error away never spins the loop."""
RATES_REFRESH_CALLS = 4
"""On a constrained link an unchanged stream plan is sent again only every this many
requests (the session asks every ``rates_every_s``): ~16 frames up and 11 COMMAND_ACKs
down each time, on a link that carries ~3 kB/s."""
_HOLD_POLL_S = 0.1
"""Mission seconds between looks at the radio's buffer while an exchange is held."""


class PortClock(Protocol):
    """What the port needs of :class:`~groundstation.daemon.clock.MissionClock`."""

    def now_s(self) -> float: ...

    def wall_s(self, mission_s: float) -> float: ...


class VehiclePort:
    """One vehicle's outgoing messages and exchanges (see the module docstring)."""

    def __init__(
        self,
        system_id: int,
        send_frame: Callable[[int, bytes], bool],
        encoder: MavlinkEncoder,
        clock: PortClock,
        *,
        timeout_s: float = 1.5,
        retries: int = 5,
        component_id: int = 1,
        queue_size: int = QUEUE_SIZE,
        budget: Callable[[], LinkBudget | None] | None = None,
    ) -> None:
        if queue_size < 1:
            raise ValueError(f"queue_size must be >= 1, got {queue_size}")
        self.system_id = system_id
        self.component_id = component_id
        self._send_frame = send_frame
        self.encoder = encoder
        self.clock = clock
        self.timeout_s = timeout_s
        self.retries = retries
        self.queue_size = queue_size
        self._budget = budget or (lambda: None)
        """The budget of the link the vehicle is bound to now (None: unknown, unlimited)."""
        self._lock = asyncio.Lock()
        self._users = 0  # exchanges running or waiting for their turn
        self._inbox: collections.deque[MAVLinkMessage] | None = None  # None: no exchange
        self._reboot_pending = False
        self._wake = asyncio.Event()
        self.sent = 0
        """Frames sent to this vehicle."""
        self._rate_calls = 0
        self._rates_sent: StreamPlan | None = None
        self.dropped = 0
        """Messages dropped because the running exchange's queue was full (oldest first)."""

    @property
    def busy(self) -> bool:
        """True while an exchange runs or waits for its turn."""
        return self._users > 0

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
        """A message of this vehicle arrived (called by the session): queue it, wake the
        driver. Dropped while no exchange runs; when the queue is full the oldest goes."""
        inbox = self._inbox
        if inbox is None:
            return
        if len(inbox) >= self.queue_size:
            inbox.popleft()
            self.dropped += 1
        inbox.append(msg)
        self._wake.set()

    def notify_rebooted(self) -> None:
        """The vehicle rebooted: the running exchange ends with VEHICLE_REBOOTED on the
        driver's next turn. Forgotten when no exchange runs."""
        if self._inbox is None:
            return
        self._reboot_pending = True
        self._wake.set()

    @contextlib.asynccontextmanager
    async def _exchange(self) -> AsyncIterator[None]:
        """Wait for our turn; own the queue and the reboot flag until the exchange ends."""
        self._users += 1
        try:
            async with self._lock:
                self._inbox = collections.deque()
                self._reboot_pending = False
                self._wake.clear()
                try:
                    yield
                finally:
                    self._inbox = None
                    self._reboot_pending = False
        finally:
            self._users -= 1

    def _perform(self, actions: list[Action]) -> TransferResult | None:
        """Send the Send actions; the result of a Finished one, if any."""
        for action in actions:
            if isinstance(action, Send):
                self.send(action.msg)
            elif isinstance(action, Finished):
                return action.result
        return None

    async def _wait(self, deadline_s: float | None) -> None:
        """Sleep until a message or a reboot arrives, or until ``deadline_s`` (mission s)."""
        self._wake.clear()
        if self._inbox or self._reboot_pending:
            return
        wait_s = _IDLE_WAIT_S if deadline_s is None else deadline_s - self.clock.now_s()
        wall_s = max(_MIN_WALL_WAIT_S, self.clock.wall_s(max(0.0, wait_s)))
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(wall_s):
                await self._wake.wait()

    async def run(self, machine: TransferBase[Any], *, safety: bool = False) -> TransferResult:
        """Run ``machine`` to its end, after the exchanges before it (see module docstring).

        A non-safety exchange first waits while the link's radio reports its buffer low
        (:meth:`LinkBudget.congested`, at most ``MAX_HOLD_S``); a safety one (a mode change,
        a home move) never waits for the radio. Cancelling the calling task cancels the
        exchange politely and re-raises.
        """
        async with self._exchange():
            if not safety:
                await self._hold()
            return await self._drive(machine)

    async def _hold(self) -> None:
        """Wait while the link's ground radio says its buffer is low (module docstring)."""
        budget = self._budget()
        if budget is None:
            return
        start_s = now_s = self.clock.now_s()
        while budget.congested(now_s) and now_s - start_s < MAX_HOLD_S:
            await asyncio.sleep(max(_MIN_WALL_WAIT_S, self.clock.wall_s(_HOLD_POLL_S)))
            now_s = self.clock.now_s()
        if now_s > start_s:
            budget.holds += 1
            budget.held_s += now_s - start_s

    def transfer_timeout_s(self) -> float:
        """The per-attempt timeout of a mission transfer now, from the link's measured
        round-trip time (:meth:`LinkBudget.transfer_timeout_s`: the configured
        ``timeout_s`` or a longer RTO; on a constrained link the RTO, at least 0.5 s)."""
        budget = self._budget()
        return self.timeout_s if budget is None else budget.transfer_timeout_s(self.timeout_s)

    async def _drive(self, machine: TransferBase[Any]) -> TransferResult:
        """The one owner of ``machine``: every call to it happens here."""
        try:
            actions = machine.start(self.clock.now_s())
            while True:
                result = self._perform(actions)
                if result is not None:
                    return result
                if machine.done:  # (Finished is always the last action; belt and braces)
                    assert machine.result is not None
                    return machine.result
                now_s = self.clock.now_s()
                deadline_s = machine.next_deadline_s()
                if self._reboot_pending:
                    self._reboot_pending = False
                    actions = machine.notify_vehicle_rebooted(now_s)
                elif self._inbox:
                    actions = machine.receive(self._inbox.popleft(), now_s)
                    if machine.rtt_samples_s:
                        self._feed_rtt(machine.rtt_samples_s)
                elif deadline_s is not None and now_s >= deadline_s:
                    actions = machine.poll(now_s)
                else:
                    await self._wait(deadline_s)
                    actions = []
        except asyncio.CancelledError:
            with contextlib.suppress(Exception):
                self._perform(machine.cancel(self.clock.now_s()))
            raise

    def _ack_retries(self, timeout_s: float) -> int | None:
        """Silent timeouts an upload waits for its final ACK: on a constrained link
        :func:`~groundstation.mavlink.link_budget.ack_retries`; else as many as its other
        waits (None)."""
        return ack_retries(timeout_s) if self._constrained() else None

    def _constrained(self) -> bool:
        """The link has a known capacity (a radio, a serial port, ``--link-rate``): an
        upload resends a lost item itself (:class:`MissionUpload`'s ``resend_items``)."""
        budget = self._budget()
        return budget is not None and budget.capacity_bps is not None

    def _pipeline(self) -> int:
        budget = self._budget()
        return 1 if budget is None else budget.pipeline

    def _feed_rtt(self, samples: list[float]) -> None:
        """Hand the machine's new round-trip samples to the link's estimator."""
        budget = self._budget()
        if budget is not None:
            for rtt_s in samples:
                budget.rtt.sample(rtt_s)
        samples.clear()

    # ------------------------------------------------------------------ missions
    @property
    def _own_system(self) -> int:
        return self.encoder.system_id

    @property
    def _own_component(self) -> int:
        return self.encoder.component_id

    async def upload(
        self, items: Sequence[MissionItem], mission_type: int = M.MAV_MISSION_TYPE_MISSION
    ) -> TransferResult:
        """Upload ``items`` of ``mission_type`` (the mission, or the fence)."""
        timeout_s = self.transfer_timeout_s()
        return await self.run(
            MissionUpload(
                self.system_id,
                self.component_id,
                items,
                mission_type=mission_type,
                timeout_s=timeout_s,
                ack_retries=self._ack_retries(timeout_s),
                resend_items=self._constrained(),
                window=self._pipeline(),
                retries=self.retries,
                own_system=self._own_system,
                own_component=self._own_component,
            )
        )

    async def download(
        self, expect_count: int | None = None, mission_type: int = M.MAV_MISSION_TYPE_MISSION
    ) -> TransferResult:
        """Read the mission (or the fence: ``mission_type``) back; ``expect_count`` (the
        count just uploaded) lets a constrained link ask for the items with the list
        request itself."""
        return await self.run(
            MissionDownload(
                self.system_id,
                self.component_id,
                mission_type=mission_type,
                window=self._pipeline(),
                expect_count=expect_count,
                timeout_s=self.transfer_timeout_s(),
                retries=self.retries,
                own_system=self._own_system,
                own_component=self._own_component,
            )
        )

    async def set_current(self, seq: int, known_current_seq: int | None) -> TransferResult:
        return await self.run(
            MissionSetCurrent(
                self.system_id,
                self.component_id,
                seq,
                known_current_seq=known_current_seq,
                timeout_s=max(1.0, self.transfer_timeout_s() * 2 / 3),
                retries=self.retries,
                own_system=self._own_system,
                own_component=self._own_component,
            )
        )

    # ------------------------------------------------------------------ commands
    async def command(
        self, command: int, params: Sequence[float], timeout_s: float = 1.0, retries: int = 5,
        *, safety: bool = False,
    ) -> int | None:
        """COMMAND_LONG until its COMMAND_ACK: the MAV_RESULT, or None on silence or reboot
        (``safety``: never held for the radio's buffer)."""
        machine = CommandLong(
            self.system_id,
            self.component_id,
            command,
            params,
            timeout_s=timeout_s,
            retries=retries,
            own_system=self._own_system,
        )
        await self.run(machine, safety=safety)
        return machine.ack_result

    async def set_mode(self, mode: int) -> int | None:
        """MAV_CMD_DO_SET_MODE (custom mode); the MAV_RESULT, or None on silence. A safety
        exchange: never held for the radio's buffer."""
        return await self.command(
            M.MAV_CMD_DO_SET_MODE, [M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, mode], safety=True
        )

    async def arm(self) -> int | None:
        return await self.command(M.MAV_CMD_COMPONENT_ARM_DISARM, [1.0], retries=2)

    async def param_set(
        self, name: str, value: float, timeout_s: float = 1.0, retries: int = 5
    ) -> bool:
        """PARAM_SET until PARAM_VALUE echoes ``value``; False on silence or reboot."""
        result = await self.run(
            ParamSet(
                self.system_id,
                self.component_id,
                name,
                value,
                timeout_s=timeout_s,
                retries=retries,
            )
        )
        return result.ok

    async def param_read(
        self, name: str, timeout_s: float = 1.0, retries: int = 2
    ) -> float | None:
        """PARAM_REQUEST_READ by name until its PARAM_VALUE: the value, or None on silence
        (ArduPilot does not answer a name it does not have) or reboot."""
        machine = ParamRead(
            self.system_id,
            self.component_id,
            name,
            timeout_s=timeout_s,
            retries=retries,
            own_system=self._own_system,
        )
        await self.run(machine)
        return machine.value

    async def param_list(self) -> tuple[dict[str, float], TransferResult]:
        """Every parameter (PARAM_REQUEST_LIST, the missing ones re-read by index:
        :class:`ParamList`): what came, and how the download ended. Not a safety
        exchange: it waits while the radio's buffer is low, as a mission does."""
        machine = ParamList(
            self.system_id,
            self.component_id,
            timeout_s=self.transfer_timeout_s(),
            retries=self.retries,
            own_system=self._own_system,
        )
        result = await self.run(machine)
        return machine.values, result

    async def set_home(
        self, lat_deg: float, lon_deg: float, alt_m: float | None, timeout_s: float = 1.0,
        retries: int = 3,
    ) -> tuple[HomeSet, TransferResult]:
        """MAV_CMD_DO_SET_HOME verified by HOME_POSITION (:class:`HomeSet`; ``alt_m`` None:
        keep the vehicle's home altitude): the machine (its confirmed home, error) and its
        result."""
        machine = HomeSet(
            self.system_id,
            self.component_id,
            lat_deg,
            lon_deg,
            alt_m,
            timeout_s=timeout_s,
            retries=retries,
            own_system=self._own_system,
        )
        result = await self.run(machine, safety=True)  # a return's home: never held
        return machine, result

    def request_rates(self, position_hz: float) -> None:
        """Ask for the telemetry the daemon needs (fire and forget; repeated by the session).

        REQUEST_DATA_STREAM for the groups (older autopilots, ArduPilot's SRx), then
        SET_MESSAGE_INTERVAL per message (:func:`~groundstation.mavlink.link_budget.stream_plan`):
        on an unlimited link only the position, which the planner and the camera need most;
        on a constrained one (a radio, a serial port, ``--link-rate``) what floe reads at
        rates within a share of the capacity, and what it does not read off.
        """
        budget = self._budget()
        plan = (stream_plan(position_hz, None) if budget is None
                else budget.streams(position_hz))
        self._rate_calls += 1
        if (budget is not None and budget.capacity_bps is not None
                and plan == self._rates_sent and self._rate_calls % RATES_REFRESH_CALLS):
            return  # a constrained link: the same plan again only every few calls
        self._rates_sent = plan
        for stream_id, rate in plan.groups:
            self.send(
                M.MAVLink_request_data_stream_message(
                    self.system_id, self.component_id, stream_id, rate, 1
                )
            )
        for msg_id, hz in plan.intervals:
            self.send(
                M.MAVLink_command_long_message(
                    self.system_id, self.component_id, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                    msg_id, 1e6 / hz if hz > 0 else -1, 0, 0, 0, 0, 0,
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
