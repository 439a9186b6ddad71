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
  with any duals y (y <= 0 on the <= rows) and reduced costs r = c - A^T y, for every LP
  solution x, c^T x = r^T x + y_eq^T A_eq x + y_ub^T A_ub x >= sum_j min_(k into j) r_k
  + 1^T y_eq + b_ub^T y_ub, since the columns into target j sum to exactly 1 and
  A_ub x <= b_ub. So it bounds the LP optimum (and J - C) from below whatever the solver's
  tolerances, and whichever columns HiGHS saw: this is what makes *column generation*
  sound. Above 30 targets the LP starts from a few columns per target (its K cheapest
  predecessors and the incumbent plan's arcs), each round prices every column with the
  duals of the restricted LP and adds the most negative per (position, target); each
  round's bound is valid, the best one is kept (it reaches the full LP's optimum when no
  column is negative). A round costs a fraction of the full LP (docs/planner.md).

scipy (HiGHS inside) is imported lazily: small instances are solved exactly by the DP and never
need it. highspy itself cannot be loaded next to OR-Tools (their bundled HiGHS builds clash).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
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
    rounds: int = 1  # column generation: restricted LPs solved (1: the full LP)


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


def _layered_costs(inst: Instance, layers: int) -> tuple[FloatArray, FloatArray]:
    """Column costs: a[u, j] (m x n) and z[p, i, j] (P - 1 x n x n, index p - 2, +inf on
    the diagonal): w_uj + b h_uj sigma_j and w_ij + b sigma_j (h_ij + L[p - 1, i])."""
    m, n = inst.m, inst.n
    b = 1.0 - inst.tau
    w = inst.arc_weight()
    hop = inst.hop
    sigma = inst.sigma
    cost_a = w[:m, m:] + b * hop[:m, m:] * sigma[None, :]
    reach = hops_to_reach(inst)
    tw = w[m:, m:] + b * hop[m:, m:] * sigma[None, :]
    cost_z = np.empty((max(layers - 1, 0), n, n))
    for pz in range(layers - 1):  # position p = pz + 2 leaves i at position p - 1 = pz + 1
        cost_z[pz] = tw + b * sigma[None, :] * reach[pz + 1][:, None]
        np.fill_diagonal(cost_z[pz], np.inf)
    return cost_a, cost_z


@dataclass
class _Pricing:
    """Duals of a (restricted) layered LP priced over every column (see lp_bound)."""

    value: float  # safe bound on J - C
    reduced_a: FloatArray  # m x n: r = c - A^T y
    reduced_z: FloatArray  # P - 1 x n x n
    into: FloatArray  # n: min r over the columns into each target

    def fixing(self) -> tuple[FloatArray, FloatArray]:
        """A plan using column k (into j) costs at least value + r_k - into_j (>= 0)."""
        return (
            np.maximum(self.reduced_a - self.into[None, :], 0.0),
            np.maximum(self.reduced_z - self.into[None, None, :], 0.0),
        )


def _price(
    m: int, n: int, layers: int, cost_a: FloatArray, cost_z: FloatArray,
    y_eq: FloatArray, y_ub: FloatArray,
) -> _Pricing:
    """Reduced costs r = c - A^T y of every column, and the safe bound
        b^T y + sum_j min_(columns k into j) r_k,
    valid for any y_eq and any y_ub <= 0 (lp_bound's docstring)."""
    y_ub = np.minimum(y_ub, 0.0)
    absorbing = layers < n
    leave = y_ub[m:].reshape(max(layers - 1, 0), n)  # leave[p - 2, i]: leave i into p
    red_a = cost_a - y_eq[None, :] - y_ub[:m, None]
    if layers >= 2:
        red_a = red_a + leave[0][None, :]
    red_z = cost_z - y_eq[None, None, :] - leave[:, :, None]
    if layers >= 2:
        nxt = np.zeros_like(leave)
        nxt[:-1] = leave[1:]
        if absorbing:
            nxt[-1] = leave[-1]
        red_z += nxt[:, None, :]
    into = red_a.min(axis=0)
    if layers >= 2:
        into = np.minimum(into, red_z.min(axis=(0, 1)))
    value = float(y_eq.sum() + y_ub[:m].sum() + into.sum())
    return _Pricing(value, red_a, red_z, into)


