"""mu, F1max, the 10 % rule, the idle-UAV rule, edge cases, time limit, hint, stop, determinism."""

from __future__ import annotations

import math
import random
import threading
import time
from dataclasses import replace

import pytest
from planner_fixtures import random_problem

from planner import (
    PlanningProblem,
    PlanSolver,
    ProblemError,
    TargetEstimate,
    UavPose,
    dubins_distance_to_point,
    solve_plan,
)
from planner.heuristics import RouteCoster, best_insertion
from planner.instance import build_instance, f1_max
from planner.solve import hint_routes


def covers(result_routes: dict[str, list[str]], ids: set[str]) -> bool:
    flat = [t for r in result_routes.values() for t in r]
    return len(flat) == len(set(flat)) and set(flat) == ids


def line_problem(**kw: object) -> PlanningProblem:
    # UAV at the origin heading +x, targets straight ahead: every distance is Euclidean
    return PlanningProblem(
        uavs=(UavPose("u", 0.0, 0.0, 0.0),),
        targets=(TargetEstimate("a", 100.0, 0.0, 4.0), TargetEstimate("b", 200.0, 0.0, 2.0)),
        turn_radius_m=1.0,
        **kw,  # type: ignore[arg-type]
    )


def test_mu_and_objective_by_hand() -> None:
    # d: u->a 100, u->b 200, a->b 100, b->a 100, a->u 100, b->u 200: d_avg = 800 / 6
    # F2avg = d_avg * (N - nUAV) = 800 / 6 * 2; F1max = 4 * (3 - 2) + 2 * (3 - 3) = 4
    r = solve_plan(line_problem())
    mu = 4 / (800 / 6 * 2)
    assert r.mu == pytest.approx(mu, rel=1e-12)
    assert r.routes == {"u": ["a", "b"]}
    # F1 = 4 (3 - 2) + 2 (3 - 3) = 4; F2 = mu * 200
    assert r.f1 == pytest.approx(4.0)
    assert r.f2 == pytest.approx(mu * 200)
    assert r.objective == pytest.approx(-0.5 * 4 + 0.5 * mu * 200)


def test_mu_given_is_used() -> None:
    r = solve_plan(line_problem(mu=2.5))
    assert r.mu == 2.5
    # with a large mu distance dominates: a then b is still the shortest, F2 = 2.5 * 200
    assert r.f2 == pytest.approx(500.0)


def test_arrival_objective_by_hand() -> None:
    r = solve_plan(line_problem(objective="arrival", tau=0.0))
    d_avg = 800 / 6
    # F1' = sum sigma (N - 1 - D / d_avg): a at D = 100, b at D = 200
    f1 = 4 * (2 - 100 / d_avg) + 2 * (2 - 200 / d_avg)
    assert r.routes == {"u": ["a", "b"]}
    assert r.f1 == pytest.approx(f1)
    assert r.objective == pytest.approx(-f1)


def test_f1_max_round_robin() -> None:
    # m = 2, N = 6: t = 2, 2, 3, 3 for sigma 5, 3, 2, 1
    assert f1_max([1, 3, 5, 2], 2, 6) == pytest.approx(5 * 4 + 3 * 4 + 2 * 3 + 1 * 3)
    assert f1_max([1, 3, 5, 2], 1, 5) == pytest.approx(5 * 3 + 3 * 2 + 2 * 1 + 1 * 0)


def test_mu_is_one_when_all_sigma_zero() -> None:
    p = replace(
        line_problem(), targets=tuple(replace(t, sigma=0.0) for t in line_problem().targets)
    )
    r = solve_plan(p)
    assert r.mu == 1.0
    assert r.excluded == []  # 0 < 0 is false: nothing dropped
    assert covers(r.routes, {"a", "b"})


def test_ten_percent_rule() -> None:
    base = random_problem(1, 2, 3)
    targets = (
        *base.targets[:2],
        TargetEstimate("low", 10.0, 10.0, 0.0001),
        TargetEstimate("edge", 20.0, 20.0, 1.0),
    )
    sig = [10.0, 8.0, 0.0001, 1.0]
    targets = tuple(replace(t, sigma=s) for t, s in zip(targets, sig, strict=True))
    # mean 4.750025, limit 0.4750025: "low" dropped, "edge" kept
    r = solve_plan(replace(base, targets=targets))
    assert r.excluded == ["low"]
    assert covers(r.routes, {"t0", "t1", "edge"})
    inst = build_instance(replace(base, targets=targets))
    assert inst.n == 3  # N computed on what remains


def test_ten_percent_boundary_is_kept() -> None:
    base = random_problem(2, 1, 2)
    # mean 10, limit 0.1 * 10 = 1.0; sigma 1.0 is not strictly below it
    targets = (replace(base.targets[0], sigma=19.0), replace(base.targets[1], sigma=1.0))
    r = solve_plan(replace(base, targets=targets))
    assert r.excluded == []


def test_idle_uav_goes_to_nearest_by_dubins() -> None:
    p = PlanningProblem(
        uavs=(
            UavPose("u1", -100.0, 50.0, -math.pi / 2),  # 50 m from A, pointing at it
            UavPose("u2", 250.0, 50.0, -math.pi / 2),  # 50 m from B, pointing at it
            UavPose("u3", 0.0, 0.0, 0.0),  # A is 100 m behind it, B 250 m ahead
        ),
        targets=(TargetEstimate("A", -100.0, 0.0, 5.0), TargetEstimate("B", 250.0, 0.0, 5.0)),
        turn_radius_m=105.0,
    )
    behind = dubins_distance_to_point(0, 0, 0, -100, 0, 105)
    assert behind > 250.0  # Euclid says A, Dubins says B
    r = solve_plan(p)
    assert r.routes == {"u1": ["A"], "u2": ["B"], "u3": []}
    assert r.idle == {"u3": "B"}


