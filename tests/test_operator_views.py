"""Operator views of a real daemon (in this process, built-in simulator or a closed TCP port
on 127.0.0.1, ephemeral ports): one predicate (``log_lines.is_operator_event``) keeps
``truth``/``track``/``detection`` lines out of ``/api/events?notable=1``, the live page's
event pushes and the status table's recent pane; links that hear no vehicle and dropped
detections are journalled and repeated on mission time; and the readable log lines."""

from __future__ import annotations

import asyncio
import io
import json
import logging
import re
import socket
from pathlib import Path
from typing import Any

import aiohttp
import pytest
from daemon_run import status_text, stop_when

from groundstation.commands.run import build_config, run_daemon
from groundstation.daemon.alerts import (
    NO_VEHICLE_AFTER_S,
    SILENT_AFTER_S,
    SILENT_REPEAT_S,
    never_heard,
)
from groundstation.daemon.config import StatusMode
from groundstation.daemon.console import ConsoleHandler, OperatorConsole
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.journal import read_journal
from groundstation.daemon.log_lines import describe_line, is_operator_event, line_level
from groundstation.link.detection_feed import encode_detection

STATE_UPDATES = {"truth", "track", "detection", "input"}


def _run(tmp_path: Path, args: list[str], on_started: Any = None,
         prints: list[str] | None = None) -> Daemon:
    config = build_config([*args, "--run-dir", str(tmp_path), "--status", "quiet"])
    out = prints if prints is not None else []
    return asyncio.run(asyncio.wait_for(
        run_daemon(config, print_fn=out.append, on_started=on_started, install_signals=False),
        90.0))


@pytest.mark.timeout(120)
def test_notable_events_and_page_pushes_hold_operator_events_only(tmp_path: Path) -> None:
    notable: list[dict[str, Any]] = []
    pushed: list[dict[str, Any]] = []
    watchers: list[asyncio.Task[None]] = []

    async def watch(daemon: Daemon) -> None:
        while daemon.control_url is None:
            await asyncio.sleep(0.05)
        async with aiohttp.ClientSession(base_url=daemon.control_url) as http, \
                http.ws_connect("/ws") as ws:
            async for msg in ws:  # until the daemon closes the page as it stops
                data = json.loads(msg.data)
                if data.get("type") == "events":
                    pushed.extend(e["line"] for e in data["events"])
                if not daemon.stopping:
                    async with http.get("/api/events?since=0&limit=5000&notable=1") as r:
                        notable[:] = [e["line"] for e in (await r.json())["events"]]

    def started(daemon: Daemon) -> None:
        watchers.append(asyncio.get_running_loop().create_task(watch(daemon)))

    daemon = _run(tmp_path, ["--vehicles", "sim:2", "--scenario", "paper-boat", "--speedup",
                             "20", "--duration", "60", "--http", "127.0.0.1:0",
                             "--detections", "off"], started)
    journal = read_journal(daemon.run_dir / "journal.jsonl")
    assert sum(e["event"] == "truth" for e in journal) >= 20  # there was something to leave out
    for view in (notable, pushed):
        events = [e["event"] for e in view]
        assert "plan" in events and "upload" in events, events
        assert not STATE_UPDATES & set(events), events
        assert all(is_operator_event(e) for e in view)
    table = status_text(daemon)
    recent = table.split("recent:", 1)[1].splitlines()
    assert len([x for x in recent if x.strip()]) >= 3
    for line in recent:
        assert not re.search(r"t=[\d.]+ (truth|track|detection|input) ", line), line
    for watcher in watchers:
        watcher.cancel()


