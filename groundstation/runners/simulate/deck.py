"""The ship's deck and the planes' batteries in ``gcs simulate`` (a scenario with ``watch:``).

What ArduPlane and the ship's crew do, as far as the ground station can tell:

* every plane starts on deck, disarmed, with a full pack (``world/battery.py``, sized to
  ``watch.endurance_s``), and stands where the ship is;
* a launch order (``LaunchVehicle``) puts it in the air ``watch.launch_s`` later, at the
  ship, on the ship's heading (the catapult and the climb-out);
* in the air it drains its pack at its airspeed in the wind it flies in; its autopilot
  reports the remaining charge in whole percents (``BATTERY_STATUS``), which the simulator
  passes to the core every :data:`BATTERY_REPORT_S` mission seconds;
* at 0 % it falls where it is: lost (journalled ``vehicle_fell``);
* an RTL (``SendHome``) flies to the home it has *at that moment* (``SetHome`` moves the
  home; ArduPlane fixes the RTL's target at the mode's entry) and circles it;
* a plane in RTL within ``watch.recovery_radius_m`` of the ship is recovered (journalled
  ``vehicle_recovered`` with its charge and where its return ended); after
  ``watch.turnaround_s`` (the battery swap) it is a ready spare again.

Where the return *ended* is the distance to the ship's true position when the plane first
reached its RTL circle, or was recovered, whichever came first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum

from world.battery import Battery, BatteryModel
from world.model import Boat
from world.scenario import FleetSpec, WatchSpec

__all__ = ["BATTERY_REPORT_S", "Deck", "DeckState", "Landing"]

BATTERY_REPORT_S = 5.0


class DeckState(StrEnum):
    READY = "ready"
    TURNAROUND = "turnaround"
    LAUNCHING = "launching"
    AIR = "air"
    FALLEN = "fallen"


@dataclass
class _Plane:
    battery: Battery
    state: DeckState = DeckState.READY
    until_s: float = 0.0
    home_xy_m: tuple[float, float] = (0.0, 0.0)
    rtl_xy_m: tuple[float, float] | None = None
    """Where its RTL goes (None: not in RTL)."""
    return_end_m: float | None = None
    next_report_s: float = 0.0


@dataclass(frozen=True)
class Landing:
    """A recovery: when, the charge left (%), where the return ended (m from the ship)."""

    t_s: float
    vehicle: str
    battery_pct: float
    return_end_m: float


@dataclass
class Deck:
    """The deck's and the batteries' state (module docstring)."""

    spec: WatchSpec
    fleet: FleetSpec
    boat: Boat
    planes: dict[str, _Plane] = field(default_factory=dict)
    landings: list[Landing] = field(default_factory=list)
    fallen: list[tuple[float, str]] = field(default_factory=list)
    launches: int = 0

    def add(self, vehicle: str) -> None:
        model = BatteryModel(endurance_s=self.spec.endurance_s,
                             cruise_speed_m_s=self.fleet.speed_m_s)
        self.planes[vehicle] = _Plane(Battery(model), home_xy_m=(self.boat.x_m, self.boat.y_m))

    def state(self, vehicle: str) -> DeckState:
        return self.planes[vehicle].state

    def on_deck(self, vehicle: str) -> bool:
        return self.planes[vehicle].state in (DeckState.READY, DeckState.TURNAROUND,
                                              DeckState.LAUNCHING)

    def battery_pct(self, vehicle: str) -> float:
        return 100.0 * self.planes[vehicle].battery.remaining

    def launch(self, t_s: float, vehicle: str) -> bool:
        """A launch order; False when the plane is not a ready spare."""
        plane = self.planes[vehicle]
        if plane.state is not DeckState.READY:
            return False
        plane.state, plane.until_s = DeckState.LAUNCHING, t_s + self.spec.launch_s
        return True

    def airborne_due(self, t_s: float, vehicle: str) -> bool:
        """The launched plane is in the air now (once)."""
        plane = self.planes[vehicle]
        if plane.state is DeckState.LAUNCHING and t_s >= plane.until_s - 1e-9:
            plane.state = DeckState.AIR
            plane.rtl_xy_m = None
            plane.return_end_m = None
            plane.home_xy_m = (self.boat.x_m, self.boat.y_m)  # home at the launch
            self.launches += 1
            return True
        return False

    def ready_due(self, t_s: float, vehicle: str) -> bool:
        """The battery swap is done now (once): a full pack, a ready spare."""
        plane = self.planes[vehicle]
        if plane.state is DeckState.TURNAROUND and t_s >= plane.until_s - 1e-9:
            plane.state = DeckState.READY
            plane.battery.swap()
            return True
        return False

    def set_home(self, vehicle: str, x_m: float, y_m: float) -> None:
        if math.isfinite(x_m) and math.isfinite(y_m):
            self.planes[vehicle].home_xy_m = (x_m, y_m)

    def rtl(self, vehicle: str) -> tuple[float, float]:
        """Enter RTL: its target is the home now."""
        plane = self.planes[vehicle]
        plane.rtl_xy_m = plane.home_xy_m
        plane.return_end_m = None
        return plane.rtl_xy_m

    def in_rtl(self, vehicle: str) -> bool:
        return self.planes[vehicle].rtl_xy_m is not None

    def drain(self, vehicle: str, dt_s: float, airspeed_m_s: float, wind_m_s: float) -> bool:
        """Drain a flying plane's pack for ``dt_s``; True when it just ran empty (falls)."""
        plane = self.planes[vehicle]
        if plane.state is not DeckState.AIR:
            return False
        plane.battery.drain(dt_s, airspeed_m_s, wind_m_s)
        if plane.battery.empty:
            plane.state = DeckState.FALLEN
            return True
        return False

    def report_due(self, t_s: float, vehicle: str) -> float | None:
        """The remaining % (whole, as ArduPilot reports it) when a report is due."""
        plane = self.planes[vehicle]
        if plane.state is not DeckState.AIR or t_s + 1e-9 < plane.next_report_s:
            return None
        plane.next_report_s = t_s + BATTERY_REPORT_S
        return float(round(100.0 * plane.battery.remaining))

    def check_return(self, t_s: float, vehicle: str, x_m: float, y_m: float,
                     loiter_radius_m: float) -> bool:
        """A plane in RTL: note where its return ended; True when it is recovered now."""
        plane = self.planes[vehicle]
        if plane.state is not DeckState.AIR or plane.rtl_xy_m is None:
            return False
        to_ship = math.hypot(x_m - self.boat.x_m, y_m - self.boat.y_m)
        at_circle = math.dist((x_m, y_m), plane.rtl_xy_m) <= loiter_radius_m + 15.0
        if plane.return_end_m is None and at_circle:
            plane.return_end_m = to_ship
        if to_ship > self.spec.recovery_radius_m:
            return False
        if plane.return_end_m is None:
            plane.return_end_m = to_ship
        plane.state, plane.until_s = DeckState.TURNAROUND, t_s + self.spec.turnaround_s
        plane.rtl_xy_m = None
        self.landings.append(Landing(t_s, vehicle, 100.0 * plane.battery.remaining,
                                     plane.return_end_m))
        return True
