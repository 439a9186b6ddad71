"""One vehicle's session: the driver of its :class:`~groundstation.vehicle.controller.
VehicleController`.

The policy (join, park, launch, override, take-back, reboot, link restore, battery,
progress, the guard on commands) lives in the sans-IO controller; the session only carries
it out. Every message of the vehicle's system goes to the telemetry reducer; a message of
the autopilot component whose HEARTBEAT created the session goes to the vehicle port (the
transfers) and is fed to the controller as a ``Frame``; one of another component only as
a ``ForeignFrame`` (counted, ignored). The session runs the ONE exchange the controller
asks for at a time through the :class:`~groundstation.daemon.vehicle_port.VehiclePort`
(in a task, so a ``CancelExchange`` cancels it politely) and feeds the result back; it
journals, warns and hands core events to the daemon as the controller says.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import dataclasses
import logging
import math
from collections.abc import Callable, Sequence
from typing import Any, Protocol

from domain.errors import LocalProtocolError
from domain.geodesy import GeoOrigin
from groundstation.core import events as ev
from groundstation.core.commands import FlyToTarget
from groundstation.core.config import WatchConfig
from groundstation.daemon.clock import MissionClock
from groundstation.daemon.config import DaemonConfig, VehicleSettings, controller_settings
from groundstation.daemon.vehicle_port import VehiclePort
from groundstation.mavlink.codec import MAVLinkMessage, mavlink2
from groundstation.mavlink.fence_items import FenceCircle, build_fence_items, compare_fence
from groundstation.mavlink.mission_items import MissionItem, build_mission_items
from groundstation.mavlink.mission_verify import ItemMismatch, compare_missions
from groundstation.mavlink.telemetry import VehicleSnapshot, VehicleTelemetry
from groundstation.vehicle import controller_io
from groundstation.vehicle.controller import FlyRecord, VehicleController
from groundstation.vehicle.state import LinkState, VehicleState

__all__ = ["FlyRecord", "SessionHost", "VehicleSession"]

log = logging.getLogger(__name__)
M = mavlink2
TRACK_EVERY_S = 5.0


class SessionHost(Protocol):
    """What a session needs from the daemon."""

    @property
    def origin(self) -> GeoOrigin: ...

    def core_event(self, event: ev.Event) -> object: ...

    def journal(self, event: str, *, logged: bool = False, **fields: Any) -> None: ...

    def clip(self, x_m: float, y_m: float, loiter_radius_m: float
             ) -> tuple[float, float, bool]:
        """The waypoint inside the operating area, a loiter's room inside the fence."""
        ...

    def fence(self) -> FenceCircle | None:
        """The operating area's geofence now (None: no area)."""
        ...

    def mission_verified(self, vehicle: str, purpose: str,
                         items: Sequence[MissionItem]) -> None:
        """A mission was uploaded and verified by read-back (its WPL file is written)."""
        ...

    def params_read(self, vehicle: str, values: dict[str, float]) -> None:
        """The vehicle's parameters, read once (its ``.parm`` snapshot is written)."""
        ...


