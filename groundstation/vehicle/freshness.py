"""One vehicle's telemetry freshness, sans-IO: how old its newest position is, whether it is
*lagging*, and the pose to plan it from while it is.

The age comes from :class:`~groundstation.mavlink.telemetry_age.TelemetryAge` (the vehicle's
``time_boot_ms`` against the mission time floe applied each frame at). The newest position
is the reducer's (``VehicleSnapshot.position_boot_ms``: a position older than the newest is
already dropped there), so in a backlog the newest position wins, however old.

**Lagging**: its newest position is older than ``lag_threshold_s`` although frames of its
autopilot keep arriving (one was heard when that position was already more than
``lag_threshold_s`` old: a backlog, or a flood of frames that carry no position), and the
link is not lost. A silent link is not lagging: it is degraded, then lost. It ends when a
position at most half ``lag_threshold_s`` old arrives (:data:`FRESH_FRACTION`).

**The prediction** (:meth:`Freshness.predict`), the pose the core is given instead of a
fix older than ``lag_threshold_s``: the fix moved on for its age (at most
``max_predict_s``):

* flying floe's verified mission (``aim``): along the straight line to the aim point at its
  groundspeed, and once there (or if the fix was already within the loiter radius plus
  ``loiter_margin_m`` of it) the loiter's centre, heading kept, with ``sigma_m`` at least the
  loiter radius (where on the circle is unknown);
* otherwise dead reckoning on its groundspeed vector (GLOBAL_POSITION_INT ``vx``/``vy``,
  else the groundspeed along its heading).

Its uncertainty grows with the age: ``sigma_m = sigma0_m + sigma_rate * speed * age``
(a plane that may have turned: a third of the distance flown by default).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from groundstation.mavlink.telemetry_age import TelemetryAge, TelemetryAgeSettings
from groundstation.mavlink.telemetry_events import VehicleSnapshot

__all__ = ["FRESH_FRACTION", "Freshness", "FreshnessChange", "PredictedPose"]

FRESH_FRACTION = 0.5
"""Lagging ends on a position at most this fraction of ``lag_threshold_s`` old (hysteresis:
a backlog's bursts must not make it start and end at every burst)."""


@dataclass(frozen=True)
class PredictedPose:
    """A pose predicted from a fix ``fix_age_s`` old (local ENU m, heading CCW from east)."""

    x_m: float
    y_m: float
    heading_rad: float
    sigma_m: float
    fix_age_s: float
    how: str
    """``dead_reckoning``, ``to_aim`` or ``loiter``."""


@dataclass(frozen=True)
class FreshnessChange:
    """Lagging started (``lagging`` True) or ended, at ``t_s``, with the age then."""

    t_s: float
    lagging: bool
    age_s: float
    lagged_s: float = 0.0
    worst_age_s: float = 0.0


class Freshness:
    """See the module docstring. Fed every frame's ``time_boot_ms``; asked at each tick."""

    def __init__(
        self,
        lag_threshold_s: float = 2.0,
        *,
        max_predict_s: float = 60.0,
        sigma0_m: float = 5.0,
        sigma_rate: float = 1.0 / 3.0,
        loiter_margin_m: float = 60.0,
        clock: TelemetryAgeSettings | None = None,
    ) -> None:
        self.lag_threshold_s = lag_threshold_s
        self.max_predict_s = max_predict_s
        self.sigma0_m = sigma0_m
        self.sigma_rate = sigma_rate
        self.loiter_margin_m = loiter_margin_m
        self.clock = TelemetryAge(clock)
        self.lagging = False
        self._since_s = 0.0
        self._worst_s = 0.0
        self.lag_spells = 0
        """Times the vehicle started lagging (for the run's figures)."""

    def frame(self, boot_ms: int, t_s: float) -> None:
        """A frame of the autopilot that carries its clock, applied at ``t_s``."""
        self.clock.observe(boot_ms, t_s)

    def reset(self) -> None:
        """The autopilot rebooted: its clock starts again."""
        self.clock.reset()

    def fix_age_s(self, snap: VehicleSnapshot, now_s: float) -> float | None:
        """How old its newest position is at ``now_s`` (None: no position, or no clock)."""
        if snap.position_boot_ms is None or snap.x_m is None or snap.y_m is None:
            return None
        return self.clock.age_s(snap.position_boot_ms, now_s)

    def stale(self, snap: VehicleSnapshot, now_s: float) -> float | None:
        """The fix's age if it is too old to plan from (> ``lag_threshold_s``), else None."""
        age = self.fix_age_s(snap, now_s)
        return age if age is not None and age > self.lag_threshold_s else None

    def assess(
        self, snap: VehicleSnapshot, now_s: float, link_lost: bool
    ) -> FreshnessChange | None:
        """Whether lagging started or ended at ``now_s`` (see the module docstring)."""
        age = self.fix_age_s(snap, now_s)
        if self.lagging:
            if age is not None:
                self._worst_s = max(self._worst_s, age)
            if age is None or age <= self.lag_threshold_s * FRESH_FRACTION:
                self.lagging = False
                return FreshnessChange(now_s, False, age or 0.0, now_s - self._since_s,
                                       self._worst_s)
            return None
        if age is None or age <= self.lag_threshold_s or link_lost:
            return None
        produced = self.clock.produced_s(snap.position_boot_ms or 0, now_s)
        heard = snap.last_heard_s
        if produced is None or heard is None or heard - produced <= self.lag_threshold_s:
            return None  # nothing heard since it went stale: silence, not lag
        self.lagging = True
        self.lag_spells += 1
        self._since_s = now_s
        self._worst_s = age
        return FreshnessChange(now_s, True, age)

    def predict(
        self,
        snap: VehicleSnapshot,
        now_s: float,
        aim_xy_m: tuple[float, float] | None = None,
        loiter_radius_m: float = 0.0,
    ) -> PredictedPose | None:
        """The fix predicted to ``now_s`` (None when there is no stale fix to predict)."""
        age = self.stale(snap, now_s)
        if age is None or snap.x_m is None or snap.y_m is None:
            return None
        dt = min(age, self.max_predict_s)
        heading = snap.heading_rad if snap.heading_rad is not None else 0.0
        ve, vn = snap.ve_m_s, snap.vn_m_s
        if ve is None or vn is None:
            speed = snap.speed_m_s or 0.0
            ve, vn = speed * math.cos(heading), speed * math.sin(heading)
        speed = math.hypot(ve, vn)
        sigma = self.sigma0_m + self.sigma_rate * speed * age
        x, y = snap.x_m, snap.y_m
        if aim_xy_m is not None:
            ax, ay = aim_xy_m
            dist = math.hypot(ax - x, ay - y)
            there = dist <= loiter_radius_m + self.loiter_margin_m
            if there or speed * dt >= dist - loiter_radius_m:
                return PredictedPose(ax, ay, heading, max(sigma, loiter_radius_m), age, "loiter")
            bearing = math.atan2(ay - y, ax - x)
            travel = speed * dt
            return PredictedPose(x + travel * math.cos(bearing), y + travel * math.sin(bearing),
                                 bearing, sigma, age, "to_aim")
        return PredictedPose(x + ve * dt, y + vn * dt, heading, sigma, age, "dead_reckoning")
