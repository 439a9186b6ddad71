"""solve_plan / PlanSolver: choose the method, run it within the time limit, report.

Pipeline: 10 % rule and distances (planner.instance); no kept target -> trivial optimum;
where the subset DP is cheap (planner.exact_dp.dp_is_cheap, by measured cost per fleet size)
-> exact DP; otherwise greedy insertion, the previous plan (hint) if it is better, iterated
local search, a proven lower bound (planner.bound: the layered LP, by column generation
above 30 targets, where it fits the CPU budget, else the in-arc bound), then CP-SAT hinted
with the best plan (planner.cpsat_model) where it pays: the position model (sequence
objective, <= 30 targets) with every variable whose LP reduced cost exceeds the incumbent's
gap fixed to 0, or the circuit model (arrival and latency, up to 60 targets) when the CPU
left covers its build. The result is the best plan by its exact float
objective; status "optimal" when the DP ran or CP-SAT proved optimality, "feasible" when
CP-SAT found a plan, "fallback" otherwise (the heuristic plan).

Every result carries `bound` (a proven lower bound on J; = objective when optimal) and
`gap` = (objective - bound) / |objective| (0 when both are 0, None when only the objective is).

Deadlines are wall time measured with `clock` (time.perf_counter; no mission clock is
read); phases whose cost is known in CPU (the LP, CP-SAT's build) are sized by the CPU the
solve actually obtains (planner.budget: rate = `cpu_clock` time per wall second so far,
times the wall time left), a phase that does not fit is not started, and HiGHS and CP-SAT
get the wall time left as their own limits (an unfinished LP round hands back the bound of
the rounds before). The local search gets everything else and polls the deadline before
each target's moves, stopping when the next poll would come late (planner.budget.Poll).
The rule is measured and stated in docs/planner.md ("Time budget"). With
deterministic=True nothing depends on the wall clock: the local search has a fixed
iteration budget, the LP a fixed size and number of rounds, and CP-SAT runs one worker with
max_deterministic_time.
"""

from __future__ import annotations

import importlib
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

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
from planner.budget import Budget, Poll
from planner.exact_dp import dp_is_cheap, solve_dp
from planner.heuristics import LocalSearch, RouteCoster, best_insertion
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
LS_FIRST_SHARE = 0.2  # above 30 targets: the first search ends by this share of the limit,
FIRST_KICKS = 20  # or after its first descent and this many kicks (the LP then gets more CPU)
LP_CPU_SHARE = 0.6  # the LP may use at most this share of the CPU left (the search the rest)
LP_END_RESERVE = 0.1  # HiGHS's wall limit ends this share of the limit before the deadline
CG_CANDIDATES = 6  # column generation: cheapest predecessors per target in the first round
DETERMINISTIC_CG_ROUNDS = 2  # deterministic mode: column-generation rounds, not time
CG_S_PER_COLUMN = 6e-6  # HiGHS CPU per restricted-LP z column (cg_round_cpu_s)
CG_S_PER_COLUMN2 = 2e-9  # ... growing with the number of columns
CG_S_PER_FIRST = 4e-6  # HiGHS CPU per a column (first targets, m n of them)
CG_S_PER_PRICE = 2.5e-7  # pricing CPU per column of the full LP (costs, reduced costs)

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
    free = [k for k in range(inst.n) if k not in taken]
    if idle and free:
        # every (distance, UAV, target) pair in increasing order (numpy: 0.03 s -> 1 ms with
        # 10 idle UAVs and 500 targets)
        dist = inst.d_net[np.ix_(idle, [m + k for k in free])]
        uu, kk = np.meshgrid(np.asarray(idle), np.asarray(free), indexing="ij")
        order = np.lexsort((kk.ravel(), uu.ravel(), dist.ravel()))
        flat_u, flat_k = uu.ravel(), kk.ravel()
        for at in order:
            u, k = int(flat_u[at]), int(flat_k[at])
            if k in taken or inst.problem.uavs[u].id in out:
                continue
            out[inst.problem.uavs[u].id] = inst.target_id(k)
            taken.add(k)
            if len(out) == len(idle):
                break
    for u in idle:
        uav_id = inst.problem.uavs[u].id
        if uav_id not in out:
            out[uav_id] = inst.target_id(int(inst.d_net[u, m:].argmin()))
    return {inst.problem.uavs[u].id: out[inst.problem.uavs[u].id] for u in idle}


