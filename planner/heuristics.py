"""Greedy construction and iterated local search on the route costs of planner.instance.

A plan is one list of kept-target indices per UAV; its value is constant + sum of
route costs (Instance.route_cost). Moves (first improvement, repeated to a local optimum):
relocate one target anywhere, or-opt (move a chain of 2-3, either orientation), swap two
targets, 2-opt inside a route, tail exchange between two routes. Iterated local search
then kicks the plan (relocate a few random targets, or reverse a random chain) and keeps the
result if it is better. Everything is driven by a seeded random.Random, so with an iteration
budget (no deadline) it is deterministic.
"""

from __future__ import annotations

import itertools
import random
from collections.abc import Callable, Sequence

from planner.instance import Instance

Routes = list[list[int]]
_EPS = 1e-9
MAX_DESCENT_MOVES = 20_000
"""A descent stops after this many improving moves. With tied values (identical sigmas)
and objectives of order 1e6, rounding noise above ``_EPS`` can make a chain move back to
where it came from forever (measured: a 13-target discovery problem never ended in
deterministic mode, which has no clock to stop it); converging descents make far fewer."""


class RouteCoster:
    """Fast pure-Python route cost (lists instead of numpy indexing)."""

    def __init__(self, inst: Instance) -> None:
        self.m = inst.m
        self.n = inst.n
        w = inst.arc_weight()
        self.w = w.tolist()
        self.h = inst.hop.tolist()
        self.sigma = inst.sigma.tolist()
        self.b = 1.0 - inst.tau

    def cost(self, u: int, route: Sequence[int]) -> float:
        w, h, sigma, b, m = self.w, self.h, self.sigma, self.b, self.m
        total = 0.0
        hops = 0.0
        prev = u
        for k in route:
            node = m + k
            wp = w[prev]
            hops += h[prev][node]
            total += wp[node] + b * sigma[k] * hops
            prev = node
        return total

    def total(self, routes: Sequence[Sequence[int]]) -> float:
        return sum(self.cost(u, r) for u, r in enumerate(routes))


def best_insertion(
    coster: RouteCoster, routes: Routes, costs: list[float], chain: list[int]
) -> tuple[float, int, int]:
    """Cheapest (delta, route, position) to insert `chain` (in this order), O(1) per place.

    Inserting chain c_1..c_s between nodes `prev` (cumulative hops H_prev) and `next`
    changes the cost by
        W(prev, c_1) + W_int + W(c_s, next) - W(prev, next)
        + b [S_c (H_prev + h(prev, c_1)) + K_c]
        + b [h(prev, c_1) + h_int + h(c_s, next) - h(prev, next)] S_after,
    with W = tau mu d, b = 1 - tau, S_c the chain's sigma, K_c = sum sigma_ci (hops from c_1
    to c_i), h_int the chain's own hops and S_after the sigma of the targets after prev.
    """
    del costs  # kept for the signature; the deltas are computed from the routes
    w, h, sigma, b, m = coster.w, coster.h, coster.sigma, coster.b, coster.m
    first, last = m + chain[0], m + chain[-1]
    w_int = 0.0
    h_int = 0.0
    k_c = 0.0
    s_c = sigma[chain[0]]
    for a, c in itertools.pairwise(chain):
        w_int += w[m + a][m + c]
        h_int += h[m + a][m + c]
        k_c += sigma[c] * h_int
        s_c += sigma[c]
    best = (float("inf"), -1, -1)
    for u, route in enumerate(routes):
        after = 0.0
        for k in route:
            after += sigma[k]
        prev = u
        hops = 0.0
        size = len(route)
        for pos in range(size + 1):
            wp, hp = w[prev], h[prev]
            delta = wp[first] + w_int + b * (s_c * (hops + hp[first]) + k_c)
            if pos < size:
                nxt = m + route[pos]
                delta += w[last][nxt] - wp[nxt]
                delta += b * (hp[first] + h_int + h[last][nxt] - hp[nxt]) * after
            if delta < best[0]:
                best = (delta, u, pos)
            if pos < size:
                hops += hp[nxt]
                after -= sigma[route[pos]]
                prev = nxt
    return best


