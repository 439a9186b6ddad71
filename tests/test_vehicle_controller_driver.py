"""The session as the controller's driver: real MAVLink messages in, a fake port, fake time.

It runs one exchange at a time, cancels the running one when the controller says so (link
lost), tells the port about a confirmed reboot, and keeps other components' frames out of
the vehicle's state."""

from __future__ import annotations

import asyncio
from typing import Any

from domain.geodesy import GeoOrigin
from groundstation.core import events as ev
from groundstation.daemon.clock import MissionClock
from groundstation.daemon.config import VehicleSettings
from groundstation.daemon.config_parse import parse_config
from groundstation.daemon.session import VehicleSession
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_transfer import TransferCode, TransferResult

M = mavlink2
ORIGIN = GeoOrigin(78.9, 11.9)


def wire(msg: Any, compid: int = 1) -> MAVLinkMessage:
    out = MavlinkDecoder().feed(MavlinkEncoder(1, compid).encode(msg))
    assert len(out) == 1
    return out[0]


class Host:
    origin = ORIGIN

    def __init__(self) -> None:
        self.events: list[ev.Event] = []
        self.lines: list[tuple[str, dict[str, Any]]] = []

    def core_event(self, event: ev.Event) -> None:
        self.events.append(event)

    def journal(self, event: str, **fields: Any) -> None:
        self.lines.append((event, fields))

    def clip(self, x_m: float, y_m: float, loiter_radius_m: float
             ) -> tuple[float, float, bool]:
        return x_m, y_m, False

    def fence(self) -> None:
        return None

    def mission_verified(self, vehicle: str, purpose: str, items: Any) -> None:
        pass

    def params_read(self, vehicle: str, values: Any) -> None:
        pass


class Port:
    """Downloads answer at once; uploads hang until cancelled."""

    def __init__(self) -> None:
        self.busy = False
        self.calls: list[str] = []
        self.cancelled = 0
        self.reboots = 0
        self.delivered: list[MAVLinkMessage] = []

    def deliver(self, msg: MAVLinkMessage) -> None:
        self.delivered.append(msg)

    def notify_rebooted(self) -> None:
        self.reboots += 1

    def request_rates(self, position_hz: float) -> None:
        self.calls.append("rates")

    async def param_read(self, name: str) -> float | None:
        self.calls.append(f"read {name}")
        return 22.0 if name == "AIRSPEED_CRUISE" else None

    async def param_list(self) -> tuple[dict[str, float], TransferResult]:
        self.calls.append("param list")
        return {"AIRSPEED_CRUISE": 22.0}, TransferResult(True, TransferCode.SUCCESS, "ok")

    async def download(self, expect_count: int | None = None, mission_type: int = 0
                       ) -> TransferResult:
        self.calls.append("download")
        return TransferResult(True, TransferCode.SUCCESS, "ok", items=())

    async def upload(self, items: Any, mission_type: int = 0) -> TransferResult:
        self.calls.append("upload")
        try:
            await asyncio.sleep(3600)
        except asyncio.CancelledError:
            self.cancelled += 1
            raise
        raise AssertionError("not reached")


def heartbeat(status: int = M.MAV_STATE_ACTIVE) -> Any:
    return M.MAVLink_heartbeat_message(1, 3, 1 | 128, 10, status, 3)


def position(boot_ms: int) -> Any:
    return M.MAVLink_global_position_int_message(
        boot_ms, 789_000_000, 119_000_000, 105_000, 100_000, 2200, 0, 0, 9000
    )


async def _flying_session(t: list[float]) -> tuple[VehicleSession, Host, Port]:
    host, port = Host(), Port()
    clock = MissionClock(1.0, source=lambda: t[0])
    session = VehicleSession(
        1, "v1", 0, host, parse_config({"vehicles": ["sim:1"]}, {}), VehicleSettings(), port, clock  # type: ignore[arg-type]
    )
    for k in range(8):  # 4 s of telemetry: flying in AUTO
        t[0] = 0.5 * k
        if k % 2 == 0:
            session.on_message(wire(heartbeat()))
            session.on_message(wire(M.MAVLink_mission_current_message(1, 3)))
        session.on_message(wire(position(100_000 + 500 * k)))
        session.check_link(t[0])
    return session, host, port


def test_link_loss_cancels_the_running_exchange() -> None:
    async def main() -> tuple[VehicleSession, Host, Port]:
        t = [0.0]
        session, host, port = await _flying_session(t)
        runner = asyncio.create_task(session.run())
        for _ in range(200):
            await asyncio.sleep(0.005)
            if "upload" in port.calls:
                break
        assert port.calls[:3] == ["rates", "read AIRSPEED_CRUISE", "download"]
        assert "upload" in port.calls
        t[0] = 20.0  # silence: the link is lost
        session.check_link(t[0])
        for _ in range(200):
            await asyncio.sleep(0.005)
            if port.cancelled:
                break
        session.stopping = True
        await asyncio.wait_for(runner, 5.0)
        return session, host, port

    session, host, port = asyncio.run(main())
    assert port.cancelled == 1 and session.link == "lost"
    assert session.status == "connecting"
    assert [e for e, _ in host.lines if e == "link_lost"]


