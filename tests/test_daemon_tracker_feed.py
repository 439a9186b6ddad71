"""The daemon's side of the tracker: detection-feed ``frame`` lines become ``CameraFrame``
events and unlabelled detection lines ``Detection(target=None)``, the detections of a frame
share its mission time and vehicle; frames of unknown vehicles are dropped and counted."""

from __future__ import annotations

from dataclasses import dataclass
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
from groundstation.daemon.journal import Journal

ORIGIN = GeoOrigin(78.9, 11.9, 0.0)


def _daemon(tmp_path: Path, t: list[float]) -> Daemon:
    config = parse_config({"vehicles": ["udpin:127.0.0.1:0"]}, {})
    journal = Journal(tmp_path / "journal.jsonl", lambda: t[0], lambda: 1.7e9)
    clock = MissionClock(1.0, source=lambda: t[0])
    return Daemon(config, CoreConfig(), clock, tmp_path, ORIGIN, journal, None)


def _line(kind: str, time_s: float, vehicle: int | None, x_m: float, y_m: float,
          **extra: Any) -> dict[str, Any]:
    lat, lon, _ = ORIGIN.to_geodetic(x_m, y_m, 0.0)
    return {"v": 1, "kind": kind, "time_s": time_s, "vehicle": vehicle, "target": None,
            "lat_deg": lat, "lon_deg": lon, "sigma_m": 0.0, **extra}


@dataclass(frozen=True)
class _FakeCameraFrame:  # the core's CameraFrame before wt/core is merged
    t_s: float
    vehicle: str
    x_m: float
    y_m: float
    radius_m: float


def test_frame_and_unlabelled_detections_reach_the_core_as_one_scan(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(ev, "CameraFrame", _FakeCameraFrame, raising=False)
    t = [0.0]
    daemon = _daemon(tmp_path, t)
    session = daemon._new_session(2)
    t[0] = 10.0
    frames: list[Any] = []
    detections: list[ev.Detection] = []
    monkeypatch.setattr(daemon.feed, "frame", frames.append)
    monkeypatch.setattr(daemon, "add_detection", detections.append)
    lines = FeedLines(daemon)
    lines(_line("frame", 55.0, 2, 300.0, -200.0, radius_m=150.0))
    t[0] = 10.004  # the clock moves on between the lines of one datagram
    lines(_line("detection", 55.0, 2, 320.0, -190.0, sigma_m=2.0))
    lines(_line("detection", 55.0, 2, 250.0, -260.0))
    t[0] = 10.5
    lines(_line("detection", 55.5, 2, 0.0, 0.0))  # a later scan without a frame
    [frame] = frames
    assert isinstance(frame, _FakeCameraFrame)
    assert frame.t_s == 10.0 and frame.vehicle == session.id and frame.radius_m == 150.0
    assert frame.x_m == pytest.approx(300.0, abs=0.01)
    assert frame.y_m == pytest.approx(-200.0, abs=0.01)
    assert [(d.t_s, d.vehicle, d.target) for d in detections] == [
        (10.0, session.id, None), (10.0, session.id, None), (10.5, session.id, None)]
    assert detections[0].r_m2 == pytest.approx(4.0) and detections[1].r_m2 is None
    assert detections[0].x_m == pytest.approx(320.0, abs=0.01)
    assert lines.frames == 1 and lines.frames_unknown == 0


def test_frames_of_unknown_vehicles_or_without_origin_are_counted(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(ev, "CameraFrame", _FakeCameraFrame, raising=False)
    t = [1.0]
    daemon = _daemon(tmp_path, t)
    frames: list[Any] = []
    monkeypatch.setattr(daemon.feed, "frame", frames.append)
    lines = FeedLines(daemon)
    lines(_line("frame", 1.0, 7, 0.0, 0.0, radius_m=150.0))  # no session for system 7
    lines(_line("frame", 1.0, None, 0.0, 0.0, radius_m=150.0))
    assert frames == [] and lines.frames_unknown == 2
    daemon.origin_or_none = None
    lines(_line("frame", 2.0, 7, 0.0, 0.0, radius_m=150.0))
    assert daemon.detections_no_origin == 1


def test_labelled_detection_keeps_its_target(tmp_path: Path) -> None:
    t = [3.0]
    daemon = _daemon(tmp_path, t)
    daemon._new_session(1)
    daemon.core_event(ev.TargetAdded(0.0, "A", 100.0, 100.0, 0.0, 0.0, 25.0))
    FeedLines(daemon)(_line("detection", 3.0, 1, 101.0, 99.0, target="A", sigma_m=2.0))
    lines = (tmp_path / "journal.jsonl").read_text().splitlines()
    assert any('"event":"detection"' in x and '"target":"A"' in x for x in lines)