def lp_ready() -> bool:
    """Whether scipy's LP is loaded (its first import costs ~0.3-0.5 s of wall time)."""
    return "scipy.optimize" in sys.modules


def load_lp(cpu_left_s: float, lp_cpu_s: float) -> bool:
    """Whether scipy's LP is loaded, importing it first when its import (SCIPY_IMPORT_S of
    CPU) and the LP (`lp_cpu_s`) fit the CPU left; a solve that cannot afford the import
    does not start it (until issue 30 it was imported at the start of any solve with a limit
    of 1 s or more: 2.5 s of wall time for a 1 s `gcs plan` 10x50 at load 30)."""
    if lp_ready():
        return True
    if SCIPY_IMPORT_S + lp_cpu_s > cpu_left_s:
        return False
    importlib.import_module("scipy.optimize")
    return True


def warm_up() -> None:
    """Import the LP (scipy) and CP-SAT (OR-Tools) libraries now, outside any solve's budget
    (~0.3-0.5 s each, once per process). A benchmark calls it once at start; the daemon
    once a problem is beyond the DP (:func:`needs_libraries`). Without it the
    first solve that needs them pays the imports, when they fit its budget."""
    importlib.import_module("scipy.optimize")
    importlib.import_module("ortools.sat.python.cp_model")


def libraries_loaded() -> bool:
    """Whether both of :func:`warm_up`'s libraries are imported."""
    return lp_ready() and cpsat_import_s() == 0.0


def needs_libraries(m: int, n: int, time_limit_s: float) -> bool:
    """Whether a problem of ``m`` UAVs and ``n`` targets is beyond the DP (:func:`dp_is_cheap`,
    which needs neither library), so that its solve may use the LP and CP-SAT. With 3
    UAVs the DP solves up to 12 targets at a 1 s limit, 11 at 0.1 s (a 2 s limit at 20x)."""
    return not dp_is_cheap(m, n, time_limit_s)


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


