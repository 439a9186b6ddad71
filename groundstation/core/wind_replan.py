"""Replanning legs the wind has moved: the first wind estimate, or a changed wind.

A vehicle's leg is predicted in the wind the core plans with when it is commanded
(``DecisionCore.planning_wind_m_s``): before the vehicles' first WIND estimate that is the
fallback (``--wind``, the scenario's, or still air), and a vehicle joins the plan about
10 s before its own first estimate arrives (docs/wind.md, "The first leg"). With
commitment such a leg was kept until its loiter ended, however wrong its prediction.

**Rule.** A busy vehicle's leg, commanded in the wind ``w_0`` from source ``s_0``, is
*re-predicted* when the planning wind ``w`` is from another source (the first estimate
replaces the fallback, or the fallback comes back) or ``|w - w_0| > change_m_s``: the rest
of the leg is flown again in both winds, from where the vehicle is now, ::

    shift = T(pose, aim; w) - T(pose, aim; w_0)     T: the intercept's flight time to the
                                                    fixed aim point (planner.wind.
                                                    time_in_wind_s; Dubins in the moving
                                                    air, at the vehicle's cruise airspeed)

and it is *replanned* when ``|shift| > margin_s``; its new arrival is ``eta + shift``
(``eta`` the leg's predicted arrival, ``FlyToTarget.eta_s``). Both times start from the
same pose, so the shift is the wind's alone: how late the vehicle already is (an upload
that took seconds on a slow link, a pose a few frames old, a loaded host) is in both and
cancels. Comparing ``t + T(pose, aim; w)`` with ``eta`` instead made a first estimate
equal to a right ``--wind`` replan legs whose upload had been slow (5.2-5.6 s "moved" by
14.9 against 15 m/s, with four suite workers beside two busy loops). With commitment the
vehicle becomes idle (its target is no longer covered, the next plan may give it the same
target or another), without it the vehicle is re-commanded even if its new aim point is
within ``retarget_threshold_m`` of the old one. A leg re-predicted within the margin keeps
flying and counts as predicted in ``w`` (it is re-predicted only after a further change of
``change_m_s``). A vehicle within the camera's footprint radius of its aim point is there:
not re-predicted. Each replanned leg is a ``wind_replan`` note (vehicle, target, old and
new arrival).

Pure (no clock, no I/O): the core calls :meth:`WindReplan.legs` on every wind update, with
the active vehicles and a function that re-predicts a leg.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from groundstation.core.commands import Note
from groundstation.core.fleet import VehicleRecord

__all__ = ["LegReplan", "WindReplan"]


@dataclass(frozen=True)
class LegReplan:
    """A leg to replan: its vehicle, the arrival it was commanded with and the new one."""

    vehicle: VehicleRecord
    eta_s: float
    new_eta_s: float


class WindReplan:
    """See the module docstring. ``change_m_s`` None: the rule is off."""

    def __init__(self, change_m_s: float | None, margin_s: float, fov_radius_m: float) -> None:
        self.change_m_s = change_m_s
        self.margin_s = margin_s
        self.fov_radius_m = fov_radius_m

    def legs(
        self,
        t_s: float,
        wind_xy_m_s: tuple[float, float],
        source: str,
        vehicles: Iterable[VehicleRecord],
        flight_time_s: Callable[[VehicleRecord, tuple[float, float], tuple[float, float]],
                                float],
    ) -> list[LegReplan]:
        """The legs to replan now; every leg it re-predicts counts as predicted in
        ``wind_xy_m_s`` (``source``) from now on. ``flight_time_s(vehicle, aim, wind)``:
        the flight time from the vehicle's pose to the aim point in ``wind`` (ENU m/s)."""
        if self.change_m_s is None:
            return []
        out: list[LegReplan] = []
        for v in vehicles:
            aim, eta = v.aim_xy_m, v.eta_s
            if not v.busy or aim is None or eta is None or v.leg_wind_xy_m_s is None:
                continue
            moved = math.dist(wind_xy_m_s, v.leg_wind_xy_m_s)
            if source == v.leg_wind_source and not moved > self.change_m_s:
                continue
            old_wind = v.leg_wind_xy_m_s
            v.leg_wind_xy_m_s, v.leg_wind_source = wind_xy_m_s, source
            if math.dist((v.x_m, v.y_m), aim) <= self.fov_radius_m:
                continue  # there already
            shift_s = flight_time_s(v, aim, wind_xy_m_s) - flight_time_s(v, aim, old_wind)
            if math.isfinite(shift_s) and abs(shift_s) > self.margin_s:
                out.append(LegReplan(v, eta, eta + shift_s))
        return out

    @staticmethod
    def replan(t_s: float, legs: Iterable[LegReplan], commit: bool) -> list[Note]:
        """Apply :meth:`legs`' answer: each leg's vehicle is made idle (``commit``) and its
        aim point forgotten, so the next plan commands it again; one ``wind_replan`` note
        each."""
        notes: list[Note] = []
        for leg in legs:
            v = leg.vehicle
            if commit:
                v.busy = False
            v.aim_xy_m = None
            notes.append(Note(t_s, "wind_replan", v.id, v.target,
                              f"arrival {leg.eta_s:.1f} -> {leg.new_eta_s:.1f} s"))
        return notes
