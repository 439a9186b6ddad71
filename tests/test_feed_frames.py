"""Frames on the detection feed: the ``frame`` line (groundstation/link/detection_feed.py) and
``gcs sitl --detections`` sending one datagram per frame, frame line first
(sitl/detections.py, sitl/sitl_setup.py)."""

from __future__ import annotations

import json
import math
import socket
import time
from pathlib import Path
from typing import Any

import pytest

from groundstation.link.detection_feed import (
    FeedDetection,
    FeedError,
    FeedFilter,
    encode_detection,
    encode_frame,
    parse_line,
)
from sitl.server import ServerOptions, SitlServer
from sitl.sitl_setup import scenario_setup
from world.scenario import load_scenario

FRAME = {"v": 1, "kind": "frame", "time_s": 2.5, "vehicle": 3, "target": None,
         "lat_deg": 78.93, "lon_deg": 11.92, "sigma_m": 0.0, "radius_m": 150.0}


def test_frame_line_round_trips() -> None:
    raw = encode_frame(2.5, 78.93, 11.92, 150.0, vehicle=3)
    assert raw.endswith(b"\n") and json.loads(raw) == FRAME
    assert parse_line(raw.strip()) == FeedDetection(2.5, "frame", 3, None, 78.93, 11.92, 0.0,
                                                    150.0)
    # radius_m is ignored on other kinds; old lines still compare as before
    det = parse_line(encode_detection(1.0, 78.9, 11.9, vehicle=1, radius_m=10.0).strip())
    assert det.radius_m is None and det == FeedDetection(1.0, "detection", 1, None, 78.9,
                                                         11.9, 0.0)
    with pytest.raises(FeedError, match="radius_m"):
        encode_frame(1.0, 78.9, 11.9, 0.0)


@pytest.mark.parametrize(("change", "reason"), [
    ({"radius_m": None}, "radius_m: expected a number"),
    ({"radius_m": 0}, "radius_m: must be > 0"),
    ({"radius_m": -5}, "radius_m: -5 out of range"),
    ({"radius_m": "150"}, "radius_m: expected a number"),
    ({"radius_m": True}, "radius_m: expected a number"),
    ({"radius_m": 1e7}, "radius_m: 1e+07 out of range"),
    ({"target": "A"}, "target: must be null for a frame"),
    ({"lat_deg": 95.0}, "lat_deg"),
])
def test_malformed_frames_are_counted(change: dict[str, Any], reason: str) -> None:
    line = dict(FRAME, **change)
    if change.get("radius_m", 1) is None:
        del line["radius_m"]
        reason = "radius_m: missing"
    text = json.dumps(line)
    with pytest.raises(FeedError, match=reason.split(":")[0]):
        parse_line(text)
    f = FeedFilter()
    assert f.feed(text.encode() + b"\n" + encode_frame(3.0, 78.9, 11.9, 150.0, vehicle=3)) \
        == [FeedDetection(3.0, "frame", 3, None, 78.9, 11.9, 0.0, 150.0)]
    assert f.counters.malformed == 1 and f.counters.accepted == 1
    assert f.last_reason is not None and reason in f.last_reason


def test_nan_radius_is_malformed() -> None:
    text = json.dumps(dict(FRAME, radius_m=math.nan))
    with pytest.raises(FeedError, match="radius_m: not finite"):
        parse_line(text)


def test_frame_and_its_detections_share_a_time_without_being_out_of_order() -> None:
    f = FeedFilter()
    datagram = (encode_frame(4.0, 78.9, 11.9, 150.0, vehicle=1)
                + encode_detection(4.0, 78.9, 11.9, vehicle=1, sigma_m=2.0)
                + encode_detection(4.0, 78.9, 11.9, vehicle=1, sigma_m=2.0))
    got = f.feed(datagram)
    assert [d.kind for d in got] == ["frame", "detection", "detection"]
    assert f.counters.accepted == 3 and f.counters.out_of_order == 0


