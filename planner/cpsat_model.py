"""CP-SAT models of the visitation problem (integer-scaled; see docs/planner.md).

"position" model (sequence objective, exact, strong LP bound): booleans
    a[u, j]     UAV u flies first to target j (position 1),
    z[i, j, p]  target j is reached from target i at position p (p = 2 .. n);
    sum_u a[u, j] + sum_{i, p} z[i, j, p] = 1            every target once,
    sum_j a[u, j] <= 1                                   one path per UAV,
    sum_j z[i, j, p + 1] <= in(i, p)                     leave i at p + 1 only if reached at p,
with in(i, 1) = sum_u a[u, i], in(i, p) = sum_k z[k, i, p]. Positions increase along a path so
no sub-tour exists. Cost of a[u, j]: tau mu d_uj + (1 - tau) sigma_j; of z[i, j, p]:
tau mu d_ij + (1 - tau) sigma_j p. This is the time-indexed formulation of the travelling
repairman problem; its LP bound is far stronger than MTZ's.

"circuit" model (every objective, O(N^2) variables, for larger instances):
AddMultipleCircuit over depot 0, UAV nodes and target nodes, arcs depot -> UAV (fixed true),
UAV -> depot (empty path), UAV -> target, target -> target, target -> depot.
Sequence: integer position p_j with a[u, j] => p_j = 1 and y[i, j] => p_j = p_i + 1,
cost (1 - tau) sigma_j p_j + tau mu d y. Arrival and latency (weighted hops h_ij): a
single-commodity flow f_ij (the sigma still to be served after the arc, integers of sigma
rounded to 1e-7 of their sum), f_ij <= S y_ij, inflow - outflow = sigma_j, cost
tau mu d_ij y_ij + (1 - tau) h_ij f_ij (latency: tau = 0, h_ij = d_ij / speed, so the cost is
sum_j sigma_j a_j exactly: the flow on the arc into j, times its hop time, summed).

All costs are multiplied by a scale and rounded to integers; the exact float objective of
the returned routes is recomputed by the caller. The flow's hop coefficients get at least
1e7 integer steps (a coarser scale, 100 steps, made "optimal" arrival plans 0.1 % worse).
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from ortools.sat.python import cp_model

from planner.instance import Instance

BoolArray = npt.NDArray[np.bool_]

_MAX_COEF = 1e8  # largest scaled objective coefficient
_SIGMA_STEPS = 1e7  # flow model: sigma in integer units of 1e-7 of the total
_HOP_STEPS = 1e7  # flow model: integer steps of the largest flow coefficient
_OBJECTIVE_RANGE = 1e18  # bound on sum |coef| x max |var| of the flow model's objective


def _sum(lits: list[cp_model.IntVar]) -> cp_model.LinearExprT:
    return cp_model.LinearExpr.sum(lits)


@dataclass
class CpSatOutcome:
    status: str  # "optimal", "feasible" or "none"
    routes: list[list[int]] | None
    wall_time_s: float
    stopped: bool
    model: str
    bound: float | None = None  # proven lower bound on J (constant included), if known


class CpSatRun:
    """Build one model; solve() may be interrupted by stop() from another thread."""

    def __init__(
        self,
        inst: Instance,
        model: str,
        keep: tuple[BoolArray, BoolArray] | None = None,
    ) -> None:
        """`model`: "position" (sequence objective only) or "circuit"; planner.solve chooses
        (POSITION_MODEL_MAX_TARGETS). `keep` (position model): (first[u, j], arc[p, i, j])
        masks of the variables to create (planner.bound.keep_columns: the others cannot
        improve on the hint)."""
        if model not in ("position", "circuit"):
            raise ValueError(f"unknown CP-SAT model {model!r} (position or circuit)")
        if model == "position" and not inst.unit_hops:
            raise ValueError("the position model only supports the sequence objective")
        self.inst = inst
        self.kind = model
        self.model = cp_model.CpModel()
        self._lock = threading.Lock()
        self._solver: cp_model.CpSolver | None = None
        self._stopped = False
        self.first: dict[tuple[int, int], cp_model.IntVar] = {}
        self.arcs: dict[tuple[int, int, int], cp_model.IntVar] = {}  # (i, j, p), p=0 circuit
        self.empty: dict[int, cp_model.IntVar] = {}  # circuit: UAV u -> depot
        self.last: dict[int, cp_model.IntVar] = {}  # circuit: target i -> depot
        self.keep = keep
        # objective bound -> J: J >= (scaled bound - slack) / scale + constant, slack the
        # largest total rounding error of the coefficients a solution can use (None: unknown)
        self.scale = 1.0
        self.slack: float | None = None
        if model == "position":
            self._build_position()
        else:
            self._build_circuit()

    # -- models ------------------------------------------------------------------------------
    def _scale(self, max_coef: float) -> float:
        # below 1e-200 every plan costs the same to 1e-6; keep the scale finite
        return _MAX_COEF / max_coef if max_coef > 1e-200 else 1.0

    def _build_position(self) -> None:
        inst, md = self.inst, self.model
        m, n = inst.m, inst.n
        w = inst.arc_weight()
        b = 1.0 - inst.tau
        sigma = inst.sigma
        max_coef = float(w.max(initial=0.0) + b * sigma.max(initial=0.0) * n)
        scale = self._scale(max_coef)
        obj_vars: list[cp_model.IntVar] = []
        obj_coefs: list[int] = []
        into: list[list[cp_model.IntVar]] = [[] for _ in range(n)]
        at: list[list[list[cp_model.IntVar]]] = [[[] for _ in range(n + 1)] for _ in range(n)]
        out: list[list[list[cp_model.IntVar]]] = [[[] for _ in range(n + 1)] for _ in range(n)]
        keep_first, keep_arc = self.keep if self.keep is not None else (None, None)
        for u in range(m):
            lits = []
            for j in range(n):
                if keep_first is not None and not keep_first[u, j]:
                    continue
                var = md.new_bool_var(f"a_{u}_{j}")
                self.first[(u, j)] = var
                lits.append(var)
                into[j].append(var)
                at[j][1].append(var)
                obj_vars.append(var)
                obj_coefs.append(round(scale * (w[u, m + j] + b * sigma[j])))
            md.add_at_most_one(lits)
        for p in range(2, n + 1):
            if keep_arc is not None and not keep_arc[p].any():
                continue
            for i in range(n):
                for j in range(n):
                    if i == j or (keep_arc is not None and not keep_arc[p, i, j]):
                        continue
                    var = md.new_bool_var(f"z_{i}_{j}_{p}")
                    self.arcs[(i, j, p)] = var
                    into[j].append(var)
                    at[j][p].append(var)
                    out[i][p].append(var)
                    obj_vars.append(var)
                    obj_coefs.append(round(scale * (w[m + i, m + j] + b * sigma[j] * p)))
        for j in range(n):
            md.add_exactly_one(into[j])
            for p in range(1, n):
                if out[j][p + 1]:
                    md.add(_sum(out[j][p + 1]) <= _sum(at[j][p]))
        # the number of targets at position p never increases with p
        for p in range(2, n + 1):
            here = [v for j in range(n) for v in at[j][p]]
            before = [v for j in range(n) for v in at[j][p - 1]]
            if here:
                md.add(_sum(here) <= _sum(before))
        md.minimize(cp_model.LinearExpr.weighted_sum(obj_vars, obj_coefs))
        self.scale, self.slack = scale, 0.5 * n  # exactly n variables are 1

    def _build_circuit(self) -> None:
        inst, md = self.inst, self.model
        m, n = inst.m, inst.n
        w = inst.arc_weight()
        b = 1.0 - inst.tau
        sigma = inst.sigma
        arrival = not inst.unit_hops  # weighted hops: arrival or latency
        arcs: list[tuple[int, int, cp_model.IntVar]] = []
        # node ids: 0 depot, 1..m UAVs, m+1..m+n targets
        for u in range(m):
            arcs.append((0, 1 + u, md.new_constant(1)))
            self.empty[u] = md.new_bool_var(f"empty_{u}")
            arcs.append((1 + u, 0, self.empty[u]))
            for j in range(n):
                var = md.new_bool_var(f"a_{u}_{j}")
                self.first[(u, j)] = var
                arcs.append((1 + u, 1 + m + j, var))
        for i in range(n):
            self.last[i] = md.new_bool_var(f"end_{i}")
            arcs.append((1 + m + i, 0, self.last[i]))
            for j in range(n):
                if i != j:
                    var = md.new_bool_var(f"y_{i}_{j}")
                    self.arcs[(i, j, 0)] = var
                    arcs.append((1 + m + i, 1 + m + j, var))
        md.add_multiple_circuit(arcs)
        if not arrival:
            max_coef = float(w.max(initial=0.0) + b * sigma.max(initial=0.0) * n)
            scale = self._scale(max_coef)
            pos = [md.new_int_var(1, n, f"p_{j}") for j in range(n)]
            terms = []
            for (u, j), var in self.first.items():
                md.add(pos[j] == 1).only_enforce_if(var)
                terms.append(round(scale * w[u, m + j]) * var)
            for (i, j, _), var in self.arcs.items():
                md.add(pos[j] == pos[i] + 1).only_enforce_if(var)
                terms.append(round(scale * w[m + i, m + j]) * var)
            for j in range(n):
                terms.append(round(scale * b * sigma[j]) * pos[j])
            md.minimize(sum(terms))
            self.scale, self.slack = scale, 0.5 * n + 0.5 * n * n  # n arcs, positions <= n
            self._pos = pos
            return
        total = float(sigma.sum())
        unit = total / _SIGMA_STEPS
        if not 0.0 < unit < float("inf"):  # none, or so small that the step underflows
            unit = 1.0
        sig_int = [round(s / unit) for s in sigma]
        cap = sum(sig_int)
        h = inst.hop
        # the flow's coefficient b h unit gets _HOP_STEPS integer steps, the arcs' at most
        # _MAX_COEF (whichever binds)
        flow_max = float(b * h.max(initial=0.0) * unit)
        w_max = float(w.max(initial=0.0))
        # keep sum |coefficient| x domain of the objective far inside int64
        hop_steps = min(_HOP_STEPS, _OBJECTIVE_RANGE / (max(cap, 1) * (m + n) * max(n, 1)))
        scale = min(
            hop_steps / flow_max if flow_max > 1e-200 else float("inf"),
            _MAX_COEF / w_max if w_max > 1e-200 else float("inf"),
        )
        if not scale < float("inf"):
            scale = 1.0
        flow_in: list[list[cp_model.IntVar]] = [[] for _ in range(n)]
        flow_out: list[list[cp_model.IntVar]] = [[] for _ in range(n)]
        terms = []
        self._flows: dict[str, cp_model.IntVar] = {}
        arcs_src: list[tuple[int, int, bool, cp_model.IntVar]] = [
            (u, j, True, var) for (u, j), var in self.first.items()
        ]
        arcs_src += [(i, j, False, var) for (i, j, _), var in self.arcs.items()]
        for i, j, from_uav, var in arcs_src:
            src = i if from_uav else m + i
            f = md.new_int_var(0, cap, f"f_{var.name}")
            md.add(f <= cap * var)
            md.add(f >= sig_int[j] * var)
            flow_in[j].append(f)
            if not from_uav:
                flow_out[i].append(f)
            self._flows[var.name] = f
            terms.append(round(scale * w[src, m + j]) * var)
            terms.append(round(scale * b * h[src, m + j] * unit) * f)
        for j in range(n):
            md.add(sum(flow_in[j]) - sum(flow_out[j]) == sig_int[j])
        md.minimize(sum(terms))
        self._sig_int = sig_int

    # -- hint / solve -------------------------------------------------------------------------
    def add_hint(self, routes: Sequence[Sequence[int]]) -> None:
        """Complete hint from a plan (kept-target indices per UAV)."""
        first_on = {(u, r[0]) for u, r in enumerate(routes) if r}
        arc_on: set[tuple[int, int, int]] = set()
        pos: dict[int, int] = {}
        for r in routes:
            for p, k in enumerate(r, start=1):
                pos[k] = p
            for p in range(1, len(r)):
                arc_on.add((r[p - 1], r[p], p + 1 if self.kind == "position" else 0))
        for first_key, var in self.first.items():
            self.model.add_hint(var, first_key in first_on)
        for arc_key, var in self.arcs.items():
            self.model.add_hint(var, arc_key in arc_on)
        for u, var in self.empty.items():
            self.model.add_hint(var, not routes[u])
        ends = {r[-1] for r in routes if r}
        for i, var in self.last.items():
            self.model.add_hint(var, i in ends)
        if self.kind == "circuit" and hasattr(self, "_pos"):
            for j, var in enumerate(self._pos):
                self.model.add_hint(var, pos.get(j, 1))
        if hasattr(self, "_flows"):
            sig = self._sig_int
            for u, r in enumerate(routes):
                remaining = sum(sig[k] for k in r)
                prev_name = None
                for k in r:
                    name = f"a_{u}_{k}" if prev_name is None else f"y_{prev_name}_{k}"
                    self.model.add_hint(self._flows[name], remaining)
                    remaining -= sig[k]
                    prev_name = str(k)
            hinted = {(f"a_{u}_{r[0]}" if r else "") for u, r in enumerate(routes)} | {
                f"y_{a}_{c}" for r in routes for a, c in itertools.pairwise(r)
            }
            for name, f in self._flows.items():
                if name not in hinted:
                    self.model.add_hint(f, 0)

    def stop(self) -> None:
        with self._lock:
            self._stopped = True
            if self._solver is not None:
                self._solver.stop_search()

    def solve(
        self,
        time_limit_s: float,
        *,
        num_workers: int = 1,
        random_seed: int = 0,
        deterministic: bool = False,
    ) -> CpSatOutcome:
        solver = cp_model.CpSolver()
        params = solver.parameters
        params.num_workers = max(1, num_workers)
        params.random_seed = random_seed
        # Presolve probing and symmetry detection cost seconds on the position model and
        # buy nothing (measured on 5x20: presolve 5 s -> 0.05 s); the LP does the work.
        params.cp_model_probing_level = 0
        params.symmetry_level = 0
        # level 2 (cuts) pays on the strong position model; the circuit model's LP is weak
        params.linearization_level = 2 if self.kind == "position" else 1
        if deterministic:
            params.num_workers = 1
            params.max_deterministic_time = max(time_limit_s, 1e-3)
        else:
            params.max_time_in_seconds = max(time_limit_s, 1e-3)
        with self._lock:
            if self._stopped:
                return CpSatOutcome("none", None, 0.0, True, self.kind)
            self._solver = solver
        code = solver.solve(self.model)
        with self._lock:
            self._solver = None
            stopped = self._stopped
        if code == cp_model.OPTIMAL:
            status = "optimal"
        elif code == cp_model.FEASIBLE:
            status = "feasible"
        else:
            return CpSatOutcome("none", None, solver.wall_time, stopped, self.kind)
        bound = None
        if self.slack is not None:
            raw = float(solver.best_objective_bound)
            if abs(raw) < 1e18:
                bound = (raw - self.slack) / self.scale + self.inst.constant
        routes = self._routes(solver)
        return CpSatOutcome(status, routes, solver.wall_time, stopped, self.kind, bound)

    def _routes(self, solver: cp_model.CpSolver) -> list[list[int]]:
        succ: dict[int, int] = {}
        for (i, j, _), var in self.arcs.items():
            if solver.boolean_value(var):
                succ[i] = j
        routes: list[list[int]] = [[] for _ in range(self.inst.m)]
        for (u, j), var in self.first.items():
            if solver.boolean_value(var):
                k: int | None = j
                while k is not None and len(routes[u]) <= self.inst.n:
                    routes[u].append(k)
                    k = succ.get(k)
        return routes
