"""The decision core's wind: the vehicles' own estimates, combined robustly, else a fallback.

Inputs are :class:`~groundstation.core.events.WindReport` events (one vehicle's WIND message
as the ENU vector ``w = (w_x, w_y)`` the air moves towards, at most ~1 Hz per vehicle) and
the mission time; the output is the wind the planner and the intercept use, and the journal
lines that say when it changed. Pure: no clock, no I/O; a replay fed the same inputs gives
the same estimate at every instant.

**Which reports count.** A vehicle counts if its latest report is younger than
``max_age_s`` (30 mission s: ArduPlane sends WIND at 1 Hz, so this is many missed
messages) and it is active in the plan (flying and commanded: a vehicle on the ground or
taken over by a pilot says nothing about the wind where floe flies). Its value ``w_i`` is
the mean of its reports over the ``average_s`` (20 s) up to its latest: a planned leg lasts
a minute or more, so the wind over it matters, not the gust at the instant of planning.
Gusts of standard deviation ``g`` and correlation time ``tau`` average down to about
``g sqrt(2 tau / T)`` over ``T``: 2 m/s gusts of 5 s to 1.4 m/s over 20 s, at 20 s of lag
behind a real change of the mean.

**Combination** of the ``n`` fresh reports ``w_1 .. w_n``:

* ``n = 0``: the fallback, ``CoreConfig.wind_xy_m_s`` (the config's ``wind``, else the
  scenario's, else calm); source ``"fallback"``.
* ``n = 1``: that vehicle's report.
* ``n >= 3``: the component-wise median ``(median_i w_x,i, median_i w_y,i)``. One vehicle
  reporting garbage (or a steady 40 m/s) cannot move it beyond the spread of the others:
  the median's breakdown point is 50 %.
* ``n = 2``: if ``|w_1 - w_2| <= disagree_m_s`` (5 m/s) their mean (the median of two).
  Otherwise there is no majority, and the report closer to the *anchor* wins (ties: the
  lower vehicle id). The anchor is the last estimate that vehicles corroborated (two that
  agreed, or the median of three or more), and before any, the fallback (the operator's
  configured wind). Why: a vehicle whose estimate runs away does not drag the fleet's with
  it, the estimate does not flip between two vehicles report by report, and a lone
  vehicle's say (``n = 1``) is used but never becomes the judge of a second one. Averaging
  two disagreeing reports would be wrong for both; falling back to the configured wind
  would throw away two measurements for one guess.

**Outliers.** A vehicle whose report stays more than ``disagree_m_s`` away from the
estimate (with at least one other vehicle reporting) for ``outlier_after_s`` (10 mission
s) is flagged once, as a ``wind_outlier`` note; it is flagged again only after it agreed
in between.

**Withdrawn.** A :class:`~groundstation.core.events.WindWithdrawn` input (the vehicle's
autopilot disabled its failed airspeed sensor, and its WIND estimate without airspeed
reads 40-60 % of the true wind) forgets that vehicle's reports at once and recomputes the
estimate: with others reporting, their combination stands (with three or more the median
had already outvoted it, with one or two it had not); with none, the fallback replaces it
at once rather than ``max_age_s`` later, and a ``wind_fallback`` note (a warning) says
so. The vehicle counts again from its next ``WindReport`` (its controller sends none until
the sensor is back and the estimate has settled again).

**Journal.** A :class:`~groundstation.core.commands.WindEstimate` (a ``wind`` line) when the
estimate changed meaningfully from the last one journalled: its speed by more than
``change_speed_m_s`` (1 m/s), its direction by more than ``change_deg`` (10 deg, while
either speed is at least 1 m/s: the direction of a near calm is noise), or its source
(vehicles / fallback). The initial state (the fallback) is not journalled: a run without
any wind report journals no ``wind`` line at all, as before wind existed.
"""

from __future__ import annotations

import math
import statistics
from collections import deque
from dataclasses import dataclass

from domain.limits import MAX_WIND_M_S
from domain.wind_triangle import wind_from_vector
from groundstation.core.commands import Command, Note, WindEstimate
from groundstation.core.events import WindReport, WindWithdrawn

__all__ = ["FALLBACK", "VEHICLES", "WindEstimator", "WindState", "describe_wind"]

