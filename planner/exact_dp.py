"""Exact dynamic programme over subsets (small instances).

Backward recursion over the path suffix (see planner.instance for the arc cost): for a set S
of targets and its first node j,

    F(S, j) = min_{k in S \\ {j}} [ tau mu d_jk + (1 - tau) h_jk sigma(S \\ {j}) + F(S \\ {j}, k) ],
    F({j}, j) = 0.

UAV u covering S:  G_u(S) = min_j [ tau mu d_uj + (1 - tau) h_uj sigma(S) + F(S, j) ], G_u({}) = 0.
Split over UAVs:   H_1 = G_1,  H_u(S) = min_{T subset S} H_{u-1}(S \\ T) + G_u(T).
The optimum is constant + H_m(all). Work: n^2 2^n for F, (m - 2) 3^n for H (the last
split is a scan of the submasks of what is left, so one or two UAVs need no 3^n table).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import numpy.typing as npt

from planner.instance import Instance

IntArray = npt.NDArray[np.int64]


DP_MAX_TARGETS = 17  # memory: f and nxt are 2^n x n (2 x 18 MB at 17)
SPLIT_MAX_TARGETS = 13  # memory: the (S, T) table has 3^n pairs (38 MB at 13)
PATH_S_PER_UNIT = 1.2e-8  # seconds per n^2 2^n unit (measured: 1x16 0.16 s, 1x17 0.6 s)
SPLIT_S_PER_PAIR = 2.5e-8  # per 3^n pair and middle UAV (3x13: 0.035 s)
TABLE_S_PER_PAIR = 2.2e-7  # building the 3^n table, once per n and process (3x13: 0.33 s)


def dp_seconds(m: int, n: int) -> float:
    """Estimated DP time (both cores busy): n^2 2^n for the paths (any m), 3^n per UAV
    beyond the second for the split (two UAVs need no table: the last split is a submask
    scan), and the 3^n table (counted always, though it is built once per size and process, so that
    the choice is a pure function of (m, n, limit) and replays choose alike)."""
    est = PATH_S_PER_UNIT * n * n * 2.0**n
    if m >= 3:
        est += (SPLIT_S_PER_PAIR * (m - 2) + TABLE_S_PER_PAIR) * 3.0**n
    return est


def dp_is_cheap(m: int, n: int, time_limit_s: float = 5.0) -> bool:
    """Whether the DP is the method to use: it fits its memory caps and its estimated time
    is at most 0.25 s and half the limit (the DP cannot be interrupted). Measured
    against CP-SAT: 1x16 0.16 s by DP vs 22.8 s by CP-SAT; 5x12 0.02 s vs ~0.3 s."""
    if n > DP_MAX_TARGETS or (m >= 3 and n > SPLIT_MAX_TARGETS):
        return False
    return dp_seconds(m, n) <= min(0.25, 0.5 * time_limit_s)


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


_LAYER_ROWS = 1 << 15
"""(set, first target) pairs per vectorised block of :func:`solve_dp`'s recursion: at 17
targets a block's arrays stay a few MB instead of the ~30 MB of a whole layer."""
CACHED_LAYERS_MAX_TARGETS = 13
"""Up to this many targets the recursion's index blocks are kept per size and process
(< 2 MB); above, they are built at each solve (a fraction of its time there)."""


def _subset_tables(n: int) -> tuple[IntArray, IntArray, list[list[tuple[IntArray, ...]]]]:
    """For ``n`` targets: every mask ``S``, its bits (2^n x n), and per size ``c`` >= 2 the
    blocks ``(S, j, S \\ {j})`` of every set of ``c`` targets and every ``j`` in it, at most
    ``_LAYER_ROWS`` pairs a block (a pure function of ``n``)."""
    masks = np.arange(1 << n, dtype=np.int64)
    bits = (masks[:, None] >> np.arange(n)) & 1
    popcount = bits.sum(axis=1)
    layers: list[list[tuple[IntArray, ...]]] = []
    for c in range(2, n + 1):
        layer = masks[popcount == c]
        rows, js = np.nonzero(bits[layer] == 1)
        sel = layer[rows]
        prev = sel ^ (np.int64(1) << js)
        layers.append([(sel[k:k + _LAYER_ROWS], js[k:k + _LAYER_ROWS], prev[k:k + _LAYER_ROWS])
                       for k in range(0, len(sel), _LAYER_ROWS)])
    for array in (masks, bits):
        array.flags.writeable = False  # shared between solves
    for layer_blocks in layers:
        for block in layer_blocks:
            for array in block:
                array.flags.writeable = False
    return masks, bits, layers


