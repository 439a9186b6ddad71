"""Numeric instance built from a PlanningProblem: kept targets, distances, mu, route costs.

Nodes: UAVs 0..m-1, kept targets m..N-1 (N = m + n). `d` is N x N: Euclidean, except
UAV -> target, which is the Dubins distance to the point with free final heading.

In wind (PlanningProblem.planning_wind_m_s), `d` is the travel time expressed as still-air
metres, d_ij = V T_ij with V = speed_m_s and T_ij from planner.wind: straight legs at the
ground speed along their track, the first leg the fastest Dubins flight in the moving air.
It is asymmetric (d_ij != d_ji); every method below uses d_ij only in the direction of the
arc i -> j. With w = 0 it is exactly the still-air matrix (the wind code is not entered).

Every objective charges ``d_net``, the same times without the wind's potential
(planner.wind.potential_s: T_ij = T_sym,ij + phi_j - phi_i over any flown path):

    d_net_ij = V T_sym,ij = d_ij - V (phi_j - phi_i),   phi(p) = -(w . p) / (V^2 - |w|^2).

The potential part of a flight's time depends only on where it starts and ends, so in a
plan it is a transfer, not a cost: along a route it sums to phi(last target) - phi(UAV), a
credit for ending downwind (F2); in an arrival time it is phi(target) - phi(UAV), a credit
for serving a target from upwind (the hops of ``arrival`` and ``latency``). Neither is
earned: the fleet stays with its targets, so what a plan gains that way a later flight pays
back to the second, and a plan made every few seconds would claim it again each time.
Measured (docs/wind.md): with d the planner left downwind UAVs without a route twice as
often as in still air, and mean uncertainty on paper-boat was 13-37 % worse than wind-blind
planning at 10-15 m/s (sequence) and 8-19 % (latency, 5 UAVs). The true times (d) stay what
the core aims and predicts arrivals with (planner.wind.time_in_wind_s). d_avg is the same
for both (the potential differences sum to 0 over all ordered pairs), so mu is too. In
still air d_net is d.

Paper objective ("sequence"), with t[uav] = 1 and t = 1 + p for the p-th target of a path:

    J = -(1 - tau) F1 + tau F2,   F1 = sum_i sigma_i (N - t_i),   F2 = mu sum_(i,j) y_ij d_net_ij.

Writing H_i for the hop count p_i, F1 = (N - 1) S - sum_i sigma_i H_i with S = sum sigma, so

    J = -(1 - tau) (N - 1) S + (1 - tau) sum_i sigma_i H_i + tau mu sum_arcs d_net_ij.

"arrival" replaces the hop count by the arrival time in units of the mean hop time:
H_i = (D_i / speed) / (d_avg / speed) = D_i / d_avg, D_i = path length (m) to target i
(summed over d_net),
i.e. F1' = sum_i sigma_i (N - 1 - arrival_i / T_hop), T_hop = d_avg / speed_m_s. (If
d_avg = 0 every D_i is 0 and H_i = 0.)

"latency" (sigma-weighted arrival time, m^2 s) has no distance term, no tau and no mu:

    J = L = sum_i sigma_i a_i,   a_i = D_i / speed_m_s   (s).

L is the first-order time-integrated uncertainty: if every track kept its sigma_i until the
visit and dropped to 0 then, integral_0^T sum_i sigma_i(t) dt = sum_i sigma_i a_i for any
horizon T past the last arrival. (The distance is in a_i already; "arrival" with tau > 0
counts it twice.) Here H_i = a_i, the hop length is h_ij = d_net_ij / speed_m_s, tau is taken
as 0, mu is reported as 0, the constant is 0; F1 = L and F2 = 0.

All three are "cumulative hop" objectives and a path's cost is a sum over its arcs: arc
(i -> j) costs a d_net_ij + b h_ij R_j, where R_j is the sigma of j and of every target
after it on the path, a = tau mu (`arc_weight`), b = 1 - tau, h_ij = 1 (sequence),
d_net_ij / d_avg (arrival) or d_net_ij / speed_m_s (latency); J = constant + sum of arc
costs.

mu = F1max / F2avg unless given; F2avg = d_avg (N - m); F1max by the problem's mu_rule
(planner.problem.MuRule): ``floe`` sum_k sigma_(k) (N - t_k), sigma sorted descending,
t_k = 2 + k // m; ``paper`` (N - 2) sum sigma (every target right after a UAV, t = 2);
``unconstrained`` (N - 1) sum sigma (t = 1); mu = 1 if either is 0.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from planner.dubins import dubins_distance_to_point, dubins_distances_to_points
from planner.problem import MuRule, Objective, PlanningProblem, ProblemError, wind_problem
from planner.wind import first_leg_times_s, potential_s, straight_leg_times_s

FloatArray = npt.NDArray[np.float64]

DUBINS_SCALAR_MAX = 2_000
"""Up to this many UAV -> target pairs the first legs are computed one by one (the plans of
every daemon-sized problem stay bit for bit what they were); above, by numpy (0.11 -> 0.06
CPU-s at 50x500)."""


def kept_targets(problem: PlanningProblem) -> tuple[list[int], list[int]]:
    """10 % rule: indices of kept and excluded targets (sigma < fraction * mean is dropped)."""
    sigmas = [t.sigma for t in problem.targets]
    if not sigmas:
        return [], []
    limit = problem.min_sigma_fraction * (sum(sigmas) / len(sigmas))
    kept = [k for k, s in enumerate(sigmas) if not s < limit]
    dropped = [k for k, s in enumerate(sigmas) if s < limit]
    return kept, dropped


def f1_max(
    sigmas: Sequence[float], n_uav: int, n_nodes: int, rule: MuRule = MuRule.FLOE
) -> float:
    """F1max of eq. 18 by ``rule`` (MuRule): ``floe``, the round-robin upper bound of F1 (the
    k-th largest sigma gets t = 2 + k // n_uav); ``paper``, every target at t = 2:
    (N - 2) sum sigma; ``unconstrained``, every target at t = 1: (N - 1) sum sigma."""
    if rule == MuRule.PAPER:
        return float((n_nodes - 2) * sum(sigmas))
    if rule == MuRule.UNCONSTRAINED:
        return float((n_nodes - 1) * sum(sigmas))
    ordered = sorted(sigmas, reverse=True)
    return float(sum(s * (n_nodes - (2 + k // n_uav)) for k, s in enumerate(ordered)))


@dataclass
class Instance:
    """Kept targets only. Arrays are indexed by node (UAVs first)."""

    problem: PlanningProblem
    target_index: list[int]  # kept target k -> index into problem.targets
    excluded: list[str]
    m: int
    n: int
    d: FloatArray  # N x N distances (m): still air, or V x the travel time in the wind
    d_net: FloatArray  # N x N what the objectives charge (m): d without the wind's potential
    hop: FloatArray  # N x N hop lengths (1, d_net / d_avg or d_net / speed_m_s)
    sigma: FloatArray  # length n, kept targets
    mu: float  # 0 for latency
    d_avg: float
    tau: float  # the problem's tau; 0 for latency

    @property
    def n_nodes(self) -> int:
        return self.m + self.n

    @property
    def latency(self) -> bool:
        """The latency objective: J = sum sigma_i a_i, no constant, no distance term."""
        return self.problem.objective == Objective.LATENCY

    @property
    def unit_hops(self) -> bool:
        """Every hop length is 1 (the sequence objective)."""
        return self.problem.objective == Objective.SEQUENCE

    @property
    def constant(self) -> float:
        """The route-independent part of J: -(1 - tau) (N - 1) S, or 0 for latency."""
        if self.latency:
            return 0.0
        return -(1.0 - self.tau) * (self.n_nodes - 1) * float(self.sigma.sum())

    def arc_weight(self) -> FloatArray:
        """tau mu d_net: distance part of every arc."""
        return self.tau * self.mu * self.d_net

    def route_cost(self, uav: int, route: Sequence[int]) -> float:
        """Variable cost of one path (targets as 0-based kept indices); 0 if empty."""
        cost = 0.0
        prev = uav
        hops = 0.0
        a = self.tau * self.mu
        b = 1.0 - self.tau
        m = self.m
        for k in route:
            node = m + k
            hops += self.hop[prev, node]
            cost += a * self.d_net[prev, node] + b * self.sigma[k] * hops
            prev = node
        return cost

    def evaluate(self, routes: Sequence[Sequence[int]]) -> tuple[float, float, float]:
        """(J, F1, F2) of a full plan (one route per UAV); for latency (L, L, 0)."""
        weighted = 0.0  # sum_i sigma_i H_i
        dist = 0.0
        m = self.m
        for u, route in enumerate(routes):
            prev = u
            hops = 0.0
            for k in route:
                node = m + k
                hops += self.hop[prev, node]
                dist += self.d_net[prev, node]
                weighted += self.sigma[k] * hops
                prev = node
        if self.latency:
            return weighted, weighted, 0.0
        f1 = (self.n_nodes - 1) * float(self.sigma.sum()) - weighted
        f2 = self.mu * dist
        return -(1.0 - self.tau) * f1 + self.tau * f2, f1, f2

    def target_id(self, k: int) -> str:
        return self.problem.targets[self.target_index[k]].id


def _wind_costs(
    problem: PlanningProblem, xy: FloatArray, m: int, wind: tuple[float, float]
) -> FloatArray:
    """d = V T in the wind (module docstring); ProblemError for an unflyable wind."""
    reason = wind_problem(wind, problem.speed_m_s)
    if reason is not None:
        raise ProblemError("wind_m_s", reason)
    speed = problem.speed_m_s
    times = straight_leg_times_s(xy, wind, speed)
    if m and len(xy) > m:
        pose = np.array([(u.x_m, u.y_m, u.heading_rad) for u in problem.uavs], dtype=float)
        times[:m, m:] = first_leg_times_s(
            pose[:, 0:1], pose[:, 1:2], pose[:, 2:3], xy[None, m:, 0], xy[None, m:, 1],
            wind, speed, problem.turn_radius_m,
        )
    return speed * times


def build_instance(problem: PlanningProblem) -> Instance:
    """Apply the 10 % rule and compute d, hop lengths and mu."""
    if not problem.uavs:
        raise ProblemError("uavs", "at least one UAV is needed")
    if problem.turn_radius_m <= 0 or not math.isfinite(problem.turn_radius_m):
        raise ProblemError("turn_radius", "must be > 0")
    kept, dropped = kept_targets(problem)
    uavs = problem.uavs
    targets = [problem.targets[k] for k in kept]
    m, n = len(uavs), len(targets)
    nodes = [(u.x_m, u.y_m) for u in uavs] + [(t.x_m, t.y_m) for t in targets]
    xy = np.array(nodes, dtype=float).reshape(m + n, 2)
    wind = problem.planning_wind_m_s
    if wind is None:
        diff = xy[:, None, :] - xy[None, :, :]
        d = np.sqrt((diff**2).sum(axis=2))
        if m * n > DUBINS_SCALAR_MAX:  # numpy, agrees to ~1e-15 relative (tested)
            pose = np.array([(u.x_m, u.y_m, u.heading_rad) for u in uavs], dtype=float)
            d[:m, m:] = dubins_distances_to_points(
                pose[:, 0:1], pose[:, 1:2], pose[:, 2:3], xy[None, m:, 0], xy[None, m:, 1],
                problem.turn_radius_m,
            )
        else:
            for i, u in enumerate(uavs):
                for k, t in enumerate(targets):
                    d[i, m + k] = dubins_distance_to_point(
                        u.x_m, u.y_m, u.heading_rad, t.x_m, t.y_m, problem.turn_radius_m
                    )
        d_net = d
    else:
        d = _wind_costs(problem, xy, m, wind)
        phi = problem.speed_m_s * potential_s(xy, wind, problem.speed_m_s)
        d_net = d + (phi[:, None] - phi[None, :])  # V T_sym (module docstring)
    size = m + n
    d_avg = float(d.sum() / (size * (size - 1))) if size > 1 else 0.0
    sigma = np.array([t.sigma for t in targets], dtype=float)
    if problem.mu is not None:
        mu = float(problem.mu)
    else:
        f1m = f1_max(sigma.tolist(), m, size, problem.mu_rule) if m else 0.0
        f2avg = d_avg * (size - m)
        mu = f1m / f2avg if f1m != 0.0 and f2avg != 0.0 else 1.0
    tau = problem.tau
    if problem.objective == Objective.ARRIVAL:
        hop = d_net / d_avg if d_avg > 0.0 else np.zeros_like(d)
    elif problem.objective == Objective.LATENCY:
        hop = d_net / problem.speed_m_s
        tau, mu = 0.0, 0.0
    else:
        hop = np.ones_like(d)
    if not math.isfinite(mu):
        mu = 1.0
    return Instance(
        problem=problem,
        target_index=kept,
        excluded=[problem.targets[k].id for k in dropped],
        m=m,
        n=n,
        d=d,
        d_net=d_net,
        hop=hop,
        sigma=sigma,
        mu=mu,
        d_avg=d_avg,
        tau=tau,
    )
