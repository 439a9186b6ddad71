"""Arrival error: when the core predicted a vehicle would reach its aim point, against when
it got there. Shared by every frontend through :class:`~groundstation.core.metrics.MetricsRecorder`.

Each :class:`~groundstation.core.commands.FlyToTarget` carries ``eta_s``, the mission time
the core predicts the vehicle reaches the aim point ``p``. The camera sees what lies within
the FOV radius ``r`` of the vehicle, so the vehicle is *there* once its distance to ``p``
drops to ``r``. Its positions come as samples (the offline simulator: the true position
every step; the daemon: each telemetry position); the entry time ``t_in`` is interpolated
linearly in distance between the two samples that bracket it.

Comparing ``t_in`` with ``eta_s`` directly would count the last ``r`` metres of flight as
error (150 m at 22 m/s is 6.8 s, more than the 2 s one wants to resolve), so the flown
arrival at ``p`` is::

    t_arr = t_in + r / v_g,        error = t_arr - eta_s      (> 0: late)

with ``v_g`` the ground speed over the bracketing samples (chord / time): the time to cover
the last ``r`` at the speed the vehicle is actually flying. It is exact for a straight final
approach at constant ground speed (the pass-over, where guidance points the ground course at
``p``), and it uses the vehicle's measured speed, never the planner's, so a planner's wind
model does not grade its own prediction. With a loiter mission the vehicle heads for the
circle rather than ``p``; ``t_arr`` is then where a straight approach would have reached
``p``: a guidance offset of a second or two, the same whatever the planner assumed (a calm
run shows it).

Counted: commands whose vehicle entered the FOV of the aim point before anything
redirected it. Not counted, and reported in ``arrivals``: ``superseded`` (a newer
FlyToTarget, a release or a send-home came first), ``inside_at_command`` (the vehicle was
already within ``r`` of the new aim point when told: nothing to predict), ``unfinished``
(still on its way when the run ended). A command without ``eta_s`` is not followed.

Reported: ``arrival_error_s`` ``{median, p90}`` of ``|error|``, ``arrival_bias_s`` the
median signed error (None when nothing was counted). The same split by leg:
``arrival_error_first_s`` / ``arrival_error_later_s`` ``{median, p90, max, counted}``
(None when none was counted) and ``arrival_bias_first_s`` / ``arrival_bias_later_s``. A
vehicle's *first leg* is its first counted arrival: its flight from the join to the first
aim point it reached (planned at the join, before its own wind estimate exists:
docs/wind.md, "The first leg"), measured against the command in force when it arrived (a
leg replanned on the way counts with its replanned prediction); every later counted
arrival is a later leg. Percentiles interpolate linearly
between order statistics (numpy's default): ``p(q) = x[i] + (x[i+1] - x[i]) f``,
``i + f = (n - 1) q``.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

__all__ = ["ArrivalTracker", "percentile"]


def percentile(values: Sequence[float], q: float) -> float:
    """Linear-interpolation percentile of a non-empty sequence, ``q`` in [0, 1]."""
    ordered = sorted(values)
    pos = (len(ordered) - 1) * q
    i = math.floor(pos)
    if i >= len(ordered) - 1:
        return ordered[-1]
    return ordered[i] + (ordered[i + 1] - ordered[i]) * (pos - i)


@dataclass
class _Pending:
    t_s: float
    target: str
    aim_xy_m: tuple[float, float]
    eta_s: float
    fov_radius_m: float


@dataclass
class ArrivalTracker:
    """Follows each vehicle's current FlyToTarget until it arrives or is redirected."""

    errors_s: list[float] = field(default_factory=list)
    first_errors_s: list[float] = field(default_factory=list)
    later_errors_s: list[float] = field(default_factory=list)
    """``errors_s`` split into the first legs and the later ones (module docstring)."""
    superseded: int = 0
    inside_at_command: int = 0
    _pending: dict[str, _Pending] = field(default_factory=dict)
    _last: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    _arrived: set[str] = field(default_factory=set)

    def commanded(self, t_s: float, vehicle: str, target: str, x_m: float, y_m: float,
                  eta_s: float | None, fov_radius_m: float) -> None:
        """``vehicle`` was sent to the aim point (x_m, y_m), predicted for ``eta_s``."""
        if self._pending.pop(vehicle, None) is not None:
            self.superseded += 1
        if eta_s is None or not all(math.isfinite(v) for v in (x_m, y_m, eta_s)):
            return
        last = self._last.get(vehicle)
        if last is not None and math.dist(last[1:], (x_m, y_m)) <= fov_radius_m:
            self.inside_at_command += 1
            return
        self._pending[vehicle] = _Pending(t_s, target, (x_m, y_m), eta_s, fov_radius_m)

    def abandoned(self, vehicle: str) -> None:
        """``vehicle`` was released or sent home: its command will not be flown."""
        if self._pending.pop(vehicle, None) is not None:
            self.superseded += 1

    def position(self, t_s: float, vehicle: str, x_m: float, y_m: float) -> None:
        """A position sample of ``vehicle`` (true or telemetry) at mission time ``t_s``."""
        if not (math.isfinite(x_m) and math.isfinite(y_m) and math.isfinite(t_s)):
            return
        last = self._last.get(vehicle)
        if last is not None and t_s <= last[0]:
            return  # a repeated or late sample: nothing to interpolate over
        self._last[vehicle] = (t_s, x_m, y_m)
        pending = self._pending.get(vehicle)
        if pending is None:
            return
        r = pending.fov_radius_m
        d1 = math.dist((x_m, y_m), pending.aim_xy_m)
        if d1 > r:
            return
        del self._pending[vehicle]
        d0 = math.inf if last is None else math.dist(last[1:], pending.aim_xy_m)
        if last is None or d0 <= r:  # no position outside since the command
            self.inside_at_command += 1
            return
        t0, x0, y0 = last
        dt = t_s - t0
        t_in = t0 + dt * (d0 - r) / (d0 - d1)
        ground_m_s = math.dist((x0, y0), (x_m, y_m)) / dt
        error = t_in + r / ground_m_s - pending.eta_s
        self.errors_s.append(error)
        first = vehicle not in self._arrived
        self._arrived.add(vehicle)
        (self.first_errors_s if first else self.later_errors_s).append(error)

    def to_dict(self) -> dict[str, Any]:
        """``arrival_error_s``, ``arrival_bias_s``, ``arrivals`` and the split by leg
        (module docstring)."""
        errors = self.errors_s
        absolute = [abs(e) for e in errors]
        first, later = self.first_errors_s, self.later_errors_s
        return {
            "arrival_error_s": {
                "median": statistics.median(absolute),
                "p90": percentile(absolute, 0.9),
            } if errors else None,
            "arrival_bias_s": statistics.median(errors) if errors else None,
            "arrival_error_first_s": _summary(first),
            "arrival_bias_first_s": statistics.median(first) if first else None,
            "arrival_error_later_s": _summary(later),
            "arrival_bias_later_s": statistics.median(later) if later else None,
            "arrivals": {
                "counted": len(errors),
                "superseded": self.superseded,
                "inside_at_command": self.inside_at_command,
                "unfinished": len(self._pending),
            },
        }


def _summary(errors: Sequence[float]) -> dict[str, float | int] | None:
    """``{median, p90, max, counted}`` of ``|error|`` (None when nothing was counted)."""
    if not errors:
        return None
    absolute = [abs(e) for e in errors]
    return {"median": statistics.median(absolute), "p90": percentile(absolute, 0.9),
            "max": max(absolute), "counted": len(absolute)}
