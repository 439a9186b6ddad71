"""Serial link over a pseudo-terminal pair: frames both ways, and reopening a vanished port.

The link opens a symlink (as one would use ``/dev/serial/by-id/...``); "unplugging" removes
the symlink and closes the pty, "plugging back" makes a new pty and a symlink to it. (The
symlink goes first so that the link never reopens a pty number another process reuses.)
"""

from __future__ import annotations

import asyncio
import os
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from link_fixtures import TIMEOUT_S, heartbeat, wait_until

from groundstation.link import LinkOptions, Received, open_link
from groundstation.link.serial_link import SerialLink
from groundstation.mavlink.codec import MavlinkDecoder

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="needs POSIX ptys")
pytest.importorskip("serial_asyncio_fast")

FAST = LinkOptions(reconnect_initial_s=0.02, reconnect_max_s=0.1)


def new_pty(link_path: Path) -> int:
    """A pty whose slave ``link_path`` points at; returns the (non-blocking) master fd."""
    master, slave = os.openpty()
    os.set_blocking(master, False)
    tmp = link_path.with_suffix(".new")
    os.symlink(os.ttyname(slave), tmp)
    os.replace(tmp, link_path)
    os.close(slave)  # the link opens it by name
    return master


async def read_messages(master: int, decoder: MavlinkDecoder, n: int) -> list[Any]:
    out: list[Any] = []
    deadline = time.monotonic() + TIMEOUT_S
    while len(out) < n:
        try:
            out.extend(decoder.feed(os.read(master, 4096)))
        except BlockingIOError:
            if time.monotonic() > deadline:
                raise AssertionError("no data from the serial link") from None
            await asyncio.sleep(0.002)
    return out


def test_serial_link_over_a_pty_survives_unplugging(tmp_path: Path) -> None:
    async def main() -> None:
        radio = tmp_path / "radio"
        master = new_pty(radio)
        got: list[Received] = []
        link = open_link(f"{radio},57600", on_receive=got.append, options=FAST)
        assert isinstance(link, SerialLink)
        async with link:
            await wait_until(lambda: link.connected)
            frame = heartbeat(1)
            os.write(master, frame[:5])  # any chunking
            os.write(master, frame[5:] + b"\x00\x01junk")
            os.write(master, heartbeat(1))
            await wait_until(lambda: len(got) == 2)
            assert got[0].raw == frame and got[0].system_id == 1
            assert link.counters.bad_frames >= 1

            assert link.send(heartbeat(255))
            (msg,) = await read_messages(master, MavlinkDecoder(), 1)
            assert msg.get_srcSystem() == 255

            # Unplugged: udev removes the by-id name, then the device goes away.
            os.unlink(radio)
            os.close(master)
            await wait_until(lambda: not link.connected)
            assert link.send(heartbeat(255)) is False
            await asyncio.sleep(0.1)  # a few failed reopen attempts

            master = new_pty(radio)  # plugged back in
            await wait_until(lambda: link.connected)
            assert link.counters.reconnects == 1
            os.write(master, heartbeat(1))
            await wait_until(lambda: len(got) == 3)
            assert link.send(heartbeat(255))
            (msg,) = await read_messages(master, MavlinkDecoder(), 1)
            assert msg.get_srcSystem() == 255
        os.close(master)

    asyncio.run(main())


def test_serial_link_keeps_trying_a_missing_device(tmp_path: Path) -> None:
    async def main() -> None:
        radio = tmp_path / "absent"
        link = open_link(f"serial:{radio}:115200", options=FAST)
        async with link:
            await asyncio.sleep(0.1)
            assert link.running and not link.connected
            master = new_pty(radio)
            await wait_until(lambda: link.connected)
            assert link.counters.connects == 1
        os.close(master)

    asyncio.run(main())