VEHICLES = "vehicles"
FALLBACK = "fallback"


@dataclass(frozen=True)
class WindState:
    """The core's wind at one instant: ENU vector (towards), source, vehicles used."""

    wx_m_s: float
    wy_m_s: float
    source: str
    vehicles: tuple[str, ...] = ()

    @property
    def xy_m_s(self) -> tuple[float, float]:
        return self.wx_m_s, self.wy_m_s

    @property
    def speed_m_s(self) -> float:
        return math.hypot(self.wx_m_s, self.wy_m_s)

    @property
    def from_deg(self) -> float:
        """Compass direction the wind blows from, [0, 360)."""
        return wind_from_vector(self.wx_m_s, self.wy_m_s)[1]


def describe_wind(wx_m_s: float, wy_m_s: float) -> str:
    """``12.0 m/s from 270 deg`` (``calm`` below 0.05 m/s)."""
    speed, from_deg = wind_from_vector(wx_m_s, wy_m_s)
    if speed < 0.05:
        return "calm"
    return f"{speed:.1f} m/s from {from_deg:.0f} deg"


@dataclass(frozen=True)
class _Report:
    t_s: float
    wx_m_s: float
    wy_m_s: float


class WindEstimator:
    """See the module docstring. ``report`` the inputs, ``update`` on every tick."""

    def __init__(
        self,
        fallback_xy_m_s: tuple[float, float],
        *,
        max_age_s: float = 30.0,
        average_s: float = 20.0,
        disagree_m_s: float = 5.0,
        outlier_after_s: float = 10.0,
        change_speed_m_s: float = 1.0,
        change_deg: float = 10.0,
    ) -> None:
        self.fallback = WindState(fallback_xy_m_s[0], fallback_xy_m_s[1], FALLBACK)
        self.max_age_s = max_age_s
        self.average_s = average_s
        self.disagree_m_s = disagree_m_s
        self.outlier_after_s = outlier_after_s
        self.change_speed_m_s = change_speed_m_s
        self.change_deg = change_deg
        self.current = self.fallback
        """The estimate now (what the planner uses)."""
        self.journalled = self.fallback
        """The estimate last journalled (the initial fallback counts as journalled)."""
        self.anchor = self.fallback.xy_m_s
        """The last estimate vehicles corroborated, else the fallback (module docstring)."""
        self.reports: dict[str, deque[_Report]] = {}
        """Each vehicle's reports over the last ``average_s`` before its latest."""
        self.rejected = 0
        """Reports dropped: not finite, or stronger than any flyable weather."""
        self._outlier_since: dict[str, float] = {}
        self._flagged: set[str] = set()
        self.heard = False
        """A report was ever kept. Until then :meth:`update` has nothing to do: no report
        is held, so the estimate is the fallback it always was (already counted as
        journalled) and no vehicle is an outlier; the core skips it (and the wind replan:
        every leg was predicted in that fallback) on every tick of a calm run."""

    # ------------------------------------------------------------------ inputs
    def report(self, event: WindReport) -> None:
        """Keep ``event`` as its vehicle's latest report (a bad one is counted, dropped)."""
        wx, wy = event.wx_m_s, event.wy_m_s
        if not (math.isfinite(wx) and math.isfinite(wy)) or math.hypot(wx, wy) > MAX_WIND_M_S:
            self.rejected += 1
            return
        self.heard = True
        kept = self.reports.setdefault(event.vehicle, deque())
        if kept and event.t_s < kept[-1].t_s:
            kept.clear()  # time went back (a replay edited by hand): start again
        kept.append(_Report(event.t_s, wx, wy))
        while event.t_s - kept[0].t_s > self.average_s:
            kept.popleft()

    def withdraw(self, event: WindWithdrawn, active: set[str]) -> list[Command]:
        """Forget ``event.vehicle``'s reports and recompute at once (module docstring)."""
        used = event.vehicle in self.current.vehicles
        self.reports.pop(event.vehicle, None)
        out = self.update(event.t_s, active)
        if used and self.current.source == FALLBACK:
            detail = (f"vehicle {event.vehicle}'s wind estimate is withdrawn ({event.reason}) "
                      f"and no other vehicle reports one: planning falls back to the "
                      f"configured wind, {describe_wind(*self.fallback.xy_m_s)}")
            out.append(Note(event.t_s, "wind_fallback", event.vehicle, None, detail))
        return out

    def fresh(self, t_s: float, active: set[str]) -> dict[str, tuple[float, float]]:
        """The value of each vehicle that counts at ``t_s`` (module docstring)."""
        out: dict[str, tuple[float, float]] = {}
        for vehicle, kept in sorted(self.reports.items()):
            if vehicle in active and t_s - kept[-1].t_s <= self.max_age_s:
                n = len(kept)
                out[vehicle] = (sum(r.wx_m_s for r in kept) / n, sum(r.wy_m_s for r in kept) / n)
        return out

    def update(self, t_s: float, active: set[str]) -> list[Command]:
        """Recompute the estimate at ``t_s`` from the reports of the ``active`` vehicles;
        the journal lines this causes (a changed estimate, a newly flagged outlier)."""
        reports = self.fresh(t_s, active) if self.reports else {}
        self.current = self._combine(reports)
        out: list[Command] = self._outliers(t_s, reports) if reports or self._outlier_since else []
        if self._changed(self.current, self.journalled):
            self.journalled = self.current
            c = self.current
            out.append(WindEstimate(t_s, c.wx_m_s, c.wy_m_s, c.source, c.vehicles))
        return out

    # ------------------------------------------------------------------ combination
    def _combine(self, reports: dict[str, tuple[float, float]]) -> WindState:
        if not reports:
            return self.fallback
        ids = tuple(reports)
        if len(ids) == 1:
            wx, wy = reports[ids[0]]
            return WindState(wx, wy, VEHICLES, ids)
        if len(ids) == 2:
            (a, wa), (b, wb) = reports.items()
            if math.dist(wa, wb) > self.disagree_m_s:
                # the one closer to what vehicles last agreed on; ties to the first id
                chosen = b if math.dist(wb, self.anchor) < math.dist(wa, self.anchor) else a
                wx, wy = reports[chosen]
                return WindState(wx, wy, VEHICLES, (chosen,))
            wx, wy = (wa[0] + wb[0]) / 2.0, (wa[1] + wb[1]) / 2.0
        else:
            wx = statistics.median(w[0] for w in reports.values())
            wy = statistics.median(w[1] for w in reports.values())
        self.anchor = wx, wy
        return WindState(wx, wy, VEHICLES, ids)

    def _outliers(self, t_s: float, reports: dict[str, tuple[float, float]]) -> list[Command]:
        out: list[Command] = []
        estimate = self.current.xy_m_s
        for vehicle in list(self._outlier_since):
            if vehicle not in reports:
                del self._outlier_since[vehicle]  # silent or out of the plan: no evidence
        for vehicle, w in reports.items():
            if len(reports) < 2 or math.dist(w, estimate) <= self.disagree_m_s:
                self._outlier_since.pop(vehicle, None)
                self._flagged.discard(vehicle)  # agreed again: may be flagged anew
                continue
            since = self._outlier_since.setdefault(vehicle, t_s)
            if t_s - since >= self.outlier_after_s - 1e-9 and vehicle not in self._flagged:
                self._flagged.add(vehicle)
                detail = (f"reports {describe_wind(*w)} for {t_s - since:.0f} s; the fleet's "
                          f"estimate is {describe_wind(*estimate)}")
                out.append(Note(t_s, "wind_outlier", vehicle, None, detail))
        return out

    def _changed(self, new: WindState, old: WindState) -> bool:
        if new is old and self.change_speed_m_s >= 0.0 and self.change_deg >= 0.0:
            return False  # what the rules below give for one state (every calm tick)
        if new.source != old.source:
            return True
        if abs(new.speed_m_s - old.speed_m_s) > self.change_speed_m_s:
            return True
        if max(new.speed_m_s, old.speed_m_s) < 1.0:
            return False
        turn = abs((new.from_deg - old.from_deg + 180.0) % 360.0 - 180.0)
        return turn > self.change_deg

    @property
    def flagged(self) -> frozenset[str]:
        """Vehicles flagged as wind outliers (and not agreeing since)."""
        return frozenset(self._flagged)
