"""Each vehicle's energy: what its battery says, how fast it drains, and how long it can
stay out before it must turn for the ship.

The model is the remaining charge ``r`` (%) falling at a rate ``c`` (%/s) in flight. ``c``
starts at the configured endurance's, ``c_0 = 100 / endurance_s``, with a standard
deviation of 25 % of it, and is learnt from the vehicle's reports (``BatteryReport``)
with a scalar Kalman filter: between an anchor reading ``(t_a, r_a)`` and a reading
``(t, r)`` at least :data:`MIN_SPAN_S` later, both in flight,

    m = (r_a - r) / (t - t_a),   var(m) = 2 sigma_r^2 / (t - t_a)^2

with ``sigma_r`` = :data:`READING_SIGMA_PCT` (ArduPilot reports whole percents: the
quantisation's 0.29 % and the estimator's own noise); the rate's variance grows by
``(RATE_DRIFT * c_0)^2`` per minute between updates (the drain changes with airspeed, wind
and climbs). Between readings the charge is extrapolated, ``r(t) = r_a' - c (t - t_r)``
from the last reading ``(t_r, r_a')``.

Where a vehicle reports nothing useful (no remaining %, or garbage), its charge is
*assumed*: full when first seen in flight, draining at ``c_0``; a vehicle whose reports stop
goes on being extrapolated. Every decision uses the cautious rate ``c_hi = c + 2 sd(c)``,
so the less the model knows, the earlier it sends the vehicle home.

A vehicle at ``t`` with charge ``r(t)``, reserve ``r_res`` and a flight of ``T_ret`` seconds
to the ship's predicted position (in wind, against the ship's motion) has

    spare_s(t) = (r(t) - r_res) / c_hi - (T_ret + RETURN_MARGIN_S)

seconds before it must turn home; a leg of ``T_leg`` seconds (flight, loiter) then a return of
``T_ret'`` from its end is flyable when ``(r(t) - r_res) / c_hi >= T_leg + T_ret' +
RETURN_MARGIN_S``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["RETURN_MARGIN_S", "EnergyView", "VehicleEnergy"]

MIN_SPAN_S = 20.0
READING_SIGMA_PCT = 0.5
RATE_DRIFT = 0.05
PRIOR_SD_SHARE = 0.25
RETURN_MARGIN_S = 60.0
"""Added to every return: the approach to the ship and a turn or two waiting for it."""


@dataclass(frozen=True)
class EnergyView:
    """What the operator sees of a vehicle's energy at ``t_s``."""

    t_s: float
    remaining_pct: float
    rate_pct_min: float
    """The learnt drain (%/min)."""
    rate_sd_pct_min: float
    source: str
    """``reported`` (from the vehicle's battery) or ``assumed`` (configured endurance)."""
    endurance_left_s: float
    """Flight time until the reserve, at the cautious rate."""
    return_s: float | None
    """Flight time to the ship's predicted position now (None: ship unknown)."""
    turn_home_s: float | None
    """Mission time by which it must turn home (None: ship unknown)."""
    reachable: bool
    """It can still reach the ship with its reserve."""


