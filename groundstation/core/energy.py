"""Each vehicle's energy: what its battery says, how fast it drains, and how long it can
stay out before it must turn for the ship.

The model is the remaining charge ``r`` (%) falling at a rate ``c`` (%/s) in flight. The
configured endurance gives the prior ``c_0 = 100 / endurance_s`` with a standard deviation
``sd_0`` of 25 % of it. The vehicle's readings in flight (``BatteryReport``) over the last
:data:`WINDOW_S` seconds give a least-squares slope ``m`` with the standard error

    se(m)^2 = sigma_r^2 / sum_i (t_i - t_mean)^2

(``sigma_r`` = :data:`READING_SIGMA_PCT`: ArduPilot reports whole percents, a quantisation
of 0.29 %, and its estimator has noise of its own). The rate is the precision-weighted
combination of the two,

    1 / var(c) = 1 / sd_0^2 + 1 / se(m)^2,   c = var(c) (c_0 / sd_0^2 + m / se(m)^2),

so a vehicle that reports nothing keeps the configured rate and its wide margin, and one
that reports for ten minutes is known to about a percent. Between readings the charge is
extrapolated from the last one, ``r(t) = r_last - c (t - t_last)``.

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
from collections import deque
from dataclasses import dataclass

__all__ = ["RETURN_MARGIN_S", "EnergyView", "VehicleEnergy"]

WINDOW_S = 600.0
MIN_SPAN_S = 60.0
"""A slope needs readings spanning at least this."""
READING_SIGMA_PCT = 0.5
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
        self.prior_var = (PRIOR_SD_SHARE * self.c0_pct_s) ** 2
        self.rate_pct_s = self.c0_pct_s
        self.rate_var = self.prior_var
        self._window: deque[tuple[float, float]] = deque()  # readings in flight (t, r)
        self._last: tuple[float, float] | None = None  # the newest reading (t, r)
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
        """A new battery (a spare on deck): forget the last flight's readings, keep the
        rate learnt from them."""
        self._window.clear()
        self.flying_since_s = None
        if remaining_pct is not None and _valid_pct(remaining_pct):
            self._last = (t_s, float(remaining_pct))
            self.reported = True
        else:
            self._last = None
            self.reported = False

    def flying(self, t_s: float) -> None:
        """The vehicle is seen in flight (its first sighting starts the assumed drain)."""
        if self.flying_since_s is None:
            self.flying_since_s = t_s

    def landed(self) -> None:
        self.flying_since_s = None
        self._window.clear()

    def report(self, t_s: float, remaining_pct: float | None) -> bool:
        """A battery reading; False when it says nothing useful (None, NaN, out of range)."""
        if remaining_pct is None or not _valid_pct(remaining_pct):
            return False
        self.reported = True
        self._last = (t_s, float(remaining_pct))
        if self.flying_since_s is None:
            return True
        self._window.append(self._last)
        while self._window and self._window[0][0] < t_s - WINDOW_S:
            self._window.popleft()
        self._learn()
        return True

    def _learn(self) -> None:
        """The prior and the window's slope, combined (module docstring)."""
        n = len(self._window)
        if n < 3 or self._window[-1][0] - self._window[0][0] < MIN_SPAN_S:
            return
        t_mean = sum(t for t, _ in self._window) / n
        r_mean = sum(r for _, r in self._window) / n
        sxx = sum((t - t_mean) ** 2 for t, _ in self._window)
        sxy = sum((t - t_mean) * (r - r_mean) for t, r in self._window)
        slope = -sxy / sxx
        se2 = READING_SIGMA_PCT**2 / sxx
        precision = 1.0 / self.prior_var + 1.0 / se2
        self.rate_var = 1.0 / precision
        self.rate_pct_s = max(0.0, self.rate_var * (self.c0_pct_s / self.prior_var
                                                    + slope / se2))

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
            r -= self.rate_pct_s * max(0.0, t_s - max(t_r, self.flying_since_s))
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
