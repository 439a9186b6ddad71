"""observer.existence (probability inside a footprint, existence updates) and
observer.association (GNN costs, JPDA marginals) against independent computations."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from observer.association import gnn_assign, jpda_marginals
from observer.existence import (
    existence_after_hit,
    existence_after_miss,
    inside_probability,
    position_after_miss,
)

CASES = [
    ((0.0, 0.0), [[25.0, 0.0], [0.0, 25.0]]),  # well inside
    ((140.0, 0.0), [[100.0, 30.0], [30.0, 400.0]]),  # near the edge, tilted
    ((300.0, 50.0), [[1e5, 2e4], [2e4, 3e4]]),  # outside, wide
    ((150.0, 0.0), [[1.0, 0.0], [0.0, 1.0]]),  # on the edge
    ((0.0, 0.0), [[1e7, 0.0], [0.0, 1e7]]),  # huge: Pin ~ R^2 / (2 sigma^2)
    ((149.0, 0.0), [[1e-8, 0.0], [0.0, 5.0]]),  # degenerate axis
    ((400.0, 0.0), [[4.0, 0.0], [0.0, 4.0]]),  # far outside
]


def test_inside_probability_matches_monte_carlo() -> None:
    rng = np.random.default_rng(5)
    means = np.array([c[0] for c in CASES])
    covs = np.array([c[1] for c in CASES])
    got = inside_probability(means, covs, (0.0, 0.0), 150.0)
    for k, (m, p) in enumerate(CASES):
        pts = rng.multivariate_normal(m, p, size=50_000)
        mc = float(np.mean(np.hypot(pts[:, 0], pts[:, 1]) <= 150.0))
        assert got[k] == pytest.approx(mc, abs=4.0 * math.sqrt(mc * (1 - mc) / 50_000) + 1e-4)
    assert got[0] == 1.0 and got[-1] == 0.0
    assert got[4] == pytest.approx(1.0 - math.exp(-(150.0**2) / 2e7), rel=1e-4)


def test_existence_updates() -> None:
    r = np.array([0.999, 0.5, 0.5])
    pin = np.array([1.0, 1.0, 0.0])
    after = existence_after_miss(r, 0.85, pin)
    odds = after / (1 - after)
    assert odds[0] == pytest.approx(999 * 0.15) and odds[1] == pytest.approx(0.15)
    assert after[2] == 0.5  # out of view: no evidence
    # a hit right on a precise track is strong evidence; one in clutter-dense water less so
    lik = 1.0 / (2 * math.pi * 10.0)
    assert existence_after_hit(0.1, 0.85, 1.0, lik, 1e-6) > 0.99
    assert existence_after_hit(0.1, 0.85, 1.0, lik, 1.0) < 0.1


def test_gnn_takes_the_likeliest_joint_assignment() -> None:
    """Two tracks, two detections: the greedy nearest pair (d0-t0, ratio 10^4) would leave
    d1 to nothing; the joint optimum pairs d0-t1 and d1-t0 (10^3 * 10^3 > 10^4 * 1)."""
    lr = np.array([[math.log(1e4), math.log(1e3)], [math.log(1e3), -math.inf]])
    assert gnn_assign(lr) == {0: 1, 1: 0}
    # a pair less likely than "clutter or new" (ratio < 1) is not taken
    assert gnn_assign(np.log(np.array([[0.5]]))) == {}
    assert gnn_assign(np.zeros((0, 3))) == {}


def test_jpda_marginals_equal_brute_force() -> None:
    rng = np.random.default_rng(2)
    lr = rng.normal(0.0, 2.0, size=(4, 3))
    lr[rng.random((4, 3)) < 0.3] = -np.inf
    beta = jpda_marginals(lr, 10_000)
    n, m = lr.shape
    total, acc = 0.0, np.zeros((n, m))
    for picks in itertools.product(range(-1, n), repeat=m):  # detection per track or -1
        chosen = [i for i in picks if i >= 0]
        if len(chosen) != len(set(chosen)):
            continue
        logw = sum(lr[i, j] for j, i in enumerate(picks) if i >= 0)
        if not np.isfinite(logw):
            continue
        w = math.exp(logw)
        total += w
        for j, i in enumerate(picks):
            if i >= 0:
                acc[i, j] += w
    # clusters are independent, so the marginals of the whole scan equal the brute force
    np.testing.assert_allclose(beta, acc / total, atol=1e-12)
    assert np.all(beta.sum(axis=0) <= 1.0 + 1e-12) and np.all(beta.sum(axis=1) <= 1.0 + 1e-12)
    approx = jpda_marginals(lr, 1)  # over the limit: per-track PDA, still probabilities
    assert np.all(approx.sum(axis=0) <= 1.0 + 1e-12)


def test_position_after_a_miss_matches_monte_carlo() -> None:
    """The moment-matched density after a miss, N(m, P) (1 - pd 1_D) / Z, against weighted
    samples; a track deep inside the disc (symmetric cut) is left alone."""
    rng = np.random.default_rng(9)
    means = np.array([[100.0, 20.0], [200.0, 0.0], [0.0, 0.0]])
    covs = np.array(
        [[[1e4, 3e3], [3e3, 2e4]], [[400.0, 0.0], [0.0, 900.0]], [[25.0, 0.0], [0.0, 25.0]]]
    )
    mask, new_m, new_p = position_after_miss(means, covs, (0.0, 0.0), 150.0, 0.85)
    assert mask.tolist() == [True, True, False]
    for k in range(2):
        pts = rng.multivariate_normal(means[k], covs[k], size=100_000)
        w = np.where(np.hypot(pts[:, 0], pts[:, 1]) <= 150.0, 0.15, 1.0)
        mean = (pts * w[:, None]).sum(axis=0) / w.sum()
        d = pts - mean
        cov = (d.T * w) @ d / w.sum()
        np.testing.assert_allclose(new_m[k], mean, atol=0.03 * math.sqrt(covs[k].trace()))
        np.testing.assert_allclose(new_p[k], cov, rtol=0.05, atol=0.02 * covs[k].trace())
    assert new_m[0][0] > means[0][0]  # pushed out of the disc, away from its centre
