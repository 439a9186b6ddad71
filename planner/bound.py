"""Proven lower bounds on the objective J of an Instance (any objective of its arc form).

Every objective floe solves is J = C + sum over used arcs (i -> j) of w_ij + b h_ij R_j, with
C = Instance.constant, w = tau mu d, b = 1 - tau >= 0, hops h >= 0 and R_j the sigma of j and
of every target after it (planner.instance). Equivalently the variable part is
sum_arcs w_ij + b sum_j sigma_j H_j, where H_j = the hops summed along the path up to j.
Along a path, the target at position p (p = 1 for a UAV's first target) reached over the arc
(i -> j) has H_j = h_ij if p = 1 and H_j = H_i + h_ij >= L[p - 1, i] + h_ij otherwise, where
L[q, i] bounds the hops of any walk reaching i at position q or later (hops_to_reach). For
the sequence objective every hop is 1 and this is an equality: H_j = p.

Two bounds, both valid for every objective:

* ``in_arc_bound`` (O(N^2), any size): each target is entered by exactly one arc and
  sum_j sigma_j (p_j - 1) is smallest when the largest sigma take the first places round robin
  over the m UAVs (position 1 + k // m for the k-th largest), so
      J >= C + sum_j min_i (w_ij + b h_ij sigma_j) + b h_min sum_k sigma_(k) (k // m).
* ``lp_bound``: the layered (position-indexed) LP relaxation. Columns a[u, j] (UAV u flies
  first to j; cost w_uj + b h_uj sigma_j) and z[i, j, p] (j is reached from i at position p,
  p = 2..P; cost w_ij + b sigma_j (h_ij + L[p - 1, i])); rows: every target entered once
  (= 1), at most one first target per UAV (<= 1), and leaving i into layer p needs i in layer
  p - 1: sum_j z[i, j, p] <= in(i, p - 1). With P < n the last layer is absorbing ("position
  >= P"; its arcs cost as at P, and they may also leave from layer P itself), which keeps the
  LP small on big fleets and only weakens it. This is the time-indexed travelling-repairman
  formulation (the CP-SAT position model's LP). The value returned is a *safe dual bound*:
  with HiGHS's duals y and reduced costs r = c - A^T y, b^T y + sum_j min(r_j, 0) (every column
  is <= 1) bounds the LP optimum from below whatever the solver's tolerances, so rounding never
  lets the bound exceed the optimum.

scipy (HiGHS inside) is imported lazily: small instances are solved exactly by the DP and never
need it. highspy itself cannot be loaded next to OR-Tools (their bundled HiGHS builds clash).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from planner.instance import Instance

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

LP_MAX_COLUMNS = 400_000  # above this the LP is not tried (HiGHS ~ 2 s here)
MIN_LAYERS = 2  # P = 1 is no layered LP: below this the in-arc bound is used alone


@dataclass(frozen=True)
class LpBound:
    """A solved layered LP: `value` is a proven lower bound on J (constant included).

    `reduced` holds the safe reduced cost of every column (a then z, see `layers`): any plan
    using column k costs at least value + reduced[k] (used to fix CP-SAT variables)."""

    value: float
    layers: int  # P: positions 1..P, the last absorbing if P < n
    reduced: FloatArray
    lp_time_s: float


def h_min(inst: Instance) -> float:
    """Smallest hop of a usable arc (UAV -> target, target -> target), 0 if none."""
    m, n = inst.m, inst.n
    if n == 0:
        return 0.0
    first = inst.hop[:m, m:]
    best = float(first.min())
    if n > 1:
        tt = inst.hop[m:, m:].copy()
        np.fill_diagonal(tt, np.inf)
        best = min(best, float(tt.min()))
    return max(best, 0.0)


def _round_robin_extra(inst: Instance) -> float:
    """min over plans of sum_j sigma_j (p_j - 1): k-th largest sigma at position 1 + k // m."""
    ordered = np.sort(inst.sigma)[::-1]
    return float((ordered * (np.arange(inst.n) // inst.m)).sum())


def in_arc_bound(inst: Instance) -> float:
    """J >= C + sum_j min_i (w_ij + b h_ij sigma_j) + b h_min sum_k sigma_(k) (k // m)."""
    m, n = inst.m, inst.n
    if n == 0:
        return 0.0
    b = 1.0 - inst.tau
    w = inst.arc_weight()
    into = w[:, m:] + b * inst.hop[:, m:] * inst.sigma[None, :]  # a fresh array
    into[m:, :][np.arange(n), np.arange(n)] = np.inf  # no arc j -> j
    entry = float(into.min(axis=0).sum())
    return inst.constant + entry + b * h_min(inst) * _round_robin_extra(inst)


def hops_to_reach(inst: Instance) -> FloatArray:
    """L[p, i] (p = 1..n, row 0 unused): a lower bound on the hops H_i summed along any path
    that reaches target i at position p or later. With W_p(i) the fewest hops of a walk of
    exactly p arcs from some UAV to i (W_1(i) = min_u h_ui, W_p(i) = min_k W_(p-1)(k) + h_ki),
    L[p] = min over q >= p of W_q (a suffix minimum, so it also holds for the absorbing
    layer). For the sequence objective L[p, i] = p; for hop lengths that differ (arrival)
    it is much stronger than p h_min."""
    m, n = inst.m, inst.n
    walk = np.empty((n + 1, n))
    walk[0] = np.inf
    walk[1] = inst.hop[:m, m:].min(axis=0)
    tt = inst.hop[m:, m:].copy()
    np.fill_diagonal(tt, np.inf)
    for p in range(2, n + 1):
        walk[p] = (walk[p - 1][:, None] + tt).min(axis=0)
    walk[1:] = np.minimum.accumulate(walk[1:][::-1], axis=0)[::-1]
    return np.maximum(walk, 0.0)


def lp_columns(n: int, m: int, layers: int) -> int:
    """Number of LP columns with `layers` positions."""
    return m * n + max(layers - 1, 0) * n * max(n - 1, 0)


def layer_cap(n: int, m: int, all_positions: bool) -> int:
    """Most positions P worth an LP. all_positions (up to 30 targets): P = n, as CP-SAT's
    position model fixes its variables by the reduced costs of the LP with one layer per
    position. Otherwise P = min(n, max(4, ceil(2 n / m))): paths much longer than the
    average n / m are rare in good plans, so more layers buy little, and the absorbing last
    layer keeps the bound valid."""
    if all_positions:
        return n
    return min(n, max(4, -(-2 * n // max(m, 1))))


def choose_layers(n: int, m: int, cap: int, max_columns: int = LP_MAX_COLUMNS) -> int:
    """Most positions P <= cap (see layer_cap) whose LP has at most max_columns columns;
    0 if that is fewer than MIN_LAYERS. Callers with a time budget shrink P further."""
    cap = min(cap, n)
    if cap < MIN_LAYERS:
        return 0
    room = (max_columns - m * n) // (n * (n - 1)) + 1
    layers = min(cap, room)
    return layers if layers >= MIN_LAYERS else 0


def _arc_index(n: int) -> tuple[IntArray, IntArray]:
    """(i, j) of the n (n - 1) target -> target arcs, i-major."""
    i, j = np.nonzero(~np.eye(n, dtype=bool))
    return i.astype(np.int64), j.astype(np.int64)


def lp_bound(inst: Instance, layers: int, time_limit_s: float) -> LpBound | None:
    """Solve the layered LP with P = `layers` positions (at least 2 when n >= 2); None if
    HiGHS does not finish within `time_limit_s`."""
    import time

    from scipy.optimize import linprog
    from scipy.sparse import coo_matrix

    start = time.perf_counter()
    m, n = inst.m, inst.n
    if n == 0 or layers < 1:
        return None
    b = 1.0 - inst.tau
    w = inst.arc_weight()
    hop = inst.hop
    sigma = inst.sigma
    reach = hops_to_reach(inst)
    layers = max(min(layers, n), min(2, n))  # with n >= 2 the absorbing layer needs P >= 2
    absorbing = layers < n
    # -- columns: a[u, j] (u-major), then z[i, j, p] for p = 2..P, arcs i-major within p
    ai, aj = np.divmod(np.arange(m * n, dtype=np.int64), n)
    cost_a = w[ai, m + aj] + b * hop[ai, m + aj] * sigma[aj]
    ti, tj = _arc_index(n)
    n_arc = len(ti)
    n_z = (layers - 1) * n_arc
    p_of = np.repeat(np.arange(2, layers + 1, dtype=np.int64), n_arc)
    zi = np.tile(ti, layers - 1)
    zj = np.tile(tj, layers - 1)
    cost_z = w[m + zi, m + zj] + b * sigma[zj] * (hop[m + zi, m + zj] + reach[p_of - 1, zi])
    cost = np.concatenate([cost_a, cost_z])
    n_a = m * n
    col_z = n_a + np.arange(n_z, dtype=np.int64)
    # -- equality rows: target j entered once
    eq_rows = np.concatenate([aj, zj])
    eq_cols = np.concatenate([np.arange(n_a, dtype=np.int64), col_z])
    a_eq = coo_matrix((np.ones(len(eq_rows)), (eq_rows, eq_cols)), shape=(n, len(cost)))
    b_eq = np.ones(n)
    # -- inequality rows: UAV u (row u); leave i into layer p (row m + (p - 2) n + i), p = 2..P
    rows = [ai, m + (p_of - 2) * n + zi]  # first: a in UAV rows; outs: +1
    cols = [np.arange(n_a, dtype=np.int64), col_z]
    vals = [np.ones(n_a), np.ones(n_z)]
    if layers >= 2:
        # in(i, 1) = sum_u a[u, i] enters the row of layer 2 with -1
        rows.append(m + aj)
        cols.append(np.arange(n_a, dtype=np.int64))
        vals.append(-np.ones(n_a))
        # in(j, p) (z into j at layer p) enters the row "leave j into p + 1" for p < P
        inner = p_of < layers
        rows.append(m + (p_of[inner] - 1) * n + zj[inner])
        cols.append(col_z[inner])
        vals.append(-np.ones(int(inner.sum())))
        if absorbing:
            # the last layer also feeds itself: leaving j into P needs j in P - 1 or P
            last = p_of == layers
            rows.append(m + (layers - 2) * n + zj[last])
            cols.append(col_z[last])
            vals.append(-np.ones(int(last.sum())))
    n_ub = m + max(layers - 1, 0) * n
    a_ub = coo_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(n_ub, len(cost)),
    )
    b_ub = np.concatenate([np.ones(m), np.zeros(n_ub - m)])
    remaining = time_limit_s - (time.perf_counter() - start)
    if remaining <= 0.0:
        return None
    res = linprog(
        cost,
        A_ub=a_ub.tocsr(),
        b_ub=b_ub,
        A_eq=a_eq.tocsr(),
        b_eq=b_eq,
        bounds=(0.0, None),
        method="highs",
        options={"time_limit": remaining, "presolve": False},  # presolve: slower here, and
        # not interrupted by the time limit
    )
    if res.status != 0 or res.eqlin is None or res.ineqlin is None:
        return None
    y_eq = np.asarray(res.eqlin.marginals, dtype=float)
    y_ub = np.minimum(np.asarray(res.ineqlin.marginals, dtype=float), 0.0)
    reduced = cost - a_eq.T @ y_eq - a_ub.T @ y_ub
    safe = float(b_eq @ y_eq + b_ub @ y_ub + np.minimum(reduced, 0.0).sum())
    if not math.isfinite(safe):
        return None
    return LpBound(
        value=inst.constant + safe,
        layers=layers,
        reduced=np.maximum(reduced, 0.0),
        lp_time_s=time.perf_counter() - start,
    )


def keep_columns(inst: Instance, lp: LpBound, upper: float) -> tuple[BoolArray, BoolArray]:
    """Reduced-cost fixing: (first[u, j], arc[p, i, j]) true for the columns a plan costing at
    most `upper` (J, constant included) may use, i.e. lp.value + reduced <= upper (+ 1e-7
    relative slack for rounding). A plan using any other column costs more than `upper`, so
    with `upper` the incumbent's J no better plan uses it. Positions p = 2..lp.layers."""
    m, n = inst.m, inst.n
    tol = 1e-7 * (abs(upper - inst.constant) + abs(upper) + 1.0)
    ok = lp.value + lp.reduced <= upper + tol
    first = ok[: m * n].reshape(m, n)
    arc = np.zeros((lp.layers + 1, n, n), dtype=bool)
    if lp.layers >= 2:
        ti, tj = _arc_index(n)
        n_arc = len(ti)
        p_of = np.repeat(np.arange(2, lp.layers + 1, dtype=np.int64), n_arc)
        arc[p_of, np.tile(ti, lp.layers - 1), np.tile(tj, lp.layers - 1)] = ok[m * n :]
    return first, arc
