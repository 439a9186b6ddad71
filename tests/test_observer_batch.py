"""The observer's batched prediction against filterpy's per-track predict.

``KalmanBatch`` predicts every track that advances one grid step with one stacked product;
the tracks must come out as filterpy's ``KalmanFilter.predict`` leaves them (1e-9 relative:
on one machine they are bit-for-bit equal, the same BLAS products). The observer as a whole
(batch, partial steps, gaps, corrections) must equal tracks advanced one by one.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from observer import Observer, ObserverConfig
from observer.kalman_track import (
    C,
    CvFilter,
    KalmanBatch,
    KalmanTrack,
    process_noise,
    transition,
)

REL = 1e-9


def _random_track(rng: np.random.Generator, grid_step_s: float) -> KalmanTrack:
    """A track with a random state and a random full (SPD, coupled) covariance."""
    q_per_s = float(rng.uniform(0.0, 2.0))
    track = KalmanTrack(0.0, rng.normal(0.0, 500.0, size=4).tolist(), [1.0] * 4, q_per_s,
                        grid_step_s)
    m = rng.normal(size=(4, 4)) * 10.0 ** rng.uniform(-2, 3)
    track.kf.P = m @ m.T + np.eye(4) * 1e-3
    track.x_view, track.p_view = track.kf.x, track.kf.P
    return track


def _kalman_filter() -> Any:
    """filterpy's KalmanFilter, the reference (imported here: it pulls in scipy.stats, a
    second of CPU that the workers which never run these tests need not pay)."""
    from filterpy.kalman import KalmanFilter

    return KalmanFilter(dim_x=4, dim_z=2)


def _filterpy_predict(x: np.ndarray, p: np.ndarray, dt_s: float, q_per_s: float
                      ) -> tuple[np.ndarray, np.ndarray]:
    kf = _kalman_filter()
    kf.x, kf.P = x.copy(), p.copy()
    kf.predict(F=transition(dt_s), Q=process_noise(q_per_s, dt_s))
    return kf.x, kf.P


def _assert_close(a: np.ndarray, b: np.ndarray) -> None:
    np.testing.assert_allclose(a, b, rtol=REL, atol=REL * max(1.0, float(np.abs(b).max())))


@pytest.mark.parametrize("seed", range(6))
def test_batched_step_equals_filterpy_predict_for_random_states_and_steps(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(20):
        h = float(rng.choice([0.1, 0.05, 0.2, rng.uniform(0.01, 5.0)]))
        tracks = [_random_track(rng, h) for _ in range(int(rng.integers(1, 25)))]
        expected = [_filterpy_predict(tr.kf.x, tr.kf.P, h, tr.q_per_s) for tr in tracks]
        KalmanBatch(h).predict_to(tracks, h)
        for tr, (x, p) in zip(tracks, expected, strict=True):
            assert tr.t_s == h and tr.t_anchor_s == h
            _assert_close(tr.kf.x, x)
            _assert_close(tr.kf.P, p)
            assert tr.sigma == pytest.approx(float(p[0, 0] + p[1, 1]), rel=REL)
            assert tr.p_view is tr.kf.P  # on the grid the view is the committed state


def test_repeated_batches_reuse_stacks_and_still_equal_filterpy() -> None:
    rng = np.random.default_rng(7)
    h = 0.1
    tracks = [_random_track(rng, h) for _ in range(8)]
    states = [(tr.kf.x.copy(), tr.kf.P.copy()) for tr in tracks]
    batch = KalmanBatch(h)
    for k in range(1, 51):
        batch.predict_to(tracks, k * h)
        states = [_filterpy_predict(x, p, h, tr.q_per_s)
                  for tr, (x, p) in zip(tracks, states, strict=True)]
        if k == 20:  # a new q on one track and a correction on another: no stale stacks
            tracks[3].set_process_noise(1.5)
            tracks[5].correct(k * h, 10.0, -20.0, 5.0)
            states[5] = (tracks[5].kf.x.copy(), tracks[5].kf.P.copy())
    for tr, (x, p) in zip(tracks, states, strict=True):
        _assert_close(tr.kf.x, x)
        _assert_close(tr.kf.P, p)


def _observer_pair(seed: int) -> tuple[Observer, list[KalmanTrack], np.random.Generator]:
    """An observer and the same targets as bare tracks, to be advanced one by one."""
    rng = np.random.default_rng(seed)
    cfg = ObserverConfig(q_per_s=0.1, r_m2=5.0, max_step_s=0.1)
    obs = Observer(cfg)
    singles = []
    for k in range(12):
        state = rng.normal(0.0, 300.0, size=2).tolist() + rng.uniform(-3, 3, size=2).tolist()
        p0 = rng.uniform(0.5, 50.0, size=4).tolist()
        t0 = float(rng.choice([0.0, 0.0, 0.35]))
        obs.add_target(f"T{k:02d}", t0, state[0], state[1], vx_m_s=state[2], vy_m_s=state[3],
                       p0=p0)
        singles.append(KalmanTrack(t0, state, p0, cfg.q_per_s, cfg.max_step_s))
    return obs, singles, rng


@pytest.mark.parametrize("seed", range(4))
def test_observer_equals_tracks_advanced_one_by_one(seed: int) -> None:
    obs, singles, rng = _observer_pair(seed)
    t = 0.0
    for _ in range(300):
        # fixed steps (the simulator), jitter (the world's summed clock), irregular ticks
        # (the daemon) and gaps of several grid steps
        t += float(rng.choice([0.1, 0.1, 0.1 + 2e-15, 0.037, 0.6, 1e-13]))
        obs.predict_to(t)
        for tr in singles:
            tr.predict_to(t)
        if rng.uniform() < 0.2:
            k = int(rng.integers(len(singles)))
            x, y = singles[k].state[:2]
            mx, my = x + float(rng.normal(0, 2)), y + float(rng.normal(0, 2))
            assert obs.measure(t, mx, my, f"T{k:02d}").accepted
            singles[k].correct(t, mx, my, 5.0)
        if rng.uniform() < 0.02:
            k = int(rng.integers(len(singles)))
            obs.set_process_noise(f"T{k:02d}", 0.4)
            singles[k].set_process_noise(0.4)
    for k, tr in enumerate(singles):
        snap = obs.track(f"T{k:02d}")
        assert snap.t_s == tr.t_s
        assert (snap.x_m, snap.y_m, snap.vx_m_s, snap.vy_m_s) == pytest.approx(tr.state, rel=REL)
        assert snap.sigma == pytest.approx(tr.sigma, rel=REL)
        assert snap.cov_xy == pytest.approx(tr.cov_xy, rel=REL)


@pytest.mark.parametrize("seed", range(4))
def test_floe_filter_predicts_and_updates_as_filterpy_bit_for_bit(seed: int) -> None:
    """``CvFilter`` makes filterpy's numpy calls in filterpy's order: equal, not just close."""
    rng = np.random.default_rng(100 + seed)
    for _ in range(60):
        x = rng.normal(0.0, 500.0, size=(4, 1))
        m = rng.normal(size=(4, 4)) * 10.0 ** rng.uniform(-2, 3)
        p = m @ m.T + np.eye(4) * 1e-3
        dt_s, q_per_s = float(rng.uniform(0.01, 5.0)), float(rng.uniform(0.0, 2.0))
        z, r = rng.normal(0.0, 500.0, size=2), float(rng.uniform(0.1, 400.0)) * np.eye(2)
        ref = _kalman_filter()
        ref.x, ref.P, ref.H = x.copy(), p.copy(), C.copy()
        ours = CvFilter(x.copy(), p.copy())
        for f in (ref, ours):
            f.predict(F=transition(dt_s), Q=process_noise(q_per_s, dt_s))
        assert np.array_equal(ours.x, ref.x) and np.array_equal(ours.P, ref.P)
        for f in (ref, ours):
            f.update(z, R=r)
        assert np.array_equal(ours.x, ref.x)
        assert np.array_equal(ours.P, ref.P)
        assert np.array_equal(ours.K, ref.K)
