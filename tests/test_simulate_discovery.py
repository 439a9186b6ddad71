"""gcs simulate in discovery mode: unknown icebergs, a prior, an unlabelled camera with
clutter, search cells; the journal replays IDENTICAL; a labelled camera never touches the
tracker."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from simulate_run import simulate_text

from groundstation.cli import main
from groundstation.core import tracking
from groundstation.runners.simulate.simulator import SimulationOptions, run_simulation
from world.discovery_spec import discovery_mode
from world.scenario import load_scenario

SMALL_DISCOVERY = """\
name: small-discovery
description: 3 unknown icebergs in 1 km x 1 km, a prior (2 listed, 1 phantom), pd 0.85, clutter
duration_s: 60
origin: {lat_deg: 78.93, lon_deg: 11.92}
area: {x_m: [0, 1000], y_m: [0, 1000]}
fleet: {count: 2, loiter_s: 0, launch: {x_m: 500.0, y_m: 500.0}}
targets:
  known: false
  list:
    - {id: A, x_m: 200, y_m: 300, vx_m_s: 0.3, vy_m_s: -0.2}
    - {id: B, x_m: 800, y_m: 750, vx_m_s: -0.2, vy_m_s: 0.1}
    - {id: C, x_m: 650, y_m: 150, vx_m_s: 0.1, vy_m_s: 0.3}
prior: {listed: 2, max_age_s: 60, phantoms: 1, sigma_m: 20}
camera: {pd: 0.85, clutter_per_frame: 0.3, labelled: false}
search: {cell_m: 500, growth_m2_per_s: 50, max_cells: 2, prior_weight: 1.0}
observer: {model: kalman, q_per_s: 0.01, r_m2: 5.0, iceberg_q_per_s: 0.0005}
planner: {objective: latency, time_limit_s: 1.0}
policy: {replan: both, period_s: 10.0}
"""


@pytest.fixture(scope="module")
def discovery_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate_text(tmp_path_factory.mktemp("discovery-run"), SMALL_DISCOVERY)


def test_discovery_run_journals_tracks_notes_and_search(discovery_run: Path) -> None:
    records = [json.loads(line) for line in (discovery_run / "journal.jsonl").read_text()
               .splitlines()]
    inputs = [r for r in records if r["event"] == "input"]
    kinds = {r["kind"] for r in inputs}
    assert {"CameraFrame", "Detection"} <= kinds
    added = [r for r in inputs if r["kind"] == "TargetAdded"]
    assert len(added) == 3 and all(r["prior"] is True for r in added)  # only the prior
    assert all(r["target"] is None for r in inputs if r["kind"] == "Detection")
    assert any(r["event"] == "track_born" for r in records)
    assert any(r["event"] == "track_confirmed" for r in records)
    statuses = {r["status"] for r in records if r["event"] == "track"}
    assert statuses <= {"tentative", "confirmed", "prior"} and "confirmed" in statuses
    search = [r for r in records if r["event"] == "search"]
    assert [r["t"] for r in search] == [float(10 * k) for k in range(7)]
    assert len(search[0]["cells"]) == 4 and len(search[0]["cells"][0]) == 5
    metrics = json.loads((discovery_run / "metrics.json").read_text())
    for key in ("gospa_mean_m", "true_confirmed_fraction", "time_to_confirm_s",
                "false_tracks_per_hour", "id_switches", "mean_uncertainty"):
        assert key in metrics
    assert 0.0 <= metrics["true_confirmed_fraction"] <= 1.0


def test_discovery_journal_replays_identical(
    discovery_run: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["replay", str(discovery_run), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["identical"] is True and report["differences"] == []
    records = [json.loads(line) for line in (discovery_run / "journal.jsonl").read_text()
               .splitlines()]
    notes = sum(1 for r in records if r["event"].startswith("track_"))
    assert notes > 3
    assert report["track_samples_compared"] == sum(1 for r in records if r["event"] == "track")
    assert report["track_samples_differing"] == 0


def test_labelled_camera_never_calls_the_tracker(monkeypatch: pytest.MonkeyPatch) -> None:
    scenario = load_scenario("paper-boat")
    assert scenario.camera.labelled and scenario.camera.pd == 1.0
    assert scenario.camera.clutter_per_frame == 0.0 and not discovery_mode(scenario)

    class Refused:
        def __init__(self, *args: object) -> None:
            raise AssertionError("the tracker was created for a labelled camera")

    monkeypatch.setattr(tracking, "Tracker", Refused)
    run = run_simulation(scenario, SimulationOptions(seed=0, uavs=3, duration_s=20.0,
                                                     snapshot_times_s=(1.0,)))
    assert run.metrics["plans"] > 0 and run.metrics["visits"]
    assert "gospa_mean_m" not in run.metrics  # the labelled run's metrics are as before