def _restricted_lp(
    m: int, n: int, layers: int, cost_a: FloatArray, cost_z: FloatArray,
    zp: IntArray, zi: IntArray, zj: IntArray, time_limit_s: float,
) -> tuple[FloatArray, FloatArray] | None:
    """HiGHS on the layered LP with every a column and the z columns (zp, zi, zj) (zp =
    p - 2); its duals (y_eq, y_ub), or None if it did not finish in time."""
    from scipy.optimize import linprog
    from scipy.sparse import coo_matrix

    absorbing = layers < n
    n_a = m * n
    ai, aj = np.divmod(np.arange(n_a, dtype=np.int64), n)
    cost = np.concatenate([cost_a.ravel(), cost_z[zp, zi, zj]])
    col_z = n_a + np.arange(len(zp), dtype=np.int64)
    eq_rows = np.concatenate([aj, zj])
    eq_cols = np.concatenate([np.arange(n_a, dtype=np.int64), col_z])
    a_eq = coo_matrix((np.ones(len(eq_rows)), (eq_rows, eq_cols)), shape=(n, len(cost)))
    rows = [ai, m + zp * n + zi]
    cols = [np.arange(n_a, dtype=np.int64), col_z]
    vals = [np.ones(n_a), np.ones(len(zp))]
    if layers >= 2:
        rows.append(m + aj)
        cols.append(np.arange(n_a, dtype=np.int64))
        vals.append(-np.ones(n_a))
        inner = zp < layers - 2
        rows.append(m + (zp[inner] + 1) * n + zj[inner])
        cols.append(col_z[inner])
        vals.append(-np.ones(int(inner.sum())))
        if absorbing:
            last = ~inner
            rows.append(m + zp[last] * n + zj[last])
            cols.append(col_z[last])
            vals.append(-np.ones(int(last.sum())))
    n_ub = m + max(layers - 1, 0) * n
    a_ub = coo_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(n_ub, len(cost)),
    )
    b_ub = np.concatenate([np.ones(m), np.zeros(n_ub - m)])
    if time_limit_s <= 0.0:
        return None
    res = linprog(
        cost,
        A_ub=a_ub.tocsr(),
        b_ub=b_ub,
        A_eq=a_eq.tocsr(),
        b_eq=np.ones(n),
        bounds=(0.0, None),
        method="highs",
        options={"time_limit": time_limit_s, "presolve": False},  # presolve: slower here,
        # and not interrupted by the time limit
    )
    if res.status != 0 or res.eqlin is None or res.ineqlin is None:
        return None
    y_eq = np.asarray(res.eqlin.marginals, dtype=float)
    y_ub = np.asarray(res.ineqlin.marginals, dtype=float)
    if not (np.isfinite(y_eq).all() and np.isfinite(y_ub).all()):
        return None
    return y_eq, y_ub


def lp_bound(
    inst: Instance,
    layers: int,
    time_limit_s: float,
    *,
    routes: list[list[int]] | None = None,
    candidates: int | None = None,
    rounds: int = 1_000,
    should_stop: Callable[[], bool] | None = None,
) -> LpBound | None:
    """The layered LP with P = `layers` positions (at least 2 when n >= 2), as a proven
    bound; None if no LP finished within `time_limit_s` (wall, HiGHS's own limit).

    With `candidates` = K (column generation), the LP starts from every a column, the z
    columns into each target j from its K cheapest predecessors, and the columns of
    `routes` (a plan, so the restricted LP is feasible); each round solves it, prices every
    column with its duals, keeps the best safe bound so far and adds, per (position, j), the
    most negative column. It stops when none is negative (the bound is then the full LP's
    optimum), after `rounds`, when `should_stop()` or when HiGHS does not finish: an
    interrupted round hands back the best bound of the rounds before. Without `candidates`
    the full LP is solved once."""
    start = time.perf_counter()
    m, n = inst.m, inst.n
    if n == 0 or layers < 1:
        return None
    layers = max(min(layers, n), min(2, n))  # with n >= 2 the absorbing layer needs P >= 2
    cost_a, cost_z = _layered_costs(inst, layers)
    n_layers = layers - 1
    if candidates is None or n_layers == 0:
        mask = np.isfinite(cost_z)
    else:
        k = min(candidates, n - 1)
        pred = np.argsort(cost_z[0], axis=0, kind="stable")[:k]  # k x n: cheapest into j
        mask = np.zeros(cost_z.shape, dtype=bool)
        mask[:, pred, np.arange(n)[None, :]] = True
        for route in routes or []:
            for pos in range(1, len(route)):
                mask[min(pos + 1, layers) - 2, route[pos - 1], route[pos]] = True
        mask &= np.isfinite(cost_z)
    stop = should_stop or (lambda: False)
    best: _Pricing | None = None
    solved = 0
    for _ in range(max(rounds, 1)):
        zp, zi, zj = (a.astype(np.int64) for a in np.nonzero(mask))
        remaining = time_limit_s - (time.perf_counter() - start)
        duals = _restricted_lp(m, n, layers, cost_a, cost_z, zp, zi, zj, remaining)
        if duals is None:
            break
        solved += 1
        priced = _price(m, n, layers, cost_a, cost_z, duals[0], duals[1])
        if not math.isfinite(priced.value):
            break
        if best is None or priced.value > best.value:
            best = priced
        if candidates is None or n_layers == 0 or stop():
            break
        # add per (position, j) the most negative column not yet in
        raw = np.where(mask, np.inf, priced.reduced_z)
        gain = raw.min(axis=1)  # P - 1 x n
        arg = raw.argmin(axis=1)
        add_p, add_j = np.nonzero(gain < -1e-9 * (abs(priced.value) + 1.0))
        if len(add_p) == 0:
            break
        mask[add_p, arg[add_p, add_j], add_j] = True
    if best is None:
        return None
    ti, tj = _arc_index(n)
    fix_a, fix_z = best.fixing()
    reduced_z = fix_z[:, ti, tj].ravel() if n_layers else np.zeros(0)
    return LpBound(
        value=inst.constant + best.value,
        layers=layers,
        reduced=np.concatenate([fix_a.ravel(), reduced_z]),
        lp_time_s=time.perf_counter() - start,
        rounds=solved,
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