def test_reboot_is_told_to_the_port_and_other_components_are_counted_only() -> None:
    async def main() -> tuple[VehicleSession, Host, Port]:
        t = [4.0]
        session, host, port = await _flying_session(t)
        forged = wire(M.MAVLink_mission_item_reached_message(1), compid=2)
        ack = wire(M.MAVLink_mission_ack_message(245, 190, 0, 0), compid=2)
        delivered = len(port.delivered)
        for _ in range(5):
            session.on_message(forged)
            session.on_message(ack)
        assert session.controller.foreign_frames == 10 and session.telemetry.foreign_messages == 10
        assert len(port.delivered) == delivered  # never to the transfers
        session.on_message(wire(M.MAVLink_mission_ack_message(245, 190, 0, 0)))
        assert len(port.delivered) == delivered + 1  # the autopilot's own
        for k, boot_ms in enumerate((500, 1_000, 1_500)):  # the autopilot restarted
            t[0] = 5.0 + 0.5 * k
            session.on_message(wire(M.MAVLink_system_time_message(0, boot_ms)))
        return session, host, port

    session, host, port = asyncio.run(main())
    assert port.reboots == 1 and [e for e, _ in host.lines if e == "reboot"]
    assert session.status == "connecting"


class RebootingPort(Port):
    """Uploads run until the vehicle is reported rebooted, then end VEHICLE_REBOOTED (a
    result the transfer layer calls retryable), as VehiclePort's do."""

    def __init__(self) -> None:
        super().__init__()
        self.rebooted = asyncio.Event()

    def notify_rebooted(self) -> None:
        super().notify_rebooted()
        self.rebooted.set()

    async def upload(self, items: Any, mission_type: int = 0) -> TransferResult:
        self.calls.append("upload")
        await self.rebooted.wait()
        return TransferResult(False, TransferCode.VEHICLE_REBOOTED, "vehicle rebooted")


def test_an_upload_ended_by_a_reboot_is_not_retried_to_the_rebooted_vehicle() -> None:
    async def main() -> tuple[VehicleSession, Port]:
        t = [0.0]
        session, _, _ = await _flying_session(t)
        port = RebootingPort()
        session.port = port  # type: ignore[assignment]
        runner = asyncio.create_task(session.run())
        for _ in range(400):
            await asyncio.sleep(0.005)
            if "upload" in port.calls:
                break
        assert "upload" in port.calls
        for k, boot_ms in enumerate((500, 1_000, 1_500)):  # the autopilot restarted
            t[0] = 5.0 + 0.5 * k
            session.on_message(wire(M.MAVLink_system_time_message(0, boot_ms)))
        for k in range(40):  # 20 s of mission time, 2 s of wall: the session's retry pause
            t[0] = 7.0 + 0.5 * k  # (1 s, a wall wait at this clock's speed-up 1) has passed
            standby = M.MAVLink_heartbeat_message(1, 3, 1, 0, M.MAV_STATE_STANDBY, 3)
            session.on_message(wire(standby))
            session.on_message(wire(M.MAVLink_system_time_message(0, 1_500 + 500 * (k + 1))))
            session.check_link(t[0])  # the rebooted vehicle talks on: its link stays up
            await asyncio.sleep(0.05)
        session.stopping = True
        await asyncio.wait_for(runner, 5.0)
        return session, port

    session, port = asyncio.run(main())
    assert session.status == "on_ground"  # re-assessed: the rebooted plane sits disarmed
    assert port.reboots == 1
    assert port.calls.count("upload") == 1  # no retry to a vehicle that just rebooted


def test_a_routes_points_are_clipped_into_the_operating_area_with_its_aim() -> None:
    """Every point a pass flies through is moved onto the operating area's edge, as its aim
    point is (a predicted iceberg may drift out of the area before the vehicle gets there)."""
    from groundstation.core.commands import FlyToTarget, ThroughPoint
    from groundstation.vehicle import controller_io

    loiters_m: list[float] = []

    class Edge(Host):
        def clip(self, x_m: float, y_m: float, loiter_radius_m: float
                 ) -> tuple[float, float, bool]:
            loiters_m.append(loiter_radius_m)
            return (min(x_m, 1000.0), y_m, x_m > 1000.0)

    clock = MissionClock(1.0, source=lambda: 5.0)
    session = VehicleSession(
        1, "v1", 0, Edge(), parse_config({"vehicles": ["sim:1"]}, {}), VehicleSettings(),  # type: ignore[arg-type]
        Port(), clock,  # type: ignore[arg-type]
    )  # fmt: skip
    fed: list[Any] = []
    session._feed = fed.append  # type: ignore[method-assign]
    inside = ThroughPoint("C2", 900.0, 50.0)
    command = FlyToTarget(5.0, "v1", "C1", 800.0, 0.0, 0.0, 120.0,
                          through=(inside, ThroughPoint("C3", 1400.0, 100.0)))
    session.command_fly(command)
    (fly,) = fed
    assert isinstance(fly, controller_io.Fly) and fly.clipped
    assert (fly.x_m, fly.y_m) == (800.0, 0.0)
    assert fly.command.through == (inside, ThroughPoint("C3", 1000.0, 100.0))
    # each point clipped with room for the loiter the mission flies (the fence's band)
    assert loiters_m == [120.0] * 3
    session.command_fly(FlyToTarget(6.0, "v1", "C1", 800.0, 0.0, 0.0, 120.0, through=(inside,)))
    assert not fed[-1].clipped and fed[-1].command.through == (inside,)
