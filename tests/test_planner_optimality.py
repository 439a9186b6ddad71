"""Every exact method against brute force on small random instances.

The reference objective below is written from the design notes, independently of
planner.instance: positions t, F1 = sum sigma (N - t), F2 = mu sum d, mu = F1max / F2avg.
Objectives are compared at 1e-6 relative to the size of their terms (never routes: ties).
"""

from __future__ import annotations

import itertools
import math
import random
from collections.abc import Mapping, Sequence

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from planner_fixtures import problems

from planner import (
    PlanningProblem,
    TargetEstimate,
    UavPose,
    dubins_distance_to_point,
    solve_plan,
)
from planner.solve import PlanSolver


def reference_parts(p: PlanningProblem) -> tuple[list[TargetEstimate], dict, float, float]:
    sig = [t.sigma for t in p.targets]
    mean = sum(sig) / len(sig) if sig else 0.0
    kept = [t for t in p.targets if not t.sigma < p.min_sigma_fraction * mean]
    m = len(p.uavs)
    nodes: list[tuple[str, float, float]] = [(u.id, u.x_m, u.y_m) for u in p.uavs]
    nodes += [(t.id, t.x_m, t.y_m) for t in kept]
    size = len(nodes)
    d: dict[tuple[str, str], float] = {}
    for a, (ia, xa, ya) in enumerate(nodes):
        for b, (ib, xb, yb) in enumerate(nodes):
            if a == b:
                continue
            if a < m <= b:
                u = p.uavs[a]
                d[ia, ib] = dubins_distance_to_point(
                    u.x_m, u.y_m, u.heading_rad, xb, yb, p.turn_radius_m
                )
            else:
                d[ia, ib] = math.hypot(xa - xb, ya - yb)
    d_avg = sum(d.values()) / (size * (size - 1)) if size > 1 else 0.0
    ordered = sorted((t.sigma for t in kept), reverse=True)
    f1max = sum(s * (size - (2 + k // m)) for k, s in enumerate(ordered))
    f2avg = d_avg * (size - m)
    mu = f1max / f2avg if f1max != 0 and f2avg != 0 else 1.0
    if p.mu is not None:
        mu = p.mu
    return kept, d, mu, d_avg


def reference_objective(
    p: PlanningProblem, routes: Mapping[str, Sequence[str]], parts: tuple | None = None
) -> float:
    kept, d, mu, d_avg = parts or reference_parts(p)
    size = len(p.uavs) + len(kept)
    sigma = {t.id: t.sigma for t in kept}
    assert sorted(x for r in routes.values() for x in r) == sorted(sigma)
    f1 = 0.0
    dist = 0.0
    for u in p.uavs:
        prev, travelled = u.id, 0.0
        for t_pos, tid in enumerate(routes[u.id], start=2):
            travelled += d[prev, tid]
            dist += d[prev, tid]
            prev = tid
            if p.objective == "sequence":
                f1 += sigma[tid] * (size - t_pos)
            else:
                ratio = travelled / d_avg if d_avg > 0 else 0.0
                f1 += sigma[tid] * (size - 1 - ratio)
    return -(1 - p.tau) * f1 + p.tau * mu * dist


def brute_force(p: PlanningProblem) -> float:
    parts = reference_parts(p)
    ids = [t.id for t in parts[0]]
    uavs = [u.id for u in p.uavs]
    best = math.inf
    for perm in itertools.permutations(ids):
        # split the permutation into len(uavs) consecutive, possibly empty, blocks
        for cuts in itertools.combinations_with_replacement(range(len(ids) + 1), len(uavs) - 1):
            bounds = [0, *cuts, len(ids)]
            routes = {u: list(perm[bounds[k] : bounds[k + 1]]) for k, u in enumerate(uavs)}
            best = min(best, reference_objective(p, routes, parts))
    return best


def magnitude(p: PlanningProblem) -> float:
    kept, d, mu, _ = reference_parts(p)
    size = len(p.uavs) + len(kept)
    longest = max(d.values(), default=0.0)
    return max(
        1e-9,
        (1 - p.tau) * size * sum(t.sigma for t in kept) + p.tau * mu * longest * size,
    )


def close(a: float, b: float, p: PlanningProblem) -> bool:
    return abs(a - b) <= 1e-6 * max(abs(a), abs(b), magnitude(p))


@settings(max_examples=60, deadline=None)
@given(problems())
def test_default_solver_matches_brute_force(p: PlanningProblem) -> None:
    best = brute_force(p)
    result = solve_plan(p)
    assert result.status == "optimal"
    assert close(reference_objective(p, result.routes), best, p)
    assert close(result.objective, best, p)


@settings(max_examples=50, deadline=None)
@given(problems(max_targets=5), st.sampled_from(["position", "circuit", "dp"]))
def test_each_exact_method_matches_brute_force(p: PlanningProblem, method: str) -> None:
    if method == "position" and p.objective != "sequence":
        method = "circuit"
    best = brute_force(p)
    result = PlanSolver(p, method=method).solve()
    assert result.status == "optimal"
    assert close(reference_objective(p, result.routes), best, p)
    assert close(result.objective, best, p)
    assert close(result.f1 * -(1 - p.tau) + p.tau * result.f2, result.objective, p)


@pytest.mark.parametrize("sigmas", [(5e-324,), (0.0, 5e-324)])
def test_subnormal_uncertainties_do_not_break_the_circuit_model(
        sigmas: tuple[float, ...]) -> None:
    """Hypothesis found these: a sigma sum so small that the flow's integer step
    (sum / steps) underflowed to 0 made the model divide by zero (inf, NaN)."""
    p = PlanningProblem(
        uavs=(UavPose("u0", 0.0, 0.0, 0.0),),
        targets=tuple(TargetEstimate(f"t{i}", 0.0, 0.0, s) for i, s in enumerate(sigmas)),
        turn_radius_m=1.0, tau=0.0, time_limit_s=5.0, objective="arrival")
    result = PlanSolver(p, method="circuit").solve()
    assert result.status == "optimal"
    assert close(result.objective, brute_force(p), p)


@settings(max_examples=20, deadline=None)
@given(problems(max_targets=6))
def test_heuristic_is_feasible_and_never_better_than_optimum(p: PlanningProblem) -> None:
    best = brute_force(p)
    result = PlanSolver(p, method="heuristic").solve()
    got = reference_objective(p, result.routes)
    assert got >= best - 1e-6 * magnitude(p)
    assert close(result.objective, got, p)


def seeded_problem(seed: int, m: int, n: int, objective: str) -> PlanningProblem:
    rng = random.Random(seed)
    return PlanningProblem(
        uavs=tuple(
            UavPose(f"u{k}", rng.uniform(0, 1500), rng.uniform(0, 1500), rng.uniform(-3, 3))
            for k in range(m)
        ),
        targets=tuple(
            TargetEstimate(f"t{k}", rng.uniform(0, 1500), rng.uniform(0, 1500), rng.uniform(0, 100))
            for k in range(n)
        ),
        turn_radius_m=105.0,
        objective=objective,
    )


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("m", [1, 3])
@pytest.mark.parametrize("objective", ["sequence", "arrival"])
def test_full_size_brute_force(seed: int, m: int, objective: str) -> None:
    p = seeded_problem(seed, m, 6, objective)
    best = brute_force(p)
    methods = ["auto", "dp", "circuit"] + (["position"] if objective == "sequence" else [])
    for method in methods:
        result = PlanSolver(p, method=method).solve()
        assert result.status == "optimal"
        assert close(reference_objective(p, result.routes), best, p), method
