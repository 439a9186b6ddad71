"""`gcs run --out` follows MAVProxy's --out: udp:/udpout: send, udpin: listens, tcpin: serves.

QGroundControl listens on UDP 14550 and MAVProxy (`--master udpin:0.0.0.0:14551`) on 14551,
so `--out udp:127.0.0.1:14550` must *send* there; here a UDP socket bound on an ephemeral
port plays the listening ground station. `--vehicles udp:` keeps pymavlink's meaning
(listen).
"""

from __future__ import annotations

import asyncio
import socket
from pathlib import Path
from typing import Any

import pytest

from groundstation.commands.run import build_config, run_daemon
from groundstation.daemon.daemon import Daemon
from groundstation.link import (
    LinkKind,
    LinkUrlError,
    describe_out_link,
    parse_link_url,
    parse_out_url,
)
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, mavlink2


def test_out_urls_read_as_mavproxy_and_vehicle_urls_unchanged() -> None:
    assert parse_out_url("udp:127.0.0.1:14550").kind is LinkKind.UDP_OUT
    assert parse_out_url("udp:127.0.0.1:14550").canonical == "udpout:127.0.0.1:14550"
    assert parse_out_url("udp:127.0.0.1:14550").url == "udp:127.0.0.1:14550"
    assert parse_out_url("UDP://127.0.0.1:14551").kind is LinkKind.UDP_OUT
    assert parse_out_url("udpout:127.0.0.1:14550").kind is LinkKind.UDP_OUT
    assert parse_out_url("udpin:0.0.0.0:14550").kind is LinkKind.UDP_IN
    assert parse_out_url("tcpin:0.0.0.0:5763").kind is LinkKind.TCP_SERVER
    assert parse_out_url("tcp:127.0.0.1:5763").kind is LinkKind.TCP_CLIENT
    # --vehicles udp: still listens (pymavlink's --master, docs/links.md)
    assert parse_link_url("udp:0.0.0.0:14550").kind is LinkKind.UDP_IN
    with pytest.raises(LinkUrlError, match="missing host"):
        parse_out_url("udp::14550")  # sending needs a host
    assert describe_out_link(parse_out_url("udp:127.0.0.1:14550")).startswith(
        "sends UDP to 127.0.0.1:14550"
    )
    assert describe_out_link(parse_out_url("udpin:0.0.0.0:14550")).startswith(
        "listens on UDP 0.0.0.0:14550"
    )
    assert describe_out_link(parse_out_url("tcpin:0.0.0.0:5763")).startswith(
        "serves TCP on 0.0.0.0:5763"
    )


class _Collector(asyncio.DatagramProtocol):
    def __init__(self) -> None:
        self.decoder = MavlinkDecoder()
        self.messages: list[Any] = []
        self.transport: Any = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport

    def datagram_received(self, data: bytes, addr: tuple[Any, ...]) -> None:
        self.messages.extend(self.decoder.feed(data))

    def heartbeats(self, system_id: int) -> list[Any]:
        return [
            m
            for m in self.messages
            if m.get_type() == "HEARTBEAT"
            and m.get_srcSystem() == system_id
            and m.autopilot == mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA
        ]


def _args(tmp_path: Path, *out: str) -> list[str]:
    return [
        "--vehicles", "sim:1", "--sim-airborne", "--speedup", "20", "--duration", "15",
        "--scenario", "none", "--run-dir", str(tmp_path), "--http", "off",
        "--detections", "off", "--status", "quiet", "--out", *out,
    ]  # fmt: skip


