"""Turn-turn-straight flights onto a point that drifts through the air: the fallback of
planner.wind where no shortest Dubins path arrives on time.

In the air's frame (origin at the aircraft at t = 0) the point is at ``q0 + u t``. The
aircraft turns at omega = V / R in direction s1 for t1, then in direction s2 for t2, then
flies straight with heading psi2 at V. Turning s from heading psi for t moves it by

    s R (sin(psi + s omega t) - sin psi, cos psi - cos(psi + s omega t)).

With A its position after both turns, the straight meets the point iff the point's offset
``r = q0 + u (t1 + t2) - A`` lies ahead on the relative velocity ``c = V e(psi2) - u``:
``c x r = 0`` and ``c . r >= 0``, after ``tau = c . r / |c|^2``. For each t1 of a grid the
sign change of ``c x r`` along a grid of t2 is polished (planner.roots); the best t1 of each
(s1, s2) is refined by golden section. Every candidate is a flight that arrives, so the
result is an upper bound on the minimum time, within the grids' resolution of the best
such flight (measured in benchmarks/wind_costs.py).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from planner.roots import illinois

FloatArray = npt.NDArray[np.float64]

__all__ = ["FIRST_TURN_GRID", "SECOND_TURN_GRID", "turn_straight_s", "turn_turn_straight_s"]

FIRST_TURN_GRID = 32  # t1 samples over one full turn, per (s1, s2)
SECOND_TURN_GRID = 48  # t2 samples over one full turn
_REFINE = 12  # golden-section steps on t1


def turn_straight_s(
    x: FloatArray, y: FloatArray, h: FloatArray, px: FloatArray, py: FloatArray,
    ux: FloatArray, uy: FloatArray, v: float, r: float,
) -> FloatArray:
    """Fastest turn-straight flight (s) from each pose onto its point (the first turn of
    length 0 in the module docstring; every sign change on the turn's grid, polished);
    inf where none is found."""
    rows = _Rows(px - x, py - y, h, ux, uy, v, r)
    pair = np.repeat(np.arange(x.size), 2)
    turn = np.tile(np.array([1.0, -1.0]), x.size)
    best = rows.best(pair, turn, np.zeros(pair.size), turn)
    return np.asarray(best.reshape(x.size, 2).min(axis=1), dtype=float)


def turn_turn_straight_s(
    x: FloatArray, y: FloatArray, h: FloatArray, px: FloatArray, py: FloatArray,
    ux: FloatArray, uy: FloatArray, v: float, r: float,
) -> FloatArray:
    """Fastest turn-turn-straight flight (s) from each pose onto its point, which drifts
    at u through the air (module docstring); inf where none is found."""
    size = x.size
    period = 2.0 * math.pi * r / v
    grid = np.linspace(0.0, period, FIRST_TURN_GRID + 1)[1:]
    turns = np.array([(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)])
    shape = (size, len(turns), grid.size)
    pair = np.broadcast_to(np.arange(size)[:, None, None], shape).ravel()
    s1 = np.broadcast_to(turns[None, :, 0, None], shape).ravel()
    s2 = np.broadcast_to(turns[None, :, 1, None], shape).ravel()
    t1 = np.broadcast_to(grid[None, None, :], shape).ravel()
    rows = _Rows(px - x, py - y, h, ux, uy, v, r)
    times = rows.best(pair, s1, t1, s2).reshape(shape)
    best = times.min(axis=(1, 2))
    at = np.argmin(times, axis=2)  # (size, 4): best t1 index per pair of turn directions
    lo = np.maximum(grid[at] - grid[0], 0.0)
    hi = grid[at] + grid[0]
    golden = (math.sqrt(5.0) - 1.0) / 2.0
    pair2 = np.broadcast_to(np.arange(size)[:, None, None], (size, len(turns), 2)).ravel()
    s1b = np.broadcast_to(turns[None, :, 0, None], (size, len(turns), 2)).ravel()
    s2b = np.broadcast_to(turns[None, :, 1, None], (size, len(turns), 2)).ravel()
    for _ in range(_REFINE):
        a1 = hi - golden * (hi - lo)
        a2 = lo + golden * (hi - lo)
        f = rows.best(pair2, s1b, np.stack([a1, a2], axis=2).ravel(), s2b)
        f = f.reshape(size, len(turns), 2)
        best = np.minimum(best, f.min(axis=(1, 2)))
        left = f[:, :, 0] < f[:, :, 1]
        hi = np.where(left, a2, hi)
        lo = np.where(left, lo, a1)
    return best


class _Rows:
    """Evaluation of (pair, s1, t1, s2) rows: the second turn's grid and bisection."""

    def __init__(self, qx: FloatArray, qy: FloatArray, h: FloatArray, ux: FloatArray,
                 uy: FloatArray, v: float, r: float) -> None:
        self.qx, self.qy, self.h, self.ux, self.uy = qx, qy, h, ux, uy
        self.v, self.r = v, r
        self.omega = v / r

    def cross_time(self, pair: npt.NDArray[np.intp], s1: FloatArray, t1: FloatArray,
                   s2: FloatArray, t2: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(c x r, arrival time or inf) for the flights (arrays broadcast)."""
        r, v, omega = self.r, self.v, self.omega
        h0 = self.h[pair]
        h1 = h0 + s1 * omega * t1
        h2 = h1 + s2 * omega * t2
        ax = s1 * r * (np.sin(h1) - np.sin(h0)) + s2 * r * (np.sin(h2) - np.sin(h1))
        ay = s1 * r * (np.cos(h0) - np.cos(h1)) + s2 * r * (np.cos(h1) - np.cos(h2))
        ux, uy = self.ux[pair], self.uy[pair]
        elapsed = t1 + t2
        rx = self.qx[pair] + ux * elapsed - ax
        ry = self.qy[pair] + uy * elapsed - ay
        cx = v * np.cos(h2) - ux
        cy = v * np.sin(h2) - uy
        cross = cx * ry - cy * rx
        dot = cx * rx + cy * ry
        with np.errstate(divide="ignore", invalid="ignore"):
            time = np.where(dot >= 0.0, elapsed + dot / (cx * cx + cy * cy), np.inf)
        return cross, time

    def best(self, pair: npt.NDArray[np.intp], s1: FloatArray, t1: FloatArray,
             s2: FloatArray) -> FloatArray:
        """Fastest arrival of each row over its second turn t2 in [0, one turn]."""
        period = 2.0 * math.pi / self.omega
        t2 = np.linspace(0.0, period, SECOND_TURN_GRID + 1)[None, :]
        col = (slice(None), None)
        cross, _ = self.cross_time(pair[col], s1[col], t1[col], s2[col], t2)
        row, k = np.nonzero(cross[:, :-1] * cross[:, 1:] <= 0.0)
        out = np.full(pair.size, np.inf)
        if row.size == 0:
            return out
        c_lo, c_hi = cross[row, k], cross[row, k + 1]
        sign = np.where(c_lo != 0.0, np.sign(c_lo), -np.sign(c_hi))  # g = sign c: + at lo

        def gap(t: FloatArray, idx: npt.NDArray[np.intp]) -> FloatArray:
            c, _ = self.cross_time(pair[row[idx]], s1[row[idx]], t1[row[idx]], s2[row[idx]], t)
            return np.asarray(sign[idx] * c, dtype=float)

        every = np.arange(row.size)
        root = illinois(gap, every, t2[0, k], t2[0, k + 1], sign * c_lo, sign * c_hi)
        _, time = self.cross_time(pair[row], s1[row], t1[row], s2[row], root)
        np.minimum.at(out, row, time)
        return out