def test_more_uavs_than_targets() -> None:
    p = random_problem(3, 5, 2)
    r = solve_plan(p)
    assert set(r.routes) == {"u0", "u1", "u2", "u3", "u4"}
    assert covers(r.routes, {"t0", "t1"})
    idle = {u for u, route in r.routes.items() if not route}
    assert set(r.idle) == idle and len(idle) >= 3
    assert set(r.idle.values()) <= {"t0", "t1"}


def test_zero_targets() -> None:
    r = solve_plan(random_problem(4, 2, 0))
    assert r.status == "optimal"
    assert r.routes == {"u0": [], "u1": []}
    assert r.objective == 0.0 and r.idle == {} and r.excluded == []


def test_zero_uavs_is_a_problem_error() -> None:
    with pytest.raises(ProblemError) as err:
        solve_plan(replace(random_problem(5, 1, 3), uavs=()))
    assert err.value.field == "uavs"


def test_time_limit_fallback_is_a_full_plan() -> None:
    p = random_problem(6, 10, 50, time_limit_s=0.05)
    t0 = time.perf_counter()
    r = solve_plan(p)
    assert time.perf_counter() - t0 < 3.0
    assert r.status in ("fallback", "feasible")
    assert r.hit_time_limit
    assert covers(r.routes, {t.id for t in p.targets} - set(r.excluded))


def test_previous_plan_hint_is_used() -> None:
    p = random_problem(7, 10, 50, time_limit_s=1.0)
    good = solve_plan(p)
    quick = replace(p, time_limit_s=0.01)
    hinted = solve_plan(quick, hint=good.routes)
    assert hinted.objective <= good.objective + 1e-9 * abs(good.objective)


def test_hint_mapping_ignores_unknown_and_fills_missing() -> None:
    p = random_problem(8, 2, 4)
    inst = build_instance(p)
    ids = [inst.target_id(k) for k in range(inst.n)]
    hint = {"u1": [ids[1], "ghost", ids[1], ids[0]], "nobody": [ids[2]]}
    routes = hint_routes(inst, hint)
    assert routes is not None
    assert routes[1].index(1) < routes[1].index(0)  # hinted order kept, inserts aside
    assert sorted(k for r in routes for k in r) == list(range(inst.n))
    assert hint_routes(inst, {"u0": ["ghost"]}) is None


def test_stop_from_another_thread() -> None:
    p = random_problem(9, 10, 50, time_limit_s=60.0)
    solver = PlanSolver(p)
    out: list = []
    thread = threading.Thread(target=lambda: out.append(solver.solve()))
    t0 = time.perf_counter()
    thread.start()
    threading.Timer(0.3, solver.stop).start()
    thread.join(timeout=20)
    assert not thread.is_alive()
    assert time.perf_counter() - t0 < 10.0
    r = out[0]
    assert not r.hit_time_limit
    assert covers(r.routes, {t.id for t in p.targets} - set(r.excluded))


def test_stop_before_solve_returns_fallback_at_once() -> None:
    p = random_problem(10, 5, 20, time_limit_s=60.0)
    solver = PlanSolver(p)
    solver.stop()
    r = solver.solve()
    assert r.status == "fallback"
    assert r.solve_time_s < 5.0
    assert covers(r.routes, {t.id for t in p.targets} - set(r.excluded))


@pytest.mark.parametrize(
    ("m", "n", "objective"), [(5, 20, "sequence"), (4, 35, "sequence"), (5, 20, "arrival")]
)
def test_deterministic_mode_repeats(m: int, n: int, objective: str) -> None:
    p = random_problem(11, m, n, time_limit_s=0.3, objective=objective)
    a = solve_plan(p, deterministic=True, random_seed=3)
    b = solve_plan(p, deterministic=True, random_seed=3)
    assert a.objective == b.objective
    assert a.routes == b.routes
    assert a.status == b.status


def test_mid_size_is_proven_optimal() -> None:
    p = random_problem(12, 5, 20, time_limit_s=20.0)
    r = solve_plan(p)
    assert r.status == "optimal"
    assert r.solver.startswith("cp-sat/position")
    assert not r.hit_time_limit
    # the local search alone is never better than the proven optimum
    h = PlanSolver(replace(p, time_limit_s=0.5), method="heuristic").solve()
    assert h.objective >= r.objective - 1e-6 * abs(r.objective)


@pytest.mark.parametrize("objective", ["sequence", "arrival"])
def test_insertion_delta_matches_recomputed_cost(objective: str) -> None:
    inst = build_instance(random_problem(13, 3, 12, objective=objective))
    coster = RouteCoster(inst)
    rng = random.Random(0)
    for _ in range(100):
        ks = list(range(inst.n))
        rng.shuffle(ks)
        chain, rest = ks[: rng.randint(1, 3)], ks[3:]
        routes: list[list[int]] = [[], [], []]
        for k in rest:
            routes[rng.randrange(3)].append(k)
        costs = [coster.cost(u, r) for u, r in enumerate(routes)]
        delta, u, pos = best_insertion(coster, routes, costs, chain)
        brute = min(
            coster.cost(v, r[:q] + chain + r[q:]) - costs[v]
            for v, r in enumerate(routes)
            for q in range(len(r) + 1)
        )
        assert delta == pytest.approx(brute, rel=1e-9, abs=1e-9)
        placed = routes[u][:pos] + chain + routes[u][pos:]
        assert coster.cost(u, placed) - costs[u] == pytest.approx(delta, rel=1e-9, abs=1e-9)
