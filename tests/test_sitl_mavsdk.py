"""Conformance: MAVSDK (an independent C++ MAVLink implementation; the Python package 4.x
calls it in-process through ctypes) connects to the built-in simulator, uploads and
downloads a mission with the mission_raw plugin and reads telemetry. Ephemeral ports,
bounded time."""

from __future__ import annotations

import asyncio
import socket
import sys
from pathlib import Path
from typing import Any

import pytest

mavsdk = pytest.importorskip("mavsdk")

from mavsdk.asyncio import ComponentType, Configuration, Mavsdk  # noqa: E402
from mavsdk.asyncio.plugins.mission_raw import MissionRawAsync  # noqa: E402
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync  # noqa: E402
from mavsdk.plugins.mission_raw import MissionItem  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
from test_sitl_server import ORIGIN, ServerThread, configs  # noqa: E402

from sitl.server import ServerOptions, SitlServer  # noqa: E402

pytestmark = pytest.mark.timeout(60)


def mission() -> list[Any]:
    points = [
        (0.0, 0.0, 0.0, 16, 0.0),
        (800.0, 0.0, 100.0, 16, 0.0),
        (800.0, 800.0, 100.0, 19, 30.0),
        (0.0, 800.0, 120.0, 17, 0.0),
    ]
    items = []
    for seq, (east, north, alt, cmd, p1) in enumerate(points):
        lat, lon, _ = ORIGIN.to_geodetic(east, north)
        items.append(
            MissionItem(
                seq,
                0 if seq == 0 else 6,
                cmd,
                int(seq == 0),
                1,
                p1,
                0.0,
                -150.0 if cmd == 17 else 0.0,
                0.0,
                round(lat * 1e7),
                round(lon * 1e7),
                alt,
                0,
            )
        )
    return items


async def exercise(url: str) -> dict[str, Any]:
    config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    out: dict[str, Any] = {}
    async with Mavsdk(config) as sdk:
        await sdk.add_any_connection(url)
        system = await sdk.first_autopilot(timeout_s=10.0)
        assert system is not None, "MAVSDK found no autopilot"
        out["sysid"] = await system.get_system_id()
        out["autopilot"] = int(await system.autopilot_type())
        out["vehicle"] = int(await system.vehicle_type())
        raw = MissionRawAsync(system)
        telemetry = TelemetryAsync(system)
        await raw.upload_mission(mission())
        out["download"] = [
            (i.seq, i.command, i.x, i.y, round(i.z), i.param1, i.param3)
            for i in await raw.download_mission()
        ]
        async for pos in telemetry.subscribe_position():
            if pos.latitude_deg == pos.latitude_deg:  # not NaN: a real GLOBAL_POSITION_INT
                out["position"] = (pos.latitude_deg, pos.longitude_deg, pos.relative_altitude_m)
                break
        async for armed in telemetry.subscribe_armed():
            out["armed"] = armed
            break
        async for battery in telemetry.subscribe_battery():
            out["battery_v"] = battery.voltage_v
            break
        async for mode in telemetry.subscribe_flight_mode():
            out["mode"] = int(mode)
            break
    return out


def check(result: dict[str, Any]) -> None:
    assert result["sysid"] == 1
    assert result["autopilot"] == 2 and result["vehicle"] == 2  # ArduPilot, fixed wing
    expected = [(i.seq, i.command, i.x, i.y, round(i.z), i.param1, i.param3) for i in mission()]
    expected[2] = (*expected[2][:6], 1.0)  # LOITER_TIME param3: ArduPlane keeps only the sense
    got = result["download"]
    assert [g[1:] for g in got[1:]] == [e[1:] for e in expected[1:]]
    assert got[0][1] == 16 and abs(got[0][2] - round(78.93e7)) < 10  # item 0: home
    lat, lon, alt = result["position"]
    x, y, _ = ORIGIN.to_local(lat, lon)
    assert abs(alt - 100.0) < 5.0 and 90.0 < (x * x + y * y) ** 0.5 < 130.0
    assert result["armed"] is True and 12.0 < result["battery_v"] < 12.7
    assert result["mode"] == 4  # MISSION (ArduPlane AUTO)


def test_mavsdk_over_tcp() -> None:
    server = SitlServer(
        configs(1, airborne=True, launch_x_m=105.0, launch_y_m=0.0, launch_heading_rad=1.5708),
        ServerOptions(speedup=5.0, base_port=0),
    )
    with ServerThread(server):
        result = asyncio.run(
            asyncio.wait_for(exercise(f"tcpout://127.0.0.1:{server.tcp_ports[0]}"), 40.0)
        )
    check(result)


def test_mavsdk_over_udp_out() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    server = SitlServer(
        configs(1, airborne=True, launch_x_m=105.0, launch_y_m=0.0, launch_heading_rad=1.5708),
        ServerOptions(speedup=5.0, base_port=0, out=("127.0.0.1", port)),
    )
    with ServerThread(server):
        result = asyncio.run(asyncio.wait_for(exercise(f"udpin://127.0.0.1:{port}"), 40.0))
    check(result)
