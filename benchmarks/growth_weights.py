"""Growth-aware weights for the latency objective: a measured prototype (issue 12), not in
the product. ``paper_study.py`` applies them with the variant options ``+point30`` and
``+growth``; docs/planner.md ("Growth-aware weights") has the figures.

A Kalman track of paper-boat (constant velocity, velocity noise intensity q per axis) that
has not been seen for s seconds has sigma(s) ~ (2/3) q s^3 (both axes; the velocity variance
left after the last sighting neglected), so its age is s = (1.5 sigma / q)^(1/3) and t
seconds on its sigma is sigma(s + t).

* ``point(h)``: the planner is given sigma(s + h), the sigma predicted h seconds ahead,
  instead of sigma.
* ``growth``: the time-integrated uncertainty with growth, sum_i C_i(a_i) with

      C_i(a) = integral_0^a sigma_i(s_i + t) dt = (q / 6) ((s_i + a)^4 - s_i^4),

  is not linear in the arrival time a, so it is linearised where the previous plan arrives:
  weights w_i = C_i(a_i) / a_i replace sigma and the latency objective (sum w_i a_i) is
  solved exactly again, ``rounds`` times; of the plain latency plan and these, the plan with
  the least sum_i C_i(a_i) is kept.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import Any

from planner import PlanningProblem, PlanResult, solve_plan
from planner.instance import build_instance

Solver = Callable[..., PlanResult]


def age_s(sigma: float, q_per_s: float) -> float:
    """Age of a track of this sigma under sigma = (2/3) q s^3."""
    return (1.5 * max(sigma, 0.0) / q_per_s) ** (1.0 / 3.0)


def predicted_sigma(sigma: float, q_per_s: float, ahead_s: float) -> float:
    """sigma(s + h) = sigma + (2/3) q ((s + h)^3 - s^3)."""
    s = age_s(sigma, q_per_s)
    return sigma + (2.0 / 3.0) * q_per_s * ((s + ahead_s) ** 3 - s**3)


def integrated_sigma(sigma: float, q_per_s: float, arrival_s: float) -> float:
    """C(a) = integral_0^a sigma(s + t) dt = (q / 6) ((s + a)^4 - s^4) (m^2 s)."""
    s = age_s(sigma, q_per_s)
    return q_per_s / 6.0 * ((s + arrival_s) ** 4 - s**4)


def arrival_times_s(problem: PlanningProblem, routes: Mapping[str, Sequence[str]]
                    ) -> dict[str, float]:
    """Arrival time of every routed target (first leg Dubins, then straight legs)."""
    inst = build_instance(problem)
    node = {inst.target_id(k): inst.m + k for k in range(inst.n)}
    out: dict[str, float] = {}
    for u, uav in enumerate(problem.uavs):
        prev, t_s = u, 0.0
        for tid in routes.get(uav.id, []):
            t_s += float(inst.d[prev, node[tid]]) / problem.speed_m_s
            out[tid] = t_s
            prev = node[tid]
    return out


def point_solver(q_per_s: float, ahead_s: float = 30.0) -> Solver:
    """solve_plan with every sigma replaced by its prediction `ahead_s` seconds on."""

    def solve(problem: PlanningProblem, hint: Any = None, **kw: Any) -> PlanResult:
        targets = tuple(replace(t, sigma=predicted_sigma(t.sigma, q_per_s, ahead_s))
                        for t in problem.targets)
        return solve_plan(replace(problem, targets=targets), hint, **kw)

    return solve


def growth_solver(q_per_s: float, rounds: int = 2) -> Solver:
    """solve_plan, then `rounds` re-solves with weights C_i(a_i) / a_i (module docstring)."""

    def solve(problem: PlanningProblem, hint: Any = None, **kw: Any) -> PlanResult:
        base = solve_plan(problem, hint, **kw)
        sigma = {t.id: t.sigma for t in problem.targets}
        kept = {tid for route in base.routes.values() for tid in route}

        def cost(result: PlanResult) -> float:
            arrivals = arrival_times_s(problem, result.routes)
            return sum(integrated_sigma(sigma[t], q_per_s, a) for t, a in arrivals.items())

        best, best_cost, current = base, cost(base), base
        for _ in range(rounds):
            arrivals = arrival_times_s(problem, current.routes)
            weights = {t: integrated_sigma(sigma[t], q_per_s, a) / a if a > 1e-9 else sigma[t]
                       for t, a in arrivals.items()}
            targets = tuple(replace(t, sigma=weights[t.id]) for t in problem.targets
                            if t.id in kept)
            current = solve_plan(replace(problem, targets=targets, min_sigma_fraction=0.0),
                                 hint, **kw)
            value = cost(current)
            if value < best_cost - 1e-9 * abs(best_cost):
                best, best_cost = current, value
        return replace(best, excluded=base.excluded)

    return solve
