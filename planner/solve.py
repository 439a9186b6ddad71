"""solve_plan / PlanSolver: choose the method, run it within the time limit, report.

Pipeline: 10 % rule and distances (planner.instance); no kept target -> trivial optimum;
where the subset DP is cheap (planner.exact_dp.dp_is_cheap, by measured cost per fleet size)
-> exact DP; otherwise greedy insertion, the previous plan (hint) if it is better, iterated
local search, a proven lower bound (planner.bound: the layered LP where it fits the budget,
else the in-arc bound), then CP-SAT hinted with the best plan (planner.cpsat_model) where it
pays: the position model (sequence objective, <= 30 targets) with every variable whose LP
reduced cost exceeds the incumbent's gap fixed to 0, or the circuit model up to 60 targets
when the time left covers its build. The result is the best plan by its exact float
objective; status "optimal" when the DP ran or CP-SAT proved optimality, "feasible" when
CP-SAT found a plan, "fallback" otherwise (the heuristic plan).

Every result carries `bound` (a proven lower bound on J; = objective when optimal) and
`gap` = (objective - bound) / |objective| (0 when both are 0, None when only the objective is).

Deadlines are compute budgets measured with `clock` (time.perf_counter; no mission clock is
read), polled by every phase: the local search between moves and per scan row, the LP and
CP-SAT by their own time limits, sized from the time left. With deterministic=True nothing
depends on the wall clock: the local search has a fixed iteration budget, the LP a fixed
size, and CP-SAT runs one worker with max_deterministic_time.
"""

from __future__ import annotations

import importlib
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING

from planner.bound import (
    LP_MAX_COLUMNS,
    MIN_LAYERS,
    LpBound,
    choose_layers,
    in_arc_bound,
    keep_columns,
    layer_cap,
    lp_bound,
    lp_columns,
)
from planner.exact_dp import dp_is_cheap, solve_dp
from planner.heuristics import LocalSearch, RouteCoster, best_insertion, greedy
from planner.instance import Instance, build_instance
from planner.problem import PlanningProblem, PlanResult, PlanStatus, plan_gap

if TYPE_CHECKING:
    from planner.cpsat_model import CpSatRun

POSITION_MODEL_MAX_TARGETS = 30
CIRCUIT_MODEL_MAX_TARGETS = 60  # above: the build alone eats the budget, CP-SAT never helps
DETERMINISTIC_LP_COLUMNS = 150_000  # deterministic mode: the LP's size, not its time
LP_SECONDS_PER_COLUMN = 4e-6  # HiGHS on the layered LP (measured 1.7-10 us with both cores busy)
SCIPY_IMPORT_S = 0.5  # first LP in a process: importing scipy.optimize (CPU, measured 0.3-0.45)
CIRCUIT_BUILD_S_PER_VAR = 2e-5  # Python model build, circuit model (1.3 s at 30x150)
POSITION_BUILD_S_PER_VAR = 5e-6  # position model build per LP column (0.115-0.136 s at 5x30)
ORTOOLS_IMPORT_S = 0.4  # first CP-SAT run in a process: importing OR-Tools (wall, measured)
END_MARGIN = 0.03  # fraction of the limit kept for the result (evaluate, idle rule)
CPSAT_STOP_S = 0.1  # CP-SAT overruns max_time_in_seconds by this much (measured 0.05-0.12 s)

Clock = Callable[[], float]


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

    Repeatedly the closest pair (idle UAV, free target) is matched (ties: UAV, then
    target, in input order), where a target is free if it is no route's first target and no
    idle UAV has it yet. Closest by Dubins distance; in wind by the travel time without the
    wind's potential (``d_net``, as the objectives count it: a move downwind is no nearer
    for being quick, since coming back costs what it saved). Only when no free target is
    left (more UAVs than kept targets) does an idle UAV share one: its nearest kept target.
    Sending an idle UAV where another UAV already flies sent all three UAVs to one iceberg
    at t = 0 of paper-boat (docs/planner.md, "Idle UAVs").
    """
    out: dict[str, str] = {}
    if inst.n == 0:
        return out
    m = inst.m
    idle = [u for u, route in enumerate(routes) if not route]
    taken = {route[0] for route in routes if route}
    pairs = sorted(
        (float(inst.d_net[u, m + k]), u, k) for u in idle for k in range(inst.n) if k not in taken
    )
    for _, u, k in pairs:
        if k in taken or inst.problem.uavs[u].id in out:
            continue
        out[inst.problem.uavs[u].id] = inst.target_id(k)
        taken.add(k)
    for u in idle:
        uav_id = inst.problem.uavs[u].id
        if uav_id not in out:
            out[uav_id] = inst.target_id(int(inst.d_net[u, m:].argmin()))
    return {inst.problem.uavs[u].id: out[inst.problem.uavs[u].id] for u in idle}


def lp_ready() -> bool:
    """Whether scipy's LP is loaded (its first import costs ~0.3-0.5 s of wall time)."""
    return "scipy.optimize" in sys.modules


