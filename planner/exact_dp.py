"""Exact dynamic programme over subsets (small instances).

Backward recursion over the path suffix (see planner.instance for the arc cost): for a set S
of targets and its first node j,

    F(S, j) = min_{k in S \\ {j}} [ tau mu d_jk + (1 - tau) h_jk sigma(S \\ {j}) + F(S \\ {j}, k) ],
    F({j}, j) = 0.

UAV u covering S:  G_u(S) = min_j [ tau mu d_uj + (1 - tau) h_uj sigma(S) + F(S, j) ], G_u({}) = 0.
Split over UAVs:   H_1 = G_1,  H_u(S) = min_{T subset S} H_{u-1}(S \\ T) + G_u(T).
The optimum is constant + H_m(all). Work: n^2 2^n for F, m 3^n for H.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import numpy.typing as npt

from planner.instance import Instance

IntArray = npt.NDArray[np.int64]


def dp_is_cheap(m: int, n: int) -> bool:
    """Whether the DP is fast (tens of ms): 3^n m for the split, n^2 2^n for the paths."""
    if m == 1:
        return n <= 13
    return n <= 11 or (n <= 12 and m <= 4)


@lru_cache(maxsize=8)
def _submask_pairs(n: int) -> tuple[IntArray, IntArray, IntArray]:
    """All (S, T) with T subset of S, sorted by S, plus group starts for reduceat."""
    codes = np.arange(3**n, dtype=np.int64)
    s = np.zeros_like(codes)
    t = np.zeros_like(codes)
    for i in range(n):
        digit = codes % 3
        codes //= 3
        s |= (digit > 0).astype(np.int64) << i
        t |= (digit == 2).astype(np.int64) << i
    order = np.argsort(s, kind="stable")
    s, t = s[order], t[order]
    starts = np.flatnonzero(np.r_[True, s[1:] != s[:-1]])
    return s, t, starts


def solve_dp(inst: Instance) -> list[list[int]]:
    """Optimal routes (kept target indices per UAV)."""
    m, n = inst.m, inst.n
    if n == 0:
        return [[] for _ in range(m)]
    full = (1 << n) - 1
    size = 1 << n
    w = inst.arc_weight()
    b = 1.0 - inst.tau
    tt = slice(m, m + n)
    wt, ht = w[tt, tt], inst.hop[tt, tt]
    masks = np.arange(size, dtype=np.int64)
    bits = (masks[:, None] >> np.arange(n)) & 1
    sig = bits @ inst.sigma  # sigma(S)
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
    g = np.empty((m, size))
    first = np.full((m, size), -1, dtype=np.int64)
    for u in range(m):
        cand = f + w[u, tt][None, :] + b * inst.hop[u, tt][None, :] * sig[:, None]
        best = np.argmin(cand, axis=1)
        g[u] = cand[masks, best]
        first[u] = best
        g[u, 0] = 0.0
    # split the set over UAVs
    h = [g[0]]
    if m > 1:
        s_pairs, t_pairs, starts = _submask_pairs(n)
        for u in range(1, m - 1):
            vals = h[-1][s_pairs ^ t_pairs] + g[u][t_pairs]
            h.append(np.minimum.reduceat(vals, starts))
    routes: list[list[int]] = [[] for _ in range(m)]
    remaining = full
    for u in range(m - 1, 0, -1):
        subs = _submasks(remaining)
        vals = h[u - 1][remaining ^ subs] + g[u][subs]
        take = int(subs[int(np.argmin(vals))])
        routes[u] = _path(take, int(first[u, take]), nxt)
        remaining ^= take
    routes[0] = _path(remaining, int(first[0, remaining]), nxt)
    return routes


def _submasks(mask: int) -> IntArray:
    out = [0]
    sub = mask
    while sub:
        out.append(sub)
        sub = (sub - 1) & mask
    return np.array(out, dtype=np.int64)


def _path(mask: int, start: int, nxt: IntArray) -> list[int]:
    path: list[int] = []
    j = start
    while mask:
        path.append(j)
        rest = mask ^ (1 << j)
        j = int(nxt[mask, j]) if rest else -1
        mask = rest
    return path