class VehicleSession:
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
        component_id: int = 1,
        planned_speed_m_s: float | None = None,
        watch: WatchConfig | None = None,
    ) -> None:
        self.system_id = system_id
        self.component_id = component_id
        self.id = name
        self.index = index
        self.host = host
        self.config = config
        self.settings = settings
        self.port = port
        self.clock = clock
        self.controller = VehicleController(
            name, system_id,
            controller_settings(config, settings, index, planned_speed_m_s, watch),
        )
        self.telemetry = VehicleTelemetry(
            system_id, host.origin, battery_low_pct=config.fleet.battery.low_pct,
            component_id=component_id,
        )  # fmt: skip
        self.alt_m = self.controller.alt_m
        self.track: collections.deque[tuple[float, float]] = collections.deque(maxlen=60)
        self._last_track_s = -math.inf
        self._wake = asyncio.Event()
        self._exchanges: collections.deque[controller_io.Exchange] = collections.deque()
        self._exchange_task: asyncio.Task[Any] | None = None
        self._fence_given: FenceCircle | None = None

    # ------------------------------------------------------------------ reading
    @property
    def snapshot(self) -> VehicleSnapshot:
        return self.telemetry.snapshot()

    @property
    def state(self) -> VehicleState:
        return self.controller.state

    @property
    def status(self) -> str:
        """The state as the journal and the status table spell it."""
        return self.controller.status

    @property
    def link(self) -> LinkState:
        return self.controller.link

    @property
    def telemetry_age_s(self) -> float | None:
        """How old its newest position is, against its own clock (None: not known)."""
        return self.controller.telemetry_age_s

    @property
    def lagging(self) -> bool:
        """Its frames arrive but its newest position is too old (planned from a prediction)."""
        return self.controller.lagging

    def prediction(self) -> dict[str, float] | None:
        """Where it is predicted to be while its fix is stale (the API's ``prediction``)."""
        p = self.controller.prediction()
        return None if p is None else {"x_m": p.x_m, "y_m": p.y_m, "sigma_m": p.sigma_m,
                                       "fix_age_s": p.fix_age_s}

    @property
    def fly(self) -> FlyRecord | None:
        return self.controller.fly

    @property
    def shown_fly(self) -> FlyRecord | None:
        """The mission floe has the vehicle fly, for the operator's views (API, page,
        console): only while floe flies it, not once it is released, taken over or sent
        home (its last mission is kept in :attr:`fly` for the controller)."""
        return self.fly if self.state in (VehicleState.ACTIVE, VehicleState.JOINING) else None

    @property
    def launch_held(self) -> str | None:
        """Why floe will not launch it on its own (it came down after it flew), or None."""
        return self.controller.launch_held

    @property
    def uploads_ok(self) -> int:
        return self.controller.uploads_ok

    @property
    def uploads_failed(self) -> int:
        return self.controller.uploads_failed

    @property
    def upload_retries(self) -> int:
        return self.controller.upload_retries

    @property
    def upload_delays_s(self) -> list[float]:
        return self.controller.upload_delays_s

    @property
    def commanded(self) -> bool:
        return self.controller.commanded

    @property
    def stopping(self) -> bool:
        return self.controller.stopping

    @stopping.setter
    def stopping(self, value: bool) -> None:
        if value and not self.controller.stopping:
            self._feed(controller_io.Stop(self.clock.now_s()))

    def flying(self) -> bool:
        """Sustained evidence that the vehicle flies (the controller's rule)."""
        return self.controller.flying()

    def wake(self) -> None:
        self._wake.set()

    # ------------------------------------------------------------------ in
    def on_message(self, msg: MAVLinkMessage) -> None:
        """Every message of this vehicle's system (on the event loop, from the router)."""
        t_s = self.clock.now_s()
        before = self.telemetry.messages
        foreign_before = self.telemetry.foreign_messages
        events = self.telemetry.receive(msg, t_s)
        kind = msg.get_type()
        if self.telemetry.foreign_messages != foreign_before:
            # another component of the system: counted; it never reaches the transfers
            # (a flood of them would push the autopilot's answers out of the port's queue)
            self._feed(controller_io.ForeignFrame(t_s, kind, int(msg.get_srcComponent())))
            return
        self.port.deliver(msg)
        if self.telemetry.messages != before:
            snap = self.telemetry.snapshot()
            boot_ms = getattr(msg, "time_boot_ms", None)
            clock = boot_ms if isinstance(boot_ms, int) and not isinstance(boot_ms, bool) else None
            self._feed(controller_io.AutopilotFrame(t_s, kind, snap, tuple(events), clock))
        if kind == "GLOBAL_POSITION_INT":
            s = self.snapshot
            due = t_s - self._last_track_s >= TRACK_EVERY_S
            if s.x_m is not None and s.y_m is not None and due:
                self.track.append((s.x_m, s.y_m))
                self._last_track_s = t_s

    def command_fly(self, command: FlyToTarget) -> None:
        """Core said: fly to a target (clipped into the operating area here: its aim point
        and every point of the route it flies through)."""
        loiter_m = self.controller.loiter_radius_m(command.loiter_radius_m)
        x_m, y_m, clipped = self.host.clip(command.x_m, command.y_m, loiter_m)
        through = []
        for point in command.through:
            px_m, py_m, moved = self.host.clip(point.x_m, point.y_m, loiter_m)
            through.append(dataclasses.replace(point, x_m=px_m, y_m=py_m) if moved else point)
            clipped = clipped or moved
        if tuple(through) != command.through:
            command = dataclasses.replace(command, through=tuple(through))
        self._feed(controller_io.Fly(self.clock.now_s(), command, x_m, y_m, clipped))

    def release(self, reason: str, home: bool = False) -> None:
        """Core said: stop commanding (ReleaseVehicle) or go home (SendHome)."""
        self._feed(controller_io.Release(self.clock.now_s(), reason, home))

    def set_home(self, x_m: float, y_m: float) -> None:
        """Core said: move the home (SetHome; sent to any vehicle in the air, whoever has it)."""
        self._feed(controller_io.NewHome(self.clock.now_s(), x_m, y_m))

    def want_launch(self, reason: str, relieves: str | None) -> None:
        """Core said: launch this spare (LaunchVehicle): with --launch floe does, else the
        operator is asked."""
        self._feed(controller_io.LaunchWanted(self.clock.now_s(), reason, relieves))

    @property
    def launch_wanted(self) -> dict[str, Any] | None:
        """The core's pending launch order (the API's ``launch_wanted``), until it flies."""
        order = self.controller.launch_wanted
        return None if order is None else {"reason": order.reason, "relieves": order.relieves}

    def request_launch(self) -> tuple[bool, str]:
        ok, error = self.controller.launch()
        self._carry_out(self.controller.take_outputs())
        return ok, error

    def operator_action(self, t_s: float, action: str) -> tuple[bool, str]:
        """An operator's ``release``, ``rtl`` or ``resume`` through the control API:
        ``(ok, what happened)`` (``VehicleController.operator_*``)."""
        c = self.controller
        if action == "release":
            answer = c.operator_release(t_s, "api")
        elif action == "rtl":
            answer = c.operator_rtl(t_s, "api rtl")
        elif action == "resume":
            answer = c.operator_resume(t_s, "api")
        else:
            raise ValueError(f"unknown operator action {action!r}")
        self._carry_out(c.take_outputs())
        return answer

    def override(self, t_s: float, reason: str) -> None:
        self.controller.override(t_s, reason)
        self._carry_out(self.controller.take_outputs())

    def check_link(self, t_s: float) -> None:
        """Housekeeping from the daemon's ticker: flush incomplete STATUSTEXTs, let time
        pass for the controller (link, overrides, progress, retries)."""
        if self.snapshot.last_heard_s is None:
            return
        events = self.telemetry.tick(t_s)
        if events:
            self._feed(controller_io.AutopilotFrame(t_s, "", self.snapshot, tuple(events)))
        fence = self.host.fence()
        if fence != self._fence_given:  # the area's fence now (the controller decides)
            self._fence_given = fence
            self._feed(controller_io.FenceWanted(t_s, fence))
        self._feed(controller_io.TimePassed(t_s))

    # ------------------------------------------------------------------ out
    def _feed(self, inp: controller_io.Input) -> None:
        self._carry_out(self.controller.handle(inp))

    def _carry_out(self, outputs: list[controller_io.Output]) -> None:
        for out in outputs:
            if isinstance(out, controller_io.JournalLine):
                self.host.journal(out.event, vehicle=self.id, logged=out.logged, **out.fields)
            elif isinstance(out, controller_io.CoreEvent):
                self.host.core_event(out.event)
            elif isinstance(out, controller_io.Warn):
                log.warning("%s", out.text)
            elif isinstance(out, controller_io.RequestRates):
                self.port.request_rates(out.position_hz)
            elif isinstance(out, controller_io.NotifyRebooted):
                self.port.notify_rebooted()
            elif isinstance(out, controller_io.ParamsRead):
                self.host.params_read(self.id, out.values)
            elif isinstance(out, controller_io.CancelExchange):
                if self._exchange_task is not None:
                    self._exchange_task.cancel()
            else:
                self._exchanges.append(out)
                self._wake.set()

    # ------------------------------------------------------------------ the worker
    async def run(self) -> None:
        """The session's task: let time pass for the controller, run its exchanges."""
        while True:
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(0.2):
                    await self._wake.wait()
            self._wake.clear()
            await self.step()
            if self.stopping and not self._exchanges:
                return

    async def step(self) -> None:
        self._feed(controller_io.TimePassed(self.clock.now_s()))
        while self._exchanges:
            request = self._exchanges.popleft()
            if not self.controller.wants(request):  # its job ended while it was queued
                self._feed(controller_io.ExchangeDone(self.clock.now_s(), request, None))
                continue
            task = asyncio.ensure_future(self._exchange(request))
            self._exchange_task = task
            result: Any = None
            try:
                result = await asyncio.shield(task)
            except asyncio.CancelledError:
                if not task.cancelled():
                    task.cancel()
                    raise  # the session itself is cancelled
            finally:
                self._exchange_task = None
            self._feed(controller_io.ExchangeDone(self.clock.now_s(), request, result))

    async def _exchange(self, request: controller_io.Exchange) -> Any:
        port = self.port
        if isinstance(request, controller_io.UploadMission):
            return await self._upload_verified(request)
        if isinstance(request, controller_io.UploadFence):
            return await self._upload_fence(request)
        if isinstance(request, controller_io.Download):
            return await port.download()
        if isinstance(request, controller_io.SetCurrent):
            return await port.set_current(request.seq, request.known_current_seq)
        if isinstance(request, controller_io.SetMode):
            return await port.set_mode(int(request.mode))
        if isinstance(request, controller_io.Arm):
            return await port.arm()
        if isinstance(request, controller_io.ReadParam):
            return await port.param_read(request.name)
        if isinstance(request, controller_io.ReadAllParams):
            return await port.param_list()
        if isinstance(request, controller_io.MoveHome):
            return await self._move_home(request)
        return await port.param_set(request.name, request.value)

    async def _move_home(self, request: controller_io.MoveHome) -> controller_io.HomeOutcome:
        """DO_SET_HOME at the local point, at the altitude of the vehicle's current home
        (its HOME_POSITION; asked for first when not known), verified by HOME_POSITION."""
        origin = self.host.origin
        lat_deg, lon_deg, _ = origin.to_geodetic(request.x_m, request.y_m)
        home = self.snapshot.home
        try:
            machine, result = await self.port.set_home(lat_deg, lon_deg,
                                                       None if home is None else home[2])
        except LocalProtocolError as exc:  # not a position the vehicle can be sent
            return controller_io.HomeOutcome(False, error=str(exc))
        if not result.ok or machine.home is None:
            return controller_io.HomeOutcome(False, error_m=machine.error_m,
                                             retries=result.retries_used, error=result.message)
        x_m, y_m, _ = origin.to_local(machine.home[0], machine.home[1])
        return controller_io.HomeOutcome(True, x_m, y_m, machine.error_m, result.retries_used)

    async def _upload_verified(
        self, request: controller_io.UploadMission
    ) -> controller_io.UploadOutcome:
        """Upload then read back until they match (transfer mechanics, no policy); a
        verified mission is handed to the host (its WPL file)."""
        try:
            items = build_mission_items(list(request.steps), self.host.origin)
        except ValueError as exc:
            return controller_io.UploadOutcome(False, 0, str(exc), 0)
        outcome = await self._transfer_verified(request, items, M.MAV_MISSION_TYPE_MISSION,
                                                compare_missions)
        if outcome.ok:
            self.host.mission_verified(self.id, request.purpose, items)
        return outcome

    async def _upload_fence(self, request: controller_io.UploadFence
                            ) -> controller_io.UploadOutcome:
        """The fence items (mission type FENCE) through the same verified transfer."""
        try:
            items = build_fence_items(request.fence, self.host.origin)
        except ValueError as exc:
            return controller_io.UploadOutcome(False, 0, str(exc), 0)
        return await self._transfer_verified(request, items, M.MAV_MISSION_TYPE_FENCE,
                                             compare_fence)

    async def _transfer_verified(
        self,
        request: controller_io.Exchange,
        items: list[MissionItem],
        mission_type: int,
        compare: Callable[[Sequence[MissionItem], Sequence[MissionItem]], list[ItemMismatch]],
    ) -> controller_io.UploadOutcome:
        """Upload ``items`` of ``mission_type``, read them back and ``compare``, up to the
        transfer retries; stops as soon as the controller no longer wants ``request``."""
        t0_s = self.clock.now_s()
        retries = 0
        last = ""
        for attempt in range(self.config.links.transfer_retries + 1):
            if attempt:
                retries += 1
                await asyncio.sleep(self.clock.wall_s(self.controller.s.retry_pause_s))
            if not self.controller.wants(request):  # aborted (reboot, release...): stop
                return controller_io.UploadOutcome(False, retries, "no longer wanted", len(items))
            up = await self.port.upload(items, mission_type)
            retries += up.retries_used
            if not up.ok and not up.maybe_stored:
                last = f"upload {up.code.value}: {up.message}"
                if not up.retryable:
                    break
                continue
            if not self.controller.wants(request):
                return controller_io.UploadOutcome(False, retries, "no longer wanted", len(items))
            down = await self.port.download(expect_count=len(items), mission_type=mission_type)
            retries += down.retries_used
            if not down.ok or down.items is None:
                last = f"download {down.code.value}: {down.message}"
                continue
            diff = compare(items, down.items)
            if diff:
                last = f"verify: {diff[0]}"
                continue
            return controller_io.UploadOutcome(True, retries, None, len(items),
                                               self.clock.now_s() - t0_s)
        return controller_io.UploadOutcome(False, retries, last, len(items),
                                           self.clock.now_s() - t0_s)
