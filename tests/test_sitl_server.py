"""Real sockets on 127.0.0.1 (ephemeral ports, high speed-up, bounded time): pymavlink as
a client over UDP and TCP, several vehicles, --wait-for-client, the detection feed."""

from __future__ import annotations

import asyncio
import json
import socket
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
from pymavlink import mavutil

from domain.geodesy import GeoOrigin
from sitl.detections import DetectionSource
from sitl.server import ServerOptions, SitlServer
from sitl.vehicle import VehicleConfig
from world.model import Boat, Camera, Iceberg, World

ORIGIN = GeoOrigin(78.93, 11.92)


class ServerThread:
    """A SitlServer running in its own event loop thread."""

    def __init__(self, server: SitlServer) -> None:
        self.server = server
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._main, daemon=True)
        self.error: BaseException | None = None

    def _main(self) -> None:
        async def body() -> None:
            await self.server.start()
            self.loop = asyncio.get_running_loop()
            self._ready.set()
            try:
                await self.server.run()
            finally:
                await self.server.close()

        try:
            asyncio.run(body())
        except BaseException as exc:  # surfaced by the test
            self.error = exc
            self._ready.set()

    def __enter__(self) -> ServerThread:
        self._thread.start()
        assert self._ready.wait(10.0)
        assert self.error is None, self.error
        return self

    def __exit__(self, *exc: object) -> None:
        self.loop.call_soon_threadsafe(self.server.stop)
        self._thread.join(10.0)
        assert not self._thread.is_alive()


def configs(n: int, **kw: Any) -> list[VehicleConfig]:
    return [
        VehicleConfig(
            system_id=i + 1,
            origin=ORIGIN,
            home_lat_deg=78.93,
            home_lon_deg=11.92,
            fast_boot=True,
            **kw,
        )
        for i in range(n)
    ]


