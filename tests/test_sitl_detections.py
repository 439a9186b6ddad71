"""The simulator's detection feed: same icebergs as `gcs simulate` for a seed, scripted
targets, and the JSON lines it emits."""

from __future__ import annotations

import json

import numpy as np
import pytest

from domain.geodesy import GeoOrigin
from groundstation.runners.simulate.simulator import resolve_targets
from sitl.detections import DetectionSource, scenario_targets
from world.scenario import load_scenario


@pytest.mark.parametrize("seed", [0, 7])
def test_same_seed_same_icebergs_as_gcs_simulate(seed: int) -> None:
    scenario = load_scenario("paper-boat")
    ours = scenario_targets(scenario, np.random.default_rng(seed))
    theirs = resolve_targets(scenario, np.random.default_rng(seed))
    assert [(t.id, t.x_m, t.y_m, t.vx_m_s, t.vy_m_s) for t in ours] == [
        (t.id, t.x_m, t.y_m, t.vx_m_s, t.vy_m_s) for t in theirs
    ]
    assert len(ours) == 10


def test_feed_emits_detections_of_scenario_targets_and_the_boat() -> None:
    scenario = load_scenario("paper-boat")
    feed = DetectionSource.for_scenario(scenario, 3, scenario.origin)
    first = sorted(scenario_targets(scenario, np.random.default_rng(3)), key=lambda t: t.id)[0]
    lines = [json.loads(d) for d in feed.step(5.0, {2: (first.x_m, first.y_m)})]
    kinds = {line["kind"] for line in lines}
    assert kinds == {"detection", "boat"}
    seen = [line for line in lines if line["kind"] == "detection" and line["target"] == first.id]
    assert seen and all(line["vehicle"] == 2 for line in seen)
    x, y, _ = scenario.origin.to_local(seen[0]["lat_deg"], seen[0]["lon_deg"])
    assert abs(x - first.x_m) < 30 and abs(y - first.y_m) < 30  # drifted < 3 m/s * 5 s
    assert len([line for line in lines if line["kind"] == "boat"]) == 5  # 1 Hz


def test_scripted_target_appears_at_its_time(tmp_path: object) -> None:
    from pathlib import Path

    path = Path(str(tmp_path)) / "s.yaml"
    path.write_text(
        "name: t\ndescription: t\nduration_s: 100\norigin: {lat_deg: 78.9, lon_deg: 11.9}\n"
        "fleet: {count: 1}\ntargets:\n  list:\n    - {id: A, x_m: 0, y_m: 0}\n"
        "events:\n  - {t_s: 10, kind: target_added, target: {id: B, x_m: 50, y_m: 0}}\n",
        encoding="utf-8",
    )
    scenario = load_scenario(str(path))
    feed = DetectionSource.for_scenario(scenario, 0, GeoOrigin(78.9, 11.9), anonymous=True)
    early = [json.loads(d) for d in feed.step(9.0, {1: (0.0, 0.0)})]
    assert early and all(line["target"] is None for line in early)  # anonymous
    assert set(feed.world.icebergs) == {"A"}
    feed.step(11.0, {1: (0.0, 0.0)})
    assert set(feed.world.icebergs) == {"A", "B"}
