"""The paper's MTZ model (constraints (12)-(16)) in HiGHS (highspy), SCIP (pyscipopt) and
CP-SAT (OR-Tools).

    min  -(1 - tau) sum_j sigma_j (N - t_j) + tau mu sum_ij d_ij y_ij
    s.t. sum_i y_ij <= 1, sum_j y_ij <= 1, sum_ij y_ij = N - nUAV, t_uav = 1,
         t_j >= t_i + 1 - N (1 - y_ij),  y binary, t integer in [1, N].

Only for benchmarks/planner_bench.py. highspy and OR-Tools both bundle HiGHS and clash in
one process, so this module never imports planner, and imports each solver only inside its
own function: the benchmark runs each in its own worker process and hands it the numbers
(distances, sigma, mu, tau) as an MtzData. Every solver returns (proven, objective of its
best plan recomputed in floating point, proven lower bound on J or None, wall seconds).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass
class MtzData:
    """The numbers of one instance: nodes are UAVs 0..m-1 then targets."""

    m: int
    n: int
    tau: float
    mu: float
    d: list[list[float]]
    sigma: list[float]  # targets only

    @classmethod
    def from_dict(cls, row: dict[str, Any]) -> MtzData:
        return cls(row["m"], row["n"], row["tau"], row["mu"], row["d"], row["sigma"])

    @property
    def n_nodes(self) -> int:
        return self.m + self.n

    def arc_weight(self) -> np.ndarray:
        return self.tau * self.mu * np.array(self.d, dtype=float)

    def evaluate(self, routes: list[list[int]]) -> tuple[float, float, float]:
        """(J, F1, F2) straight from the paper: t = 1 + position, F1 = sum sigma (N - t)."""
        size = self.n_nodes
        f1 = 0.0
        dist = 0.0
        for u, route in enumerate(routes):
            prev = u
            for p, k in enumerate(route, start=2):
                f1 += self.sigma[k] * (size - p)
                dist += self.d[prev][self.m + k]
                prev = self.m + k
        f2 = self.mu * dist
        return -(1 - self.tau) * f1 + self.tau * f2, f1, f2


Instance = MtzData


def _arcs(inst: Instance) -> list[tuple[int, int]]:
    size = inst.n_nodes
    return [(i, j) for i in range(size) for j in range(size) if i != j]


def _routes(inst: Instance, used: list[tuple[int, int]]) -> list[list[int]]:
    succ = dict(used)
    routes: list[list[int]] = []
    for u in range(inst.m):
        route: list[int] = []
        node = succ.get(u)
        while node is not None and node >= inst.m and len(route) <= inst.n:
            route.append(node - inst.m)
            node = succ.get(node)
        routes.append(route)
    return routes


def _costs(inst: Instance) -> tuple[float, list[float], list[float]]:
    """(constant, cost of y_ij per arc, cost of t_j per node)."""
    size = inst.n_nodes
    b = 1.0 - inst.tau
    sigma = [0.0] * inst.m + list(inst.sigma)
    const = -b * size * sum(sigma)
    w = inst.arc_weight()
    return const, [float(w[i, j]) for i, j in _arcs(inst)], [b * s for s in sigma]


Outcome = tuple[bool, float | None, float | None, float]


def solve_highs(inst: Instance, time_limit_s: float) -> Outcome:
    """(proven optimal, objective of the best plan or None, lower bound or None, wall s)."""
    import highspy

    start = time.perf_counter()
    size = inst.n_nodes
    arcs = _arcs(inst)
    _, arc_cost, t_cost = _costs(inst)
    h = highspy.Highs()
    h.setOptionValue("output_flag", False)
    h.setOptionValue("time_limit", float(time_limit_s))
    h.setOptionValue("mip_rel_gap", 1e-6)
    h.setOptionValue("threads", 1)
    inf = highspy.kHighsInf
    na = len(arcs)
    for c in arc_cost:
        h.addCol(c, 0.0, 1.0, 0, np.array([], dtype=np.int32), np.array([], dtype=float))
    for v in range(size):
        lo, hi = (1.0, 1.0) if v < inst.m else (1.0, float(size))
        h.addCol(t_cost[v], lo, hi, 0, np.array([], dtype=np.int32), np.array([], dtype=float))
    h.changeColsIntegrality(
        na + size,
        np.arange(na + size, dtype=np.int32),
        np.array([highspy.HighsVarType.kInteger] * (na + size)),
    )

    def row(lo: float, hi: float, idx: list[int], val: list[float]) -> None:
        h.addRow(lo, hi, len(idx), np.array(idx, dtype=np.int32), np.array(val, dtype=float))

    for v in range(size):
        row(-inf, 1.0, [k for k, (_, j) in enumerate(arcs) if j == v], [1.0] * (size - 1))
        row(-inf, 1.0, [k for k, (i, _) in enumerate(arcs) if i == v], [1.0] * (size - 1))
    row(size - inst.m, size - inst.m, list(range(na)), [1.0] * na)
    for k, (i, j) in enumerate(arcs):
        # t_j - t_i - N y_ij >= 1 - N
        row(1.0 - size, inf, [na + j, na + i, k], [1.0, -1.0, -float(size)])
    h.run()
    proven = h.getModelStatus() == highspy.HighsModelStatus.kOptimal
    const = _costs(inst)[0]
    dual = float(h.getInfo().mip_dual_bound)
    bound = const + dual if np.isfinite(dual) else None
    sol = h.getSolution()
    if not sol.value_valid:
        return False, None, bound, time.perf_counter() - start
    values = list(sol.col_value)
    used = [arcs[k] for k in range(na) if values[k] > 0.5]
    objective = inst.evaluate(_routes(inst, used))[0]
    return proven, objective, bound, time.perf_counter() - start


def solve_scip(inst: Instance, time_limit_s: float) -> Outcome:
    """(proven optimal, objective of the best plan or None, lower bound or None, wall s)."""
    from pyscipopt import Model, quicksum

    start = time.perf_counter()
    size = inst.n_nodes
    arcs = _arcs(inst)
    _, arc_cost, t_cost = _costs(inst)
    model = Model()
    model.hideOutput()
    model.setParam("limits/time", float(time_limit_s))
    y = {a: model.addVar(vtype="B", obj=c) for a, c in zip(arcs, arc_cost, strict=True)}
    t = [
        model.addVar(vtype="I", lb=1, ub=1 if v < inst.m else size, obj=t_cost[v])
        for v in range(size)
    ]
    for v in range(size):
        model.addCons(quicksum(y[i, j] for (i, j) in arcs if j == v) <= 1)
        model.addCons(quicksum(y[i, j] for (i, j) in arcs if i == v) <= 1)
    model.addCons(quicksum(y.values()) == size - inst.m)
    for i, j in arcs:
        model.addCons(t[j] >= t[i] + 1 - size * (1 - y[i, j]))
    model.optimize()
    proven = model.getStatus() == "optimal"
    dual = float(model.getDualbound())
    bound = _costs(inst)[0] + dual if np.isfinite(dual) and abs(dual) < 1e19 else None
    if model.getNSols() == 0:
        return False, None, bound, time.perf_counter() - start
    best = model.getBestSol()
    used = [a for a in arcs if model.getSolVal(best, y[a]) > 0.5]
    objective = inst.evaluate(_routes(inst, used))[0]
    return proven, objective, bound, time.perf_counter() - start


def solve_cpsat(inst: Instance, time_limit_s: float) -> Outcome:
    """The same MTZ model in CP-SAT (1 worker): costs scaled so the largest is 1e6 and
    rounded; the bound is CP-SAT's objective bound minus the largest rounding error."""
    from ortools.sat.python import cp_model

    start = time.perf_counter()
    size = inst.n_nodes
    arcs = _arcs(inst)
    const, arc_cost, t_cost = _costs(inst)
    largest = max([abs(c) for c in arc_cost] + [abs(c) * size for c in t_cost] + [1e-300])
    scale = 1e6 / largest
    model = cp_model.CpModel()
    y = {a: model.new_bool_var(f"y{a}") for a in arcs}
    t = [model.new_int_var(1, 1 if v < inst.m else size, f"t{v}") for v in range(size)]
    for v in range(size):
        model.add(sum(y[i, j] for (i, j) in arcs if j == v) <= 1)
        model.add(sum(y[i, j] for (i, j) in arcs if i == v) <= 1)
    model.add(sum(y.values()) == size - inst.m)
    for i, j in arcs:
        model.add(t[j] >= t[i] + 1 - size * (1 - y[i, j]))
    terms = [round(scale * c) * y[a] for a, c in zip(arcs, arc_cost, strict=True)]
    terms += [round(scale * c) * t[v] for v, c in enumerate(t_cost)]
    model.minimize(sum(terms))
    solver = cp_model.CpSolver()
    solver.parameters.num_workers = 1
    solver.parameters.max_time_in_seconds = float(time_limit_s)
    code = solver.solve(model)
    proven = code == cp_model.OPTIMAL
    rounding = 0.5 * (size + size * size) / scale  # n arcs, t <= N per node
    bound = None
    if code in (cp_model.OPTIMAL, cp_model.FEASIBLE, cp_model.UNKNOWN):
        bound = const + solver.best_objective_bound / scale - rounding
    if code not in (cp_model.OPTIMAL, cp_model.FEASIBLE):
        return False, None, bound, time.perf_counter() - start
    used = [a for a in arcs if solver.boolean_value(y[a])]
    objective = inst.evaluate(_routes(inst, used))[0]
    return proven, objective, bound, time.perf_counter() - start
