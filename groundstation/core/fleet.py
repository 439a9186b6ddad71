"""What the decision core knows of each vehicle, and how fleet status events change it."""

from __future__ import annotations

import enum
from collections.abc import Iterable
from dataclasses import dataclass, field

from groundstation.core.commands import Command, ReleaseVehicle, SendHome
from groundstation.core.events import (
    BatteryLow,
    Event,
    OperatorOverride,
    OperatorResume,
    VehicleLost,
    VehicleRebooted,
    VehicleReturned,
)

__all__ = ["FleetStatus", "VehicleRecord", "free_vehicles", "status_change"]


class FleetStatus(enum.StrEnum):
    """A vehicle's status as the core sees it, spelt as its views and journal lines spell it.

    Not the vehicle controller's :class:`~groundstation.vehicle.state.VehicleState`: the core
    knows only whether a vehicle is in the plan (``active``), taken over, sent home, or lost
    (the controller's link, a reboot, no progress, a landing: all ``VehicleLost``); the
    controller's states before a vehicle joins never reach it, except on a ship watch,
    where the deck's are the core's (``spare``, ``deck``, ``launching``, ``down``)."""

    ACTIVE = "active"
    OVERRIDDEN = "overridden"
    LOST = "lost"
    HOME = "home"
    SPARE = "spare"
    """On the ship's deck, ready to launch (the watch: ``core/watch.py``)."""
    DECK = "deck"
    """On the ship's deck, not ready: recovered, waiting for its battery swap."""
    LAUNCHING = "launching"
    """A spare whose launch was ordered, not yet in the plan."""
    DOWN = "down"
    """Came down away from the ship."""



@dataclass
class VehicleRecord:
    """What the core knows of one vehicle."""

    id: str
    x_m: float
    y_m: float
    heading_rad: float
    speed_m_s: float
    pose_t_s: float
    status: FleetStatus = FleetStatus.ACTIVE
    target: str | None = None
    busy: bool = False
    aim_xy_m: tuple[float, float] | None = None
    route: tuple[str, ...] = field(default=())
    through: tuple[str, ...] = field(default=())
    """The search cells the vehicle's mission flies through after ``target``
    (``core/route.py``)."""
    eta_s: float | None = None
    """The predicted arrival of the leg last commanded (``FlyToTarget.eta_s``)."""
    leg_t_s: float | None = None
    """When the leg last commanded was sent: its target seen since then was seen on the
    visit (``core/uploads.py``)."""
    leg_wind_xy_m_s: tuple[float, float] | None = None
    leg_wind_source: str | None = None
    """The wind that leg was predicted in, and its source (``core/wind_replan.py``)."""
    answer_due: bool = False
    """Its loiter (or pass) ended and no new leg was sent since: the next one is the loiter
    end's answer, sent at once, not deferred by the upload interval (``core/uploads.py``;
    one such leg per loiter end). Cleared when a leg is sent or a plan that included the
    vehicle gave it none."""

    @property
    def idle(self) -> bool:
        return self.status is FleetStatus.ACTIVE and not self.busy


def status_change(record: VehicleRecord, event: Event,
                  battery_low_action: str) -> tuple[list[Command], str | None]:
    """Apply a lost/returned/rebooted/override/resume/battery event to ``record``: the
    commands it causes and the reason to replan (None: nothing changed)."""
    out: list[Command] = []
    reason: str | None = None
    t_s = event.t_s
    if isinstance(event, VehicleLost):
        if record.status is FleetStatus.ACTIVE:
            record.status, record.busy = FleetStatus.LOST, False
            reason = "vehicle lost"
    elif isinstance(event, VehicleReturned):
        if record.status is FleetStatus.LOST:
            record.status, record.busy = FleetStatus.ACTIVE, False
            reason = "vehicle returned"
    elif isinstance(event, VehicleRebooted):
        if record.status in (FleetStatus.ACTIVE, FleetStatus.LOST):
            record.status, record.busy, record.target = FleetStatus.ACTIVE, False, None
            reason = "vehicle rebooted"
    elif isinstance(event, OperatorOverride):
        if record.status is not FleetStatus.OVERRIDDEN:
            record.status, record.busy = FleetStatus.OVERRIDDEN, False
            out.append(ReleaseVehicle(t_s, record.id, "operator override"))
            reason = "operator override"
    elif isinstance(event, OperatorResume):
        if record.status in (FleetStatus.OVERRIDDEN, FleetStatus.HOME):
            record.status, record.busy, record.target = FleetStatus.ACTIVE, False, None
            reason = "operator resume"
    elif isinstance(event, BatteryLow) and record.status is FleetStatus.ACTIVE:
        record.status, record.busy, record.target = FleetStatus.HOME, False, None
        if battery_low_action == "rtl":
            out.append(SendHome(t_s, record.id, "battery low"))
        else:
            out.append(ReleaseVehicle(t_s, record.id, "battery low"))
        reason = "battery low"
    return out, reason


def hand_over(records: Iterable[VehicleRecord], target: str, successor: str) -> bool:
    """``target`` went on as ``successor`` (the tracker's coalescence: the successor's
    estimate is where the target's was replaced): the vehicles flying to it, or through it,
    fly to the successor, whose leg is then the same (``UploadRule.same_leg``), so a new
    id alone sends no new mission. True if any vehicle flew to it."""
    handed = False
    for record in records:
        if record.target == target:
            record.target = successor
            handed = True
        record.through = tuple(successor if t == target else t for t in record.through)
        record.route = tuple(successor if t == target else t for t in record.route)
    return handed


def free_vehicles(records: Iterable[VehicleRecord], target: str) -> bool:
    """Release the vehicles flying to ``target`` (it is gone); True if there were any."""
    freed = False
    for record in records:
        if record.target == target:
            record.target, record.busy, record.aim_xy_m = None, False, None
            freed = True
    return freed
