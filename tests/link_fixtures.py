"""Shared helpers of the link tests: MAVLink frames, loopback UDP peers, bounded waits.

Everything binds 127.0.0.1 with ephemeral ports and every wait is bounded.
"""

from __future__ import annotations

import asyncio
import socket
import time
from collections.abc import Callable
from typing import Any

from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, mavlink2

TIMEOUT_S = 3.0


def heartbeat(
    sysid: int,
    mav_type: int = mavlink2.MAV_TYPE_FIXED_WING,
    component: int | None = None,
    autopilot: int = mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA,
) -> bytes:
    """A HEARTBEAT frame; a GCS type defaults to component 190, anything else to 1."""
    comp = component if component is not None else (190 if mav_type == mavlink2.MAV_TYPE_GCS else 1)
    enc = MavlinkEncoder(sysid, comp)
    return enc.encode(enc.mav.heartbeat_encode(mav_type, autopilot, 0, 10, 4))


def statustext(sysid: int, text: str) -> bytes:
    """A STATUSTEXT frame from (sysid, 1)."""
    enc = MavlinkEncoder(sysid, 1)
    return enc.encode(enc.mav.statustext_encode(6, text.encode()))


def attitude(sysid: int, time_boot_ms: int = 0, roll_rad: float = 0.0) -> bytes:
    """An ATTITUDE frame (telemetry) from (sysid, 1)."""
    enc = MavlinkEncoder(sysid, 1)
    return enc.encode(enc.mav.attitude_encode(time_boot_ms, roll_rad, 0.0, 0.0, 0.0, 0.0, 0.0))


def sys_status(sysid: int, battery_pct: int) -> bytes:
    """A SYS_STATUS frame with a battery level."""
    enc = MavlinkEncoder(sysid, 1)
    return enc.encode(
        enc.mav.sys_status_encode(0, 0, 0, 0, 11000, -1, battery_pct, 0, 0, 0, 0, 0, 0)
    )


async def wait_until(cond: Callable[[], bool], timeout_s: float = TIMEOUT_S) -> None:
    """Poll ``cond`` every 2 ms; fail after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not cond():
        if time.monotonic() > deadline:
            raise AssertionError("condition not met in time")
        await asyncio.sleep(0.002)


def udp_socket() -> socket.socket:
    """A non-blocking UDP socket on 127.0.0.1, ephemeral port (a vehicle or a GCS)."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.setblocking(False)
    return s


async def recv_message(sock: socket.socket) -> tuple[Any, tuple[str, int]]:
    """One datagram holding exactly one frame: (message, sender address)."""
    msg, _, addr = await recv_one(sock)
    return msg, addr


async def recv_one(sock: socket.socket) -> tuple[Any, bytes, tuple[str, int]]:
    """One datagram holding exactly one frame: (message, raw bytes, sender address)."""
    loop = asyncio.get_running_loop()
    data, addr = await asyncio.wait_for(loop.sock_recvfrom(sock, 4096), TIMEOUT_S)
    msgs = MavlinkDecoder().feed(data)
    assert len(msgs) == 1
    return msgs[0], data, addr


def drain_socket(sock: socket.socket) -> list[Any]:
    """Every message waiting on ``sock`` now (non-blocking)."""
    out: list[Any] = []
    while True:
        try:
            data = sock.recv(65535)
        except (BlockingIOError, InterruptedError):
            return out
        out.extend(MavlinkDecoder().feed(data))


class FakeVehicle:
    """A TCP server like ArduPilot SITL: greets each client with a heartbeat."""

    def __init__(self, sysid: int) -> None:
        self.sysid = sysid
        self.server: asyncio.Server | None = None
        self.writers: list[asyncio.StreamWriter] = []
        self.decoder = MavlinkDecoder()
        self.received: list[Any] = []

    async def start(self, port: int = 0) -> int:
        self.server = await asyncio.start_server(self._client, "127.0.0.1", port)
        return int(self.server.sockets[0].getsockname()[1])

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.writers.append(writer)
        writer.write(heartbeat(self.sysid))
        while data := await reader.read(4096):
            self.received.extend(self.decoder.feed(data))

    async def crash(self) -> None:
        assert self.server is not None
        self.server.close()
        for w in self.writers:
            w.transport.abort()
        self.writers.clear()
        await self.server.wait_closed()