@pytest.mark.timeout(120)
def test_silent_link_and_dropped_detections_are_reported(tmp_path: Path) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    prints: list[str] = []
    records: list[logging.LogRecord] = []

    class Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            records.append(record)

    keep = Keep(logging.WARNING)
    logging.getLogger("groundstation").addHandler(keep)

    async def send_detections() -> None:
        feed = next(p for p in prints if "detection feed on udp:" in p)
        found = re.search(r"udp:([0-9.]+):([0-9]+)", feed)
        assert found is not None, feed
        host, feed_port = found.group(1), found.group(2)
        loop = asyncio.get_running_loop()
        transport, _ = await loop.create_datagram_endpoint(
            asyncio.DatagramProtocol, remote_addr=(host, int(feed_port)))
        for i in range(5):  # no vehicle, so no mission origin: each one is dropped
            transport.sendto(encode_detection(float(i), 78.9, 11.9, target="A"))
            await asyncio.sleep(0.05)
        transport.sendto(b"not json\n")  # malformed
        transport.close()

    tasks: list[asyncio.Task[None]] = []
    try:
        # silence is counted in the link's wall seconds: the run stops at its first report,
        # 10 wall s after the link started (--duration only bounds it)
        def started(d: Daemon) -> None:
            loop = asyncio.get_running_loop()
            tasks.append(loop.create_task(send_detections()))
            tasks.append(loop.create_task(stop_when(
                d, lambda j: any(e["event"] == "link_silent" for e in j))))

        daemon = _run(tmp_path, ["--vehicles", f"tcp:127.0.0.1:{port}", "--speedup", "2",
                                 "--duration", "120", "--http", "off",
                                 "--detections", "127.0.0.1:0"], started, prints)
    finally:
        logging.getLogger("groundstation").removeHandler(keep)
    journal = read_journal(daemon.run_dir / "journal.jsonl")
    silent = [e for e in journal if e["event"] == "link_silent"]
    # after 10 wall s of the link's own time (never connected: since the start); the
    # repeat every 30 s is checked on a driven clock below
    assert [e["link"] for e in silent] == ["vehicles0"]
    assert SILENT_AFTER_S <= silent[0]["silent_s"] < SILENT_AFTER_S + 2.0
    assert silent[0]["since"] == "start" and silent[0]["t"] >= 2 * SILENT_AFTER_S * 0.9
    assert silent[0]["url"] == f"tcp:127.0.0.1:{port}" and silent[0]["connected"] is False
    drops = [e for e in journal if e["event"] == "detections_dropped"]
    assert sum(e["new"] for e in drops) == 6 and drops[-1]["total"] == 6
    assert drops[-1]["no_origin"] == 5 and drops[-1]["malformed"] == 1
    warnings = [r.getMessage() for r in records]
    assert sum("no vehicle heard in" in w for w in warnings) == 1
    # one or two reports (the datagrams may straddle a 10 s report), ending with all six
    assert any(w.startswith("detections: ") and "(6 in all: no origin 5, malformed 1)" in w
               for w in warnings), warnings
    assert any(f"cannot open TCP 127.0.0.1:{port}" in w for w in warnings)
    message = never_heard(daemon)
    assert message is not None and f"tcp:127.0.0.1:{port}: never connected" in message


def test_operator_event_predicate_and_levels() -> None:
    assert is_operator_event({"event": "plan"}) and is_operator_event({"event": "link_silent"})
    for event in STATE_UPDATES | {"mode", "armed", "fly", "solve_request", "boat"}:
        assert not is_operator_event({"event": event}), event
    assert is_operator_event({"event": "statustext", "severity": 2})
    assert not is_operator_event({"event": "statustext", "severity": 6})
    assert is_operator_event({"event": "clock_check", "ok": False})
    assert not is_operator_event({"event": "clock_check", "ok": True})
    assert line_level({"event": "upload", "ok": True, "retries": 0}) == logging.INFO
    assert line_level({"event": "upload", "ok": True, "retries": 5}) == logging.WARNING
    assert line_level({"event": "upload", "ok": False, "retries": 0}) == logging.WARNING
    assert line_level({"event": "link_lost"}) == logging.WARNING
    assert line_level({"event": "truth"}) == logging.DEBUG
    # one line_level call serves the views that need both (EventBuffer, page pushes)
    for line in ({"event": "plan"}, {"event": "truth"}, {"event": "statustext", "severity": 6},
                 {"event": "statustext", "severity": 3}, {"event": "clock_check", "ok": False},
                 {"event": "mode", "ok": False}, {"event": "arm", "ok": False}):
        assert (line_level(line) > logging.DEBUG) == is_operator_event(line), line


