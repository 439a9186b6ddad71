"""Lower bounds, gaps and deadlines: planner.bound, PlanResult.bound/gap, PlanSolver's clock.

The bounds are checked against the exact DP (itself checked against brute force in
test_planner_optimality) on random instances of every objective, never by timing. The
deadline tests drive PlanSolver with a fake clock and count what the solver did.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from planner_fixtures import problems, random_problem

from planner import PlanningProblem, PlanSolver, result_to_dict
from planner.bound import (
    choose_layers,
    in_arc_bound,
    keep_columns,
    layer_cap,
    lp_bound,
    lp_columns,
)
from planner.exact_dp import dp_is_cheap, solve_dp
from planner.instance import Instance, build_instance
from planner.problem import PlanStatus, plan_gap
from planner.solve import PlanSolver as _Solver

DOCS = Path(__file__).resolve().parent.parent / "docs" / "planner.md"


def optimum(inst: Instance) -> float:
    return inst.evaluate(solve_dp(inst))[0]


def slack(inst: Instance, value: float) -> float:
    """Float noise allowed when comparing a bound with an optimum."""
    return 1e-9 * (abs(value) + abs(inst.constant) + 1.0)


@settings(max_examples=60, deadline=None)
@given(problems(objectives=("sequence", "arrival", "latency")), st.integers(1, 7))
def test_bounds_never_exceed_the_dp_optimum(p: PlanningProblem, layers: int) -> None:
    inst = build_instance(p)
    if inst.n == 0:
        return
    best = optimum(inst)
    assert in_arc_bound(inst) <= best + slack(inst, best)
    lp = lp_bound(inst, min(layers, inst.n), 30.0)  # fewer layers: absorbing last layer
    assert lp is not None
    assert lp.value <= best + slack(inst, best)
    assert (lp.reduced >= 0).all()


@pytest.mark.parametrize(("m", "n"), [(1, 12), (2, 12), (3, 11), (4, 12)])
@pytest.mark.parametrize("objective", ["sequence", "arrival", "latency"])
def test_lp_bound_below_optimum_and_close_for_sequence(m: int, n: int, objective: str) -> None:
    for seed in range(3):
        inst = build_instance(random_problem(seed, m, n, objective=objective))
        best = optimum(inst)
        lp = lp_bound(inst, n, 30.0)
        assert lp is not None
        assert in_arc_bound(inst) <= lp.value + slack(inst, best) or objective != "sequence"
        assert lp.value <= best + slack(inst, best)
        if objective == "sequence" and m >= 3:
            # the layered LP is tight for fleets (measured 2-5 % of |J|); in-arc is ~20 %
            assert (best - lp.value) / abs(best) < 0.08


def test_known_optimum_mid_size_proven_by_cp_sat() -> None:
    """A 5x20 optimum proven by CP-SAT: every bound lies below it, and the solver's own
    result reports bound == objective, gap 0."""
    p = random_problem(12, 5, 20, time_limit_s=20.0)
    r = PlanSolver(p).solve()
    assert r.status == "optimal"
    assert r.bound == r.objective and r.gap == 0.0
    inst = build_instance(p)
    lp = lp_bound(inst, inst.n, 30.0)
    assert lp is not None
    assert lp.value <= r.objective + slack(inst, r.objective)
    assert in_arc_bound(inst) <= lp.value


@pytest.mark.parametrize("seed", range(4))
def test_reduced_cost_fixing_keeps_the_optimum(seed: int) -> None:
    """CP-SAT's position model with the variables the LP rules out removed still finds the
    DP's optimum (the incumbent fed to the fixing is a poor plan, so little is removed, and
    the greedy one, so much is)."""
    from planner.cpsat_model import CpSatRun
    from planner.heuristics import greedy

    inst = build_instance(random_problem(100 + seed, 3, 9))
    best = optimum(inst)
    lp = lp_bound(inst, inst.n, 30.0)
    assert lp is not None
    start = greedy(inst)
    for upper in (inst.evaluate(start)[0], best):
        first, arc = keep_columns(inst, lp, upper)
        run = CpSatRun(inst, "position", keep=(first, arc))
        run.add_hint(start)
        out = run.solve(30.0)
        assert out.status == "optimal" and out.routes is not None
        got = inst.evaluate(out.routes)[0]
        assert abs(got - best) <= 1e-6 * abs(best)


def test_plan_gap_definition() -> None:
    assert plan_gap(-100.0, -103.0) == pytest.approx(0.03)  # negative objective: |J|
    assert plan_gap(200.0, 150.0) == pytest.approx(0.25)
    assert plan_gap(-5.0, -5.0) == 0.0
    assert plan_gap(0.0, 0.0) == 0.0  # bound == objective == 0
    assert plan_gap(0.0, -1.0) is None  # no relative figure at objective 0
    assert plan_gap(1.0, None) is None
    assert plan_gap(1.0, 2.0) == 0.0  # never negative


def check_bound_and_gap(p: PlanningProblem, **kw: object) -> PlanStatus:
    r = PlanSolver(p, **kw).solve()  # type: ignore[arg-type]
    inst = build_instance(p)
    assert r.bound is not None
    assert r.bound <= r.objective
    assert r.gap == plan_gap(r.objective, r.bound)
    if r.status == "optimal":
        assert r.bound == r.objective and r.gap == 0.0
    else:
        assert r.gap is not None and r.gap >= 0.0
        assert r.bound < r.objective  # an unproven plan never claims a zero gap here
    if dp_is_cheap(inst.m, inst.n) and inst.n:
        assert r.bound <= optimum(inst) + slack(inst, r.objective)
    d = result_to_dict(r)
    assert d["bound"] == r.bound and d["gap"] == r.gap
    return r.status


def test_bound_and_gap_for_every_status() -> None:
    seen = {
        check_bound_and_gap(random_problem(1, 3, 10)),  # dp
        check_bound_and_gap(random_problem(2, 3, 0)),  # trivial
        check_bound_and_gap(random_problem(3, 3, 10), method="position"),  # cp-sat proof
        check_bound_and_gap(random_problem(4, 3, 10), method="heuristic"),  # fallback
        check_bound_and_gap(random_problem(5, 8, 40, time_limit_s=0.5)),  # large: ILS
        check_bound_and_gap(random_problem(6, 4, 9, objective="arrival"), method="circuit"),
        check_bound_and_gap(random_problem(7, 4, 9, objective="latency"), method="circuit"),
        check_bound_and_gap(random_problem(8, 6, 40, objective="latency", time_limit_s=0.5)),
    }
    assert {"optimal", "fallback"} <= {str(s) for s in seen}


class StepClock:
    """A clock that advances `step_s` at every reading: the deadline passes after a known
    number of polls, whatever the machine's load."""

    def __init__(self, step_s: float, frozen_after: int | None = None) -> None:
        self.step_s = step_s
        self.calls = 0
        self.frozen_after = frozen_after

    def __call__(self) -> float:
        self.calls += 1
        if self.frozen_after is not None and self.calls > self.frozen_after:
            return 1e9  # every deadline long past
        return self.calls * self.step_s