@pytest.fixture
def mav2(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    monkeypatch.setenv("MAVLINK20", "1")
    yield


def udp_client() -> Any:
    conn = mavutil.mavlink_connection(
        "udpin:127.0.0.1:0", dialect="ardupilotmega", source_system=255, source_component=190
    )
    return conn


def wait(conn: Any, kind: str | list[str], timeout_s: float = 10.0, cond: Any = None) -> Any:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        msg = conn.recv_match(type=kind, blocking=True, timeout=0.2)
        if msg is not None and (cond is None or cond(msg)):
            return msg
    raise AssertionError(f"no {kind} within {timeout_s} s")


def test_pymavlink_over_udp_arms_uploads_downloads_and_flies(mav2: None) -> None:
    conn = udp_client()
    port = conn.port.getsockname()[1]
    # 20x, not 40x: the client here answers the simulated ArduPlane's item requests from
    # the test's own thread, and at 40x its 8 s upload timeout is 0.2 wall s, which a
    # starved suite worker missed (MISSION_ACK 15, cancelled)
    server = SitlServer(
        configs(1), ServerOptions(speedup=20.0, base_port=0, out=("127.0.0.1", port))
    )
    with ServerThread(server):
        hb = wait(conn, "HEARTBEAT")
        assert hb.get_srcSystem() == 1 and hb.type == 1 and hb.autopilot == 3
        conn.target_system, conn.target_component = 1, 1
        wait(conn, "SYS_STATUS", cond=lambda m: m.onboard_control_sensors_health & 0x10000000)
        conn.mav.command_long_send(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)
        assert wait(conn, "COMMAND_ACK", cond=lambda m: m.command == 400).result == 0
        lat1, lon1, _ = ORIGIN.to_geodetic(800, 0)
        lat2, lon2, _ = ORIGIN.to_geodetic(800, 800)
        items = [
            (16, 0.0, 78.93, 11.92, 0.0),
            (22, 10.0, 0.0, 0.0, 60.0),
            (16, 0.0, lat1, lon1, 80.0),
            (19, 20.0, lat2, lon2, 80.0),
            (17, 0.0, lat2, lon2, 80.0),
        ]
        conn.mav.mission_count_send(1, 1, len(items), 0)
        for _ in items:
            req = wait(conn, "MISSION_REQUEST")  # ArduPlane asks with MISSION_REQUEST
            cmd, p1, lat, lon, alt = items[req.seq]
            conn.mav.mission_item_int_send(
                1, 1, req.seq, 6, cmd, 0, 1, p1, 0, 0, 0, round(lat * 1e7), round(lon * 1e7), alt, 0
            )
        assert wait(conn, "MISSION_ACK").type == 0
        conn.mav.mission_request_list_send(1, 1, 0)
        assert wait(conn, "MISSION_COUNT").count == len(items)
        conn.mav.mission_request_int_send(1, 1, 3, 0)
        got = wait(conn, "MISSION_ITEM_INT")
        assert (got.seq, got.command, got.param1) == (3, 19, 20.0)
        conn.mav.command_long_send(1, 1, 176, 0, 1, 10, 0, 0, 0, 0, 0)
        reached: list[int] = []
        texts: list[str] = []
        currents: list[int] = []
        end = time.monotonic() + 40.0  # bounds a run that never gets there
        while time.monotonic() < end and not ("Mission: 4 LoitUnlim" in texts and 4 in currents):
            msg = conn.recv_match(
                type=["MISSION_ITEM_REACHED", "STATUSTEXT", "MISSION_CURRENT"],
                blocking=True,
                timeout=0.2,
            )
            if msg is None:
                continue
            if msg.get_type() == "MISSION_ITEM_REACHED":
                reached.append(msg.seq)
            elif msg.get_type() == "STATUSTEXT":
                texts.append(msg.text)
            else:
                currents.append(msg.seq)
        assert reached == [1, 2, 3]
        assert "Loiter time complete" in texts and "Mission: 4 LoitUnlim" in texts
        # MISSION_CURRENT frames sent before the mode change (seq 0, as ArduPlane reports
        # before AUTO) may still be queued when a loaded machine reads on; after them the
        # current item only moves forward, through every item.
        started = currents[next((k for k, c in enumerate(currents) if c != 0), len(currents)):]
        assert started and started[-1] == 4 and sorted(set(started)) == [1, 2, 3, 4]
        assert started == sorted(started)
    conn.close()
    assert server.vehicles()[0].handler_errors == 0


def test_tcp_per_vehicle_with_distinct_system_ids(mav2: None) -> None:
    server = SitlServer(configs(3), ServerOptions(speedup=20.0, base_port=0))
    with ServerThread(server):
        ports = server.tcp_ports
        assert len(set(ports)) == 3
        for i, port in enumerate(ports):
            conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", dialect="ardupilotmega")
            assert wait(conn, "HEARTBEAT").get_srcSystem() == i + 1
            conn.close()


def test_base_port_layout_is_base_plus_10i() -> None:
    """Vehicle i listens on base + 10 i. The base is a probed free port; another process may
    take it (or base + 10) before the server binds, so a taken port means another probe
    (at most 5), never a skipped check."""
    for _attempt in range(5):
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            base = probe.getsockname()[1]
        if base > 60000:
            base -= 1000
        server = SitlServer(configs(2), ServerOptions(speedup=5.0, base_port=base))
        try:
            with ServerThread(server):
                assert server.tcp_ports == [base, base + 10]
                return
        except AssertionError as exc:
            if "Address already in use" not in str(exc):
                raise
    pytest.fail("5 probed base ports were all taken before the server bound them")


def test_wait_for_client_boots_on_connect(mav2: None) -> None:
    server = SitlServer(configs(1), ServerOptions(speedup=20.0, base_port=0, wait_for_client=True))
    with ServerThread(server):
        time.sleep(0.3)  # 6 simulated seconds pass with nobody connected
        assert server.vehicles() == []
        conn = mavutil.mavlink_connection(
            f"tcp:127.0.0.1:{server.tcp_ports[0]}", dialect="ardupilotmega"
        )
        gp = wait(conn, "GLOBAL_POSITION_INT")
        assert gp.time_boot_ms < 3000  # booted at connection, not at server start
        conn.close()


def test_garbage_over_tcp_does_not_break_the_vehicle(mav2: None) -> None:
    server = SitlServer(configs(1), ServerOptions(speedup=20.0, base_port=0))
    with ServerThread(server):
        with socket.create_connection(("127.0.0.1", server.tcp_ports[0]), timeout=5) as s:
            s.sendall(bytes(range(256)) * 20 + b"\xfd\x09\x00\x00" + b"\x00" * 30)
        conn = mavutil.mavlink_connection(
            f"tcp:127.0.0.1:{server.tcp_ports[0]}", dialect="ardupilotmega"
        )
        wait(conn, "HEARTBEAT")
        conn.close()


def test_detection_feed_over_udp() -> None:
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(5.0)
    world = World(
        [Iceberg("A", 100.0, 0.0, 0.0, 0.0)],
        Boat(500.0, 0.0, 0.0, 10.0),
        Camera(150.0, 2.0, 4.0),
        __import__("numpy").random.default_rng(1),
    )
    feed = DetectionSource(world, ORIGIN)
    cfg = configs(1, airborne=True, launch_x_m=0.0, launch_y_m=0.0)
    server = SitlServer(
        cfg, ServerOptions(speedup=20.0, base_port=0, feed_address=rx.getsockname()), feed=feed
    )
    kinds: dict[str, dict[str, Any]] = {}
    with ServerThread(server):
        end = time.monotonic() + 10.0
        while time.monotonic() < end and len(kinds) < 2:
            line = json.loads(rx.recv(4096))
            kinds.setdefault(line["kind"], line)
    rx.close()
    det = kinds["detection"]
    assert det["v"] == 1 and det["vehicle"] == 1 and det["target"] == "A"
    x, y, _ = ORIGIN.to_local(det["lat_deg"], det["lon_deg"])
    assert abs(x - 100.0) < 15 and abs(y) < 15 and det["sigma_m"] == pytest.approx(2.0)
    assert kinds["boat"]["vehicle"] is None


def test_camera_link_reads_positions_like_from_sitl_serial1(mav2: None) -> None:
    from sitl.ardupilot import CameraLink

    server = SitlServer(
        configs(1, airborne=True, launch_x_m=105.0, launch_y_m=0.0),
        ServerOptions(speedup=10.0, base_port=0),
    )
    with ServerThread(server):
        camera = CameraLink(1, "127.0.0.1", server.tcp_ports[0], ORIGIN)

        async def read() -> tuple[float, float] | None:
            task = asyncio.create_task(camera.run())
            for _ in range(100):
                await asyncio.sleep(0.05)
                if camera.position is not None:
                    break
            task.cancel()
            return camera.position

        pos = asyncio.run(read())
    assert pos is not None and camera.airborne
    assert 80.0 < (pos[0] ** 2 + pos[1] ** 2) ** 0.5 < 130.0


def test_timestamps_follow_the_speedup(mav2: None) -> None:
    server = SitlServer(configs(1), ServerOptions(speedup=20.0, base_port=0))
    samples: list[tuple[float, Any]] = []
    with ServerThread(server):
        conn = mavutil.mavlink_connection(
            f"tcp:127.0.0.1:{server.tcp_ports[0]}", dialect="ardupilotmega"
        )
        wait(conn, "SYSTEM_TIME")
        end = time.monotonic() + 1.5
        while time.monotonic() < end:  # read continuously: receive time ~ send time
            msg = conn.recv_match(type="SYSTEM_TIME", blocking=True, timeout=0.1)
            if msg is not None:
                samples.append((time.monotonic(), msg))
        conn.close()
    (w0, first), (w1, last) = samples[0], samples[-1]
    rate = (last.time_boot_ms - first.time_boot_ms) / 1000.0 / (w1 - w0)
    assert 14.0 < rate < 26.0  # simulated seconds per wall second, 20 requested
    assert len(samples) >= 20  # 1 Hz of simulated time = ~20 per wall second
    unix_ms = (last.time_unix_usec - first.time_unix_usec) / 1000
    assert abs(unix_ms - (last.time_boot_ms - first.time_boot_ms)) < 2


def test_answers_go_to_the_requesting_link_only(mav2: None) -> None:
    server = SitlServer(configs(1), ServerOptions(speedup=10.0, base_port=0))
    with ServerThread(server):
        port = server.tcp_ports[0]
        a = mavutil.mavlink_connection(
            f"tcp:127.0.0.1:{port}", dialect="ardupilotmega", source_system=255
        )
        b = mavutil.mavlink_connection(
            f"tcp:127.0.0.1:{port}", dialect="ardupilotmega", source_system=254
        )
        wait(a, "HEARTBEAT")
        wait(b, "HEARTBEAT")
        a.mav.command_long_send(1, 1, 31999, 0, 0, 0, 0, 0, 0, 0, 0)
        assert wait(a, "COMMAND_ACK").command == 31999
        assert b.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.5) is None
        assert wait(b, "HEARTBEAT")  # b still gets the telemetry
        a.close()
        b.close()