def greedy(inst: Instance, coster: RouteCoster | None = None) -> Routes:
    """Cheapest insertion, targets taken by decreasing sigma."""
    coster = coster or RouteCoster(inst)
    routes: Routes = [[] for _ in range(inst.m)]
    costs = [0.0] * inst.m
    for k in sorted(range(inst.n), key=lambda k: (-coster.sigma[k], k)):
        _, u, pos = best_insertion(coster, routes, costs, [k])
        routes[u].insert(pos, k)
        costs[u] = coster.cost(u, routes[u])
    return routes


class LocalSearch:
    """Iterated local search. `should_stop` (the caller's stop flag and deadline) is polled
    after every improving move and once per outer loop of every neighbourhood scan, so a
    deadline ends even the first descent within one scan row (O(n) route costs)."""

    def __init__(
        self,
        inst: Instance,
        seed: int = 0,
        should_stop: Callable[[], bool] | None = None,
    ) -> None:
        self.inst = inst
        self.coster = RouteCoster(inst)
        self.rng = random.Random(seed)
        self._caller_stop = should_stop or (lambda: False)
        self._move_cap = MAX_DESCENT_MOVES
        self.moves = 0  # improving moves applied (tests: the deadline is polled)

    def should_stop(self) -> bool:
        """The caller's stop, or this descent's move budget spent."""
        return self._caller_stop() or self.moves >= self._move_cap

    # -- descent -------------------------------------------------------------------------
    def descend(self, routes: Routes) -> Routes:
        self._move_cap = self.moves + MAX_DESCENT_MOVES
        routes = [list(r) for r in routes]
        costs = [self.coster.cost(u, r) for u, r in enumerate(routes)]
        improved = True
        while improved and not self.should_stop():
            improved = (
                self._relocate(routes, costs, 1)
                or self._relocate(routes, costs, 2)
                or self._relocate(routes, costs, 3)
                or self._swap(routes, costs)
                or self._two_opt(routes, costs)
                or self._tails(routes, costs)
            )
        return routes

    def _relocate(self, routes: Routes, costs: list[float], length: int) -> bool:
        coster = self.coster
        found = False
        for u in range(len(routes)):
            pos = 0
            while pos + length <= len(routes[u]):
                route = routes[u]
                chain = route[pos : pos + length]
                rest = route[:pos] + route[pos + length :]
                removed_cost = coster.cost(u, rest)
                gain0 = costs[u] - removed_cost
                saved = costs[u]
                routes[u] = rest
                costs[u] = removed_cost
                options = [chain] if length == 1 else [chain, chain[::-1]]
                best = (gain0 - _EPS, -1, -1, chain)
                for option in options:
                    delta, v, p = best_insertion(coster, routes, costs, option)
                    if delta < best[0]:
                        best = (delta, v, p, option)
                if best[1] >= 0 and not (best[1] == u and best[2] == pos and best[3] == chain):
                    # (putting the chain back where it was is no move, whatever rounding says)
                    v, p, option = best[1], best[2], best[3]
                    routes[v] = routes[v][:p] + option + routes[v][p:]
                    costs[v] = coster.cost(v, routes[v])
                    found = True
                    self.moves += 1
                    if self.should_stop():
                        return True
                else:
                    routes[u] = route
                    costs[u] = saved
                    pos += 1
                    if self.should_stop():
                        return found
        return found

    def _swap(self, routes: Routes, costs: list[float]) -> bool:
        coster = self.coster
        found = False
        places = [(u, p) for u, r in enumerate(routes) for p in range(len(r))]
        for a in range(len(places)):
            if self.should_stop():
                return found
            for c in range(a + 1, len(places)):
                (u, p), (v, q) = places[a], places[c]
                if u == v:
                    r = list(routes[u])
                    r[p], r[q] = r[q], r[p]
                    new = coster.cost(u, r)
                    if new < costs[u] - _EPS:
                        routes[u], costs[u] = r, new
                        found = True
                        self.moves += 1
                else:
                    r1, r2 = list(routes[u]), list(routes[v])
                    r1[p], r2[q] = r2[q], r1[p]
                    n1, n2 = coster.cost(u, r1), coster.cost(v, r2)
                    if n1 + n2 < costs[u] + costs[v] - _EPS:
                        routes[u], routes[v], costs[u], costs[v] = r1, r2, n1, n2
                        found = True
                        self.moves += 1
        return found

    def _two_opt(self, routes: Routes, costs: list[float]) -> bool:
        coster = self.coster
        found = False
        for u, route in enumerate(routes):
            size = len(route)
            for i in range(size - 1):
                if self.should_stop():
                    return found
                for j in range(i + 2, size + 1):
                    r = routes[u]
                    cand = r[:i] + r[i:j][::-1] + r[j:]
                    new = coster.cost(u, cand)
                    if new < costs[u] - _EPS:
                        routes[u], costs[u] = cand, new
                        found = True
                        self.moves += 1
        return found

    def _tails(self, routes: Routes, costs: list[float]) -> bool:
        coster = self.coster
        found = False
        m = len(routes)
        for u in range(m):
            for v in range(u + 1, m):
                if self.should_stop():
                    return found
                for i in range(len(routes[u]) + 1):
                    for j in range(len(routes[v]) + 1):
                        r1, r2 = routes[u], routes[v]
                        if i == len(r1) and j == len(r2):
                            continue
                        c1 = r1[:i] + r2[j:]
                        c2 = r2[:j] + r1[i:]
                        n1, n2 = coster.cost(u, c1), coster.cost(v, c2)
                        if n1 + n2 < costs[u] + costs[v] - _EPS:
                            routes[u], routes[v], costs[u], costs[v] = c1, c2, n1, n2
                            found = True
                            self.moves += 1
        return found

    # -- perturbation ----------------------------------------------------------------------
    def kick(self, routes: Routes) -> Routes:
        routes = [list(r) for r in routes]
        rng = self.rng
        n = self.inst.n
        if n < 2:
            return routes
        if rng.random() < 0.5:
            # remove a few random targets and reinsert them at random places
            count = min(n, rng.randint(2, 4))
            where = {k: u for u, r in enumerate(routes) for k in r}
            picked = rng.sample(sorted(where), count)
            for k in picked:
                routes[where[k]].remove(k)
            for k in picked:
                u = rng.randrange(len(routes))
                routes[u].insert(rng.randint(0, len(routes[u])), k)
        else:
            # move a random chain to another route (or reverse it in place)
            nonempty = [u for u, r in enumerate(routes) if r]
            u = rng.choice(nonempty)
            r = routes[u]
            i = rng.randrange(len(r))
            j = rng.randint(i + 1, min(len(r), i + 4))
            chain = r[i:j]
            del r[i:j]
            v = rng.randrange(len(routes))
            if rng.random() < 0.5:
                chain.reverse()
            routes[v].insert(rng.randint(0, len(routes[v])), *chain[:1])
            at = routes[v].index(chain[0]) + 1
            routes[v][at:at] = chain[1:]
        return routes

    def run(
        self,
        start: Routes,
        iterations: int,
        *,
        patience: int | None = None,
    ) -> tuple[Routes, float]:
        """ILS from `start` for at most `iterations` kicks (fewer if `should_stop()` turns
        true or `patience` kicks in a row bring no improvement); returns (best, its cost)."""
        best = self.descend(start)
        best_cost = self.coster.total(best)
        current, current_cost = best, best_cost
        since = 0
        for _ in range(iterations):
            if self._caller_stop():
                break
            if patience is not None and since >= patience:
                break
            since += 1
            cand = self.descend(self.kick(current))
            cost = self.coster.total(cand)
            # accept improvements, and rarely a slightly worse plan to leave a basin
            # (costs are negative or positive: compare on the absolute scale)
            worse_ok = cost < current_cost + 1e-3 * abs(current_cost) and self.rng.random() < 0.05
            if cost < current_cost - _EPS or worse_ok:
                current, current_cost = cand, cost
            if cost < best_cost - _EPS:
                best, best_cost = cand, cost
                since = 0
        return best, best_cost
