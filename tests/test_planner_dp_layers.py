"""The subset DP evaluates its recursion a layer at a time, with the same results bit for bit
as the recursion one first target at a time (issue 30: the simulation loop's plans)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from planner import exact_dp


@dataclass
class _Inst:
    m: int
    n: int
    w: np.ndarray
    hop: np.ndarray
    sigma: np.ndarray
    tau: float

    def arc_weight(self) -> np.ndarray:
        return self.w


def _instance(rng: np.random.Generator, m: int, n: int, ties: bool) -> _Inst:
    size = m + n
    if ties:  # small integers: many equal candidates, so the first minimum matters
        w = rng.integers(0, 4, (size, size)).astype(float)
        hop = rng.integers(1, 3, (size, size)).astype(float)
        sigma = rng.integers(0, 3, n).astype(float)
    else:
        w = rng.uniform(0.0, 2000.0, (size, size))
        hop = rng.uniform(1.0, 5.0, (size, size))
        sigma = rng.uniform(0.0, 1e4, n)
    if rng.random() < 0.3:
        w[rng.integers(size), rng.integers(size)] = np.inf
    tau = float(rng.choice([0.0, 0.5, 1.0, float(rng.uniform())]))
    return _Inst(m, n, w, hop, sigma, tau)


def _reference_f(inst: _Inst) -> tuple[np.ndarray, np.ndarray]:
    """F and its argmin, one first target at a time (the recursion as written until issue
    30's loop work)."""
    m, n = inst.m, inst.n
    size = 1 << n
    b = 1.0 - inst.tau
    tt = slice(m, m + n)
    wt, ht = inst.w[tt, tt], inst.hop[tt, tt]
    masks = np.arange(size, dtype=np.int64)
    bits = (masks[:, None] >> np.arange(n)) & 1
    sig = bits @ inst.sigma
    popcount = bits.sum(axis=1)
    f = np.full((size, n), np.inf)
    nxt = np.full((size, n), -1, dtype=np.int64)
    for j in range(n):
        f[1 << j, j] = 0.0
    for c in range(2, n + 1):
        layer = masks[popcount == c]
        for j in range(n):
            sel = layer[(layer >> j) & 1 == 1]
            prev = sel ^ (1 << j)
            cand = f[prev] + wt[j][None, :] + b * ht[j][None, :] * sig[prev][:, None]
            best = np.argmin(cand, axis=1)
            f[sel, j] = cand[np.arange(len(sel)), best]
            nxt[sel, j] = best
    return f, nxt


def _solved_f(inst: _Inst, monkeypatch: pytest.MonkeyPatch) -> tuple[np.ndarray, np.ndarray]:
    """F and its argmin as :func:`exact_dp.solve_dp` fills them (its first two 2^n x n
    arrays)."""
    seen: list[np.ndarray] = []
    real_full = np.full

    def spy_full(shape: object, fill: object, *args: object, **kw: object) -> np.ndarray:
        out = real_full(shape, fill, *args, **kw)  # type: ignore[call-overload]
        if shape == (1 << inst.n, inst.n):
            seen.append(out)
        return out

    with monkeypatch.context() as patch:
        patch.setattr(exact_dp.np, "full", spy_full)
        exact_dp.solve_dp(inst)  # type: ignore[arg-type]
    return seen[0], seen[1]


def test_layered_recursion_is_the_per_target_recursion_bit_for_bit(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    rng = np.random.default_rng(30)
    for case in range(120):
        inst = _instance(rng, int(rng.integers(1, 4)), int(rng.integers(1, 10)), case % 2 == 0)
        want_f, want_nxt = _reference_f(inst)
        got_f, got_nxt = _solved_f(inst, monkeypatch)
        assert np.array_equal(got_f, want_f)
        assert np.array_equal(got_nxt, want_nxt)


def test_recursion_makes_one_argmin_per_layer_not_per_target(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """3 UAVs, 10 targets: the recursion's 9 layers and one per UAV (the rows of G), not
    one per (layer, first target): 9 x 10 + 3 = 93 before."""
    inst = _instance(np.random.default_rng(1), 3, 10, False)
    calls = []
    real_argmin = np.argmin

    def counting_argmin(a: np.ndarray, *args: object, **kw: object) -> object:
        calls.append(a.shape)
        return real_argmin(a, *args, **kw)  # type: ignore[call-overload]

    monkeypatch.setattr(exact_dp.np, "argmin", counting_argmin)
    routes = exact_dp.solve_dp(inst)  # type: ignore[arg-type]
    assert sorted(t for r in routes for t in r) == list(range(10))
    assert len(calls) <= 9 + 3 + 2  # layers, G per UAV, the split's two choices
