"""Incremental descent to a local optimum: delta costs, neighbour lists, don't-look bits.

A plan is one list of kept-target indices per UAV (planner.heuristics). Its variable cost is
the sum over the arcs of every path of w_ij + b h_ij R_j (planner.instance), i.e. per route,
with node(0) = the UAV and node(p) = its p-th target,

    H[p] = H[p - 1] + h(node(p - 1), node(p))                 (cumulative hops, H[0] = 0)
    C[p] = C[p - 1] + w(node(p - 1), node(p)) + b sigma(p) H[p]   (prefix cost, C[0] = 0)
    S[p] = sum_{t >= p} sigma(t)                              (suffix sigma, S[L + 1] = 0)

and the route costs C[L]. Every move below replaces a prefix and re-attaches a tail, so its
cost follows in O(1) (O(chain) for a chain of <= 3) from these arrays: the tail of route v
from position q, attached after node x whose cumulative hops are H_x, costs

    tail(v, q, x, H_x) = C_v[L] - C_v[q - 1] - w(node_v(q - 1), node_v(q)) + w(x, node_v(q))
                         + b (H_x + h(x, node_v(q)) - H_v[q]) S_v[q]

(every hop inside the tail is kept, so every H in it moves by the same amount). Moves:

* relocate a chain of 1-3 targets (either orientation) to another route, next to one of the
  first target's neighbours (before or after it, or first after a neighbouring UAV);
* swap two neighbouring targets of different routes;
* exchange tails (2-opt*) so that a target and its neighbour in another route become
  consecutive (either order), or a neighbouring UAV takes the target's tail;
* inside one route (relocate next to a neighbour, swap, 2-opt reversal making the two
  neighbours consecutive): the new route's cost by a direct O(L) sum, L its length.

Neighbour lists: each target's NEIGHBOURS nearest nodes (targets and UAVs) by the charged
distance d_net (both directions). Don't-look bits: a queue of active targets, all at first
(or, after a kick, the targets of the routes the kick changed); a target whose moves bring
nothing leaves the queue; a move puts every target of the routes it changed back in. For
each target the best improving move over its candidates is applied. Everything is in a
fixed order, so with no deadline the descent is deterministic.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence

import numpy as np

from planner.instance import Instance

NEIGHBOURS = 10
"""Candidate neighbours per target. 10 gives the same plans as full neighbourhoods within
0.1 % at 10x50-50x250 (measured, docs/planner.md) at a fraction of their cost."""


GREEDY_POLL_EVERY = 16  # the neighbour greedy polls the deadline every this many targets


def neighbour_lists(inst: Instance, count: int = NEIGHBOURS) -> list[list[int]]:
    """Per target k: the `count` nodes (UAV u as u, target t as m + t) nearest to k by
    min(d_net[k, j], d_net[j, k]), ties by node index."""
    m, n = inst.m, inst.n
    size = m + n
    if n == 0:
        return []
    d = np.minimum(inst.d_net[m:, :], inst.d_net[:, m:].T).astype(float)  # n x N
    d[np.arange(n), m + np.arange(n)] = np.inf
    count = min(count, size - 1)
    if count <= 0:
        return [[] for _ in range(n)]
    order = np.argsort(d, axis=1, kind="stable")[:, :count]
    return [[int(j) for j in row] for row in order]


def route_cost(w: list[list[float]], h: list[list[float]], sigma: list[float], b: float,
               m: int, u: int, route: Sequence[int]) -> float:
    """The variable cost of UAV ``u`` flying ``route`` (target indices; node of target k is
    m + k): sum over its targets of w(prev, k) + b sigma_k H_k, with H_k the hops flown up
    to k, counted from scratch (the reference the incremental deltas are checked against)."""
    total = 0.0
    hops = 0.0
    prev = u
    for k in route:
        node = m + k
        hops += h[prev][node]
        total += w[prev][node] + b * sigma[k] * hops
        prev = node
    return total


class Descent:
    """Incremental local search state over one plan (see the module docstring)."""

    def __init__(
        self,
        m: int,
        w: list[list[float]],
        h: list[list[float]],
        sigma: list[float],
        b: float,
        neighbours: list[list[int]],
        should_stop: Callable[[], bool],
    ) -> None:
        self.m = m
        self.w = w
        self.h = h
        self.sigma = sigma
        self.b = b
        self.neighbours = neighbours
        self.should_stop = should_stop
        self.routes: list[list[int]] = []
        self.H: list[list[float]] = []
        self.C: list[list[float]] = []
        self.S: list[list[float]] = []
        self.where_u: list[int] = [0] * len(sigma)
        self.where_p: list[int] = [0] * len(sigma)
        self.moves = 0
        self.tol = 1e-9

    # -- state ---------------------------------------------------------------------------
    def load(self, routes: Sequence[Sequence[int]]) -> None:
        self.routes = [list(r) for r in routes]
        self.H = [[] for _ in self.routes]
        self.C = [[] for _ in self.routes]
        self.S = [[] for _ in self.routes]
        for u in range(len(self.routes)):
            self._refresh(u)
        total = sum(c[-1] for c in self.C)
        self.tol = max(1e-9, 1e-12 * (abs(total) + 1.0))

    def _refresh(self, u: int) -> None:
        w, h, sigma, b, m = self.w, self.h, self.sigma, self.b, self.m
        route = self.routes[u]
        size = len(route)
        hs = [0.0] * (size + 1)
        cs = [0.0] * (size + 1)
        ss = [0.0] * (size + 2)
        prev = u
        hops = 0.0
        cost = 0.0
        wu, wp = self.where_u, self.where_p
        for p, k in enumerate(route, 1):
            node = m + k
            hops += h[prev][node]
            cost += w[prev][node] + b * sigma[k] * hops
            hs[p] = hops
            cs[p] = cost
            wu[k] = u
            wp[k] = p
            prev = node
        acc = 0.0
        for p in range(size, 0, -1):
            acc += sigma[route[p - 1]]
            ss[p] = acc
        self.H[u], self.C[u], self.S[u] = hs, cs, ss

    def _node(self, u: int, p: int) -> int:
        return u if p == 0 else self.m + self.routes[u][p - 1]

    def _tail(self, v: int, q: int, x: int, hx: float) -> float:
        """Cost of route v's targets from position q on, attached after node x (hops hx)."""
        route = self.routes[v]
        size = len(route)
        if q > size:
            return 0.0
        cv = self.C[v]
        first = self.m + route[q - 1]
        old = v if q == 1 else self.m + route[q - 2]
        w, h = self.w, self.h
        shift = hx + h[x][first] - self.H[v][q]
        return cv[size] - cv[q - 1] - w[old][first] + w[x][first] + self.b * shift * self.S[v][q]

    def _direct(self, u: int, route: Sequence[int]) -> float:
        return route_cost(self.w, self.h, self.sigma, self.b, self.m, u, route)

    def _chain_after(self, v: int, q: int, chain: Sequence[int]) -> float:
        """Cost of route v with `chain` inserted after its position q (v without the chain)."""
        w, h, sigma, b, m = self.w, self.h, self.sigma, self.b, self.m
        x = self._node(v, q)
        hops = self.H[v][q]
        cost = self.C[v][q]
        for k in chain:
            node = m + k
            hops += h[x][node]
            cost += w[x][node] + b * sigma[k] * hops
            x = node
        return cost + self._tail(v, q + 1, x, hops)

    # -- construction --------------------------------------------------------------------
    def build_greedy(self, order: Sequence[int], n_uavs: int) -> list[list[int]]:
        """Cheapest insertion of the targets in `order`, each at the best of the slots first
        after a UAV (every UAV) and just before or after its placed neighbours (O(1) per slot
        from the route arrays): the large-instance greedy (planner.heuristics.greedy)."""
        self.load([[] for _ in range(n_uavs)])
        placed = [False] * len(self.sigma)
        routes, C = self.routes, self.C
        wu, wp = self.where_u, self.where_p
        m = self.m
        for at, k in enumerate(order):
            if at % GREEDY_POLL_EVERY == 0 and self.should_stop():
                # out of time: the rest go in after their nearest placed node, uncosted
                self._append_rest(order[at:], placed, n_uavs)
                break
            slots = [(v, 0) for v in range(n_uavs)]
            for j in self.neighbours[k]:
                if j >= m and placed[j - m]:
                    v, q = wu[j - m], wp[j - m]
                    slots.append((v, q))
                    slots.append((v, q - 1))
            best = (float("inf"), 0, 0)
            for v, q in slots:
                delta = self._chain_after(v, q, (k,)) - C[v][len(routes[v])]
                if delta < best[0]:
                    best = (delta, v, q)
            _, v, q = best
            routes[v].insert(q, k)
            placed[k] = True
            self._refresh(v)
        return [list(r) for r in routes]

    def _append_rest(self, rest: Sequence[int], placed: list[bool], n_uavs: int) -> None:
        """Each target of `rest` right after its nearest placed neighbour (a UAV: first on
        its route; none placed: first on UAV 0's), O(neighbours) each, then the arrays."""
        m, routes = self.m, self.routes
        for k in rest:
            u, pos = 0, 0
            for j in self.neighbours[k]:
                if j < m:
                    u, pos = j, 0
                    break
                if placed[j - m]:
                    t = j - m
                    u = self.where_u[t]
                    pos = self.where_p[t]
                    break
            routes[u].insert(pos, k)
            placed[k] = True
            for p, t in enumerate(routes[u], 1):
                self.where_u[t], self.where_p[t] = u, p
        for u in range(n_uavs):
            self._refresh(u)

    # -- the descent ---------------------------------------------------------------------
    def run(self, routes: Sequence[Sequence[int]], active: Sequence[int] | None = None,
            move_cap: int = 20_000) -> list[list[int]]:
        """Descend from `routes` (targets in `active` first checked; all if None) until no
        active target has an improving move, should_stop() or `move_cap` moves."""
        self.load(routes)
        n = len(self.sigma)
        queue: deque[int] = deque(range(n) if active is None else active)
        queued = [False] * n
        for k in queue:
            queued[k] = True
        cap = self.moves + move_cap
        while queue:
            if self.should_stop() or self.moves >= cap:
                break
            k = queue.popleft()
            queued[k] = False
            changed = self._improve(k)
            if changed:
                self.moves += 1
                for u in changed:
                    for t in self.routes[u]:
                        if not queued[t]:
                            queued[t] = True
                            queue.append(t)
        return [list(r) for r in self.routes]

    def _improve(self, k: int) -> tuple[int, ...]:
        """Apply the best improving move for target k; the routes it changed (or ())."""
        m, routes, C = self.m, self.routes, self.C
        wu, wp = self.where_u, self.where_p
        u = wu[k]
        i = wp[k]
        r = routes[u]
        size = len(r)
        cost_u = C[u][size]
        best_delta = -self.tol
        best: tuple[object, ...] | None = None
        nbrs = self.neighbours[k]
        # -- relocate a chain k.. (length 1-3) next to a neighbour
        for s in (1, 2, 3):
            if i + s - 1 > size:
                break
            chain = r[i - 1 : i - 1 + s]
            removed = C[u][i - 1] + self._tail(u, i + s, self._node(u, i - 1), self.H[u][i - 1])
            options = (chain,) if s == 1 else (chain, chain[::-1])
            slots: list[tuple[int, int]] = []
            for j in nbrs:
                if j < m:
                    slots.append((j, 0))
                else:
                    t = j - m
                    if t in chain:
                        continue
                    v, q = wu[t], wp[t]
                    slots.append((v, q))
                    slots.append((v, q - 1))
            seen: set[tuple[int, int]] = set()
            for v, q in slots:
                if (v, q) in seen:
                    continue
                seen.add((v, q))
                if v != u:
                    base = removed - cost_u - C[v][len(routes[v])]
                    for option in options:
                        delta = base + self._chain_after(v, q, option)
                        if delta < best_delta:
                            best_delta, best = delta, ("move", u, i, s, v, q, option)
                else:
                    # same route: positions of the route without the chain
                    qq = q if q < i else q - s
                    if qq < 0:
                        continue
                    rest = r[: i - 1] + r[i - 1 + s :]
                    for option in options:
                        cand = rest[:qq] + list(option) + rest[qq:]
                        if cand == r:
                            continue
                        delta = self._direct(u, cand) - cost_u
                        if delta < best_delta:
                            best_delta, best = delta, ("route", u, cand)
        # -- swap, tail exchange and 2-opt with each neighbour
        w, h, sigma, b = self.w, self.h, self.sigma, self.b
        H = self.H
        kn = m + k
        for j in nbrs:
            if j < m:
                v = j
                if v == u:
                    continue
                # UAV v takes k's tail: u = u[:i-1] + v[all], v = u[i:]
                cost_v = C[v][len(routes[v])]
                nu = C[u][i - 1] + self._tail(v, 1, self._node(u, i - 1), H[u][i - 1])
                nv = self._tail(u, i, v, 0.0)
                delta = nu + nv - cost_u - cost_v
                if delta < best_delta:
                    best_delta, best = delta, ("tails", u, i - 1, v, 0)
                continue
            t = j - m
            v, q = wu[t], wp[t]
            if v != u:
                cost_v = C[v][len(routes[v])]
                tn = m + t
                # swap k <-> t
                pu = self._node(u, i - 1)
                hu = H[u][i - 1] + h[pu][tn]
                nu = C[u][i - 1] + w[pu][tn] + b * sigma[t] * hu + self._tail(u, i + 1, tn, hu)
                pv = self._node(v, q - 1)
                hv = H[v][q - 1] + h[pv][kn]
                nv = C[v][q - 1] + w[pv][kn] + b * sigma[k] * hv + self._tail(v, q + 1, kn, hv)
                delta = nu + nv - cost_u - cost_v
                if delta < best_delta:
                    best_delta, best = delta, ("swap", u, i, v, q)
                # tails: k -> t (cut u after i, v after q - 1) and t -> k (u after i - 1, v after q)
                for cu, cv in ((i, q - 1), (i - 1, q)):
                    nu = C[u][cu] + self._tail(v, cv + 1, self._node(u, cu), H[u][cu])
                    nv = C[v][cv] + self._tail(u, cu + 1, self._node(v, cv), H[v][cv])
                    delta = nu + nv - cost_u - cost_v
                    if delta < best_delta:
                        best_delta, best = delta, ("tails", u, cu, v, cv)
            else:
                a, c = i - 1, q - 1  # 0-based places of k and t
                cands = []
                sw = list(r)
                sw[a], sw[c] = sw[c], sw[a]
                cands.append(sw)
                if c > a + 1:
                    cands.append(r[: a + 1] + r[a + 1 : c + 1][::-1] + r[c + 1 :])
                elif c < a - 1:
                    cands.append(r[:c] + r[c:a][::-1] + r[a:])
                for cand in cands:
                    delta = self._direct(u, cand) - cost_u
                    if delta < best_delta:
                        best_delta, best = delta, ("route", u, cand)
        if best is None:
            return ()
        return self._apply(best)

    def _apply(self, move: tuple[object, ...]) -> tuple[int, ...]:
        kind = move[0]
        routes = self.routes
        if kind == "route":
            _, u, cand = move
            assert isinstance(u, int) and isinstance(cand, list)
            routes[u] = cand
            self._refresh(u)
            return (u,)
        if kind == "move":
            _, u, i, s, v, q, option = move
            assert isinstance(u, int) and isinstance(i, int) and isinstance(s, int)
            assert isinstance(v, int) and isinstance(q, int) and isinstance(option, list)
            del routes[u][i - 1 : i - 1 + s]
            routes[v][q:q] = option
        elif kind == "swap":
            _, u, i, v, q = move
            assert isinstance(u, int) and isinstance(i, int)
            assert isinstance(v, int) and isinstance(q, int)
            routes[u][i - 1], routes[v][q - 1] = routes[v][q - 1], routes[u][i - 1]
        else:  # tails
            _, u, cu, v, cv = move
            assert isinstance(u, int) and isinstance(cu, int)
            assert isinstance(v, int) and isinstance(cv, int)
            ru, rv = routes[u], routes[v]
            routes[u], routes[v] = ru[:cu] + rv[cv:], rv[:cv] + ru[cu:]
        self._refresh(u)
        self._refresh(v)
        return (u, v)
