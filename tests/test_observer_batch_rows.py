"""The batch's bookkeeping per tick (issue 30: the simulation loop): one batching decision
per committed time, and after a correction only the corrected rows of the stacks replaced,
with every track exactly as the stacks built anew would leave it."""

from __future__ import annotations

import numpy as np
import pytest

from observer import Observer, ObserverConfig, kalman_track
from observer.kalman_track import KalmanTrack


def _observer(n: int) -> Observer:
    obs = Observer(ObserverConfig())
    for k in range(n):
        obs.add_target(f"T{k}", 0.0, 100.0 * k, 50.0 - 7.0 * k, vx_m_s=1.0 + 0.1 * k,
                       vy_m_s=-0.5, sigma0=20.0 + k)
    return obs


def _stacks(tracks: list[KalmanTrack]) -> list[tuple[np.ndarray, np.ndarray]]:
    return [(tr.kf.x.copy(), tr.kf.P.copy()) for tr in tracks]


def test_a_tick_of_tracks_on_the_grid_decides_once_and_restacks_nothing(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    obs = _observer(10)
    obs.predict_to(0.1)  # the first step stacks the tracks
    grid_steps: list[float] = []
    stacks: list[int] = []
    real_grid_steps, real_stack = kalman_track.grid_steps, np.stack

    def counting_grid_steps(anchor_s: float, t_s: float, h: float) -> tuple[int, int, float]:
        grid_steps.append(t_s)
        return real_grid_steps(anchor_s, t_s, h)

    def counting_stack(arrays: list[np.ndarray], *args: object, **kw: object) -> np.ndarray:
        stacks.append(len(arrays))
        return real_stack(arrays, *args, **kw)  # type: ignore[call-overload]

    monkeypatch.setattr(kalman_track, "grid_steps", counting_grid_steps)
    monkeypatch.setattr(kalman_track.np, "stack", counting_stack)
    for k in range(2, 12):
        obs.predict_to(k * 0.1)
    # one decision per committed time (all 10 tracks share it), not one per track
    assert grid_steps == [k * 0.1 for k in range(2, 12)]
    # a correction just after the grid point (the simulator's camera clock), then ticks
    assert obs.measure(11 * 0.1 + 3e-14, 300.0, 30.0, "T3").accepted
    obs.predict_to(1.2)
    obs.predict_to(1.3)
    assert stacks == []  # only T3's rows replaced, in a copy


def test_rows_replaced_after_corrections_equal_stacks_built_anew() -> None:
    """Two observers fed the same inputs: one through the batch as it is, the other with
    its batch's memory dropped before every step (so it stacks every track anew)."""
    kept, fresh = _observer(8), _observer(8)
    rng = np.random.default_rng(7)
    t_s = 0.0
    for step in range(1, 120):
        t_s = step * 0.1
        if step % 5 == 0:  # a detection just after the grid point, as the simulator's
            k = int(rng.integers(8))
            t_det = t_s + 1e-13 * float(rng.integers(0, 30))
            x, y = float(rng.normal(100.0 * k, 5.0)), float(rng.normal(50.0 - 7.0 * k, 5.0))
            for obs in (kept, fresh):
                obs.measure(t_det, x, y, f"T{k}")
        fresh._batch._tracks = []  # forget the stacks: np.stack of every track
        for obs in (kept, fresh):
            obs.predict_to(t_s)
        for tid in kept.target_ids:
            a, b = kept._tracks[tid], fresh._tracks[tid]
            assert isinstance(a, KalmanTrack) and isinstance(b, KalmanTrack)
            assert np.array_equal(a.kf.x, b.kf.x) and np.array_equal(a.kf.P, b.kf.P)
            assert np.array_equal(a.x_view, b.x_view) and np.array_equal(a.p_view, b.p_view)
            assert a.sigma == b.sigma and a.t_s == b.t_s
    assert kept.counters["accepted"] == fresh.counters["accepted"] > 0
