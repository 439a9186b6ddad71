"""CP-SAT's share of the time limit, driven by a fake clock and a fake CP-SAT run.

What is asserted is the budget and the decision the solver takes from the clock's readings
(CP-SAT is replaced by a recorder), never a wall time: CP-SAT gets the time left minus a
fixed allowance for its own stop, runs only when its build fits, and is never built after
stop() arrives during the LP.
"""

from __future__ import annotations

import pytest
from planner_fixtures import FakeCpSatRun, random_problem

from planner import cpsat_model
from planner.bound import LpBound
from planner.exact_dp import dp_is_cheap
from planner.instance import Instance
from planner.solve import CPSAT_STOP_S, END_MARGIN, PlanSolver, cpsat_build_s, warm_up

LIMIT_S = 2.0
M, N = 5, 20


class FakeClock:
    """Reads `t` and then advances it by `step_s` (0: frozen)."""

    def __init__(self) -> None:
        self.t = 0.0
        self.step_s = 0.0

    def __call__(self) -> float:
        now = self.t
        self.t += self.step_s
        return now


@pytest.fixture
def fake_cpsat(monkeypatch: pytest.MonkeyPatch) -> type[FakeCpSatRun]:
    warm_up()  # OR-Tools loaded: its import is no part of the estimates below
    FakeCpSatRun.built, FakeCpSatRun.budgets = [], []
    monkeypatch.setattr(cpsat_model, "CpSatRun", FakeCpSatRun)
    return FakeCpSatRun


def _solver(clock: FakeClock) -> PlanSolver:
    assert not dp_is_cheap(M, N, LIMIT_S)
    return PlanSolver(random_problem(31, M, N, time_limit_s=LIMIT_S), clock=clock)


def test_cpsat_gets_the_time_left_minus_its_stop_allowance(fake_cpsat: type[FakeCpSatRun]) -> None:
    """CP-SAT overshoots max_time_in_seconds (0.1 s measured at 5x30): with the clock frozen
    at the start, it is given the whole end minus that allowance, not the whole end."""
    r = _solver(FakeClock()).solve()
    assert fake_cpsat.built == ["position"]
    assert fake_cpsat.budgets == [pytest.approx(LIMIT_S * (1.0 - END_MARGIN) - CPSAT_STOP_S)]
    assert r.status == "fallback"


@pytest.mark.parametrize(("left_s", "built"), [(0.1, False), (1.0, True)])
def test_mid_size_cpsat_only_when_its_build_fits(
    fake_cpsat: type[FakeCpSatRun], monkeypatch: pytest.MonkeyPatch, left_s: float, built: bool
) -> None:
    """Up to 30 targets CP-SAT runs only if the time left after the LP covers its estimated
    build, its stop allowance and 0.05 s; otherwise the local search takes the rest."""
    assert CPSAT_STOP_S + 0.05 + cpsat_build_s("position", M, N) < 1.0
    clock = FakeClock()
    solver = _solver(clock)
    end = LIMIT_S * (1.0 - END_MARGIN)

    def lp(inst: Instance, mid: bool, end_: float, limit: float) -> LpBound | None:
        clock.t, clock.step_s = end - left_s, 1e-3  # the LP used the time up to here
        return None

    monkeypatch.setattr(solver, "_lp", lp)
    r = solver.solve()
    assert bool(fake_cpsat.built) is built
    if not built:
        assert r.status == "fallback" and r.hit_time_limit


def test_stop_during_the_lp_builds_no_model(
    fake_cpsat: type[FakeCpSatRun], monkeypatch: pytest.MonkeyPatch
) -> None:
    clock = FakeClock()
    solver = _solver(clock)

    def lp(inst: Instance, mid: bool, end: float, limit: float) -> LpBound | None:
        solver.stop()
        return None

    monkeypatch.setattr(solver, "_lp", lp)
    r = solver.solve()
    assert fake_cpsat.built == []
    assert r.status == "fallback" and not r.hit_time_limit
    assert sorted(k for route in r.routes.values() for k in route) == sorted(
        t.id for t in solver.problem.targets if t.id not in r.excluded
    )