def load_lp(limit_s: float) -> bool:
    """Import scipy's LP now if it is not loaded and its import takes at most half the time
    limit (the rest of the solve is then planned with the import paid)."""
    if lp_ready():
        return True
    if 0.5 * limit_s < SCIPY_IMPORT_S:
        return False
    importlib.import_module("scipy.optimize")
    return True


def warm_up() -> None:
    """Import the LP (scipy) and CP-SAT (OR-Tools) libraries now, outside any solve's budget
    (~0.3-0.5 s each, once per process). A long-lived caller (daemon, benchmark) calls it
    once at start; without it the first solve that needs them pays the imports."""
    importlib.import_module("scipy.optimize")
    importlib.import_module("ortools.sat.python.cp_model")


def cpsat_import_s() -> float:
    """Wall time still to pay for importing OR-Tools' CP-SAT (0 once loaded)."""
    return 0.0 if "ortools.sat.python.cp_model" in sys.modules else ORTOOLS_IMPORT_S


def cpsat_build_s(kind: str, m: int, n: int) -> float:
    """Estimated wall time before CP-SAT starts searching: the Python model build (position
    model: per column of its full LP, an upper bound as reduced-cost fixing only drops
    variables; circuit model: per arc variable) plus OR-Tools' import if not yet loaded."""
    if kind == "position":
        build = POSITION_BUILD_S_PER_VAR * lp_columns(n, m, n)
    else:
        build = CIRCUIT_BUILD_S_PER_VAR * n * (n + m)
    return build + cpsat_import_s()