def cg_layer_cap(n: int, m: int) -> int:
    """Most positions P for the column-generation LP: min(n, max(6, ceil(4 n / m))), twice
    layer_cap's (a round costs a tenth of the full LP, docs/planner.md)."""
    return min(n, max(6, -(-4 * n // max(m, 1))))


def cg_round_cpu_s(n: int, m: int, layers: int) -> float:
    """Estimated CPU of one column-generation round with P = `layers` (quiet machine):
    HiGHS on the restricted LP, Z = (P - 1) n (CG_CANDIDATES + 1) z columns at
    Z (6e-6 + 2e-9 Z) s (measured 10-33 us per column from 10x50 to 50x500, growing with
    the LP) and 4 us per a column (P = 2 at 50x250: 0.09 CPU-s), plus pricing every column
    of the full LP."""
    z_cols = (layers - 1) * n * (CG_CANDIDATES + 1)
    full = (layers - 1) * n * n
    highs = z_cols * (CG_S_PER_COLUMN + CG_S_PER_COLUMN2 * z_cols) + CG_S_PER_FIRST * m * n
    return 0.01 + highs + CG_S_PER_PRICE * full


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
        cpu_clock: Clock | None = None,
    ) -> None:
        """`clock`: wall time (s). `cpu_clock`: the CPU time this solve obtains (s); by
        default time.thread_time with the default wall clock, none (CPU = wall) with another
        clock (tests drive the budget by the wall clock alone)."""
        self.problem = problem
        self.hint = hint
        self.num_workers = num_workers
        self.random_seed = random_seed
        self.deterministic = deterministic
        self.method = method  # "auto", "dp", "position", "circuit", "heuristic" (tests, bench)
        self.clock = clock
        if cpu_clock is None and clock is time.perf_counter:
            cpu_clock = time.thread_time
        self.cpu_clock = cpu_clock
        self.budget = Budget(clock, cpu_clock, 0.0, 0.0)
        self._incumbent: list[list[int]] | None = None
        self.trace: list[tuple[str, float, float]] = []  # (phase, wall s, CPU s) at its end
        self.lp: LpBound | None = None  # the last solve's LP bound (benchmarks)
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
        budget = Budget(clock, self.cpu_clock, start, end)
        self.budget = budget
        self.trace = []
        self.lp = None
        inst = build_instance(problem)
        self._mark("build")
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
        # -- heuristic start
        poll = Poll(clock, end)
        stop = self._stop.is_set
        if self.deterministic:
            ls = LocalSearch(inst, self.random_seed, stop)
        else:
            ls = LocalSearch(inst, self.random_seed, lambda: stop() or poll())
        self.local_search = ls
        self._mark("setup")  # route costs as lists, neighbour lists
        routes = ls.greedy()
        best_cost = ls.coster.total(routes)
        if self.hint:
            hinted = hint_routes(inst, self.hint)
            if hinted is not None and ls.coster.total(hinted) < best_cost:
                routes, best_cost = hinted, ls.coster.total(hinted)
        self._mark("greedy")
        # Phases (docs/planner.md, "Time budget"): mid-size (<= 30 targets): a short search,
        # the full LP, CP-SAT's position model (it usually proves optimality). Larger: the
        # search to LS_FIRST_SHARE of the limit, the LP bound by column generation if its
        # estimated CPU fits the CPU the rest of the wall time will give at the rate
        # obtained so far, CP-SAT's circuit model only for arrival/latency up to 60
        # targets when its build fits, and the search again to the deadline.
        ls_share = 0.1 if mid else 0.7
        if self.deterministic:
            iterations = 30 if mid else max(5, 600 // max(n, 1))
            routes, best_cost = ls.run(routes, iterations)
        else:
            first = 0.1 if mid else LS_FIRST_SHARE
            if method == "heuristic":
                first = 1.0
            poll.restart(min(end, start + first * limit))
            patience = 20 if mid else None
            kicks = 10**9 if mid or method == "heuristic" else FIRST_KICKS
            routes, best_cost = ls.run(routes, kicks, patience=patience)
        self._mark("search")
        if method == "heuristic" or stop():
            hit = not stop()
            bound = in_arc_bound(inst)
            return self._result(inst, routes, PlanStatus.FALLBACK, "greedy+ils", start, hit, bound)
        # -- proven lower bound
        self._incumbent = routes
        lp = self._lp(inst, mid, end, limit)
        self.lp = lp
        self._mark("lp")
        bound = in_arc_bound(inst)
        if lp is not None:
            bound = max(bound, lp.value)
        if stop():  # stop() during the LP (which it cannot interrupt): no model build
            return self._result(
                inst, routes, PlanStatus.FALLBACK, "greedy+ils", start, False, bound
            )
        circuit_possible = n <= CIRCUIT_MODEL_MAX_TARGETS and not inst.unit_hops
        if not mid and not self.deterministic and (circuit_possible or method == "circuit"):
            poll.restart(min(end, start + ls_share * limit))
            routes, best_cost = ls.run(routes, 10**9)
            self._mark("search")
        # -- CP-SAT where it pays, else the local search goes on to the deadline
        # Up to 30 targets CP-SAT usually proves, so the CPU left need only cover the build,
        # the stop allowance and 0.05 s. Above, only the arrival and latency objectives try
        # the circuit model (<= 60 targets), when 3x its build fits: for the sequence
        # objective it found no plan in 0.47-0.50 s at 10x50 (issue 30), while the search
        # gains all along. Forced by method ("position", "circuit"); by size alone when
        # deterministic.
        if method in ("position", "circuit"):
            use_cpsat = True
        elif self.deterministic:
            use_cpsat = n <= CIRCUIT_MODEL_MAX_TARGETS
        elif n > CIRCUIT_MODEL_MAX_TARGETS or (not mid and inst.unit_hops):
            use_cpsat = False
        else:
            build_s = cpsat_build_s(kind, m, n)
            need_s = build_s + CPSAT_STOP_S if mid else 3.0 * build_s
            use_cpsat = budget.cpu_left_s() > need_s + 0.05
        if not use_cpsat:
            if not self.deterministic:
                poll.restart(end)
                routes, best_cost = ls.run(routes, 10**9)
                self._mark("search")
            hit = not stop()
            return self._result(inst, routes, PlanStatus.FALLBACK, "greedy+ils", start, hit, bound)
        return self._cpsat(
            inst, kind, ls.coster, routes, best_cost, lp, bound, start, end, ls_share
        )

    def _mark(self, phase: str) -> None:
        """Record the end of a phase (wall and CPU since the start; real clocks only, so a
        test's fake clock is read exactly as the phases themselves read it)."""
        if self.cpu_clock is not None:
            b = self.budget
            self.trace.append((phase, self.clock() - b.start, b.cpu() - b.cpu_start))

    def _lp(self, inst: Instance, mid: bool, end: float, limit: float) -> LpBound | None:
        """The layered LP bound, sized to the CPU it can get; None if it does not fit or no
        round finishes (HiGHS is stopped at the wall deadline minus LP_END_RESERVE of the
        limit). Mid-size: the full LP with one layer per position (CP-SAT's reduced-cost
        fixing needs it). Larger: column generation (planner.bound.lp_bound with
        candidates), P from layer_cap down to the largest whose estimated CPU fits."""
        m, n = inst.m, inst.n
        routes = self._incumbent
        if self.deterministic:  # sized by columns: nothing depends on the wall clock
            if mid:
                layers = choose_layers(n, m, layer_cap(n, m, mid), DETERMINISTIC_LP_COLUMNS)
                if layers < MIN_LAYERS:
                    return None
                return lp_bound(inst, layers, max(10.0 * limit, 10.0))
            # as many positions as the full LP had before column generation (never more
            # work than it), solved by DETERMINISTIC_CG_ROUNDS rounds
            layers = choose_layers(n, m, layer_cap(n, m, mid), DETERMINISTIC_LP_COLUMNS)
            if layers < MIN_LAYERS:
                return None
            return lp_bound(
                inst, layers, max(10.0 * limit, 10.0), routes=routes,
                candidates=CG_CANDIDATES, rounds=DETERMINISTIC_CG_ROUNDS,
            )
        budget = self.budget
        cpu_left = budget.cpu_left_s() * LP_CPU_SHARE
        wall_left = end - self.clock() - LP_END_RESERVE * limit
        if cpu_left <= 0.0 or wall_left <= 0.0:
            return None
        if mid:
            layers = choose_layers(n, m, layer_cap(n, m, mid), LP_MAX_COLUMNS)
            while layers >= MIN_LAYERS and lp_seconds(lp_columns(n, m, layers)) > cpu_left:
                layers -= 1 if layers <= 8 else max(1, layers // 4)
            if layers < MIN_LAYERS or not load_lp(cpu_left, 0.0):  # lp_seconds has the import
                return None
            wall_left = end - self.clock() - LP_END_RESERVE * limit
            return lp_bound(inst, layers, wall_left)
        layers = min(n, cg_layer_cap(n, m))
        while layers >= MIN_LAYERS and cg_round_cpu_s(n, m, layers) > cpu_left:
            layers -= 1 if layers <= 8 else max(1, layers // 4)
        if layers < MIN_LAYERS:
            return None
        round_cpu = cg_round_cpu_s(n, m, layers)
        if not lp_ready():
            while layers >= MIN_LAYERS and not load_lp(cpu_left, cg_round_cpu_s(n, m, layers)):
                layers -= 1 if layers <= 8 else max(1, layers // 4)
            if layers < MIN_LAYERS:
                return None
            round_cpu = cg_round_cpu_s(n, m, layers)
            cpu_left = budget.cpu_left_s() * LP_CPU_SHARE  # after the import
            wall_left = end - self.clock() - LP_END_RESERVE * limit
        lp_start = budget.cpu()

        def no_more_rounds() -> bool:
            # another round only if its estimate fits what is left of the LP's CPU share
            spent = budget.cpu() - lp_start
            return self._stop.is_set() or spent + round_cpu > cpu_left

        return lp_bound(
            inst, layers, wall_left, routes=routes, candidates=CG_CANDIDATES,
            should_stop=no_more_rounds,
        )

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
