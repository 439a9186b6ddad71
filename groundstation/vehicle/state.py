"""The vehicle controller's vocabulary (see :mod:`.controller`).

:class:`VehicleState` spells the states as the journal and the status table do;
:class:`LinkState` the link's; :class:`FlyRecord` is the mission a vehicle was last given.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

__all__ = ["ASSESSED", "IN_HAND", "LAUNCHED_MARGIN_M", "FlyRecord", "LinkState", "VehicleState"]

LAUNCHED_MARGIN_M = 15.0


class VehicleState(enum.Enum):
    CONNECTING = "connecting"
    ON_GROUND = "on_ground"
    LAUNCHING = "launching"
    JOINING = "joining"
    MANUAL = "manual"
    ACTIVE = "active"
    OVERRIDDEN = "overridden"
    HOME = "home"


class LinkState(enum.StrEnum):
    """The vehicle's link as the controller judges it from silence, spelt as the status
    table and the API spell it (a ``str``, so it prints and serialises as before)."""

    OK = "ok"
    DEGRADED = "degraded"
    LOST = "lost"


S = VehicleState
IN_HAND = (S.ACTIVE, S.JOINING, S.LAUNCHING)
ASSESSED = (S.CONNECTING, S.ON_GROUND, S.MANUAL)


@dataclass
class FlyRecord:
    """The mission a vehicle was last given (for the status table and the benchmark)."""

    target: str
    x_m: float
    y_m: float
    route: tuple[str, ...] = field(default=())
    verified_t_s: float | None = None
    through: tuple[tuple[float, float], ...] = ()
    """The points the mission flies through after the aim (``core/route.py``)."""
    item: int = 1
    """The furthest mission item it was seen flying to (MISSION_CURRENT)."""
    route_end: str | None = None
    """The last cell a routed pass flies through (None: the mission ends at ``target``)."""

    @property
    def end_target(self) -> str:
        """Where the mission's watched item is, so where its loiter end happens: the route's
        last cell, else the target (``jobs.target_job``)."""
        return self.route_end if self.route_end is not None else self.target

    def aim_now(self, seq: int | None) -> tuple[float, float]:
        """Where it flies now: item 1 is the aim, items 2.. the points flown through, the
        last (the unlimited loiter) at the last point. ``seq`` only moves it forward."""
        if seq is not None and seq > self.item:
            self.item = seq
        points = ((self.x_m, self.y_m), *self.through)
        return points[min(max(self.item - 1, 0), len(points) - 1)]