class VehicleEnergy:
    """One vehicle's charge and drain (module docstring)."""

    def __init__(self, endurance_s: float, reserve_pct: float) -> None:
        self.reserve_pct = reserve_pct
        self.c0_pct_s = 100.0 / endurance_s
        self.rate_pct_s = self.c0_pct_s
        self.rate_var = (PRIOR_SD_SHARE * self.c0_pct_s) ** 2
        self._anchor: tuple[float, float] | None = None  # (t, r) in flight
        self._last: tuple[float, float] | None = None  # the newest reading (t, r)
        self._rate_t_s: float | None = None
        self.reported = False
        self.flying_since_s: float | None = None

    @property
    def rate_sd_pct_s(self) -> float:
        return math.sqrt(self.rate_var)

    @property
    def cautious_rate_pct_s(self) -> float:
        """``c_hi = c + 2 sd(c)``, at least half the configured endurance's rate."""
        return max(self.rate_pct_s + 2.0 * self.rate_sd_pct_s, 0.5 * self.c0_pct_s)

    def fresh(self, t_s: float, remaining_pct: float | None = None) -> None:
        """A new battery (a spare on deck): forget the flight's anchor, keep what was
        learnt of the rate."""
        self._anchor = None
        self.flying_since_s = None
        if remaining_pct is not None and _valid_pct(remaining_pct):
            self._last = (t_s, remaining_pct)
            self.reported = True
        else:
            self._last = None
            self.reported = False

    def flying(self, t_s: float) -> None:
        """The vehicle is seen in flight (its first sighting starts the assumed drain)."""
        if self.flying_since_s is None:
            self.flying_since_s = t_s
            if self._last is not None:
                self._anchor = (t_s, self.remaining_pct(t_s))

    def landed(self) -> None:
        self.flying_since_s = None
        self._anchor = None

    def report(self, t_s: float, remaining_pct: float | None) -> bool:
        """A battery reading; False when it says nothing useful (None, NaN, out of range)."""
        if remaining_pct is None or not _valid_pct(remaining_pct):
            return False
        self.reported = True
        self._last = (t_s, float(remaining_pct))
        if self.flying_since_s is None:
            return True
        if self._anchor is None:
            self._anchor = (t_s, float(remaining_pct))
            return True
        t_a, r_a = self._anchor
        span = t_s - t_a
        if span < MIN_SPAN_S:
            return True
        self._drift(t_s)
        measured = (r_a - remaining_pct) / span
        var_m = 2.0 * READING_SIGMA_PCT**2 / span**2
        gain = self.rate_var / (self.rate_var + var_m)
        self.rate_pct_s += gain * (measured - self.rate_pct_s)
        self.rate_pct_s = max(self.rate_pct_s, 0.0)
        self.rate_var *= 1.0 - gain
        self._anchor = (t_s, float(remaining_pct))
        return True

    def _drift(self, t_s: float) -> None:
        if self._rate_t_s is not None and t_s > self._rate_t_s:
            minutes = (t_s - self._rate_t_s) / 60.0
            self.rate_var += minutes * (RATE_DRIFT * self.c0_pct_s) ** 2
        self._rate_t_s = t_s

    def remaining_pct(self, t_s: float) -> float:
        """The charge now: the last reading extrapolated in flight; assumed full when
        nothing was ever reported (module docstring)."""
        if self._last is not None:
            t_r, r = self._last
        elif self.flying_since_s is not None:
            t_r, r = self.flying_since_s, 100.0
        else:
            return 100.0
        if self.flying_since_s is not None:
            start = max(t_r, self.flying_since_s)
            r -= self.rate_pct_s * max(0.0, t_s - start)
        return max(0.0, r)

    def endurance_left_s(self, t_s: float) -> float:
        """Flight seconds until the reserve, at the cautious rate (may be negative)."""
        return (self.remaining_pct(t_s) - self.reserve_pct) / self.cautious_rate_pct_s

    def spare_s(self, t_s: float, return_s: float) -> float:
        """Seconds before it must turn home, with a return of ``return_s`` from here."""
        return self.endurance_left_s(t_s) - (return_s + RETURN_MARGIN_S)

    def expected_spare_s(self, t_s: float, return_s: float) -> float:
        """:meth:`spare_s` at the learnt rate ``c`` itself (for planning reliefs, never for
        the decision to go home)."""
        rate = max(self.rate_pct_s, 0.5 * self.c0_pct_s)
        left = (self.remaining_pct(t_s) - self.reserve_pct) / rate
        return left - (return_s + RETURN_MARGIN_S)

    def leg_ok(self, t_s: float, leg_s: float, return_after_s: float) -> bool:
        """A leg of ``leg_s`` then a return of ``return_after_s`` keeps the reserve."""
        return self.endurance_left_s(t_s) >= leg_s + return_after_s + RETURN_MARGIN_S

    def view(self, t_s: float, return_s: float | None) -> EnergyView:
        left = self.endurance_left_s(t_s)
        turn = None if return_s is None else t_s + left - (return_s + RETURN_MARGIN_S)
        reachable = True if return_s is None else (
            self.remaining_pct(t_s) / self.cautious_rate_pct_s >= return_s)
        return EnergyView(t_s, self.remaining_pct(t_s), self.rate_pct_s * 60.0,
                          self.rate_sd_pct_s * 60.0,
                          "reported" if self.reported else "assumed", left, return_s, turn,
                          reachable)


def _valid_pct(value: float) -> bool:
    return isinstance(value, int | float) and math.isfinite(value) and 0.0 <= value <= 100.0
