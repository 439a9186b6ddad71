"""Dubins distance from a pose to a point, free final heading (closed form).

A vehicle at (x, y) with heading psi (counter-clockwise from +x) and minimum turn radius r
flies to point P. With the final heading free, the shortest path is of type CS (turn, then
straight) or CC (turn, then turn the other way) (Bui, Boissonnat, Soueres, Laumond 1994).

Let s = +1 for a left (counter-clockwise) first turn and s = -1 for a right one. The first
turning circle has centre c1 = (x, y) + s r (-sin psi, cos psi); D = |P - c1| and
phi = atan2(P - c1).

CS (needs D >= r): the vehicle leaves the circle at the tangent point seen from P,
    length = r * a + sqrt(D^2 - r^2), with the arc a = mod_2pi(s (theta_t - theta_0)),
    theta_0 = psi - s pi/2 (start radial angle) and theta_t = phi - s acos(r / D).

CC (needs r <= D <= 3 r): after an arc a on c1 with radial unit vector u the vehicle
    switches to the opposite circle c2 = c1 + 2 r u, which passes through P when
    u . (P - c1) = (D^2 + 3 r^2) / (4 r), i.e. angle(u) = phi +- acos((D^2 + 3 r^2) / (4 r D));
    the second arc b runs from radial angle angle(u) + pi to angle(P - c2) turning with -s,
    length = r (a + b).

The distance is the minimum over the feasible candidates (both s, CS and both CC roots).
A point inside one circle is outside the other (they only touch at the start), so some
candidate always exists. The distance is discontinuous at the start point itself: the
point is at distance 0, a point a hair behind it needs nearly a full circle.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

_TWO_PI = 2.0 * math.pi


def _mod2pi(angle: float) -> float:
    out = math.fmod(angle, _TWO_PI)
    if out < 0.0:
        out += _TWO_PI
    # fmod can return 2 pi - tiny for -tiny inputs: keep a full turn out of round-off.
    if out >= _TWO_PI - 1e-12:
        out = 0.0
    return out


def dubins_distance_to_point(
    x_m: float, y_m: float, heading_rad: float, px_m: float, py_m: float, turn_radius_m: float
) -> float:
    """Shortest Dubins path length (m) from pose (x_m, y_m, heading_rad) to (px_m, py_m)."""
    r = turn_radius_m
    if r <= 0.0:
        return math.hypot(px_m - x_m, py_m - y_m)
    if px_m == x_m and py_m == y_m:
        return 0.0
    # round-off in the circle centres: treat |D - r| below tol as D = r
    tol = 1e-12 * (r + abs(x_m) + abs(y_m) + abs(px_m) + abs(py_m))
    best = math.inf
    sin_h, cos_h = math.sin(heading_rad), math.cos(heading_rad)
    for s in (1.0, -1.0):
        cx = x_m - s * r * sin_h
        cy = y_m + s * r * cos_h
        dx, dy = px_m - cx, py_m - cy
        dist = math.hypot(dx, dy)
        if abs(dist - r) <= tol:
            dist = r
        phi = math.atan2(dy, dx)
        theta0 = heading_rad - s * math.pi / 2.0
        if dist >= r:
            theta_t = phi - s * math.acos(min(1.0, r / dist))
            arc = _mod2pi(s * (theta_t - theta0))
            best = min(best, r * arc + math.sqrt(max(0.0, dist * dist - r * r)))
        if r <= dist <= 3.0 * r:
            k = min(1.0, (dist * dist + 3.0 * r * r) / (4.0 * r * dist))
            beta = math.acos(k)
            for sign in (1.0, -1.0):
                ang_u = phi + sign * beta
                arc1 = _mod2pi(s * (ang_u - theta0))
                c2x = cx + 2.0 * r * math.cos(ang_u)
                c2y = cy + 2.0 * r * math.sin(ang_u)
                end = math.atan2(py_m - c2y, px_m - c2x)
                arc2 = _mod2pi(-s * (end - (ang_u + math.pi)))
                best = min(best, r * (arc1 + arc2))
    return best


def dubins_distances_to_points(
    x_m: FloatArray,
    y_m: FloatArray,
    heading_rad: FloatArray,
    px_m: FloatArray,
    py_m: FloatArray,
    turn_radius_m: float,
) -> FloatArray:
    """:func:`dubins_distance_to_point` on numpy arrays (broadcast together): the minimum
    of :func:`dubins_candidates_to_points`, 0 at the start point itself; agrees with the
    scalar function to ~1e-15 relative (tested). Used where thousands of distances are
    needed per plan (the wind costs' root finding)."""
    r = float(turn_radius_m)
    x, y, h, px, py = np.broadcast_arrays(
        *(np.asarray(a, dtype=float) for a in (x_m, y_m, heading_rad, px_m, py_m))
    )
    if r <= 0.0:
        return np.asarray(np.hypot(px - x, py - y), dtype=float)
    best = dubins_candidates_to_points(x, y, h, px, py, r).min(axis=0)
    return np.where((px == x) & (py == y), 0.0, best)


CANDIDATES = ("LS", "LR+", "LR-", "RS", "RL+", "RL-")
"""The free-heading Dubins candidates, in the order of dubins_candidates_to_points' rows:
turn left then straight, left-right with either root of the switching point, and the
same turning right first."""


def dubins_candidates_to_points(
    x_m: FloatArray,
    y_m: FloatArray,
    heading_rad: FloatArray,
    px_m: FloatArray,
    py_m: FloatArray,
    turn_radius_m: float,
) -> FloatArray:
    """Lengths (m) of the six candidate paths of the module docstring, shape (6, ...)
    (rows as CANDIDATES); inf where a candidate does not exist (CS: the point inside its
    first circle; CC: the point farther than 3 r from it). Each row is continuous in the
    point inside its domain, except where a turn's arc wraps from 2 pi to 0. r > 0."""
    r = float(turn_radius_m)
    x, y, h, px, py = np.broadcast_arrays(
        *(np.asarray(a, dtype=float) for a in (x_m, y_m, heading_rad, px_m, py_m))
    )
    tol = 1e-12 * (r + np.abs(x) + np.abs(y) + np.abs(px) + np.abs(py))
    out = np.full((6, *x.shape), np.inf)
    sin_h, cos_h = np.sin(h), np.cos(h)
    with np.errstate(invalid="ignore", divide="ignore"):
        for row, s in ((0, 1.0), (3, -1.0)):
            cx = x - s * r * sin_h
            cy = y + s * r * cos_h
            dx, dy = px - cx, py - cy
            dist = np.hypot(dx, dy)
            dist = np.where(np.abs(dist - r) <= tol, r, dist)
            phi = np.arctan2(dy, dx)
            theta0 = h - s * (math.pi / 2.0)
            theta_t = phi - s * np.arccos(np.minimum(1.0, r / dist))
            arc = _mod2pi_array(s * (theta_t - theta0))
            cs = r * arc + np.sqrt(np.maximum(0.0, dist * dist - r * r))
            out[row] = np.where(dist >= r, cs, np.inf)
            cc_ok = (dist >= r) & (dist <= 3.0 * r)
            k = np.minimum(1.0, (dist * dist + 3.0 * r * r) / (4.0 * r * dist))
            beta = np.arccos(k)
            for offset, sign in ((1, 1.0), (2, -1.0)):
                ang_u = phi + sign * beta
                arc1 = _mod2pi_array(s * (ang_u - theta0))
                c2x = cx + 2.0 * r * np.cos(ang_u)
                c2y = cy + 2.0 * r * np.sin(ang_u)
                end = np.arctan2(py - c2y, px - c2x)
                arc2 = _mod2pi_array(-s * (end - (ang_u + math.pi)))
                out[row + offset] = np.where(cc_ok, r * (arc1 + arc2), np.inf)
    return out


def _mod2pi_array(angle: FloatArray) -> FloatArray:
    """_mod2pi element-wise."""
    out = np.fmod(angle, _TWO_PI)
    out = np.where(out < 0.0, out + _TWO_PI, out)
    return np.where(out >= _TWO_PI - 1e-12, 0.0, out)