def test_first_descent_polls_the_deadline() -> None:
    """With the deadline past from the first reading after the start, the first local-search
    descent stops after at most one improving move (it used to run to a local optimum:
    2.2 s at 20x100 for a 1 s limit)."""
    p = random_problem(20, 8, 60, time_limit_s=1.0)
    clock = StepClock(0.0, frozen_after=1)
    solver = _Solver(p, clock=clock)
    r = solver.solve()
    assert solver.local_search is not None
    assert solver.local_search.moves <= 1
    assert r.status == "fallback" and r.hit_time_limit
    assert sorted(t for route in r.routes.values() for t in route) == sorted(
        t.id for t in p.targets if t.id not in r.excluded
    )
    # without a deadline the same descent makes many moves
    from planner.heuristics import LocalSearch, greedy

    inst = build_instance(p)
    free = LocalSearch(inst)
    free.descend(greedy(inst, free.coster))
    assert free.moves > 1


@pytest.mark.parametrize(("m", "n"), [(8, 60), (20, 100)])
def test_deadline_is_polled_regularly(m: int, n: int) -> None:
    """A clock that advances 1/400 of the limit per reading: the whole solve (local search,
    LP sizing, CP-SAT decision, result) reads it about 400 times and returns at once after
    the limit passes: never more than a handful of readings past it."""
    limit = 1.0
    clock = StepClock(limit / 400)
    solver = _Solver(random_problem(21, m, n, time_limit_s=limit), clock=clock)
    r = solver.solve()
    assert clock.calls <= 400 + 10
    assert r.solve_time_s <= limit * 1.05
    assert solver.local_search is not None and solver.local_search.moves > 0


