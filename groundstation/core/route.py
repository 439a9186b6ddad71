"""Missions that fly through the next targets of a vehicle's planned route (issue 28).

A discovery vehicle passes a target every 15-25 s (its own camera covers a search cell from
150 m out), so a mission that held one target was followed by a new mission per target.
Instead a pass's mission holds the head of the route and up to ``CoreConfig.route_cells``
targets that follow it in the plan (plain waypoints, ``FlyToTarget.through``: a search
cell's centre, an iceberg where it is predicted when the vehicle gets there), and the core
follows the vehicle along it:

* **Moving on is not a new mission.** A plan whose first target for the vehicle is a
  target its mission already flies through, every earlier item of that mission having been
  seen since the mission was sent (a cell covered by a camera footprint, a track measured),
  only moves the core's record of the vehicle on (:func:`moved_on`); nothing is uploaded.
* **A new head is.** Any other first target (a track that is not the next cell, a cell
  off the mission, a replan that skips an item not yet seen) is a new mission, under the
  upload rule of ``core/uploads.py``.
* **The end of the mission** (its last item reached: the ``LoiterEnded`` of a pass) means
  the vehicle flew through every item; the core's record moves to the last one.
* **A vehicle with points of its route ahead waits longer** for a new head
  (``CoreConfig.route_min_interval_s``, 60 s, instead of ``upload_min_interval_s``): it
  does not circle over water it just passed meanwhile, it flies on along its route.

Only passes fly through (``loiter_s`` < 1 s), and only in runs with search cells (the
discovery rhythm; a tracking-only run keeps one target per mission); a visit that loiters
ends its mission as before. Pure: no clock, no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from groundstation.core.commands import ThroughPoint

__all__ = ["moved_on", "through_points"]


def through_points(route: tuple[str, ...], limit: int | None,
                   head_xy_m: tuple[float, float], head_t_s: float, speed_m_s: float,
                   where: Callable[[str], tuple[tuple[float, float], tuple[float, float]]
                                   | None]) -> tuple[ThroughPoint, ...]:
    """The targets that follow the head ``route[0]`` in ``route``, up to ``limit``, as
    waypoints: each where it is predicted when the vehicle gets there, flying straight on
    at ``speed_m_s`` from the head's aim ``head_xy_m`` reached ``head_t_s`` s from now
    (``where``: a target's position and drift velocity now; None: gone, the list stops).
    A search cell does not move; an iceberg drifts < 1 m/s, so the straight-leg estimate
    (one correction for the drift) is well inside the camera's footprint."""
    out: list[ThroughPoint] = []
    xy, t_s = head_xy_m, head_t_s
    for target in route[1:1 + (limit or 0)]:
        now = where(target)
        if now is None:
            break
        (x_m, y_m), (vx_m_s, vy_m_s) = now
        t_arr_s = t_s + math.dist(xy, (x_m + vx_m_s * t_s, y_m + vy_m_s * t_s)) / speed_m_s
        xy = (x_m + vx_m_s * t_arr_s, y_m + vy_m_s * t_arr_s)
        t_s = t_arr_s
        out.append(ThroughPoint(target, xy[0], xy[1]))
    return tuple(out)


def moved_on(head: str | None, through: tuple[str, ...], target: str,
             seen: Callable[[str], bool]) -> int | None:
    """``target`` is item k (1-based) of ``through``, the mission after ``head``, and every
    earlier item of the mission (``head`` and ``through[:k-1]``) was ``seen`` since the
    mission was sent: k, the vehicle moved on along the mission it has. None: it did not."""
    if head is None or target not in through:
        return None
    k = through.index(target) + 1
    if all(seen(item) for item in (head, *through[:k - 1])):
        return k
    return None