def lp_seconds(columns: int) -> float:
    """Estimated wall time of the layered LP (plus scipy's import if not yet loaded)."""
    first = 0.0 if lp_ready() else SCIPY_IMPORT_S
    return first + 0.01 + LP_SECONDS_PER_COLUMN * columns


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
        clock: Clock = time.perf_counter,
    ) -> None:
        self.problem = problem
        self.hint = hint
        self.num_workers = num_workers
        self.random_seed = random_seed
        self.deterministic = deterministic
        self.method = method  # "auto", "dp", "position", "circuit", "heuristic" (tests, bench)
        self.clock = clock
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._run: CpSatRun | None = None
        self.local_search: LocalSearch | None = None  # the last run's (tests: moves, polls)

    def stop(self) -> None:
        self._stop.set()
        with self._lock:
            run = self._run
        if run is not None:
            run.stop()

    def solve(self) -> PlanResult:
        clock = self.clock
        start = clock()
        problem = self.problem
        limit = problem.time_limit_s
        end = start + limit * (1.0 - END_MARGIN)
        inst = build_instance(problem)
        m, n = inst.m, inst.n
        if n == 0:
            empty: list[list[int]] = [[] for _ in range(m)]
            return self._result(inst, empty, PlanStatus.OPTIMAL, "trivial", start, False, None)
        method = self.method
        if method == "auto" and dp_is_cheap(m, n, limit):
            method = "dp"
        if method == "dp":
            routes = solve_dp(inst)
            return self._result(inst, routes, PlanStatus.OPTIMAL, "dp", start, False, None)
        kind = method
        if method == "auto":
            sequence = inst.unit_hops  # the sequence objective (all hops 1)
            kind = "position" if sequence and n <= POSITION_MODEL_MAX_TARGETS else "circuit"
        mid = n <= POSITION_MODEL_MAX_TARGETS  # CP-SAT usually proves these: it gets the time
        if method != "heuristic" and not self.deterministic:
            load_lp(limit)
        # -- heuristic start
        ls_end = [end]
        stop = self._stop.is_set
        if self.deterministic:
            ls = LocalSearch(inst, self.random_seed, stop)
        else:
            ls = LocalSearch(inst, self.random_seed, lambda: stop() or clock() > ls_end[0])
        self.local_search = ls
        routes = greedy(inst, ls.coster)
        best_cost = ls.coster.total(routes)
        if self.hint:
            hinted = hint_routes(inst, self.hint)
            if hinted is not None and ls.coster.total(hinted) < best_cost:
                routes, best_cost = hinted, ls.coster.total(hinted)
        # mid-size: CP-SAT usually proves optimality, keep the search short; large: the ILS
        # does the work (CP-SAT rarely improves a good plan within seconds). The LP runs
        # early (after 30 % of the limit) so that the local search after it absorbs any
        # overrun of the LP under load; then the search goes on to 70 % of the limit, and
        # to the end unless the circuit model (<= 60 targets) can still be built and run.
        ls_share = 0.1 if mid else 0.7
        if method == "heuristic":
            ls_share = 1.0
        if self.deterministic:
            iterations = 30 if mid else max(5, 600 // max(n, 1))
            routes, best_cost = ls.run(routes, iterations)
        else:
            first = ls_share if mid or method == "heuristic" else 0.3
            ls_end[0] = min(end, start + first * limit)
            patience = 20 if mid else None
            routes, best_cost = ls.run(routes, 10**9, patience=patience)
        if method == "heuristic" or stop():
            hit = not stop()
            bound = in_arc_bound(inst)
            return self._result(inst, routes, PlanStatus.FALLBACK, "greedy+ils", start, hit, bound)
        # -- proven lower bound
        lp = self._lp(inst, mid, end, limit)
        bound = in_arc_bound(inst)
        if lp is not None:
            bound = max(bound, lp.value)
        if stop():  # stop() during the LP (which it cannot interrupt): no model build
            return self._result(
                inst, routes, PlanStatus.FALLBACK, "greedy+ils", start, False, bound
            )
        if not mid and not self.deterministic:
            ls_end[0] = min(end, start + ls_share * limit)
            routes, best_cost = ls.run(routes, 10**9)
        # -- CP-SAT where it pays, else the local search goes on to the deadline
        # CP-SAT runs where its build (and OR-Tools' import) leaves it time to search: up to
        # 30 targets it usually proves, so the time left need only cover the build, the stop
        # allowance and 0.05 s; above, the circuit model must beat the local search, so 3x
        # the build. Forced by method ("position", "circuit"); by size alone when deterministic.
        if method in ("position", "circuit"):
            use_cpsat = True
        elif self.deterministic:
            use_cpsat = n <= CIRCUIT_MODEL_MAX_TARGETS
        elif n > CIRCUIT_MODEL_MAX_TARGETS:
            use_cpsat = False
        else:
            build_s = cpsat_build_s(kind, m, n)
            need_s = build_s + CPSAT_STOP_S if mid else 3.0 * build_s
            use_cpsat = end - clock() > need_s + 0.05
        if not use_cpsat:
            if not self.deterministic:
                ls_end[0] = end
                routes, best_cost = ls.run(routes, 10**9)
            hit = not stop()
            return self._result(inst, routes, PlanStatus.FALLBACK, "greedy+ils", start, hit, bound)
        return self._cpsat(
            inst, kind, ls.coster, routes, best_cost, lp, bound, start, end, ls_share
        )

    def _lp(self, inst: Instance, mid: bool, end: float, limit: float) -> LpBound | None:
        """The layered LP, sized to its budget; None if it does not fit or finish."""
        m, n = inst.m, inst.n
        cap = layer_cap(n, m, mid)
        if self.deterministic:  # sized by columns: nothing depends on the wall clock
            layers = choose_layers(n, m, cap, DETERMINISTIC_LP_COLUMNS)
            if layers < MIN_LAYERS:
                return None
            return lp_bound(inst, layers, max(10.0 * limit, 10.0))
        budget = min(end - self.clock(), 0.25 * limit if not mid else 0.4 * limit)
        if budget <= 0.0:
            return None
        layers = choose_layers(n, m, cap, LP_MAX_COLUMNS)  # then fewer until its time fits
        while layers >= MIN_LAYERS and lp_seconds(lp_columns(n, m, layers)) > budget:
            layers -= 1 if layers <= 8 else max(1, layers // 4)
        if layers < MIN_LAYERS:
            return None
        return lp_bound(inst, layers, budget)

    def _cpsat(
        self,
        inst: Instance,
        kind: str,
        coster: RouteCoster,
        routes: list[list[int]],
        best_cost: float,
        lp: LpBound | None,
        bound: float,
        start: float,
        end: float,
        ls_share: float,
    ) -> PlanResult:
        from planner.cpsat_model import CpSatRun  # OR-Tools only when CP-SAT runs

        keep = None
        if kind == "position" and lp is not None and lp.layers == inst.n:
            keep = keep_columns(inst, lp, inst.constant + best_cost)
        run = CpSatRun(inst, kind, keep=keep)
        run.add_hint(routes)
        with self._lock:
            self._run = run
        if self._stop.is_set():
            run.stop()
        limit = self.problem.time_limit_s
        if self.deterministic:
            budget = max(limit * (1.0 - ls_share), 0.01)
        else:
            budget = max(end - self.clock() - CPSAT_STOP_S, 0.01)
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
            return self._result(inst, routes, PlanStatus.FALLBACK, "greedy+ils", start, hit, bound)
        if coster.total(outcome.routes) <= best_cost:
            routes = outcome.routes
        if outcome.bound is not None:
            bound = max(bound, outcome.bound)
        hit = outcome.status != "optimal" and not outcome.stopped
        status = PlanStatus(outcome.status)
        return self._result(inst, routes, status, name, start, hit, bound)

    def _result(
        self,
        inst: Instance,
        routes: list[list[int]],
        status: PlanStatus,
        solver: str,
        start: float,
        hit: bool,
        bound: float | None,
    ) -> PlanResult:
        """`bound`: a proven lower bound on J; ignored (= the objective) when optimal."""
        objective, f1, f2 = inst.evaluate(routes)
        if status is PlanStatus.OPTIMAL:
            bound = objective
        elif bound is None:
            bound = in_arc_bound(inst)
        bound = min(bound, objective)
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
            solve_time_s=self.clock() - start,
            hit_time_limit=hit,
            bound=bound,
            gap=plan_gap(objective, bound),
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