def test_plan_and_stop_lines_read_as_text() -> None:
    plan = {"t": 25.12, "event": "plan", "request_id": 3, "reason": "period",
            "routes": {"1": ["T5", "T6", "T9"], "2": ["T2"], "3": []},
            "assignments": {"1": "T5"}, "status": "optimal", "solve_time_s": 0.003,
            "problem": {"targets": [1, 2]}, "result": {"x": 1}, "hint": None}
    assert describe_line(plan) == (
        "t=25.1 plan 1 -> T5, T6, T9 | 2 -> T2 | 3 -> - (optimal, 3 ms, period)")
    stop = {"t": 60.0, "event": "stop", "reason": "duration", "plans": 7,
            "links": {"vehicles0": {"received": 5}}, "unknown_systems": {"frames": 1}}
    assert describe_line(stop) == "t=60.0 stop reason=duration plans=7"
    upload = {"t": 3.4, "event": "upload", "vehicle": "1", "ok": True, "retries": 0}
    assert describe_line(upload) == "t=3.4 upload vehicle=1 ok=True"


def test_console_on_a_file_has_no_escape_codes() -> None:
    out, err = io.StringIO(), io.StringIO()
    console = OperatorConsole(StatusMode.AUTO, out, err)
    assert not console.live_table and console.event_lines  # auto on a file: log lines
    handler = ConsoleHandler(console.out, logging.INFO)
    for level in (logging.INFO, logging.WARNING, logging.ERROR):
        handler.handle(logging.LogRecord("groundstation.x", level, __file__, 1,
                                         "problem %d " + "x" * 150, (level,), None))
    text = out.getvalue()
    assert "\x1b" not in text
    assert len(text.splitlines()) == 3  # one line each, never wrapped at 80 columns
    assert text.splitlines()[1].startswith("gcs run: problem 30 xxx")
    quiet = OperatorConsole(StatusMode.QUIET, out, err)
    assert not quiet.live_table and not quiet.event_lines and not quiet.final_table
    forced = OperatorConsole(StatusMode.TABLE, out, err)
    assert forced.final_table and forced.event_lines and not forced.live_table


def test_event_buffer_keeps_operator_events_and_marks_problems() -> None:
    from groundstation.daemon.control.pages import EventBuffer

    buffer = EventBuffer()
    for line in ({"t": 1.0, "event": "truth", "target": "A"},
                 {"t": 1.0, "event": "plan", "routes": {}},
                 {"t": 2.0, "event": "track", "target": "A"},
                 {"t": 3.0, "event": "link_lost", "vehicle": "1"}):
        buffer.record(line)
    everything = buffer.since(0, 100, notable=False)["events"]
    notable = buffer.since(0, 100, notable=True)["events"]
    assert [e["line"]["event"] for e in everything] == ["truth", "plan", "track", "link_lost"]
    assert [(e["line"]["event"], e.get("warning", False)) for e in notable] == [
        ("plan", False), ("link_lost", True)]


