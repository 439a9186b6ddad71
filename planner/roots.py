"""Vectorised root polishing: the Illinois variant of regula falsi on many brackets.

For brackets [lo, hi] with g(lo) > 0 >= g(hi), the secant point replaces the end whose g
has its sign; when the same end is kept twice its g is halved (Illinois), which keeps the
convergence superlinear where plain regula falsi would stall on one side. Every 8th step,
and wherever the secant leaves the bracket or meets an infinite end, it bisects instead,
so a discontinuous g (a jump) is located like by bisection.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
IndexArray = npt.NDArray[np.intp]
Gap = Callable[[FloatArray, IndexArray], FloatArray]  # g(T) for the pairs of an index array

__all__ = ["Gap", "IndexArray", "illinois"]

_REL_TOL = 1e-11  # relative width of the final bracket
_MAX_POLISH = 200  # iterations (the periodic bisection alone needs under 60 for any bracket)
_JUMP_REL_TOL = 1e-8  # relative bracket width enough to locate a jump
_G_TOL = 1e-7  # |g| this small is the root (g in metres: < 1e-8 s)


def illinois(
    gap: Gap, k: IndexArray, lo: FloatArray, hi: FloatArray, g_lo: FloatArray,
    g_hi: FloatArray, *, jump_m: float = math.inf,
) -> FloatArray:
    """Polish the brackets of the pairs k (g(lo) > 0 >= g(hi)) with the Illinois variant of
    regula falsi, bisecting every 8th step (and wherever the secant leaves the bracket or
    meets an infinite end); returns the reachable end (g <= 0) of each final bracket, or
    the point where |g| <= 1e-7. A bracket narrower than 1e-8 relative across which g
    falls by more than ``jump_m`` is a jump, not a root: it is not narrowed further."""
    lo, hi, g_lo, g_hi = lo.copy(), hi.copy(), g_lo.copy(), g_hi.copy()
    g_lo_true = g_lo.copy()  # g_lo itself is halved by the Illinois rule
    side = np.zeros(lo.size, dtype=np.int8)  # which end moved last: +1 lo, -1 hi
    active = np.flatnonzero(hi - lo > _REL_TOL * np.maximum(hi, 1.0))
    for it in range(_MAX_POLISH):
        if active.size == 0:
            break
        a, b = lo[active], hi[active]
        ga, gb = g_lo[active], g_hi[active]
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            t = b - gb * (b - a) / (gb - ga)
        bisect = ~np.isfinite(t) | (t <= a) | (t >= b) | (it % 8 == 7)
        t = np.where(bisect, 0.5 * (a + b), t)
        g = gap(t, k[active])
        g = np.where(np.isnan(g), np.inf, g)
        hit = np.abs(g) <= _G_TOL  # on the root: done
        hi[active[hit]] = t[hit]
        down = g <= 0.0
        k_hi, k_lo = active[down], active[~down]
        hi[k_hi], g_hi[k_hi] = t[down], g[down]
        g_lo[k_hi] = np.where(side[k_hi] == -1, 0.5 * g_lo[k_hi], g_lo[k_hi])
        side[k_hi] = -1
        lo[k_lo], g_lo[k_lo] = t[~down], np.minimum(g[~down], 1e300)
        g_lo_true[k_lo] = g_lo[k_lo]
        g_hi[k_lo] = np.where(side[k_lo] == 1, 0.5 * g_hi[k_lo], g_hi[k_lo])
        side[k_lo] = 1
        width = hi[active] - lo[active]
        scale = np.maximum(hi[active], 1.0)
        # a jump of g (D is not continuous there) needs no more than _JUMP_REL_TOL
        jump = (width <= _JUMP_REL_TOL * scale) & (
            g_lo_true[active] - g_hi[active] > jump_m
        )
        active = active[(width > _REL_TOL * scale) & ~jump & ~hit]
    return hi