def test_downlink_loss_and_link_drop_through_the_server(mav2: None) -> None:
    from sitl.faults import FaultEvent, VehicleFaults

    lossy = VehicleFaults(1)
    lossy.down.loss = 1.0
    dropped = VehicleFaults(2)
    dropped.add_event(FaultEvent(0.0, "drop", duration_s=1e9))
    server = SitlServer(
        configs(3), ServerOptions(speedup=20.0, base_port=0), faults={1: lossy, 2: dropped}
    )
    with ServerThread(server):
        conns = [
            mavutil.mavlink_connection(f"tcp:127.0.0.1:{p}", dialect="ardupilotmega")
            for p in server.tcp_ports
        ]
        assert wait(conns[2], "HEARTBEAT").get_srcSystem() == 3  # the healthy one talks
        for conn in conns[:2]:
            assert conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5) is None
        for conn in conns:
            conn.close()


def test_run_ends_on_its_duration_even_when_a_tick_comes_late() -> None:
    """``gcs sitl --duration 10 --speedup 50`` on a starved host stopped after 11.3
    simulated s: a late tick may advance up to speedup x 0.1 s at once (5 s here), and the
    last one ran past the duration. The last tick now ends on it."""
    server = SitlServer(configs(1), ServerOptions(speedup=50.0, base_port=0))
    server._last_wall = time.monotonic() - 10.0  # the host did not run it for 10 wall s
    asyncio.run(asyncio.wait_for(server.run(3.0), 30.0))
    assert server.t_s == 3.0
