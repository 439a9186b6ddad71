"""GOSPA: the generalised optimal sub-pattern assignment distance between two point sets.

Rahmathullah, Garcia-Fernandez and Svensson, "Generalized optimal sub-pattern assignment
metric", FUSION 2017. For a set of track positions ``X`` and true positions ``Y``, a cut-off
``c > 0`` and an order ``p >= 1``, the ``alpha = 2`` form is

    d(X, Y) = ( min over gamma  sum_{(i, j) in gamma} d(x_i, y_j)^p
                                + c^p / 2 * (|X| + |Y| - 2 |gamma|) )^(1/p)

where ``gamma`` runs over the partial one-to-one assignments between ``X`` and ``Y`` and
``d`` is the Euclidean distance. Assigning a pair at distance ``d >= c`` costs at least as
much as leaving both unassigned (``c^p/2 + c^p/2``), so the optimum is the optimal
(rectangular) assignment on the cost ``min(d, c)^p``; in it a pair with ``d < c`` is a
match, and a pair with ``d >= c`` counts as one missed truth and one false track (at
``d == c`` both readings cost the same; it counts as unassigned). Every truth or track left
out by a rectangular assignment is missed or false. Then

    d(X, Y)^p = localisation^p + c^p / 2 * (missed + false),
    localisation = ( sum over matches of d^p )^(1/p).

scipy's ``linear_sum_assignment`` solves the assignment (exact, Jonker-Volgenant). With two
empty sets the distance is 0; with ``n`` points against none it is ``c / 2^(1/p) * n^(1/p)``.
Only ``alpha = 2`` is implemented: it is the form that splits into localisation, missed
and false.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

Point = tuple[float, float]


@dataclass(frozen=True)
class GospaResult:
    """The GOSPA distance and its parts (see the module docstring).

    Attributes:
        distance_m: ``d(X, Y)`` in metres.
        localisation_m: ``(sum over matches of d^p)^(1/p)`` in metres.
        missed: truths with no track within ``c``.
        false: tracks with no truth within ``c``.
        matches: the optimal assignment's matches ``(track index, truth index)`` (``d < c``),
            sorted by track index.
    """

    distance_m: float
    localisation_m: float
    missed: int
    false: int
    matches: tuple[tuple[int, int], ...] = ()


def _points(name: str, points: Sequence[Point]) -> np.ndarray:
    """Validate a sequence of (x, y) pairs into an (n, 2) float array."""
    rows: list[tuple[float, float]] = []
    for k, point in enumerate(points):
        try:
            x, y = point
        except (TypeError, ValueError):
            raise ValueError(f"{name}[{k}] must be an (x, y) pair, got {point!r}") from None
        for value in (x, y):
            if (
                isinstance(value, bool)
                or not isinstance(value, numbers.Real)
                or not math.isfinite(float(value))
            ):
                raise ValueError(f"{name}[{k}] must hold finite numbers, got {point!r}")
        rows.append((float(x), float(y)))
    return np.asarray(rows, dtype=float).reshape(len(rows), 2)


def _positive(name: str, value: float) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v) or v <= 0.0:
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return v


def gospa(
    tracks_xy: Sequence[Point],
    truth_xy: Sequence[Point],
    c_m: float = 150.0,
    p: float = 2.0,
    alpha: float = 2.0,
) -> GospaResult:
    """GOSPA distance (``alpha = 2``) between track positions and true positions.

    Args:
        tracks_xy: estimated positions (m).
        truth_xy: true positions (m).
        c_m: cut-off distance ``c`` (m), > 0.
        p: order, >= 1.
        alpha: must be 2 (the only form implemented).

    Raises:
        ValueError: a point is not a finite (x, y) pair, ``c_m <= 0``, ``p < 1`` or
            ``alpha != 2``.
    """
    c = _positive("c_m", c_m)
    order = _positive("p", p)
    if order < 1.0:
        raise ValueError(f"p must be >= 1, got {p!r}")
    if isinstance(alpha, bool) or not isinstance(alpha, numbers.Real) or float(alpha) != 2.0:
        raise ValueError(f"alpha must be 2 (the only GOSPA form implemented), got {alpha!r}")
    x = _points("tracks_xy", tracks_xy)
    y = _points("truth_xy", truth_xy)
    half_cp = c**order / 2.0
    matches: list[tuple[int, int]] = []
    loc_p = 0.0
    if len(x) and len(y):
        dist = np.hypot(x[:, None, 0] - y[None, :, 0], x[:, None, 1] - y[None, :, 1])
        from scipy.optimize import linear_sum_assignment  # only once a metric is computed

        rows, cols = linear_sum_assignment(np.minimum(dist, c) ** order)
        for i, j in zip(rows.tolist(), cols.tolist(), strict=True):
            if dist[i, j] < c:
                matches.append((i, j))
                loc_p += float(dist[i, j]) ** order
    false = len(x) - len(matches)
    missed = len(y) - len(matches)
    total_p = loc_p + half_cp * (missed + false)
    return GospaResult(
        distance_m=total_p ** (1.0 / order),
        localisation_m=loc_p ** (1.0 / order),
        missed=missed,
        false=false,
        matches=tuple(sorted(matches)),
    )
