"""solve_plan / PlanSolver: choose the method, run it within the time limit, report.

Pipeline: 10 % rule and distances (planner.instance); no kept target -> trivial optimum;
small instances -> exact subset DP (planner.exact_dp); otherwise greedy insertion, the
previous plan (hint) if it is better, iterated local search, then CP-SAT hinted with the
best plan (planner.cpsat_model). The result is the best plan by its exact float objective;
status "optimal" when the DP ran or CP-SAT proved optimality, "feasible" when CP-SAT found
a plan, "fallback" when CP-SAT found none (time limit or stop) and the heuristic plan is used.

Deadlines are compute budgets measured with time.perf_counter (no mission clock is read).
With deterministic=True nothing depends on the wall clock: the local search has a fixed
iteration budget and CP-SAT runs one worker with max_deterministic_time.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

from planner.exact_dp import dp_is_cheap, solve_dp
from planner.heuristics import LocalSearch, RouteCoster, best_insertion, greedy
from planner.instance import Instance, build_instance
from planner.problem import PlanningProblem, PlanResult, PlanStatus

if TYPE_CHECKING:
    from planner.cpsat_model import CpSatRun

POSITION_MODEL_MAX_TARGETS = 30


def hint_routes(inst: Instance, hint: Mapping[str, Sequence[str]]) -> list[list[int]] | None:
    """Previous plan mapped onto this instance: unknown, dropped or repeated ids are
    ignored, targets it misses are added by cheapest insertion. None if it holds nothing."""
    uav_index = {u.id: k for k, u in enumerate(inst.problem.uavs)}
    target_index = {inst.target_id(k): k for k in range(inst.n)}
    routes: list[list[int]] = [[] for _ in range(inst.m)]
    seen: set[int] = set()
    for uav_id, seq in hint.items():
        u = uav_index.get(uav_id)
        if u is None or isinstance(seq, str):
            continue
        for tid in seq:
            k = target_index.get(tid) if isinstance(tid, str) else None
            if k is not None and k not in seen:
                routes[u].append(k)
                seen.add(k)
    if not seen:
        return None
    coster = RouteCoster(inst)
    costs = [coster.cost(u, r) for u, r in enumerate(routes)]
    for k in range(inst.n):
        if k not in seen:
            _, u, pos = best_insertion(coster, routes, costs, [k])
            routes[u].insert(pos, k)
            costs[u] = coster.cost(u, routes[u])
    return routes


def idle_assignment(inst: Instance, routes: Sequence[Sequence[int]]) -> dict[str, str]:
    """Idle-UAV rule: UAVs whose route is empty get distinct targets no route starts with.

    Repeatedly the closest pair (idle UAV, free target) by Dubins distance is matched (ties:
    UAV, then target, in input order), where a target is free if it is no route's first
    target and no idle UAV has it yet. Only when no free target is left (more UAVs than
    kept targets) does an idle UAV share one: its nearest kept target. Sending an idle UAV
    where another UAV already flies sent all three UAVs to one iceberg at t = 0 of
    paper-boat (docs/planner.md, "Idle UAVs").
    """
    out: dict[str, str] = {}
    if inst.n == 0:
        return out
    m = inst.m
    idle = [u for u, route in enumerate(routes) if not route]
    taken = {route[0] for route in routes if route}
    pairs = sorted(
        (float(inst.d[u, m + k]), u, k) for u in idle for k in range(inst.n) if k not in taken
    )
    for _, u, k in pairs:
        if k in taken or inst.problem.uavs[u].id in out:
            continue
        out[inst.problem.uavs[u].id] = inst.target_id(k)
        taken.add(k)
    for u in idle:
        uav_id = inst.problem.uavs[u].id
        if uav_id not in out:
            out[uav_id] = inst.target_id(int(inst.d[u, m:].argmin()))
    return {inst.problem.uavs[u].id: out[inst.problem.uavs[u].id] for u in idle}


class PlanSolver:
    """Solve one problem; stop() (any thread) makes solve() return early with what it has."""

    def __init__(
        self,
        problem: PlanningProblem,
        hint: Mapping[str, Sequence[str]] | None = None,
        *,
        num_workers: int = 1,
        random_seed: int = 0,
        deterministic: bool = False,
        method: str = "auto",
    ) -> None:
        self.problem = problem
        self.hint = hint
        self.num_workers = num_workers
        self.random_seed = random_seed
        self.deterministic = deterministic
        self.method = method  # "auto", "dp", "position", "circuit", "heuristic" (tests, bench)
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._run: CpSatRun | None = None

    def stop(self) -> None:
        self._stop.set()
        with self._lock:
            if self._run is not None:
                self._run.stop()

    def solve(self) -> PlanResult:
        start = time.perf_counter()
        problem = self.problem
        limit = problem.time_limit_s
        inst = build_instance(problem)
        m, n = inst.m, inst.n
        routes: list[list[int]]
        hit = False
        if n == 0:
            empty: list[list[int]] = [[] for _ in range(m)]
            return self._result(inst, empty, PlanStatus.OPTIMAL, "trivial", start, False)
        method = self.method
        if method == "auto" and dp_is_cheap(m, n):
            method = "dp"
        if method == "dp":
            return self._result(inst, solve_dp(inst), PlanStatus.OPTIMAL, "dp", start, False)
        # heuristic start
        ls = LocalSearch(inst, self.random_seed, self._stop.is_set)
        routes = greedy(inst, ls.coster)
        best_cost = ls.coster.total(routes)
        if self.hint:
            hinted = hint_routes(inst, self.hint)
            if hinted is not None and ls.coster.total(hinted) < best_cost:
                routes, best_cost = hinted, ls.coster.total(hinted)
        kind = method
        if method == "auto":
            sequence = problem.objective == "sequence"
            kind = "position" if sequence and n <= POSITION_MODEL_MAX_TARGETS else "circuit"
        # mid-size instances: CP-SAT usually proves optimality, so keep the search short;
        # large ones: CP-SAT rarely improves a good plan within a second, the ILS does.
        mid = n <= POSITION_MODEL_MAX_TARGETS
        ls_share = 0.1 if mid else 0.7
        if method == "heuristic":
            ls_share = 1.0
        if self.deterministic:
            iterations = 30 if mid else max(5, 600 // max(n, 1))
            routes, best_cost = ls.run(routes, iterations)
        else:
            ls_end = start + ls_share * limit
            patience = 20 if mid else None
            routes, best_cost = ls.run(
                routes, 10**9, lambda: time.perf_counter() > ls_end, patience=patience
            )
        if method == "heuristic" or self._stop.is_set():
            hit = not self._stop.is_set()
            return self._result(inst, routes, PlanStatus.FALLBACK, "greedy+ils", start, hit)
        from planner.cpsat_model import CpSatRun  # lazy: ortools.sat (and pandas) cost ~0.3 s

        run = CpSatRun(inst, kind)
        run.add_hint(routes)
        with self._lock:
            self._run = run
        if self._stop.is_set():
            run.stop()
        if self.deterministic:
            budget = max(limit * (1.0 - ls_share), 0.01)
        else:
            budget = max(limit - (time.perf_counter() - start), 0.01)
        outcome = run.solve(
            budget,
            num_workers=self.num_workers,
            random_seed=self.random_seed,
            deterministic=self.deterministic,
        )
        with self._lock:
            self._run = None
        name = f"cp-sat/{outcome.model}+ils"
        if outcome.routes is None:
            hit = not outcome.stopped
            return self._result(inst, routes, PlanStatus.FALLBACK, "greedy+ils", start, hit)
        cp_cost = ls.coster.total(outcome.routes)
        if cp_cost <= best_cost:
            routes = outcome.routes
        hit = outcome.status != "optimal" and not outcome.stopped
        return self._result(inst, routes, PlanStatus(outcome.status), name, start, hit)

    def _result(
        self,
        inst: Instance,
        routes: list[list[int]],
        status: PlanStatus,
        solver: str,
        start: float,
        hit: bool,
    ) -> PlanResult:
        objective, f1, f2 = inst.evaluate(routes)
        uavs = inst.problem.uavs
        return PlanResult(
            status=status,
            solver=solver,
            objective=objective,
            f1=f1,
            f2=f2,
            mu=inst.mu,
            routes={uavs[u].id: [inst.target_id(k) for k in r] for u, r in enumerate(routes)},
            idle=idle_assignment(inst, routes),
            excluded=list(inst.excluded),
            solve_time_s=time.perf_counter() - start,
            hit_time_limit=hit,
        )


def solve_plan(
    problem: PlanningProblem,
    hint: Mapping[str, Sequence[str]] | None = None,
    *,
    num_workers: int = 1,
    random_seed: int = 0,
    deterministic: bool = False,
) -> PlanResult:
    """Solve `problem` (see PlanSolver)."""
    return PlanSolver(
        problem,
        hint,
        num_workers=num_workers,
        random_seed=random_seed,
        deterministic=deterministic,
    ).solve()
