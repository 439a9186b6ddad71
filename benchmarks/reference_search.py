"""A plain local search for the planner benchmark, independent of floe's planner code.

Greedy insertion (targets by decreasing sigma, each at its cheapest place over every route
and position), then first-improvement relocate (one target to any place of any route) and
exchange (two targets swap places) moves, each costed by summing the one or two changed
routes again, until no move improves; then, while time is left, a kick (three random
targets moved to random places) and the descent again from the best plan, keeping the best.
The deadline is polled before every move evaluated. It uses only the problem's numbers
(arc weights w = tau mu d_net, hop lengths, sigma, b = 1 - tau: the arc form of
docs/planner.md), never planner.heuristics or planner.descent.
"""

from __future__ import annotations

import random
import time
from collections.abc import Sequence


class ReferenceSearch:
    def __init__(
        self,
        m: int,
        w: list[list[float]],
        hop: list[list[float]],
        sigma: list[float],
        b: float,
        seed: int = 0,
    ) -> None:
        self.m = m
        self.w = w
        self.hop = hop
        self.sigma = sigma
        self.b = b
        self.rng = random.Random(seed)
        self.deadline = float("inf")

    def route_cost(self, u: int, route: Sequence[int]) -> float:
        """sum over arcs of w + b sigma_j H_j, H_j the hops summed up to j."""
        total = 0.0
        hops = 0.0
        prev = u
        for k in route:
            node = self.m + k
            hops += self.hop[prev][node]
            total += self.w[prev][node] + self.b * self.sigma[k] * hops
            prev = node
        return total

    def late(self) -> bool:
        return time.perf_counter() > self.deadline

    def greedy(self) -> list[list[int]]:
        routes: list[list[int]] = [[] for _ in range(self.m)]
        costs = [0.0] * self.m
        for k in sorted(range(len(self.sigma)), key=lambda k: (-self.sigma[k], k)):
            best = (float("inf"), 0, 0)
            for u, route in enumerate(routes):
                for pos in range(len(route) + 1):
                    delta = self.route_cost(u, [*route[:pos], k, *route[pos:]]) - costs[u]
                    if delta < best[0]:
                        best = (delta, u, pos)
            _, u, pos = best
            routes[u].insert(pos, k)
            costs[u] = self.route_cost(u, routes[u])
        return routes

    def descend(self, routes: list[list[int]]) -> list[list[int]]:
        routes = [list(r) for r in routes]
        costs = [self.route_cost(u, r) for u, r in enumerate(routes)]
        improved = True
        while improved and not self.late():
            improved = self._relocate(routes, costs) or self._exchange(routes, costs)
        return routes

    def _relocate(self, routes: list[list[int]], costs: list[float]) -> bool:
        for u in range(len(routes)):
            for i in range(len(routes[u])):
                if self.late():
                    return False
                k = routes[u][i]
                rest = routes[u][:i] + routes[u][i + 1 :]
                rest_cost = self.route_cost(u, rest)
                for v in range(len(routes)):
                    base = rest if v == u else routes[v]
                    old = costs[u] + (0.0 if v == u else costs[v])
                    for pos in range(len(base) + 1):
                        if v == u and pos == i:
                            continue
                        cand = [*base[:pos], k, *base[pos:]]
                        new_v = self.route_cost(v, cand)
                        new = new_v if v == u else rest_cost + new_v
                        if new < old - 1e-9 * (1.0 + abs(old)):
                            if v == u:
                                routes[u], costs[u] = cand, new_v
                            else:
                                routes[u], costs[u] = rest, rest_cost
                                routes[v], costs[v] = cand, new_v
                            return True
        return False

    def _exchange(self, routes: list[list[int]], costs: list[float]) -> bool:
        places = [(u, i) for u, r in enumerate(routes) for i in range(len(r))]
        for a, (u, i) in enumerate(places):
            if self.late():
                return False
            for v, j in places[a + 1 :]:
                if u == v:
                    r = list(routes[u])
                    r[i], r[j] = r[j], r[i]
                    new = self.route_cost(u, r)
                    if new < costs[u] - 1e-9 * (1.0 + abs(costs[u])):
                        routes[u], costs[u] = r, new
                        return True
                else:
                    r1, r2 = list(routes[u]), list(routes[v])
                    r1[i], r2[j] = r2[j], r1[i]
                    n1, n2 = self.route_cost(u, r1), self.route_cost(v, r2)
                    old = costs[u] + costs[v]
                    if n1 + n2 < old - 1e-9 * (1.0 + abs(old)):
                        routes[u], routes[v], costs[u], costs[v] = r1, r2, n1, n2
                        return True
        return False

    def kick(self, routes: list[list[int]]) -> list[list[int]]:
        routes = [list(r) for r in routes]
        where = {k: u for u, r in enumerate(routes) for k in r}
        picked = self.rng.sample(sorted(where), min(3, len(where)))
        for k in picked:
            routes[where[k]].remove(k)
        for k in picked:
            u = self.rng.randrange(len(routes))
            routes[u].insert(self.rng.randint(0, len(routes[u])), k)
        return routes

    def total(self, routes: list[list[int]]) -> float:
        return sum(self.route_cost(u, r) for u, r in enumerate(routes))

    def solve(self, time_limit_s: float) -> list[list[int]]:
        """The best plan found within `time_limit_s` of wall time (the greedy plan is
        always finished, whatever the limit)."""
        self.deadline = time.perf_counter() + time_limit_s
        best = self.descend(self.greedy())
        best_cost = self.total(best)
        while not self.late():
            cand = self.descend(self.kick(best))
            cost = self.total(cand)
            if cost < best_cost:
                best, best_cost = cand, cost
        return best
