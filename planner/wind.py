"""Travel times in a uniform wind: straight legs at ground speed, the first leg as a Dubins
path flown in the moving air (the virtual-target method).

Frames: local ENU metres, the wind ``w`` the ENU vector the air moves towards (m/s),
``V`` the airspeed, ``R`` the turn radius the aircraft flies relative to the air.

**Straight legs** (target to target): the aircraft crabs to hold the ground course
``chi_ij`` and makes good ``g(chi) = w_par + sqrt(V^2 - w_perp^2)``
(:func:`domain.wind_triangle.ground_speed_along_m_s`), so

    T_ij = |p_j - p_i| / g(chi_ij)                 (asymmetric: T_ij != T_ji in wind)

**First leg** (from the UAV's pose to a point, free final heading). In the frame of the air
(moving at ``w``, coinciding with the ground frame at t = 0) the aircraft is a Dubins car
of speed V and radius R, and a ground point moving at ``v`` (0 for a plan's target, the
track's velocity for an intercept) is the air-frame point ``q(t) = p + u t``, u = v - w,
|u| < V. A flight arrives at T only if D(pose, q(T)) <= V T (D: the still-air Dubins
distance to a point, free final heading, planner.dubins), so the first entry of the moving
point into the growing Dubins ball::

    T_entry = min { T : g(T) = D(pose, q(T)) - V T <= 0 }

is a lower bound, and where g crosses 0 continuously it is the minimum time: the shortest
air path to q(T_entry) has length V T_entry and lands on the ground point then.

* ``T_e``, the root of ``|q(T)| = V T`` (a quadratic), is a lower bound: D >= |q|.
* Outside the disc ``|q| <= 2 R`` around the start (which holds both turning circles) the
  turn-turn paths are never shorter (checked on 200 000 points, tests/test_planner_wind)
  and D is the smaller of the two turn-straight lengths; each satisfies the eikonal
  equation ``|grad| = 1``, so D is 1-Lipschitz and g falls strictly, at a rate in
  [V - |u|, V + |u|]. Until q reaches the disc the root is therefore unique, in
  ``[T_e, T_e + g(T_e) / (V - |u|)]``, and polished by the Illinois method (planner.roots):
  exact to 1e-8 s. Most legs end here.
* Where q is in the disc before the root (the target within about 2 R, or the wind carrying
  it past the start), D has jumps (on the turning circles) and turn-turn branches. There
  the first sign change of g is found by stepping ``max(g / (V + |u|), NEAR_STEP_S)``
  (``g / (V - |u|)`` once q has left the disc for good) and polished; the result is kept
  where that crossing is continuous. The steps can pass over a brief entry (the point
  touches the ball, then moves into a turning circle, where D is a loop longer), so the
  best turn-straight flight is computed as well, over the ground (planner.wind_turns);
  where the entry is a jump of D (the shortest path arrives early, none on time), the best
  turn-turn-straight flight is taken: with a strong wind and the point close behind the
  aircraft an S-turn that lets the wind carry it back is fastest.

Measured against a brute force over flown turn-straight and turn-turn-straight flights
(benchmarks/wind_costs.py, docs/planner.md "Wind"). Every function is vectorised over
numpy arrays: a plan computes m x n first legs.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from planner.dubins import dubins_distances_to_points
from planner.roots import IndexArray, illinois
from planner.wind_turns import turn_straight_s, turn_turn_straight_s

FloatArray = npt.NDArray[np.float64]

__all__ = [
    "NEAR_STEP_S",
    "first_leg_times_s",
    "potential_s",
    "straight_leg_times_s",
    "time_in_wind_s",
]

NEAR_STEP_S = 0.5
"""Smallest scan step (s) in the disc near the start, where D is not 1-Lipschitz."""
_NEAR_RADII = 2.0  # |q| <= 2 R: within the turning circles (turn-turn paths, D's jumps)
_MAX_SCAN = 100_000  # near-start scan steps (a bound, never reached with |u| < V)
_JUMP_M = 1e-3  # a polished root with g below -this is a jump of D, not an arrival


def straight_leg_times_s(
    xy_m: FloatArray, wind_xy_m_s: tuple[float, float], airspeed_m_s: float
) -> FloatArray:
    """T[i, j] = |p_j - p_i| / g(course_ij) for the rows of ``xy_m`` (N x 2), 0 on the
    diagonal and between coincident points. Needs |w| < V (then g > 0 on every course)."""
    wx, wy = wind_xy_m_s
    v = float(airspeed_m_s)
    diff = xy_m[None, :, :] - xy_m[:, None, :]  # p_j - p_i
    dist = np.sqrt((diff**2).sum(axis=2))
    safe = np.where(dist > 0.0, dist, 1.0)
    ex, ey = diff[:, :, 0] / safe, diff[:, :, 1] / safe
    w_par = wx * ex + wy * ey
    w_perp = wx * ey - wy * ex
    ground = w_par + np.sqrt(v * v - w_perp * w_perp)
    return np.where(dist > 0.0, dist / ground, 0.0)


def potential_s(
    xy_m: FloatArray, wind_xy_m_s: tuple[float, float], airspeed_m_s: float
) -> FloatArray:
    """The wind's potential (s) at the rows of ``xy_m`` (N x 2): ``phi(p) = -(w . p) /
    (V^2 - |w|^2)``. Needs |w| < V.

    Any flight at airspeed V over a ground path (straight, turning, crabbing) makes good
    ``g = w . u + sqrt((w . u)^2 + V^2 - |w|^2)`` along its course ``u`` (from
    ``|g u - w| = V``), so ``1/g = (sqrt((w . u)^2 + V^2 - |w|^2) - w . u) / (V^2 - |w|^2)``
    and its time splits into a part that is the same both ways along the path and an
    exact differential::

        T = T_sym + phi(p_end) - phi(p_start),
        T_sym = integral sqrt((w . u)^2 + V^2 - |w|^2) / (V^2 - |w|^2) ds   (u -> -u: same)

    Downwind ``phi`` falls: every flight is credited the wind's push along it, which a
    flight back repays to the second. Over a closed tour the potential cancels."""
    wx, wy = wind_xy_m_s
    v = float(airspeed_m_s)
    return -(xy_m[:, 0] * wx + xy_m[:, 1] * wy) / (v * v - wx * wx - wy * wy)


def first_leg_times_s(
    x_m: FloatArray,
    y_m: FloatArray,
    heading_rad: FloatArray,
    px_m: FloatArray,
    py_m: FloatArray,
    wind_xy_m_s: tuple[float, float],
    airspeed_m_s: float,
    turn_radius_m: float,
    target_v_m_s: tuple[FloatArray, FloatArray] | tuple[float, float] = (0.0, 0.0),
) -> FloatArray:
    """Minimum time (s) from each pose to reach its ground point (moving at
    ``target_v_m_s``), all arrays broadcast together (module docstring). ``inf`` where
    the point moves away through the air at the airspeed or faster (|v - w| >= V), NaN
    where an input is not finite."""
    vx, vy = target_v_m_s
    arrays = np.broadcast_arrays(
        *(np.asarray(a, dtype=float) for a in (x_m, y_m, heading_rad, px_m, py_m, vx, vy))
    )
    shape = arrays[0].shape
    x, y, h, px, py, tvx, tvy = (a.ravel() for a in arrays)
    wx, wy = wind_xy_m_s
    ux, uy = tvx - wx, tvy - wy
    v = float(airspeed_m_s)
    out = np.full(x.shape, np.inf)
    here = (px == x) & (py == y)
    out[here] = 0.0
    finite = np.isfinite(x + y + h + px + py + ux + uy)
    out[~finite] = np.nan
    todo = np.flatnonzero(finite & ~here & (np.hypot(ux, uy) < v))
    if todo.size:
        legs = _Legs(x[todo], y[todo], h[todo], px[todo], py[todo], ux[todo], uy[todo], v,
                     float(turn_radius_m))
        out[todo] = legs.solve()
    return out.reshape(shape)


class _Legs:
    """The root finding of first_leg_times_s for K pose -> moving point pairs (module
    docstring)."""

    def __init__(
        self, x: FloatArray, y: FloatArray, h: FloatArray, px: FloatArray, py: FloatArray,
        ux: FloatArray, uy: FloatArray, v: float, r: float,
    ) -> None:
        self.x, self.y, self.h, self.px, self.py, self.ux, self.uy = x, y, h, px, py, ux, uy
        self.v, self.r = v, r
        self.speed_u = np.hypot(ux, uy)

    def gap(self, t: FloatArray, k: IndexArray) -> FloatArray:
        """g(T) = D(pose, p + u T) - V T for the pairs k."""
        d = dubins_distances_to_points(
            self.x[k], self.y[k], self.h[k], self.px[k] + self.ux[k] * t,
            self.py[k] + self.uy[k] * t, self.r,
        )
        return d - self.v * t

    def solve(self) -> FloatArray:
        v, r = self.v, self.r
        qx, qy = self.px - self.x, self.py - self.y
        ux, uy, speed_u = self.ux, self.uy, self.speed_u
        # T_e: |q0 + u T| = V T; a = V^2 - |u|^2 > 0, b = q0 . u
        a = v * v - speed_u * speed_u
        b = qx * ux + qy * uy
        q2 = qx * qx + qy * qy
        root = np.sqrt(b * b + a * q2)
        with np.errstate(divide="ignore", invalid="ignore"):
            t_e = np.where(b >= 0.0, (b + root) / a, q2 / (root - b))
        every = np.arange(t_e.size)
        g_e = np.maximum(self.gap(t_e, every), 0.0)  # >= 0 in exact arithmetic
        # [t_in, leave]: when q is within 2 R of the start (turn-turn paths, D's jumps);
        # outside, D is 1-Lipschitz and g falls at a rate in [V - |u|, V + |u|]
        enter, leave = _disc_interval(qx, qy, ux, uy, _NEAR_RADII * r)
        t_in = np.where(leave >= t_e, np.maximum(enter, t_e), np.inf)
        t_b = t_e + g_e / (v - speed_u)  # g(t_b) <= 0 if no disc on the way
        t_b = np.minimum(t_b, t_in)
        g_b = self.gap(t_b, every)
        out = np.full(t_e.size, np.inf)
        found = np.flatnonzero(g_b <= 0.0)  # the one root before the disc: exact
        out[found] = illinois(self.gap, found, t_e[found], t_b[found], g_e[found], g_b[found],
                              jump_m=_JUMP_M)
        rest = np.flatnonzero(g_b > 0.0)
        if rest.size:
            out[rest] = self._near(rest, t_b[rest], g_b[rest], leave[rest])
        return out

    def _near(self, k: IndexArray, t0: FloatArray, g0: FloatArray, leave: FloatArray
              ) -> FloatArray:
        """From t0 (g > 0, q at the disc or inside it): the first entry into the Dubins
        ball where it is a continuous crossing (the shortest path then arrives on time);
        the best turn-straight flight, which the scan's steps may have stepped over (a brief
        entry before the point moves into a turning circle); and where the entry was a jump
        of D (no path of length V T ends at q(T)), the best turn-turn-straight flight."""
        entry = self._first_entry(k, t0, g0, leave)
        jumped = self.gap(entry, k) < -_JUMP_M
        pose = (self.x[k], self.y[k], self.h[k])
        point = (self.px[k], self.py[k], self.ux[k], self.uy[k])
        out = np.minimum(np.where(jumped, np.inf, entry),
                         turn_straight_s(*pose, *point, self.v, self.r))
        if jumped.any():
            j = np.flatnonzero(jumped)
            x, y, h = (a[j] for a in pose)
            px, py, ux, uy = (a[j] for a in point)
            out[j] = np.minimum(out[j], turn_turn_straight_s(x, y, h, px, py, ux, uy,
                                                             self.v, self.r))
        return out

    def _first_entry(self, k: IndexArray, t0: FloatArray, g0: FloatArray, leave: FloatArray
                     ) -> FloatArray:
        """Step from t0 until g <= 0, then polish: by max(g / (V + |u|), NEAR_STEP_S) while
        q is within the disc, by g / (V - |u|) (which cannot pass the root) once it has
        left it for good."""
        speed_u = self.speed_u[k]
        lo, g_lo = t0.copy(), g0.copy()
        hi, g_hi = t0.copy(), g0.copy()
        active = np.flatnonzero(g_hi > 0.0)
        for _ in range(_MAX_SCAN):
            if active.size == 0:
                break
            g = g_hi[active]
            out_of_disc = hi[active] >= leave[active]
            step = np.where(out_of_disc, g / (self.v - speed_u[active]),
                            np.maximum(g / (self.v + speed_u[active]), NEAR_STEP_S))
            t_next = hi[active] + np.maximum(step, 1e-9 * np.maximum(hi[active], 1.0))
            g_next = self.gap(t_next, k[active])
            lo[active], g_lo[active] = hi[active], g
            hi[active], g_hi[active] = t_next, g_next
            active = active[g_next > 0.0]
        moved = np.flatnonzero(hi > lo)
        out = hi.copy()
        if moved.size:
            out[moved] = illinois(self.gap, k[moved], lo[moved], hi[moved], g_lo[moved],
                                  g_hi[moved], jump_m=_JUMP_M)
        return out


def _disc_interval(
    qx: FloatArray, qy: FloatArray, ux: FloatArray, uy: FloatArray, radius: float
) -> tuple[FloatArray, FloatArray]:
    """(enter, leave): the times between which |q0 + u T| <= radius (T of any sign);
    (inf, -inf) if never. A point at rest inside stays forever."""
    u2 = ux * ux + uy * uy
    b = qx * ux + qy * uy
    c = qx * qx + qy * qy - radius * radius
    disc = b * b - u2 * c
    with np.errstate(divide="ignore", invalid="ignore"):
        root = np.sqrt(np.maximum(disc, 0.0))
        enter = np.where(disc >= 0.0, (-b - root) / u2, np.inf)
        leave = np.where(disc >= 0.0, (-b + root) / u2, -np.inf)
    still = u2 == 0.0
    enter = np.where(still, np.where(c <= 0.0, -np.inf, np.inf), enter)
    leave = np.where(still, np.where(c <= 0.0, np.inf, -np.inf), leave)
    return enter, leave


def time_in_wind_s(
    x_m: float,
    y_m: float,
    heading_rad: float,
    px_m: float,
    py_m: float,
    wind_xy_m_s: tuple[float, float],
    airspeed_m_s: float,
    turn_radius_m: float,
    target_v_m_s: tuple[float, float] = (0.0, 0.0),
) -> float:
    """Scalar :func:`first_leg_times_s`: the minimum time (s) from a pose to a ground
    point moving at ``target_v_m_s`` in the wind; ``math.inf`` if it cannot be caught (or
    an input is not finite)."""
    out = first_leg_times_s(
        np.array(x_m), np.array(y_m), np.array(heading_rad), np.array(px_m), np.array(py_m),
        wind_xy_m_s, airspeed_m_s, turn_radius_m, target_v_m_s,
    )
    value = float(out)
    return value if math.isfinite(value) else math.inf
