"""The tracker benchmark's recording and scoring (benchmarks/tracker_bench*.py), without any
tracker: an oracle that reports the truth scores perfectly, a blind one scores nothing."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))

import itertools

import tracker_bench
from tracker_bench_world import (
    Recording,
    WorldParams,
    load_recording,
    record,
    save_recording,
)

PARAMS = WorldParams(seed=3, duration_s=120.0, clutter_per_frame=0.5)


@pytest.fixture(scope="module")
def rec() -> Recording:
    return record(PARAMS)


def test_recording_is_deterministic_and_round_trips(rec: Recording, tmp_path: Path) -> None:
    assert record(PARAMS) == rec
    assert record(WorldParams(seed=4, duration_s=120.0)) != rec
    save_recording(rec, tmp_path / "frames.json")
    assert load_recording(tmp_path / "frames.json") == rec


def test_frames_follow_the_camera_model(rec: Recording) -> None:
    p = rec.params
    ticks = round(p.duration_s * p.camera_hz)
    assert len(rec.frames) == ticks * p.n_uavs
    assert [f.t_s for f in rec.frames] == sorted(f.t_s for f in rec.frames)
    in_view = detected = clutter = 0
    for f in rec.frames:
        truth = rec.truth_at(f.t_s)
        in_view += sum(math.hypot(x - f.x_m, y - f.y_m) <= f.radius_m for x, y in truth.values())
        for x, y, tid in f.detections:
            if tid is None:
                clutter += 1
                assert math.hypot(x - f.x_m, y - f.y_m) <= f.radius_m + 1e-9
            else:
                detected += 1
                tx, ty = truth[tid]
                assert math.hypot(x - tx, y - ty) < 6 * math.sqrt(p.r_m2)
    assert in_view > 50  # the lawnmower does fly over icebergs in two minutes
    assert 0.6 < detected / in_view < 1.0  # pd 0.85
    assert 0.3 < clutter / len(rec.frames) < 0.7  # 0.5 per frame
    # UAVs move at the set speed between ticks (straight legs of the lawnmower).
    uav1 = [(f.x_m, f.y_m) for f in rec.frames if f.vehicle == "uav1"]
    step = p.speed_m_s / p.camera_hz
    assert all(math.dist(a, b) <= step + 1e-6 for a, b in itertools.pairwise(uav1))


class Oracle(tracker_bench._Adapter):
    """Confirms every iceberg the camera has detected, at its true position."""

    def __init__(self, rec: Recording) -> None:
        self.rec = rec
        self.seen: set[str] = set()

    def scan(self, k: int) -> None:
        self.seen.update(tid for _, _, tid in self.rec.frames[k].detections if tid)

    def confirmed(self, t_s: float) -> dict[str, tuple[float, float]]:
        truth = self.rec.truth_at(t_s)
        return {f"N{tid}": truth[tid] for tid in sorted(self.seen)}

    def update_sources(self) -> dict[str, set[str]]:
        return {f"N{tid}": {tid} for tid in self.seen}


class Blind(tracker_bench._Adapter):
    def scan(self, k: int) -> None:
        pass

    def confirmed(self, t_s: float) -> dict[str, tuple[float, float]]:
        return {"ghost": (-5000.0, -5000.0)}

    def update_sources(self) -> dict[str, set[str]]:
        return {"ghost": {"B1", "B2"}, "other": {"B3"}}  # one track fed by two icebergs


def test_scoring_an_oracle_and_a_blind_tracker(rec: Recording) -> None:
    made: list[Oracle] = []
    oracle = tracker_bench.run(rec, lambda: made.append(Oracle(rec)) or made[-1])
    assert len(oracle.scan_s) == len(rec.frames)
    m = oracle.measures
    assert m["false_tracks_per_hour"] == 0.0
    assert m["id_switches"] == 0
    assert m["track_truth_changes"] == 0
    assert m["mixed_update_tracks"] == 0
    assert m["gospa_mean_m"] > 0.0  # icebergs not yet seen are missed
    assert m["time_to_confirm_s"]["max"] <= 1.0  # confirmed at the next 1 s sample
    seen = made[0].seen
    assert oracle.confirmed_ever == len(seen)
    assert 0 < len(seen) < len(rec.truth)
    end = rec.truth_at(PARAMS.duration_s)
    in_area = {t for t, (x, y) in end.items() if 0 <= x <= 3000 and 0 <= y <= 3000}
    assert m["true_confirmed_fraction"] == pytest.approx(len(seen & in_area) / len(in_area))
    blind = tracker_bench.run(rec, Blind)
    assert blind.measures["true_confirmed_fraction"] == 0.0
    assert blind.measures["false_tracks_per_hour"] == pytest.approx(3600.0 / PARAMS.duration_s)
    assert blind.measures["gospa_mean_m"] > m["gospa_mean_m"]
    assert blind.measures["mixed_update_tracks"] == 1


def test_crossing_pairs_pass_within_50_m() -> None:
    """The ``crossing`` stress case: the first 2 k icebergs pass each other in pairs within
    ``crossing_miss_m`` (closest approach inside the run), the rest are as without pairs."""
    params = WorldParams(seed=5, duration_s=100.0, crossing_pairs=3)
    rec = record(params)
    plain = record(WorldParams(seed=5, duration_s=100.0))
    assert rec.truth[6:] == plain.truth[6:] and rec.truth[:6] != plain.truth[:6]
    for k in range(3):
        a, b = rec.truth[2 * k], rec.truth[2 * k + 1]
        gaps = [math.dist(rec.truth_at(t)[a.id], rec.truth_at(t)[b.id]) for t in range(101)]
        closest = min(range(101), key=gaps.__getitem__)
        assert gaps[closest] <= 50.0 + 0.5 and 25 <= closest <= 75
    assert tracker_bench.CASES["crossing"] == {"crossing_pairs": 4}


def test_percentile_is_nearest_rank() -> None:
    assert tracker_bench.percentile([3.0, 1.0, 2.0, 4.0], 90) == 4.0
    assert tracker_bench.percentile([3.0, 1.0, 2.0, 4.0], 50) == 2.0
    assert tracker_bench.percentile([7.0], 90) == 7.0
