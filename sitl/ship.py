"""The ship a watch's vehicles launch from and land on (sans-IO, clock-free).

Each simulated vehicle of a watch (``watch:`` in the scenario, a boat, ``fleet.launch:
boat``) carries its own :class:`SimShip`: the scenario's boat (``BoatSpec.build()``, the
same ``world.model.Boat`` the detection feed's world sails) advanced in steps of at most
``SHIP_STEP_S`` = 0.1 s, as the world steps it, so every vehicle and the feed see the ship at
the same place at the same simulated time (a route's turns fall inside a step exactly, so the
partition of time into steps changes nothing but rounding).

The ship's motion is a function of the simulator's time only: the ship does not reboot.
"""

from __future__ import annotations

from world.battery import BatteryModel
from world.model import Boat
from world.scenario import BoatSpec, WatchSpec

__all__ = ["SHIP_STEP_S", "SimShip", "describe_watch"]

SHIP_STEP_S = 0.1


class SimShip:
    """The ship's position and velocity at a simulated time (monotonic: asking for an
    earlier time than the last answer gives the last state)."""

    def __init__(self, spec: BoatSpec, t0_s: float = 0.0) -> None:
        self.spec = spec
        self.boat: Boat = spec.build()
        self.t_s = t0_s

    def advance(self, t_s: float) -> None:
        """Sail to ``t_s`` in steps of at most ``SHIP_STEP_S``."""
        while self.t_s < t_s - 1e-9:
            dt_s = min(SHIP_STEP_S, t_s - self.t_s)
            self.boat.step(dt_s)
            self.t_s += dt_s

    def position_m(self, t_s: float) -> tuple[float, float]:
        """(x_m, y_m) in the scenario's local ENU frame at ``t_s``."""
        self.advance(t_s)
        return self.boat.x_m, self.boat.y_m

    def velocity_m_s(self, t_s: float) -> tuple[float, float]:
        """ENU ground velocity at ``t_s``."""
        self.advance(t_s)
        return self.boat.velocity_m_s


def describe_watch(
    battery: BatteryModel | None, ship: BoatSpec | None, watch: WatchSpec | None
) -> list[str]:
    """``gcs sitl``'s start lines for a watch: the ship, the recovery, the pack (none
    without a watch)."""
    if watch is None:
        return []
    lines = []
    if ship is not None:
        route = f", looping a route of {len(ship.route)} waypoints" if ship.route else ""
        lines.append(
            f"ship: from ({ship.x_m:g}, {ship.y_m:g}) m at {ship.speed_m_s:g} m/s{route}; "
            "vehicles stand on its deck and take off from it"
        )
        lines.append(
            f"recovery: RTL or LAND within {watch.recovery_radius_m:g} m of the ship; "
            f"turnaround {watch.turnaround_s:g} s (fresh pack, reboot on deck)"
        )
    if battery is not None:
        lines.append(
            f"battery: endurance {battery.endurance_s:g} s at {battery.cruise_speed_m_s:g} m/s "
            f"in still air ({battery.capacity_mah:g} mAh, {battery.cruise_current_a:.1f} A at "
            "cruise); at 0 % the plane falls"
        )
    return lines