_cached_subset_tables = lru_cache(maxsize=CACHED_LAYERS_MAX_TARGETS)(_subset_tables)
"""Every size up to the cap is kept (a fleet's plans come in many sizes: paper-boat's
3 UAVs plan 3 to 10 targets)."""


def solve_dp(inst: Instance) -> list[list[int]]:
    """Optimal routes (kept target indices per UAV).

    The recursion for ``F`` is evaluated a layer (all sets of one size) at a time: every
    pair ``(S, j)`` of the layer in one array expression, element for element the
    arithmetic of one ``j`` at a time (``F(S \\ {j}, k) + tau mu d_jk`` plus
    ``(1 - tau) h_jk sigma(S \\ {j})``, the first minimum over ``k``), so the routes and
    costs are the same bit for bit; at 3x10 it is ~9x fewer numpy calls."""
    m, n = inst.m, inst.n
    if n == 0:
        return [[] for _ in range(m)]
    full = (1 << n) - 1
    size = 1 << n
    w = inst.arc_weight()
    b = 1.0 - inst.tau
    tt = slice(m, m + n)
    wt, bht = w[tt, tt], b * inst.hop[tt, tt]  # (1 - tau) h_jk: the same products as per j
    tables = (_cached_subset_tables if n <= CACHED_LAYERS_MAX_TARGETS else _subset_tables)
    masks, bits, layers = tables(n)
    sig = bits @ inst.sigma  # sigma(S)
    f = np.full((size, n), np.inf)
    nxt = np.full((size, n), -1, dtype=np.int64)
    for j in range(n):
        f[1 << j, j] = 0.0
    for layer in layers:
        for sel, js, prev in layer:
            cand = f[prev] + wt[js] + bht[js] * sig[prev][:, None]
            best = np.argmin(cand, axis=1)
            f[sel, js] = cand[np.arange(len(sel)), best]
            nxt[sel, js] = best
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
    if m > 2:
        s_pairs, t_pairs, starts = _submask_pairs(n)
        for u in range(1, m - 1):
            vals = h[-1][s_pairs ^ t_pairs] + g[u][t_pairs]
            h.append(np.minimum.reduceat(vals, starts))
    routes: list[list[int]] = [[] for _ in range(m)]
    remaining = full
    for u in range(m - 1, 0, -1):
        subs = _submasks(remaining, masks)
        vals = h[u - 1][remaining ^ subs] + g[u][subs]
        take = int(subs[int(np.argmin(vals))])
        routes[u] = _path(take, int(first[u, take]), nxt)
        remaining ^= take
    routes[0] = _path(remaining, int(first[0, remaining]), nxt)
    return routes


def _submasks(mask: int, masks: IntArray) -> IntArray:
    """Every subset of ``mask``: the empty one, then the others in decreasing order (the
    order of ``sub = (sub - 1) & mask`` from ``mask``, whose first minimum is taken), out
    of ``masks`` (``0 .. 2^n - 1``)."""
    upto = masks[:mask + 1]
    subs = upto[(upto & mask) == upto]  # increasing, 0 first
    return np.concatenate((subs[:1], subs[:0:-1]))


def _path(mask: int, start: int, nxt: IntArray) -> list[int]:
    path: list[int] = []
    j = start
    while mask:
        path.append(j)
        rest = mask ^ (1 << j)
        j = int(nxt[mask, j]) if rest else -1
        mask = rest
    return path
