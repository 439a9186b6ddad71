"""gcs replay --serve and gcs report on a tlog written by pymavlink's own logger.

The tlog comes from the built-in simulator (``gcs sitl --count 3``, three system ids),
received and logged by pymavlink. pymavlink's UDP class does not log (only the generic
``mavfile.recv_msg`` writes ``setup_logfile``'s tlog), so the logger calls that routine.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import io
import itertools
import json
import os
import socket
import subprocess
import sys
import threading
import time
from html.parser import HTMLParser
from pathlib import Path

import pytest

from groundstation.cli import main
from groundstation.commands.replay import serve_frames, serve_spec
from groundstation.link.url import LinkKind
from groundstation.mavlink.codec import MavlinkDecoder
from groundstation.runners.replay.serve import serving_schedule
from groundstation.runners.replay.tlog import read_tlog

LOGGER = """
import os, subprocess, sys, time
os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil
conn = mavutil.mavlink_connection("udpin:127.0.0.1:0")
port = conn.port.getsockname()[1]
conn.setup_logfile(sys.argv[1])
sim = subprocess.Popen([sys.executable, "-m", "groundstation.cli", "sitl", "--count", "3",
    "--speedup", "20", "--base-port", "0", "--out", f"udp:127.0.0.1:{port}",
    "--detections", "none", "--airborne", "--duration", "600"],
    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
ids = set()
end = time.time() + 30
while time.time() < end and (len(ids) < 3 or time.time() < start + 1.5):
    m = mavutil.mavfile.recv_msg(conn)   # the generic routine writes the logfile
    if m is None:
        time.sleep(0.002)
        continue
    if not ids:
        start = time.time()
    ids.add(m.get_srcSystem())
sim.terminate(); sim.wait(10)
conn.logfile.close()
print(sorted(ids))
"""


@pytest.fixture(scope="module")
def sim_tlog(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("tlog") / "pymavlink.tlog"
    env = {**os.environ, "MAVLINK20": "1"}
    out = subprocess.run(
        [sys.executable, "-c", LOGGER, str(path)],
        capture_output=True,
        text=True,
        timeout=60,
        env=env,
        check=True,
    )
    assert out.stdout.strip() == "[1, 2, 3]"
    return path


@pytest.fixture(scope="module")
def damaged_tlog(sim_tlog: Path) -> Path:
    """A copy with 40 garbage bytes in the middle and the last record cut short."""
    data = bytearray(sim_tlog.read_bytes())
    middle = len(data) // 2
    data[middle : middle + 40] = b"\x55" * 40
    path = sim_tlog.with_name("damaged.tlog")
    path.write_bytes(bytes(data[:-7]))
    return path


class _Receiver:
    """A UDP socket on an ephemeral 127.0.0.1 port counting frames per system id."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.1)
        self.port = self.sock.getsockname()[1]
        self.counts: collections.Counter[int] = collections.Counter()
        self.types: collections.Counter[str] = collections.Counter()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data, _ = self.sock.recvfrom(65536)
            except TimeoutError:
                continue
            for msg in MavlinkDecoder().feed(data):
                self.counts[msg.get_srcSystem()] += 1
                self.types[msg.get_type()] += 1

    def close(self) -> None:
        time.sleep(0.2)
        self._stop.set()
        self._thread.join(5)
        self.sock.close()


def _serve(path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[_Receiver, dict]:
    receiver = _Receiver()
    try:
        status = main(
            [
                "replay",
                str(path),
                "--serve",
                f"udpout:127.0.0.1:{receiver.port}",
                "--speed",
                "5",
                "--json",
            ]
        )
    finally:
        receiver.close()
    assert status == 0
    return receiver, json.loads(capsys.readouterr().out)


def test_pymavlink_tlog_is_read_with_three_vehicles(sim_tlog: Path) -> None:
    summary = read_tlog(sim_tlog)
    assert list(summary.vehicles) == [1, 2, 3]
    assert summary.skipped == []
    for v in summary.vehicles.values():
        assert v.messages["HEARTBEAT"] > 0 and len(v.positions) > 0
        assert v.modes and v.modes[-1][1] == "AUTO"


def test_serve_plays_every_vehicle_frame_with_its_system_id(
    sim_tlog: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    summary = read_tlog(sim_tlog)
    receiver, stats = _serve(sim_tlog, capsys)
    expected = {k: v.frames for k, v in summary.vehicles.items()}
    assert stats["by_system"] == {str(k): n for k, n in expected.items()}
    assert dict(receiver.counts) == expected
    assert receiver.types["GLOBAL_POSITION_INT"] == sum(
        v.messages["GLOBAL_POSITION_INT"] for v in summary.vehicles.values()
    )
    span = (summary.last_t_s or 0) - (summary.first_t_s or 0)
    assert stats["wall_s"] >= 0.8 * span / 5  # paced at 5x the recorded pace


def test_serve_damaged_copy_reports_skipped_ranges(
    damaged_tlog: Path, sim_tlog: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    receiver, stats = _serve(damaged_tlog, capsys)
    size = damaged_tlog.stat().st_size
    assert len(stats["skipped"]) == 2
    (a0, b0), (_a1, b1) = stats["skipped"]
    assert a0 < size // 2 + 40 < b0 + 60 and b1 == size  # the middle, then the cut end
    assert set(receiver.counts) == {1, 2, 3}
    assert sum(receiver.counts.values()) == stats["frames_sent"]
    whole = sum(v.frames for v in read_tlog(sim_tlog).vehicles.values())
    assert whole - 6 <= stats["frames_sent"] < whole


def test_serving_schedule_paces_and_caps_gaps(sim_tlog: Path) -> None:
    summary, frames = serving_schedule(sim_tlog, speed=4.0, max_gap_s=0.01)
    items = list(frames)
    assert items[0].at_s == 0.0
    assert all(b.at_s >= a.at_s for a, b in itertools.pairwise(items))
    assert items[-1].at_s <= 0.01 / 4 * len(items)
    _, frames = serving_schedule(sim_tlog, speed=4.0)
    span = (summary.last_t_s or 0) - (summary.first_t_s or 0)
    assert list(frames)[-1].at_s == pytest.approx(span / 4, abs=0.01)


def test_serve_over_tcp_and_url_forms(sim_tlog: Path) -> None:
    assert serve_spec("udp:127.0.0.1:14550").kind is LinkKind.UDP_OUT
    assert serve_spec("udpout:127.0.0.1:14550").kind is LinkKind.UDP_OUT
    assert serve_spec("tcp:127.0.0.1:5760").kind is LinkKind.TCP_CLIENT

    async def scenario() -> tuple[int, dict]:
        got = bytearray()

        async def client(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
            while chunk := await reader.read(65536):
                got.extend(chunk)
            writer.close()

        server = await asyncio.start_server(client, "127.0.0.1", 0)
        port = server.sockets[0].getsockname()[1]
        _, frames = serving_schedule(sim_tlog, speed=50.0)
        stats = await serve_frames(serve_spec(f"tcp:127.0.0.1:{port}"), frames, ready_timeout_s=5.0)
        await asyncio.sleep(0.1)
        server.close()
        await server.wait_closed()
        return len(MavlinkDecoder().feed(bytes(got))), stats

    received, stats = asyncio.run(asyncio.wait_for(scenario(), 30))
    assert received == stats["frames_sent"] > 1000


def test_serve_is_cancellable(sim_tlog: Path) -> None:
    async def scenario() -> float:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1", 0))
        _, frames = serving_schedule(sim_tlog, speed=0.05)  # would take minutes
        task = asyncio.create_task(
            serve_frames(serve_spec(f"udpout:127.0.0.1:{sock.getsockname()[1]}"), frames)
        )
        await asyncio.sleep(0.3)
        start = time.monotonic()
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task
        sock.close()
        return time.monotonic() - start

    assert asyncio.run(scenario()) < 1.0


def test_serve_bad_input_is_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], sim_tlog: Path
) -> None:
    assert main(["replay", str(tmp_path / "none.tlog"), "--serve", "udpout:127.0.0.1:9"]) == 2
    assert "no such file" in capsys.readouterr().err
    junk = tmp_path / "junk.tlog"
    junk.write_bytes(b"\x01" * 500)
    assert main(["replay", str(junk), "--serve", "udpout:127.0.0.1:9"]) == 2
    assert "no valid MAVLink record" in capsys.readouterr().err
    assert main(["replay", str(sim_tlog), "--serve", "bogus:1"]) == 2
    assert "bad link URL" in capsys.readouterr().err
    assert main(["replay", str(sim_tlog)]) == 2
    assert "--detections" in capsys.readouterr().err


class _Page(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.imgs: list[dict[str, str | None]] = []
        self.text: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "img":
            self.imgs.append(dict(attrs))

    def handle_data(self, data: str) -> None:
        self.text.append(data)


@pytest.mark.parametrize("which", ["sim_tlog", "damaged_tlog"])
def test_report_of_a_tlog(which: str, request: pytest.FixtureRequest, tmp_path: Path) -> None:
    import base64

    path = request.getfixturevalue(which)
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["report", str(path), "--out", str(tmp_path), "--quiet"]) == 0
    page = _Page()
    page.feed((tmp_path / "report.html").read_text())
    ids = {img.get("alt") for img in page.imgs}
    assert ids == {"Map of the flight", "Plan timeline per vehicle"}
    for img in page.imgs:
        src = img["src"] or ""
        assert base64.b64decode(src.split(",", 1)[1]).startswith(b"\x89PNG\r\n\x1a\n")
    text = " ".join(page.text)
    assert "AUTO" in text
    summary = read_tlog(path)
    tracks = summary.local_tracks()
    xs = [x for t in tracks.values() for x in t[:, 1]]
    ys = [y for t in tracks.values() for y in t[:, 2]]
    [map_img] = [img for img in page.imgs if img.get("alt") == "Map of the flight"]
    x0, x1 = map(float, (map_img["data-xlim"] or "").split(","))
    y0, y1 = map(float, (map_img["data-ylim"] or "").split(","))
    assert x0 <= min(xs) and max(xs) <= x1 and y0 <= min(ys) and max(ys) <= y1
    assert (x1 - x0) < 3 * (max(xs) - min(xs)) + 400  # zoomed on the tracks, not the world
    if which == "damaged_tlog":
        assert "skipped damaged bytes" in text


def test_core_on_bare_tlog_with_detections(
    sim_tlog: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from domain.geodesy import GeoOrigin
    from groundstation.link.tlog import TlogReader

    first = next(
        r.message for r in TlogReader(sim_tlog) if r.message.get_type() == "GLOBAL_POSITION_INT"
    )
    origin = GeoOrigin(first.lat / 1e7, first.lon / 1e7)
    t0 = first.time_boot_ms / 1000.0
    lines = []
    for k, (target, east, north) in enumerate([("A", 400, 100), ("B", -300, 500)]):
        lat, lon, _ = origin.to_geodetic(east, north)
        lines.append(
            json.dumps(
                {
                    "v": 1,
                    "kind": "detection",
                    "time_s": t0 + 0.5 + 0.1 * k,
                    "vehicle": 1,
                    "target": target,
                    "lat_deg": lat,
                    "lon_deg": lon,
                    "sigma_m": 2.0,
                }
            )
        )
    lines.append("not json")
    detections = tmp_path / "det.jsonl"
    detections.write_text("\n".join(lines) + "\n")
    assert main(["replay", str(sim_tlog), "--detections", str(detections), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["detections_used"] == 2 and len(out["detections_skipped"]) == 1
    flies = [d for d in out["decisions"] if d["event"] == "fly"]
    assert {d["vehicle"] for d in flies} == {"1", "2", "3"}
    assert {d["target"] for d in flies} == {"A", "B"}
    aim = {d["target"]: (d["x_m"], d["y_m"]) for d in flies}
    assert aim["A"] == pytest.approx((400.0, 100.0), abs=0.5)
    assert aim["B"] == pytest.approx((-300.0, 500.0), abs=0.5)


def test_ctrl_c_stops_serving_cleanly(sim_tlog: Path) -> None:
    import signal

    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "groundstation.cli",
            "replay",
            str(sim_tlog),
            "--serve",
            "udpout:127.0.0.1:9",
            "--speed",
            "0.01",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stderr is not None
        assert "serving 3 vehicle(s)" in proc.stderr.readline()  # started sending
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)  # a bound, not a speed: loaded CI hosts
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130
    assert "interrupted; link closed" in out and "Traceback" not in err
