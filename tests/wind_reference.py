"""A brute-force reference for the first leg in wind, independent of planner.wind.

It never leaves the ground frame and knows nothing of virtual targets or Dubins distances:
it flies candidate paths in the wind and keeps the fastest that passes over the (possibly
moving) target. A turn at the maximum rate omega = V / R in direction s (+1 left) from the
air heading psi0 puts the aircraft, after t seconds, at

    X(t) = X0 + c_s + s R (sin psi(t), -cos psi(t)) + w t,   psi(t) = psi0 + s omega t,
    c_s = s R (-sin psi0, cos psi0)                          (a trochoid over the ground)

and a straight after it moves at V (cos psi, sin psi) + w. Families:

* turn-straight (CS): the turn ends where the straight's ground ray passes through the
  target: cross(v_rel, P - X) changes sign along a fine grid of t1, bisected to 1e-12 s;
* turn-turn-straight (CCS, optional): a grid of t1, for each a grid of the second turn's
  t2 with the same sign-change search, then a golden-section refinement of t1 around the
  best. With the straight of length 0 this covers turn-turn paths.

Every candidate is a flyable path, so the result is an upper bound on the minimum time,
exact to the grid's resolution where the optimum is of these forms (in the air frame the
optimum is a Dubins turn-straight or turn-turn path, so it is).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
_BISECT = 60


def _fly_turn(
    x: FloatArray, y: FloatArray, psi0: FloatArray, s: float, t: FloatArray, r: float,
    omega: float, wind: tuple[float, float],
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Ground position and air heading after turning s for t (arrays broadcast)."""
    psi = psi0 + s * omega * t
    cx = x - s * r * np.sin(psi0)
    cy = y + s * r * np.cos(psi0)
    return (cx + s * r * np.sin(psi) + wind[0] * t, cy - s * r * np.cos(psi) + wind[1] * t, psi)


def _straight_hits(
    gx: FloatArray, gy: FloatArray, psi: FloatArray, t0: FloatArray, target: tuple[float, ...],
    v: float, wind: tuple[float, float],
) -> tuple[FloatArray, FloatArray]:
    """(cross, time): cross = v_rel x (P(t0) - X), and the arrival time if the target lies
    ahead on the straight's relative ray (else inf)."""
    px, py, tvx, tvy = target
    rx, ry = px + tvx * t0 - gx, py + tvy * t0 - gy
    cx = v * np.cos(psi) + wind[0] - tvx
    cy = v * np.sin(psi) + wind[1] - tvy
    cross = cx * ry - cy * rx
    dot = cx * rx + cy * ry
    c2 = cx * cx + cy * cy
    with np.errstate(divide="ignore", invalid="ignore"):
        time = np.where(dot >= 0.0, t0 + dot / c2, np.inf)
    return cross, time


def reference_time_s(
    x: float, y: float, heading: float, px: float, py: float,
    wind: tuple[float, float], v: float, r: float,
    target_v: tuple[float, float] = (0.0, 0.0), *, n1: int = 20000, n_cc: int = 0,
) -> float:
    """Fastest CS (and, with n_cc > 0, CCS on an n_cc x n_cc grid) flight onto the target
    (see module docstring)."""
    omega = v / r
    period = 2.0 * math.pi / omega
    target = (px, py, target_v[0], target_v[1])
    if px == x and py == y:
        return 0.0
    best = math.inf
    for s in (1.0, -1.0):
        best = min(best, _cs(x, y, heading, s, target, v, r, omega, wind, n1, period))
        if n_cc:
            best = min(best, _ccs(x, y, heading, s, target, v, r, omega, wind, n_cc, period))
    return best


def _cs(
    x: float, y: float, heading: float, s: float, target: tuple[float, ...], v: float,
    r: float, omega: float, wind: tuple[float, float], n1: int, period: float,
) -> float:
    t = np.linspace(0.0, period, n1 + 1)

    def cross_time(tt: FloatArray) -> tuple[FloatArray, FloatArray]:
        gx, gy, psi = _fly_turn(np.float64(x), np.float64(y), np.float64(heading), s, tt, r,
                                omega, wind)
        return _straight_hits(gx, gy, psi, tt, target, v, wind)

    cross, _ = cross_time(t)
    k = np.flatnonzero(cross[:-1] * cross[1:] <= 0.0)
    if not k.size:
        return math.inf
    lo, hi = t[k], t[k + 1]
    sign_lo = np.sign(cross[k])
    for _ in range(_BISECT):
        mid = 0.5 * (lo + hi)
        c, _ = cross_time(mid)
        same = np.sign(c) == sign_lo
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    _, time = cross_time(0.5 * (lo + hi))
    return float(time.min(initial=math.inf))


def _ccs_rows(
    x: float, y: float, heading: float, s: float, target: tuple[float, ...], v: float,
    r: float, omega: float, wind: tuple[float, float], t1: FloatArray, n2: int, period: float,
) -> FloatArray:
    """For each t1: the fastest turn(s, t1)-turn(-s, t2)-straight hit over a t2 grid."""
    gx1, gy1, psi1 = _fly_turn(np.float64(x), np.float64(y), np.float64(heading), s, t1, r,
                               omega, wind)
    # the second turn starts at the first one's end; wind already carried t1 seconds
    t2 = np.linspace(0.0, period, n2 + 1)

    def cross_time(rows: npt.NDArray[np.intp], tt: FloatArray) -> tuple[FloatArray, FloatArray]:
        gx, gy, psi = _fly_turn(gx1[rows], gy1[rows], psi1[rows], -s, tt, r, omega, wind)
        return _straight_hits(gx, gy, psi, t1[rows] + tt, target, v, wind)

    rows_all = np.arange(t1.size)[:, None]
    cross, _ = cross_time(rows_all, t2[None, :])
    ri, ki = np.nonzero(cross[:, :-1] * cross[:, 1:] <= 0.0)
    out = np.full(t1.size, np.inf)
    if not ri.size:
        return out
    lo, hi = t2[ki], t2[ki + 1]
    sign_lo = np.sign(cross[ri, ki])
    for _ in range(_BISECT):
        mid = 0.5 * (lo + hi)
        c, _ = cross_time(ri, mid)
        same = np.sign(c) == sign_lo
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    _, time = cross_time(ri, 0.5 * (lo + hi))
    np.minimum.at(out, ri, time)
    return out


def _ccs(
    x: float, y: float, heading: float, s: float, target: tuple[float, ...], v: float,
    r: float, omega: float, wind: tuple[float, float], n: int, period: float,
) -> float:
    t1 = np.linspace(0.0, period, n + 1)
    times = _ccs_rows(x, y, heading, s, target, v, r, omega, wind, t1, n, period)
    k = int(np.argmin(times))
    best = float(times[k])
    if not math.isfinite(best):
        return math.inf
    lo, hi = t1[max(k - 1, 0)], t1[min(k + 1, n)]
    golden = (math.sqrt(5.0) - 1.0) / 2.0
    for _ in range(40):
        a = hi - golden * (hi - lo)
        b = lo + golden * (hi - lo)
        fa, fb = _ccs_rows(x, y, heading, s, target, v, r, omega, wind, np.array([a, b]), n,
                           period)
        best = min(best, float(fa), float(fb))
        if fa < fb:
            hi = b
        else:
            lo = a
    return best
