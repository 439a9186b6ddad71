"""Greedy construction and iterated local search on the route costs of planner.instance.

A plan is one list of kept-target indices per UAV; its value is constant + sum of
route costs (Instance.route_cost). Moves (per target the best improving one, repeated to a
local optimum):
relocate a chain of 1-3 targets (either orientation), swap two targets, 2-opt inside a
route, tail exchange between two routes, each next to a target's nearest nodes and costed
incrementally (planner.descent). Iterated local search
then kicks the plan (relocate a few random targets, or reverse a random chain) and keeps the
result if it is better. Everything is driven by a seeded random.Random, so with an iteration
budget (no deadline) it is deterministic.
"""

from __future__ import annotations

import itertools
import random
from collections.abc import Callable, Sequence

from planner.descent import Descent, neighbour_lists, route_cost
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
        return route_cost(self.w, self.h, self.sigma, self.b, self.m, u, route)

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


GREEDY_FULL_MAX = 20_000
"""Above n (n + m) = this, the greedy tries only the slots next to a target's neighbours and
after each UAV (planner.descent.Descent.build_greedy): every slot costs O(n) per target in
Python, 0.29 CPU-s at 50x500 (0.05 s by neighbours)."""


def greedy(
    inst: Instance, coster: RouteCoster | None = None, descent: Descent | None = None
) -> Routes:
    """Cheapest insertion, targets taken by decreasing sigma (every slot; above
    GREEDY_FULL_MAX the slots next to each target's neighbours, given `descent`)."""
    coster = coster or RouteCoster(inst)
    if descent is not None and inst.n * (inst.n + inst.m) > GREEDY_FULL_MAX:
        order = sorted(range(inst.n), key=lambda k: (-coster.sigma[k], k))
        return descent.build_greedy(order, inst.m)
    routes: Routes = [[] for _ in range(inst.m)]
    costs = [0.0] * inst.m
    for k in sorted(range(inst.n), key=lambda k: (-coster.sigma[k], k)):
        _, u, pos = best_insertion(coster, routes, costs, [k])
        routes[u].insert(pos, k)
        costs[u] = coster.cost(u, routes[u])
    return routes


class LocalSearch:
    """Iterated local search. Descents are incremental (planner.descent: delta costs,
    neighbour lists, don't-look bits). `should_stop` (the caller's stop flag and deadline)
    is polled before every target's moves are evaluated (at most a few dozen O(1) move
    costs), so a deadline ends even the first descent within a fraction of a millisecond."""

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
        self._descent = Descent(
            inst.m,
            self.coster.w,
            self.coster.h,
            self.coster.sigma,
            self.coster.b,
            neighbour_lists(inst),
            self._caller_stop,
        )

    def greedy(self) -> Routes:
        """planner.heuristics.greedy with this search's neighbour lists."""
        return greedy(self.inst, self.coster, self._descent)

    @property
    def moves(self) -> int:
        """Improving moves applied so far (tests: the deadline is polled)."""
        return self._descent.moves

    # -- descent -------------------------------------------------------------------------
    def descend(self, routes: Routes, active: Sequence[int] | None = None) -> Routes:
        """A local optimum from `routes` (planner.descent); `active`: the targets whose
        moves are tried first (all if None). At most MAX_DESCENT_MOVES improving moves."""
        return self._descent.run(routes, active, MAX_DESCENT_MOVES)

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
        """ILS from `start` for at most `iterations` kicks (fewer if the caller's
        `should_stop` turns true or `patience` kicks in a row bring no improvement); returns
        (best, its cost)."""
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
            kicked = self.kick(current)
            touched = [k for u, r in enumerate(kicked) if r != current[u] for k in r]
            cand = self.descend(kicked, touched)
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