def test_deterministic_mode_gives_a_bound() -> None:
    p = random_problem(22, 4, 35, time_limit_s=0.3)
    a = PlanSolver(p, deterministic=True).solve()
    b = PlanSolver(p, deterministic=True).solve()
    assert a.bound == b.bound and a.gap == b.gap
    assert a.routes == b.routes  # no clock: the same plan (replay re-solves it)
    assert a.bound is not None and a.bound < a.objective


def test_choose_layers_caps_columns() -> None:
    """One rule for the LP's positions: at most layer_cap, at most max_columns columns, at
    least MIN_LAYERS (else 0: no LP)."""
    assert layer_cap(20, 5, True) == 20 and layer_cap(20, 5, False) == 8
    assert layer_cap(250, 50, False) == 10 and layer_cap(3, 5, False) == 3
    assert choose_layers(20, 5, 20) == 20
    assert choose_layers(250, 50, 250) == 7  # (400000 - 12500) // 62250 + 1
    assert lp_columns(250, 50, 7) <= 400_000 < lp_columns(250, 50, 8)
    assert choose_layers(250, 50, 5) == 5
    assert choose_layers(250, 50, 250, 150_000) == 3
    assert choose_layers(400, 50, 400, 150_000) == 0  # 2 layers: 179600 columns
    assert choose_layers(1, 3, 1) == 0


def test_output_schema_is_documented() -> None:
    """Every key of the `gcs plan` output appears in docs/planner.md's output table."""
    r = PlanSolver(random_problem(23, 2, 4)).solve()
    text = DOCS.read_text(encoding="utf-8")
    first_cells = re.findall(r"^\| ([^|]+)\|", text, flags=re.MULTILINE)
    documented = {k for cell in first_cells for k in re.findall(r"`([a-z_0-9]+)`", cell)}
    assert set(result_to_dict(r)) <= documented


def test_single_uav_uses_the_dp_up_to_sixteen_targets() -> None:
    assert dp_is_cheap(1, 16, 1.0) and dp_is_cheap(2, 16, 1.0)
    assert not dp_is_cheap(1, 18, 60.0)
    r = PlanSolver(random_problem(24, 1, 15, time_limit_s=1.0)).solve()
    assert r.solver == "dp" and r.status == "optimal"


def test_old_record_without_bound_reads_as_none() -> None:
    from groundstation.core.records import result_from_record, result_to_record

    r = PlanSolver(random_problem(25, 2, 5)).solve()
    record = result_to_record(r)
    assert result_from_record(record) == r
    old = {k: v for k, v in record.items() if k not in ("bound", "gap")}
    back = result_from_record(old)
    assert back.bound is None and back.gap is None
    assert replace(back, bound=r.bound, gap=r.gap) == r


@pytest.mark.parametrize("model", ["position", "circuit"])
@pytest.mark.parametrize("seconds", [0.02, 5.0])
def test_cp_sat_bound_never_exceeds_the_optimum(model: str, seconds: float) -> None:
    """CP-SAT's objective bound, turned back into J with the coefficients' rounding slack,
    stays below the DP optimum whether CP-SAT stops early or proves (then it is tight)."""
    from planner.cpsat_model import CpSatRun
    from planner.heuristics import greedy

    for seed in range(2):
        inst = build_instance(random_problem(200 + seed, 3, 11))
        best = optimum(inst)
        run = CpSatRun(inst, model)
        run.add_hint(greedy(inst))
        out = run.solve(seconds)
        if out.bound is None:
            continue
        assert out.bound <= best + slack(inst, best)
        if out.status == "optimal":
            assert best - out.bound <= 1e-6 * abs(best)


def test_plan_journal_line_carries_bound_and_gap_once() -> None:
    """The plan line keeps bound and gap in its `result` (non-finite as None), not twice."""
    from groundstation.core.commands import PlanAdopted
    from groundstation.core.records import command_to_record

    p = random_problem(26, 2, 5)
    r = PlanSolver(p).solve()
    line = command_to_record(PlanAdopted(1.0, 7, p, r, {}, {}, "test"))
    assert "bound" not in line and "gap" not in line
    assert line["result"]["bound"] == r.bound and line["result"]["gap"] == r.gap


def test_cp_sat_model_is_chosen_by_the_solver_only() -> None:
    """CpSatRun has no "auto" choice of its own (it disagreed with planner.solve's)."""
    from planner.cpsat_model import CpSatRun

    inst = build_instance(random_problem(27, 2, 5))
    with pytest.raises(ValueError, match="position or circuit"):
        CpSatRun(inst, "auto")
    assert CpSatRun(inst, "position").kind == "position"
