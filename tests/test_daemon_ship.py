"""``gcs run --ship URL`` end to end: a moving ship's NMEA 0183 sentences from a TCP server
(dropped once: the daemon reconnects) or a UDP sender become the core's ``BoatPosition``
inputs in the journal, converted with the run's origin; silence is warned and journalled.
Assertions are on mission time and journal events; wall time only bounds the run."""

from __future__ import annotations

import asyncio
import contextlib
import math
import os
import re
from pathlib import Path
from typing import Any

import pytest
from daemon_run import Journal, events, stop_when

from domain.geodesy import GeoOrigin
from groundstation.commands.run import build_config, run, run_daemon
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.journal import read_journal
from groundstation.daemon.ship_feed import UERE_M
from groundstation.link.nmea import KNOT_M_S, NmeaReader
from groundstation.link.nmea_source import NmeaSource, parse_ship_url

WALL_TIMEOUT_S = 90.0


def _sentence(body: str) -> bytes:
    checksum = 0
    for char in body.encode("ascii"):
        checksum ^= char
    return f"${body}*{checksum:02X}\r\n".encode("ascii")


def _dm(value_deg: float, width: int) -> tuple[str, float]:
    """NMEA ``(d)ddmm.mmmmmmm`` of an unsigned angle, and the angle that text says."""
    degrees = int(value_deg)
    minutes = round((value_deg - degrees) * 60.0, 7)
    if minutes >= 60.0:
        degrees, minutes = degrees + 1, 0.0
    return f"{degrees:0{width}d}{minutes:010.7f}", degrees + minutes / 60.0


class _Ship:
    """A ship steaming at ``speed_kn`` on ``course_deg`` from 300 m east, 200 m north of
    the origin; ``epoch(i)`` is the i-th second's HDT, VTG, GGA and RMC sentences."""

    course_deg = 60.0
    speed_kn = 10.0
    heading_deg = 75.5
    hdop = 1.4

    def __init__(self, origin: GeoOrigin) -> None:
        self.origin = origin
        self.sent: list[tuple[float, float]] = []
        """The (lat, lon) each epoch's text says, in order."""

    def epoch(self, i: int) -> bytes:
        speed_m_s = self.speed_kn * KNOT_M_S
        course = math.radians(self.course_deg)
        east = 300.0 + i * speed_m_s * math.sin(course)
        north = 200.0 + i * speed_m_s * math.cos(course)
        lat, lon, _ = self.origin.to_geodetic(east, north)
        lat_text, lat_sent = _dm(abs(lat), 2)
        lon_text, lon_sent = _dm(abs(lon), 3)
        lat_sent *= 1 if lat >= 0 else -1
        lon_sent *= 1 if lon >= 0 else -1
        ns, ew = ("N" if lat >= 0 else "S"), ("E" if lon >= 0 else "W")
        self.sent.append((lat_sent, lon_sent))
        hhmmss = f"1200{i:02d}.00"
        return (_sentence(f"HEHDT,{self.heading_deg:.1f},T")
                + _sentence(f"GPVTG,{self.course_deg:.1f},T,,M,{self.speed_kn:.2f},N,,K,A")
                + _sentence(f"GPGGA,{hhmmss},{lat_text},{ns},{lon_text},{ew},1,09,"
                            f"{self.hdop:.1f},12.0,M,30.0,M,,")
                + _sentence(f"GNRMC,{hhmmss},A,{lat_text},{ns},{lon_text},{ew},"
                            f"{self.speed_kn:.2f},{self.course_deg:.1f},260126,,,A"))


def _ship_inputs(journal: Journal) -> Journal:
    return [e for e in journal if e["event"] == "input" and e.get("kind") == "BoatPosition"]


def _config(tmp_path: Path, *args: str) -> Any:
    return build_config(["--vehicles", "sim:1", "--duration", "300", "--speedup", "20",
                         *args, "--run-dir", str(tmp_path), "--http", "off",
                         "--detections", "off", "--status", "quiet"])