@pytest.mark.timeout(60)
def test_out_udp_and_udpout_send_heartbeats_to_a_listening_socket(tmp_path: Path) -> None:
    """Two ground stations listening (QGroundControl's and MAVProxy's habit): both get
    the vehicle's heartbeats without ever sending anything; a start line names each."""
    lines: list[str] = []

    async def main() -> tuple[_Collector, _Collector, Daemon]:
        loop = asyncio.get_running_loop()
        qgc_t, qgc = await loop.create_datagram_endpoint(_Collector, local_addr=("127.0.0.1", 0))
        mp_t, mavproxy = await loop.create_datagram_endpoint(
            _Collector, local_addr=("127.0.0.1", 0)
        )
        try:
            qgc_port = qgc_t.get_extra_info("sockname")[1]
            mp_port = mp_t.get_extra_info("sockname")[1]
            config = build_config(
                _args(tmp_path, f"udp:127.0.0.1:{qgc_port}", f"udpout:127.0.0.1:{mp_port}")
            )
            daemon = await run_daemon(config, print_fn=lines.append, install_signals=False)
            return qgc, mavproxy, daemon
        finally:
            qgc_t.close()
            mp_t.close()

    qgc, mavproxy, daemon = asyncio.run(asyncio.wait_for(main(), 50.0))
    assert daemon.internal_error is None
    # 15 mission s at 1 Hz: each listener heard the vehicle's own heartbeats
    assert len(qgc.heartbeats(1)) >= 5, qgc.messages[:5]
    assert len(mavproxy.heartbeats(1)) >= 5
    out_lines = [line for line in lines if "out link" in line]
    assert len(out_lines) == 2
    assert out_lines[0].startswith("gcs run: out link udpout:127.0.0.1:")
    assert "sends UDP to 127.0.0.1:" in out_lines[0]


@pytest.mark.timeout(60)
def test_out_udpin_listens_and_answers_a_ground_station_that_speaks(tmp_path: Path) -> None:
    """`--out udpin:` binds and waits: a ground station that sends it a heartbeat then
    receives the vehicle's frames on its own socket."""
    lines: list[str] = []
    started: list[Daemon] = []

    async def client(gcs: _Collector) -> None:
        while not started or not started[0].router.out_links:
            await asyncio.sleep(0.02)
        link: Any = started[0].router.out_links[0]
        while True:
            try:
                address = link.local_address
                break
            except Exception:  # not bound yet
                await asyncio.sleep(0.02)
        encoder = MavlinkEncoder(255, 190)
        beat = mavlink2.MAVLink_heartbeat_message(
            mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3
        )
        assert gcs.transport is not None
        while True:  # as QGroundControl: a heartbeat every second
            gcs.transport.sendto(encoder.encode(beat), address)
            await asyncio.sleep(0.2)

    async def main() -> tuple[_Collector, Daemon]:
        loop = asyncio.get_running_loop()
        transport, gcs = await loop.create_datagram_endpoint(
            _Collector, local_addr=("127.0.0.1", 0)
        )
        speaker = asyncio.create_task(client(gcs))
        try:
            config = build_config(_args(tmp_path, "udpin:127.0.0.1:0"))
            daemon = await run_daemon(
                config, print_fn=lines.append, install_signals=False, on_started=started.append
            )
            return gcs, daemon
        finally:
            speaker.cancel()
            transport.close()

    gcs, daemon = asyncio.run(asyncio.wait_for(main(), 50.0))
    assert daemon.internal_error is None
    assert len(gcs.heartbeats(1)) >= 3
    assert any("out link udpin:127.0.0.1:0: listens on UDP" in line for line in lines)


def test_nothing_listens_on_an_out_udp_port(tmp_path: Path) -> None:
    """The --out port stays free for the ground station: floe's udp: out link does not
    bind it (before the fix, `--out udp:127.0.0.1:14550` took QGroundControl's port)."""
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()

    async def main() -> None:
        from groundstation.link import open_link

        link = open_link(parse_out_url(f"udp:127.0.0.1:{port}"), link_id="out0")
        await link.start()
        try:
            taken = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            taken.bind(("127.0.0.1", port))  # would fail if the out link listened there
            taken.close()
        finally:
            await link.stop()

    asyncio.run(asyncio.wait_for(main(), 10.0))
