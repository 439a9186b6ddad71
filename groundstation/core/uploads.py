"""When a vehicle is sent a new mission: the one place of the rule (issue 28).

Every :class:`~groundstation.core.commands.FlyToTarget` is a mission upload (10-20 frames
each way on a radio link), so the core sends one only when it matters:

* **Same leg.** A vehicle already flying to ``target`` is not sent there again unless the
  aim point moved farther than ``retarget_m`` from the aim it flies to (by default the loiter
  radius: a pass or loiter over the old aim still has the target in view). Without
  commitment this keeps a vehicle on its leg through every periodic replan that agrees;
  and a search cell a vehicle flies to stays in the planning problem even when other cells
  grew past it (``CoreConfig.keep_held_cells``), so it is not turned away for that alone.
* **Minimum interval.** A vehicle is sent at most one FlyToTarget per ``min_interval_s``
  mission seconds. A redirect or a moved aim that comes sooner is *deferred*: the vehicle
  keeps flying what it has, and a replan is asked for as soon as the interval has passed
  (:meth:`UploadRule.due`), so the deferred decision is taken again on fresh estimates.
  The one exception is a loiter end's answer (``VehicleRecord.answer_due``): the vehicle
  has finished its mission and holds, its target changes, so its next leg is sent at once
  (the next target of its route, or the plan the loiter end asks for at the next tick,
  whatever the replanning policy). That is one upload per loiter end, and the interval
  starts again from it.
  Safety is never delayed: going home, RTL, release, SetHome, an energy return and the
  operator's actions are other commands, and a vehicle that joins, returns, reboots or
  is resumed by the operator starts a fresh interval (:meth:`UploadRule.reset`), as does
  a leg the wind moved (``core/wind_replan.py``: bounded by its own rule, once per 2 m/s
  change).
* **Missed visits.** A loiter end (or pass) after which the target was not seen since
  the vehicle was sent (a track with no accepted measurement, a search cell whose centre no
  footprint covered) is a *miss*: the vehicle looked at empty water, or never got there.
  That target is not given to that vehicle again while its aim point stays within
  ``retarget_m`` of the missed aim and its value (sigma, m^2, or a cell's value) has not
  grown by the factor ``revisit_growth``; the plan's next target for the vehicle is flown
  instead (or nothing: the vehicle holds over its last aim until the next plan). The
  vehicle's loiter-end loop at a lost target is bounded so: one miss, then a revisit only
  once the estimate moved or grew enough to be worth one (or the target was seen since);
  a miss that grew or was seen asks for a replan (:meth:`UploadRule.review`, each tick).

* **Hourly budget.** Beside the intervals, a vehicle's FlyToTargets are paced by a token
  bucket: ``budget_per_h`` tokens an hour, up to :data:`BUDGET_BURST` held, one spent per
  FlyToTarget. A redirect (anything but a loiter end's answer) waits while fewer than one
  token is held and is due when the bucket refills to one; a loiter end's answer is never
  delayed and may take the bucket below zero, which later redirects repay. Over ``T``
  mission seconds a vehicle is sent at most ``BUDGET_BURST + budget_per_h T / 3600`` plus
  the answers sent while in debt: the intervals alone bound redirects (one per
  ``route_min_interval_s``) but not redirects and loiter-end answers together (issue 28:
  60 uploads per vehicle per hour on discovery, and 62-68 on some seeds once the
  trajectories differ).

``min_interval_s``, ``revisit_growth`` and ``budget_per_h`` None: that part of the rule is
off (journals written before the rule replay as they ran). Pure: no clock, no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

__all__ = ["BUDGET_BURST", "Miss", "UploadRule"]

BUDGET_BURST = 2.0
"""Tokens of the hourly budget a vehicle can hold: two FlyToTargets back to back."""


@dataclass(frozen=True)
class Miss:
    """A visit that did not see its target: where the vehicle was sent, and the target's
    value (m^2) when the visit ended."""

    aim_xy_m: tuple[float, float]
    value_m2: float
    t_s: float


class UploadRule:
    """See the module docstring."""

    def __init__(self, min_interval_s: float | None, retarget_m: float,
                 revisit_growth: float | None, budget_per_h: float | None = None) -> None:
        self.min_interval_s = min_interval_s
        self.retarget_m = retarget_m
        self.revisit_growth = revisit_growth
        self.budget_per_h = budget_per_h
        self._tokens: dict[str, tuple[float, float]] = {}  # vehicle -> (tokens, at t_s)
        self._sent_s: dict[str, float] = {}
        self._due_s: dict[str, float] = {}
        self._misses: dict[tuple[str, str], Miss] = {}
        self.deferred = 0
        """FlyToTargets not sent because the interval had not passed (counted)."""

    # ------------------------------------------------------------------ same leg
    def same_leg(self, target: str | None, aim_xy_m: tuple[float, float] | None,
                 new_target: str, new_aim_xy_m: tuple[float, float]) -> bool:
        """The vehicle already flies to ``new_target`` at an aim within ``retarget_m``."""
        return (target == new_target and aim_xy_m is not None
                and math.dist(aim_xy_m, new_aim_xy_m) < self.retarget_m)

    # ------------------------------------------------------------------ interval
    def too_soon(self, vehicle: str, t_s: float, interval_s: float | None = None) -> bool:
        """A FlyToTarget to ``vehicle`` now would come within the minimum interval (or
        ``interval_s``, a longer one: a vehicle with points of its route still ahead,
        ``core/route.py``); the caller defers it and :meth:`due` asks for a replan when
        the interval has passed."""
        due_s = self._budget_due_s(vehicle, t_s)
        last = self._sent_s.get(vehicle)
        if self.min_interval_s is not None and last is not None:
            interval_s = self.min_interval_s if interval_s is None else max(
                interval_s, self.min_interval_s)
            if t_s - last < interval_s - 1e-9:
                due_s = max(due_s or t_s, last + interval_s)
        if due_s is None:
            return False
        self._due_s[vehicle] = due_s
        self.deferred += 1
        return True

    def _level(self, vehicle: str, t_s: float) -> float:
        """Tokens ``vehicle`` holds at ``t_s`` (module docstring, "Hourly budget")."""
        assert self.budget_per_h is not None
        tokens, at_s = self._tokens.get(vehicle, (BUDGET_BURST, t_s))
        return min(BUDGET_BURST, tokens + max(0.0, t_s - at_s) * self.budget_per_h / 3600.0)

    def _budget_due_s(self, vehicle: str, t_s: float) -> float | None:
        """When the bucket holds a token again, if it holds none now (else None)."""
        if not self.budget_per_h:
            return None
        level = self._level(vehicle, t_s)
        if level >= 1.0 - 1e-9:
            return None
        return t_s + (1.0 - level) * 3600.0 / self.budget_per_h

    def sent(self, vehicle: str, t_s: float) -> None:
        """A FlyToTarget went to ``vehicle`` at ``t_s``: a token spent."""
        self._sent_s[vehicle] = t_s
        self._due_s.pop(vehicle, None)
        if self.budget_per_h:
            self._tokens[vehicle] = (self._level(vehicle, t_s) - 1.0, t_s)

    def reset(self, vehicle: str, t_s: float) -> None:
        """``vehicle`` (re)entered the plan or left it, or the wind moved its leg (at
        ``t_s``): its next command is not delayed (the interval starts afresh, and the
        bucket holds at least the one token that command spends)."""
        self._sent_s.pop(vehicle, None)
        self._due_s.pop(vehicle, None)
        if self.budget_per_h and vehicle in self._tokens:
            self._tokens[vehicle] = (max(1.0, self._level(vehicle, t_s)), t_s)

    def due(self, t_s: float) -> bool:
        """A deferred FlyToTarget's interval has passed: replan now (once per deferral)."""
        if not self._due_s:
            return False
        done = [v for v, due_s in self._due_s.items() if t_s >= due_s - 1e-9]
        for vehicle in done:
            del self._due_s[vehicle]
        return bool(done)

    # ------------------------------------------------------------------ misses
    def missed(self, t_s: float, vehicle: str, target: str, aim_xy_m: tuple[float, float],
               value_m2: float) -> bool:
        """Record a visit of ``vehicle`` to ``target``, ended at ``t_s``, that did not see
        it; False when the rule is off."""
        if self.revisit_growth is None:
            return False
        self._misses[(vehicle, target)] = Miss(aim_xy_m, value_m2, t_s)
        return True

    def review(self, value_of: Callable[[str], float | None],
               seen_s_of: Callable[[str], float | None]) -> bool:
        """Forget the misses whose target is gone (``value_of`` None), was seen since
        (``seen_s_of``), or grew by ``revisit_growth``; True when one that grew or was seen
        was forgotten (a visit may be worth it again: replan). A moved aim is found by the
        next plan (:meth:`blocked`)."""
        if not self._misses or self.revisit_growth is None:
            return False
        again = False
        for key, miss in list(self._misses.items()):
            value = value_of(key[1])
            if value is None:
                del self._misses[key]
                continue
            seen_s = seen_s_of(key[1])
            if (seen_s is not None and seen_s > miss.t_s) or (
                    value >= self.revisit_growth * miss.value_m2):
                del self._misses[key]
                again = True
        return again

    def blocked(self, vehicle: str, target: str, aim_xy_m: tuple[float, float],
                value_m2: float) -> bool:
        """``target`` at ``aim_xy_m`` (worth ``value_m2``) is the water ``vehicle`` just
        looked at in vain: not worth sending it back. A miss whose target has since moved
        farther than ``retarget_m`` or grown by ``revisit_growth`` is forgotten."""
        miss = self._misses.get((vehicle, target))
        if miss is None or self.revisit_growth is None:
            return False
        if (math.dist(miss.aim_xy_m, aim_xy_m) < self.retarget_m
                and value_m2 < self.revisit_growth * miss.value_m2):
            return True
        del self._misses[(vehicle, target)]
        return False

    def seen(self, target: str) -> None:
        """``target`` was seen (or is gone): every vehicle's miss of it is forgotten."""
        for key in [k for k in self._misses if k[1] == target]:
            del self._misses[key]
