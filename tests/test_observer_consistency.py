"""Statistical check: over a seeded run against world.model, the observer's position error is
consistent with its covariance (NEES), and a mis-tuned filter fails the same check."""

from __future__ import annotations

import numpy as np
import pytest

from observer import Observer, ObserverConfig
from world.model import Camera, Iceberg, World

N_TARGETS = 40
# chi-square quantiles (scipy.stats.chi2.ppf), hard-coded to keep scipy out of the tests:
CHI2_80_LO, CHI2_80_HI = 51.172, 116.321  # 0.5 % and 99.5 % for 80 dof (2 dof x 40 targets)
CHI2_2_95 = -2.0 * np.log(0.05)  # 5.991, closed form for 2 dof
P0 = (25.0, 25.0, 0.5, 0.5)
DT_S = 0.1
DURATION_S = 120.0


def nees_series(filter_q_per_s: float, seed: int = 11) -> np.ndarray:
    """Position NEES e' P^-1 e (2 dof) of every target every 0.5 s, shape (times, targets).

    Truth: constant velocity plus process noise q = 0.1 (the paper's Q). Camera: 2 Hz,
    R = 5 I, every target in view, but target i is only measured while
    ``(t // 10) % 3 == i % 3``: 10 s seen, 20 s unseen, so the check covers both long
    predictions and corrections.
    """
    rng = np.random.default_rng(seed)
    icebergs = [
        Iceberg(f"T{i:02d}", float(x), float(y), float(vx), float(vy), q_per_s=0.1)
        for i, (x, y, vx, vy) in enumerate(
            np.column_stack(
                [rng.uniform(0, 1500, (N_TARGETS, 2)), rng.uniform(-3, 3, (N_TARGETS, 2))]
            )
        )
    ]
    world = World(icebergs, None, Camera(fov_radius_m=1e7, rate_hz=2.0, r_m2=5.0), rng)
    obs = Observer(ObserverConfig(q_per_s=filter_q_per_s, r_m2=5.0))
    init = np.random.default_rng(seed + 1)
    for k, ice in enumerate(world.icebergs.values()):
        e = init.normal(0.0, np.sqrt(P0))
        obs.add_target(
            ice.id,
            0.0,
            ice.x_m + e[0],
            ice.y_m + e[1],
            vx_m_s=ice.vx_m_s + e[2],
            vy_m_s=ice.vy_m_s + e[3],
            p0=P0,
        )
        assert obs.target_ids[-1] == ice.id and k < N_TARGETS
    rows = []
    for step in range(1, round(DURATION_S / DT_S) + 1):
        world.step(DT_S)
        obs.predict_to(world.t_s)
        measurements = world.observe({"uav": (0.0, 0.0)})
        if not measurements:
            continue
        truth = world.true_positions()
        row = []
        for snap in obs.tracks():  # the prior at this camera tick
            pxx, pxy, pyy = snap.cov_xy
            e = np.array([truth[snap.id][0] - snap.x_m, truth[snap.id][1] - snap.y_m])
            row.append(float(e @ np.linalg.solve([[pxx, pxy], [pxy, pyy]], e)))
        rows.append(row)
        window = int(world.t_s // 10.0) % 3
        for m in measurements:
            if int(m.target[1:]) % 3 == window:
                obs.measure(m.t_s, m.x_m, m.y_m, m.target, r_m2=m.r_m2)
        assert step > 0
    counters = obs.counters
    if filter_q_per_s == 0.1:  # a tuned filter gates out ~1e-4 of the true measurements
        assert counters["rejected_gate"] <= 1e-3 * counters["accepted"], counters
    return np.array(rows)


def test_nees_is_consistent_with_the_covariance() -> None:
    nees = nees_series(0.1)
    n_times, n_targets = nees.shape
    assert (n_times, n_targets) == (241, N_TARGETS)  # ticks 0 (due at the first step) .. 240
    # Average NEES over the targets at one time: N * ANEES ~ chi2(2 N) if consistent.
    lo, hi = CHI2_80_LO / n_targets, CHI2_80_HI / n_targets
    per_time = nees.mean(axis=1)
    inside = np.mean((per_time >= lo) & (per_time <= hi))
    assert inside >= 0.95, (inside, lo, hi)
    # Over the whole run: the mean is 2 (dof); samples are correlated in time, so the bound
    # is loose (+-15 %) but still far tighter than a mis-tuned filter (see below).
    assert nees.mean() == pytest.approx(2.0, rel=0.15)
    # 95 % of single NEES samples should lie below chi2_2(0.95) = 5.99
    assert np.mean(nees <= CHI2_2_95) == pytest.approx(0.95, abs=0.03)
    # (seeds 1-12 give mean NEES 1.78-2.10, per-time inside 0.96-1.0, fraction 0.94-0.97)


def test_mistuned_filters_fail_the_same_check() -> None:
    overconfident = nees_series(0.001)  # q 100 times too small
    conservative = nees_series(10.0)  # q 100 times too large
    assert overconfident.mean() > 2.0 * 1.15 * 3
    assert conservative.mean() < 2.0 * 0.85 / 3