class _Warnings(logging.Handler):
    """Keeps the text of every record it is given."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.records: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record.getMessage())


def _offline_daemon(tmp_path: Path, speedup: float, t: list[float]) -> tuple[Daemon, Any]:
    """A daemon with no link started and a hand-driven mission clock (``t[0]``): the
    operator alerts' tests add links to its router and check them; returns it and its
    journal (to close)."""
    from groundstation.core.config import CoreConfig
    from groundstation.daemon.clock import MissionClock
    from groundstation.daemon.config_parse import parse_config
    from groundstation.daemon.journal import Journal

    config = parse_config({"vehicles": ["udpin:127.0.0.1:0"]}, {})
    journal = Journal(tmp_path / "journal.jsonl", lambda: t[0], lambda: 1.7e9)
    daemon = Daemon(config, CoreConfig(), MissionClock(speedup, source=lambda: t[0]), tmp_path,
                    None, journal, None)
    return daemon, journal


def test_silent_link_advice_and_drops_come_from_the_link_and_the_daemon(tmp_path: Path) -> None:
    """The advice switches on the link's kind (an upper-case ``TCP:`` is a TCP client), the
    URL is the link's own, and the drops read the daemon's two counters."""
    from groundstation.daemon.alerts import OperatorAlerts
    from groundstation.link import open_link

    t = [0.0]
    daemon, journal = _offline_daemon(tmp_path, 1.0, t)
    for i, url in enumerate(("TCP:127.0.0.1:5760", "tcpin:127.0.0.1:5761",
                             "udpout:127.0.0.1:14550")):
        daemon.router.add_vehicle_link(open_link(url, link_id=f"vehicles{i}"))
    daemon.drops.detections_no_origin, daemon.drops.detections_dropped = 3, 2
    wall = [100.0]
    alerts = OperatorAlerts(daemon, wall_s=lambda: wall[0])
    keep = _Warnings()
    records = keep.records
    logging.getLogger("groundstation").addHandler(keep)
    try:
        alerts.check(0.0)  # the links' count starts at the first check, on their clock
        wall[0] += SILENT_AFTER_S - 0.1
        alerts.check(5.0)
        assert not records
        wall[0] += 0.1
        alerts.check(SILENT_AFTER_S)
    finally:
        logging.getLogger("groundstation").removeHandler(keep)
        journal.close()
    assert [x.link_id for x in alerts.silent_links()] == ["vehicles0", "vehicles1", "vehicles2"]
    assert len(records) == 4, records  # three silent links and the drops, once each
    assert "(TCP:127.0.0.1:5760)" in records[0] and "no other program holds" in records[0]
    assert "connects to this address" in records[1] and "udpout sends first" in records[2]
    assert alerts.link_state(alerts.silent_links()[0]) == "never connected"
    assert alerts.drops() == {"no_origin": 3, "outside_area": 2}
    assert records[3].startswith("detections: 5 dropped")
    lines = read_journal(tmp_path / "journal.jsonl")
    assert [e["url"] for e in lines if e["event"] == "link_silent"] == [
        "TCP:127.0.0.1:5760", "tcpin:127.0.0.1:5761", "udpout:127.0.0.1:14550"]


def test_link_silence_threshold_is_the_configured_one(tmp_path: Path) -> None:
    """``links.silent_after_s`` (``--link-silent-after``): a link is reported silent at
    that many wall seconds after its start, not before, whatever the default; the flag
    sets it and a threshold that is not a positive number is refused, naming the flag."""
    from domain.errors import ConfigError
    from groundstation.daemon.alerts import OperatorAlerts
    from groundstation.daemon.config_parse import parse_config
    from groundstation.link import open_link

    config = parse_config({"vehicles": ["udpin:127.0.0.1:0"]}, {"--link-silent-after": 2.5})
    assert config.links.silent_after_s == 2.5
    assert parse_config({"vehicles": ["udpin:127.0.0.1:0"]}, {}).links.silent_after_s == (
        SILENT_AFTER_S)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ConfigError, match="--link-silent-after"):
            parse_config({"vehicles": ["udpin:127.0.0.1:0"]}, {"--link-silent-after": bad})
    t = [0.0]
    daemon, journal = _offline_daemon(tmp_path, 1.0, t)
    daemon.router.add_vehicle_link(open_link("tcp:127.0.0.1:5760", link_id="vehicles0"))
    wall = [50.0]
    alerts = OperatorAlerts(daemon, wall_s=lambda: wall[0],
                            silent_after_s=config.links.silent_after_s)
    try:
        alerts.check(0.0)
        wall[0] += 2.4
        alerts.check(2.4)
        assert not alerts.silent_links()
        wall[0] += 0.1
        alerts.check(2.5)
        assert [x.link_id for x in alerts.silent_links()] == ["vehicles0"]
    finally:
        journal.close()
    (line,) = [e for e in read_journal(tmp_path / "journal.jsonl")
               if e["event"] == "link_silent"]
    assert line["silent_s"] == 2.5 and line["since"] == "start"


def test_upload_retries_are_counted_by_the_controller() -> None:
    """The table's retries column reads the controller's count (every upload job's
    retries), not the journal subscription that may drop lines."""
    from test_vehicle_controller import active_rig

    from groundstation.vehicle import controller_io as vio

    rig = active_rig()
    before = rig.c.upload_retries
    rig.auto_answer = False
    rig.fly("A")
    rig.answer(vio.UploadOutcome(False, 5, "upload timeout", 3))  # 5 retries, then failed
    assert rig.c.upload_retries == before + 5 and rig.c.uploads_failed == 1
    rig.auto_answer = True
    rig.run(5.0)  # retried and flown: no retry this time
    assert rig.c.uploads_ok >= 1 and rig.c.upload_retries == before + 5


def test_link_silence_counts_from_the_links_own_connect_and_first_frame(
        tmp_path: Path) -> None:
    """Issue 29: a run at 5x/10x against ``gcs sitl`` warned "no vehicle heard in 17 s ...
    connected but silent" (17 *mission* seconds, counted from the mission's start, with
    37 frames received). Silence is counted on the link's clock, from its latest
    progress: the start, its connect, its first frame; the advice fits the progress."""
    from groundstation.daemon.alerts import OperatorAlerts
    from groundstation.link import open_link

    t = [0.0]
    daemon, journal = _offline_daemon(tmp_path, 10.0, t)
    link = open_link("tcp:127.0.0.1:5760", link_id="vehicles0")
    daemon.router.add_vehicle_link(link)
    wall = [0.0]
    alerts = OperatorAlerts(daemon, wall_s=lambda: wall[0])
    keep = _Warnings()
    records = keep.records
    logging.getLogger("groundstation").addHandler(keep)

    def at(wall_s: float) -> None:
        wall[0] = wall_s
        t[0] = wall_s * 10.0  # the mission at 10x
        alerts.check(min(t[0], 5.0))  # (no drops report in this test)

    try:
        at(0.0)
        at(1.7)  # 17 mission s: the old false alarm
        link.counters.connects = 1
        at(2.0)  # connected
        link.counters.frames_in = 37
        at(4.0)  # frames arrive; the vehicle is not made yet
        at(13.9)
        assert records == []  # 11.9 s after the connect, 9.9 s after the first frame
        at(4.0 + NO_VEHICLE_AFTER_S - 0.1)  # frames arrive: a vehicle may need its GPS
        assert records == []
        at(4.0 + NO_VEHICLE_AFTER_S)
        assert len(records) == 1
        assert "no vehicle heard in 60 s since its first frame" in records[0]
        assert "37 frames received" in records[0] and "connected but silent" not in records[0]
        link.counters.connects = 2  # a reconnect is no progress: the count goes on
        at(4.0 + NO_VEHICLE_AFTER_S + SILENT_REPEAT_S - 0.1)
        assert len(records) == 1
        at(4.0 + NO_VEHICLE_AFTER_S + SILENT_REPEAT_S)
        assert len(records) == 2
    finally:
        logging.getLogger("groundstation").removeHandler(keep)
        journal.close()
    (first, _) = [e for e in read_journal(tmp_path / "journal.jsonl")
                  if e["event"] == "link_silent"]
    assert first["since"] == "first frame" and first["silent_s"] == NO_VEHICLE_AFTER_S
    assert first["received"] == 37


def test_the_stop_line_is_the_journals_last_even_with_frames_still_arriving(
        tmp_path: Path) -> None:
    """A frame read in the same wake as the shutdown (the built-in vehicles write several
    frames at once) was acted on after the stop line: a full suite saw a ``loiter_end``
    journalled after ``stop``. From the stop line on, a vehicle frame changes nothing: here
    the first position of an unknown system, which would otherwise set the mission origin
    and journal an ``origin`` line."""
    from groundstation.link.base import Received
    from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, mavlink2

    t = [12.0]
    daemon, journal = _offline_daemon(tmp_path, 1.0, t)
    frame = MavlinkEncoder(7, 1).encode(mavlink2.MAVLink_global_position_int_message(
        1000, 783_000_000, 155_000_000, 100_000, 100_000, 0, 0, 0, 0))
    rx = Received(MavlinkDecoder().feed(frame)[0], frame, "vehicles0", 1.7e9)
    try:
        asyncio.run(daemon._shutdown())
        daemon._on_vehicle_frame(rx)  # after the stop line
    finally:
        journal.close()
    lines = read_journal(tmp_path / "journal.jsonl")
    assert lines[-1]["event"] == "stop", [e["event"] for e in lines]
    assert daemon.origin_or_none is None and daemon.drops.unknown_frames == 0
