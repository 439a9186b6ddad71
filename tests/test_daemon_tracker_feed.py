"""The daemon's side of the tracker: detection-feed ``frame`` lines (through the feed's own
parser) become ``CameraFrame`` inputs and unlabelled detection lines ``Detection(target=
None)``, the detections of a frame share its mission time and vehicle and the core scans
them together at the next tick; frames of unknown vehicles are dropped and counted."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from domain.geodesy import GeoOrigin
from groundstation.core import events as ev
from groundstation.core.config import CoreConfig
from groundstation.daemon.clock import MissionClock
from groundstation.daemon.config_parse import parse_config
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.feed_lines import FeedLines
from groundstation.daemon.journal import Journal, read_journal
from groundstation.link.detection_feed import (
    FeedDetection,
    FeedFilter,
    encode_detection,
    encode_frame,
)

ORIGIN = GeoOrigin(78.9, 11.9, 0.0)


def _daemon(tmp_path: Path, t: list[float]) -> Daemon:
    config = parse_config({"vehicles": ["udpin:127.0.0.1:0"]}, {})
    journal = Journal(tmp_path / "journal.jsonl", lambda: t[0], lambda: 1.7e9)
    clock = MissionClock(1.0, source=lambda: t[0])
    return Daemon(config, CoreConfig(), clock, tmp_path, ORIGIN, journal, None)


def _line(kind: str, time_s: float, vehicle: int | None, x_m: float, y_m: float,
          **extra: Any) -> bytes:
    lat, lon, _ = ORIGIN.to_geodetic(x_m, y_m, 0.0)
    if kind == "frame":
        return encode_frame(time_s, lat, lon, extra["radius_m"], vehicle=vehicle)
    return encode_detection(time_s, lat, lon, kind=kind, vehicle=vehicle, **extra)


def _items(*lines: bytes) -> list[FeedDetection]:
    """What the feed's receiver hands on for one datagram of these lines."""
    return FeedFilter().feed(b"".join(lines))


def test_frame_and_unlabelled_detections_reach_the_core_as_one_scan(tmp_path: Path) -> None:
    t = [0.0]
    daemon = _daemon(tmp_path, t)
    session = daemon._new_session(2)
    t[0] = 10.0
    lines = FeedLines(daemon)
    items = _items(_line("frame", 55.0, 2, 300.0, -200.0, radius_m=150.0),
                   _line("detection", 55.0, 2, 320.0, -190.0, sigma_m=2.0),
                   _line("detection", 55.0, 2, 250.0, -260.0))
    assert [i.kind for i in items] == ["frame", "detection", "detection"]
    for k, item in enumerate(items):
        t[0] = 10.0 + 0.004 * k  # the clock moves on between the lines of one datagram
        lines(item)
    t[0] = 10.5
    lines(_items(_line("detection", 55.5, 2, 0.0, 0.0))[0])  # a later scan, no frame
    inputs = [r for r in read_journal(tmp_path / "journal.jsonl") if r["event"] == "input"]
    frames = [r for r in inputs if r["kind"] == "CameraFrame"]
    detections = [r for r in inputs if r["kind"] == "Detection"]
    assert [(r["t"], r["vehicle"], r["radius_m"]) for r in frames] == [
        (10.0, session.id, 150.0)]
    assert frames[0]["x_m"] == pytest.approx(300.0, abs=0.01)
    assert frames[0]["y_m"] == pytest.approx(-200.0, abs=0.01)
    assert [(r["t"], r["vehicle"], r.get("target")) for r in detections] == [
        (10.0, session.id, None), (10.0, session.id, None), (10.5, session.id, None)]
    assert detections[0]["r_m2"] == pytest.approx(4.0) and detections[1].get("r_m2") is None
    assert lines.frames == 1 and lines.frames_unknown == 0
    t[0] = 10.6
    daemon.tick(10.6)  # the core scans the buffered frames: a tentative track per detection
    views = [v for v in daemon.core.track_views() if v.status == "tentative"]
    assert len(views) == 3
    assert min(math.dist((v.x_m, v.y_m), (320.0, -190.0)) for v in views) < 5.0
    notes = [r for r in read_journal(tmp_path / "journal.jsonl") if r["event"] == "track_born"]
    assert sorted(n["target"] for n in notes) == sorted(v.id for v in views)


def test_frames_of_unknown_vehicles_or_without_origin_are_counted(tmp_path: Path) -> None:
    t = [1.0]
    daemon = _daemon(tmp_path, t)
    lines = FeedLines(daemon)
    for item in _items(_line("frame", 1.0, 7, 0.0, 0.0, radius_m=150.0),  # no session for 7
                       _line("frame", 1.0, None, 0.0, 0.0, radius_m=150.0)):
        lines(item)
    assert lines.frames_unknown == 2 and lines.frames == 0
    daemon.origin_or_none = None
    lines(_items(_line("frame", 2.0, 7, 0.0, 0.0, radius_m=150.0))[0])
    assert daemon.detections_no_origin == 1
    inputs = [r for r in read_journal(tmp_path / "journal.jsonl") if r["event"] == "input"]
    assert not [r for r in inputs if r["kind"] == "CameraFrame"]


def test_labelled_detection_keeps_its_target(tmp_path: Path) -> None:
    t = [3.0]
    daemon = _daemon(tmp_path, t)
    daemon._new_session(1)
    daemon.core_event(ev.TargetAdded(0.0, "A", 100.0, 100.0, 0.0, 0.0, 25.0))
    FeedLines(daemon)(_items(_line("detection", 3.0, 1, 101.0, 99.0, target="A",
                                   sigma_m=2.0))[0])
    lines = read_journal(tmp_path / "journal.jsonl")
    [line] = [x for x in lines if x["event"] == "detection"]
    assert line["target"] == "A" and line["accepted"] is True  # today's path
