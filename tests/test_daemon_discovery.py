"""The daemon with the multi-target tracker: the status JSON's tracker keys and the
console's counts, the scenario world in discovery mode (unknown icebergs not announced, the
prior announced as prior targets, camera frames before their unlabelled detections), and a
short ``gcs run --scenario discovery`` (in this process) whose journal holds frames, track
statuses, search lines and track notes, replays IDENTICAL and reports the tracking figure."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

from daemon_run import run_gcs, status_text

from domain.geodesy import GeoOrigin
from groundstation.cli import main
from groundstation.core import events as ev
from groundstation.core.config import CoreConfig
from groundstation.daemon.clock import MissionClock
from groundstation.daemon.config_parse import parse_config
from groundstation.daemon.control.bodies import jsonable
from groundstation.daemon.control.controller import DaemonController
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.journal import Journal, read_journal
from groundstation.daemon.world import ScenarioWorld
from groundstation.runners.report.data import load_run_data
from planner.search_cells import SearchConfig
from world.discovery_spec import discovery_mode
from world.scenario import load_scenario, resolve_targets

ORIGIN = GeoOrigin(78.9, 11.9, 0.0)


def _daemon(tmp_path: Path, t: list[float], core: CoreConfig) -> Daemon:
    config = parse_config({"vehicles": ["udpin:127.0.0.1:0"]}, {})
    journal = Journal(tmp_path / "journal.jsonl", lambda: t[0], lambda: 1.7e9)
    clock = MissionClock(1.0, source=lambda: t[0])
    return Daemon(config, core, clock, tmp_path, ORIGIN, journal, None)


def test_status_json_and_table_show_tracks_by_status_and_search_cells(tmp_path: Path) -> None:
    t = [0.0]
    core = CoreConfig(search=SearchConfig(cell_m=500.0), area_m=(0.0, 1000.0, 0.0, 1000.0))
    daemon = _daemon(tmp_path, t, core)
    daemon.core_event(ev.TargetAdded(0.0, "A", 100.0, 100.0, 0.0, 0.0, 25.0))
    daemon.feed.scenario_event(ev.TargetAdded(0.0, "P1", 600.0, 600.0, sigma0=1800.0,
                                              prior=True))
    # a frame far from both with one unlabelled detection: a tentative track at the tick
    daemon.feed.frame(ev.CameraFrame(0.5, "1", 800.0, 200.0, 150.0))
    daemon.add_detection(ev.Detection(0.5, "1", None, 810.0, 210.0, 4.0))
    t[0] = 1.0
    daemon.tick(1.0)
    state = jsonable(DaemonController(daemon).state())
    status = {tr["id"]: tr["status"] for tr in state["tracks"]}
    assert status["A"] == "confirmed" and status["P1"] == "prior"
    [new] = [k for k, v in status.items() if v == "tentative"]
    assert state["track_counts"] == {"confirmed": 1, "tentative": 1, "prior": 1}
    assert {"existence", "sigma_m2", "t_s", "x_m", "y_m"} <= set(state["tracks"][0])
    cells = state["search_cells"]
    assert len(cells) == 4 and {c["size_m"] for c in cells} == {500.0}
    assert {"id", "x_m", "y_m", "value_m2", "last_covered_s"} <= set(cells[0])
    text = status_text(daemon)
    assert "tracks: 1 confirmed, 1 tentative, 1 prior; 4 search cells" in text
    assert "P1" in text and new not in text.split("tracks:")[1]  # tentative: only counted
    lines = read_journal(tmp_path / "journal.jsonl")
    added = [x for x in lines if x["event"] == "target_added" and x["target"] == "P1"]
    assert added and added[0]["prior"] is True and added[0]["source"] == "prior"
    assert any(x["event"] == "track_born" and x["target"] == new for x in lines)
    daemon.feed.journal_tracks()
    lines = read_journal(tmp_path / "journal.jsonl")
    tracks = {x["target"]: x["status"] for x in lines if x["event"] == "track"}
    assert tracks == {"A": "confirmed", "P1": "prior", new: "tentative"}
    [search] = [x for x in lines if x["event"] == "search"]
    assert len(search["cells"]) == 4 and len(search["cells"][0]) == 5


def test_scenario_world_in_discovery_mode(tmp_path: Path) -> None:
    scenario = load_scenario("discovery")
    assert discovery_mode(scenario) and not discovery_mode(load_scenario("paper-boat"))
    import numpy as np

    truth = resolve_targets(scenario, np.random.default_rng(4))
    over = {"1": (truth[0].x_m, truth[0].y_m), "2": (truth[1].x_m, truth[1].y_m)}
    world = ScenarioWorld(scenario, 4, lambda: over)
    first = world.step_to(0.0)
    assert first and all(isinstance(e, ev.TargetAdded) and e.prior for e in first)
    assert len(first) == len(world.prior) == 9  # 8 listed + 1 phantom
    later = world.step_to(2.0)
    assert not any(isinstance(e, ev.TargetAdded) for e in later)  # unknown icebergs
    frames = [e for e in later if isinstance(e, ev.CameraFrame)]
    assert len(frames) >= 6 and {f.vehicle for f in frames} == {"1", "2"}
    for k, e in enumerate(later):
        if isinstance(e, ev.Detection):
            assert e.target is None
            head = next(f for f in reversed(later[:k]) if isinstance(f, ev.CameraFrame))
            assert (head.t_s, head.vehicle) == (e.t_s, e.vehicle)
    assert any(isinstance(e, ev.Detection) for e in later)  # pd 0.85, two icebergs in view


def test_discovery_run_replays_identical_and_reports(tmp_path: Path) -> None:
    """``gcs run --scenario discovery`` in this process until its journal holds two rounds
    of track lines and a tentative track in one (a few mission seconds at 50x)."""

    def enough(journal: list[dict[str, object]]) -> bool:
        tracks = [x for x in journal if x["event"] == "track"]
        return (len({x["t"] for x in tracks}) >= 2
                and any(x.get("status") == "tentative" for x in tracks))

    daemon, lines = run_gcs(tmp_path, "--vehicles", "sim:3", "--scenario", "discovery",
                            "--duration", "60", "--speedup", "50", "--sim-airborne",
                            until=enough)
    run = daemon.run_dir
    kinds = {x.get("kind") for x in lines if x["event"] == "input"}
    assert {"CameraFrame", "Detection", "TargetAdded"} <= kinds
    assert any(x["event"] == "input" and x.get("kind") == "TargetAdded" and x.get("prior")
               for x in lines)
    assert not any(x["event"] == "input" and x.get("kind") == "Detection" and x.get("target")
                   for x in lines)  # the camera is unlabelled
    assert {x.get("status") for x in lines if x["event"] == "track"} >= {"prior", "tentative"}
    assert any(x["event"] == "search" for x in lines)
    assert any(x["event"] == "track_born" for x in lines)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["replay", str(run), "--no-resolve", "--json"]) == 0
    report = json.loads(out.getvalue())
    assert report["identical"] and report["track_samples_compared"] > 10
    assert report["decisions_recorded"] == report["decisions_replayed"] > 0
    from groundstation.runners.report.track_plots import plot_tracking  # matplotlib: here

    figure = plot_tracking(load_run_data(run))  # the report's figure of the daemon's lines
    assert figure is not None and figure.info["search_cells"] > 0
    assert figure.info["counts"]["born"] >= 1 and figure.info["tracks"]["prior"]