async def _run(config: Any, done: Any, on_started: Any = None,
               print_fn: Any = None) -> Daemon:
    watchers: list[asyncio.Task[None]] = []

    def started(daemon: Daemon) -> None:
        if on_started is not None:
            on_started(daemon)
        watchers.append(asyncio.create_task(stop_when(daemon, done)))

    try:
        return await run_daemon(config, print_fn=print_fn or (lambda _: None),
                                install_signals=False, on_started=started)
    finally:
        for watcher in watchers:
            watcher.cancel()


def test_ship_over_tcp_becomes_boat_positions_then_silence(tmp_path: Path) -> None:
    epochs = 6
    box: dict[str, Any] = {"connections": 0}

    def done(journal: Journal) -> bool:
        ship = _ship_inputs(journal)
        return len(ship) >= 2 * epochs and any(
            e["t"] > ship[-1]["t"] for e in events(journal, "ship_feed_silent"))

    async def main() -> Daemon:
        ready, closing = asyncio.Event(), asyncio.Event()

        async def serve(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
            box["connections"] += 1
            first = box["connections"] == 1
            await ready.wait()
            ship: _Ship = box["ship"]
            for i in range(3) if first else range(3, epochs):
                writer.write(ship.epoch(i))
                if i == 1:  # garbage and a bad checksum between fixes: counted, dropped
                    writer.write(b"\x00noise\r\n$GPHDT,75.5,T*00\r\n")
                await writer.drain()
            if first:  # the server drops the client: it reconnects with back-off
                writer.close()
                return
            await closing.wait()  # open, and silent, until the run stops
            writer.close()

        server = await asyncio.start_server(serve, "127.0.0.1", 0)
        port = server.sockets[0].getsockname()[1]

        def started(daemon: Daemon) -> None:
            assert daemon.origin_or_none is not None
            box["ship"] = _Ship(daemon.origin_or_none)
            ready.set()

        config = _config(tmp_path, "--ship", f"tcp:127.0.0.1:{port}",
                         "--ship-silent-after", "5")
        async with server:
            try:
                return await _run(config, done, started)
            finally:
                closing.set()
                await asyncio.sleep(0)

    daemon = asyncio.run(asyncio.wait_for(main(), WALL_TIMEOUT_S))
    journal = read_journal(daemon.run_dir / "journal.jsonl")
    origin = GeoOrigin(**journal[0]["origin"])
    ship: _Ship = box["ship"]
    inputs = _ship_inputs(journal)
    assert len(inputs) == 2 * epochs  # a GGA and an RMC per epoch, nothing else
    assert {e["source"] for e in inputs} == {"nmea"}  # the scenario's boat no longer feeds
    speed_m_s = ship.speed_kn * KNOT_M_S
    for k, line in enumerate(inputs):
        lat, lon = ship.sent[k // 2]
        x_m, y_m, _ = origin.to_local(lat, lon)
        assert line["x_m"] == pytest.approx(x_m, abs=1e-3)
        assert line["y_m"] == pytest.approx(y_m, abs=1e-3)
        assert line["vx_m_s"] == pytest.approx(speed_m_s * math.sin(math.radians(60.0)))
        assert line["vy_m_s"] == pytest.approx(speed_m_s * math.cos(math.radians(60.0)))
        assert line["heading_rad"] == pytest.approx(math.pi / 2 - math.radians(75.5))
        assert line["sigma_m"] == pytest.approx(ship.hdop * UERE_M)
    first = inputs[0]
    assert first["x_m"] == pytest.approx(300.0, abs=0.01)
    assert first["y_m"] == pytest.approx(200.0, abs=0.01)
    times = [e["t"] for e in inputs]
    assert times == sorted(times)
    silent = [e for e in events(journal, "ship_feed_silent") if e["t"] > times[-1]]
    assert silent and silent[0]["t"] - times[-1] >= 5.0 - 0.6  # the watch's 0.5 s period
    assert silent[0]["valid"] == 0
    links = events(journal, "ship_feed_link", state="connected")
    assert len(links) == 2  # the reconnection after the server dropped us
    (summary,) = events(journal, "ship_feed_summary")
    assert summary["fixes"] == 2 * epochs and summary["connects"] == 2
    assert summary["dropped"]["checksum"] == 1 and summary["dropped"]["garbage"] == 1


def test_ship_over_udp_garbage_only_is_silent(tmp_path: Path) -> None:
    printed: list[str] = []
    box: dict[str, Any] = {}

    def done(journal: Journal) -> bool:
        return bool(events(journal, "ship_feed_silent"))

    async def main() -> Daemon:
        async def send_garbage() -> None:
            while not any("ship feed" in line for line in printed):
                await asyncio.sleep(0.01)
            line = next(line for line in printed if "ship feed" in line)
            match = re.search(r"listens on UDP ([0-9.]+):([0-9]+)", line)
            assert match is not None, line
            loop = asyncio.get_running_loop()
            transport, _ = await loop.create_datagram_endpoint(
                asyncio.DatagramProtocol, remote_addr=(match[1], int(match[2])))
            try:
                while True:
                    transport.sendto(b"$GPGGA,120000,7855.0,N,01157.0,E,1,08,0.9,,,,*00\r\n"
                                     b"hello\r\n")
                    box["sent"] = box.get("sent", 0) + 1
                    await asyncio.sleep(0.02)
            finally:
                transport.close()

        sender = asyncio.create_task(send_garbage())
        try:
            return await _run(_config(tmp_path, "--ship", "udp:127.0.0.1:0",
                                      "--ship-silent-after", "3"),
                              done, print_fn=printed.append)
        finally:
            sender.cancel()

    daemon = asyncio.run(asyncio.wait_for(main(), WALL_TIMEOUT_S))
    journal = read_journal(daemon.run_dir / "journal.jsonl")
    assert _ship_inputs(journal) == []
    (silent,) = events(journal, "ship_feed_silent")
    assert silent["t"] >= 3.0 - 1e-6
    assert silent["valid"] == 0
    assert silent["detail"] in ("nothing received", f"{silent['sentences']} sentences, none valid")
    (summary,) = events(journal, "ship_feed_summary")
    assert summary["fixes"] == 0 and summary["valid"] == 0
    assert summary["dropped"]["checksum"] + summary["dropped"]["garbage"] > 0 or box.get("sent")


@pytest.mark.parametrize("url", ["udpout:127.0.0.1:10110", "tcp:127.0.0.1", "nmea0183"])
def test_a_bad_ship_url_is_one_line_and_exit_2(url: str, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    status = run(["--vehicles", "sim:1", "--ship", url, "--run-dir", str(tmp_path),
                  "--status", "quiet"])
    err = capsys.readouterr().err
    assert status == 2
    assert err.count("\n") == 1 and "--ship" in err and "Traceback" not in err


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
def test_serial_source_reads_a_pseudo_terminal() -> None:
    """``serial:DEVICE`` at NMEA's 4800 baud, on a pty standing in for the ship's GPS."""
    import tty

    master, slave = os.openpty()
    tty.setraw(slave)
    spec = parse_ship_url(f"serial:{os.ttyname(slave)}")
    assert spec.baud == 4800
    reader = NmeaReader()
    fixes: list[Any] = []
    states: list[tuple[str, str]] = []

    async def main() -> None:
        source = NmeaSource(spec, lambda data: fixes.extend(reader.feed(data, 1.0)),
                            lambda state, reason: states.append((state, reason)))
        task = asyncio.create_task(source.run())
        while not states:
            await asyncio.sleep(0.01)
        os.write(master, _sentence("GPGGA,120000,7855.0000,N,01157.0000,E,1,08,0.9,5,M,,M,,"))
        while not fixes:
            await asyncio.sleep(0.01)
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task
        await source.stop()

    try:
        asyncio.run(asyncio.wait_for(main(), 20.0))
    finally:
        os.close(master)
        os.close(slave)
    assert states[0] == ("connected", "")
    assert fixes[0].lat_deg == pytest.approx(78 + 55 / 60)