def scenario_file(tmp_path: Path, camera: str) -> str:
    path = tmp_path / "s.yaml"
    path.write_text(
        "name: frames\nduration_s: 100\norigin: {lat_deg: 78.93, lon_deg: 11.92}\n"
        "fleet: {count: 1, launch: {x_m: 0, y_m: 0}}\n"
        "targets:\n  known: false\n  list:\n"
        "    - {id: A, x_m: 60, y_m: 0}\n    - {id: B, x_m: 0, y_m: 60}\n"
        f"camera: {camera}\n", encoding="utf-8")
    return str(path)


def test_sim_feed_frames_first_then_detections(tmp_path: Path) -> None:
    """The sans-IO feed with frames: one datagram per frame, frame line first."""
    scenario = load_scenario(scenario_file(tmp_path, "{pd: 0.5, clutter_per_frame: 1.0}"))
    setup = scenario_setup(scenario, 1, (78.93, 11.92), False)
    feed = setup.make_feed(7, False)
    assert feed is not None and feed.frames
    datagrams = feed.step(20.0, {1: (0.0, 0.0)})
    frames = [d for d in datagrams if b'"frame"' in d]
    assert len(frames) == 41  # camera ticks 0, 0.5, ..., 20 s (2 Hz)
    counts = []
    for d in frames:
        lines = [json.loads(x) for x in d.splitlines()]
        assert lines[0]["kind"] == "frame" and lines[0]["radius_m"] == 150.0
        assert all(x["kind"] == "detection" and x["target"] is None for x in lines[1:])
        assert {(x["time_s"], x["vehicle"]) for x in lines} == {(lines[0]["time_s"], 1)}
        counts.append(len(lines) - 1)
    # pd 0.5 of 2 icebergs plus Poisson(1) clutter: mean 2 per frame, some empty frames
    assert 0 in counts and max(counts) >= 3 and 1.0 < sum(counts) / len(counts) < 3.0


def test_the_papers_scenarios_feed_as_before() -> None:
    scenario = load_scenario("paper-boat")
    setup = scenario_setup(scenario, 3, (78.93, 11.92), False)
    feed = setup.make_feed(3, False)
    assert feed is not None and not feed.frames
    datagrams = feed.step(30.0, {1: (750.0, 750.0), 2: (300.0, 900.0), 3: (1200.0, 200.0)})
    lines = [json.loads(d) for d in datagrams]  # one line per datagram
    assert {x["kind"] for x in lines} == {"detection", "boat"}
    assert all(x["target"] is not None for x in lines if x["kind"] == "detection")


def test_gcs_sitl_sends_frames_over_udp(tmp_path: Path) -> None:
    """A built-in vehicle flying over two icebergs; the feed goes to a real UDP socket."""
    scenario = load_scenario(scenario_file(tmp_path, "{pd: 0.8, clutter_per_frame: 0.5}"))
    setup = scenario_setup(scenario, 1, (78.93, 11.92), False)
    feed = setup.make_feed(0, False)
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(0.5)
    config = setup.vehicle_config(0, airborne=True, airborne_alt_m=100.0, fast_boot=True,
                                  unix_time_at_zero_s=0.0)
    server = SitlServer([config], ServerOptions(speedup=20.0, base_port=0,
                                                feed_address=rx.getsockname()), feed=feed)
    from test_sitl_server import ServerThread

    datagrams: list[bytes] = []
    try:
        with ServerThread(server):
            end = time.monotonic() + 20.0
            while time.monotonic() < end and sum(b'"frame"' in d for d in datagrams) < 6:
                try:
                    datagrams.append(rx.recv(65536))
                except TimeoutError:
                    continue
    finally:
        rx.close()
    framed = [d for d in datagrams if b'"frame"' in d]
    assert len(framed) >= 6
    f = FeedFilter()
    for d in framed:
        got = f.feed(d)
        assert got[0].kind == "frame" and got[0].radius_m == 150.0 and got[0].vehicle == 1
        assert all(x.kind == "detection" and x.target is None and x.time_s == got[0].time_s
                   for x in got[1:])
    assert f.counters.malformed == 0 and f.counters.out_of_order == 0
    assert any(len(d.splitlines()) > 1 for d in framed)  # it saw something
