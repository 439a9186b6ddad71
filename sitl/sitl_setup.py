"""What ``gcs sitl`` derives from a scenario: origin, home, airframe, launch poses, the
world's detection feed and the scripted vehicle events turned into faults.

Scenario events map to faults of the vehicle whose system id is the event's ``vehicle``
(an integer string): ``vehicle_lost`` -> link drop until the matching ``vehicle_returned``
(else for good), ``vehicle_rebooted`` -> reboot, ``override`` -> the operator switches to
FBWA, ``resume`` -> the operator switches back to AUTO, ``battery_low`` -> 10 % battery
(spelt by :func:`sitl.faults.fault_spec`).
A scenario attribute ``faults`` (a list of ``--fault`` specs), if the scenario format has
one, is added as is. Without a scenario: origin = home, no world (no detection feed),
vehicles start at home with headings spread over the circle, calm air. The vehicles fly in
``WindField(wind, seed)`` (:mod:`sitl.sim_wind`): the scenario's wind unless the caller
gives another (``--wind``), and the seed the detection feed draws the icebergs with. The feed
sends frame lines unless the scenario's camera is the paper's (``CameraSpec.classic``).

A watch (``watch:`` in the scenario): every vehicle's pack is
``BatteryModel(endurance_s=watch.endurance_s, cruise_speed_m_s=fleet.speed_m_s)``; with a
boat and the fleet launched from it (``fleet.launch: boat``, no launch point), the
vehicles stand on the ship's deck (:mod:`sitl.ship`) and are recovered and turned around
as the watch says; their CRASH_DETECT is 1 (a crash disarms). Without a watch, none of this
(the default pack: 15 A at cruise, 2400 s).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from domain.geodesy import GeoOrigin
from sitl.detections import DetectionSource
from sitl.faults import fault_spec
from sitl.ship import describe_watch
from sitl.vehicle import VehicleConfig
from world.battery import BatteryModel
from world.scenario import BoatSpec, WatchSpec
from world.wind import WindSpec

__all__ = ["SitlSetup", "scenario_setup"]


@dataclass
class SitlSetup:
    """Derived settings for N built-in vehicles."""

    origin: GeoOrigin
    home: tuple[float, float]
    speed_m_s: float = 22.0
    turn_radius_m: float = 105.0
    launch: list[tuple[float, float, float]] = field(default_factory=list)
    fault_specs: list[str] = field(default_factory=list)
    feed_factory: Callable[[int, bool], DetectionSource | None] | None = None
    skipped_events: list[str] = field(default_factory=list)
    wind: WindSpec = field(default_factory=WindSpec)
    battery: BatteryModel | None = None
    """The pack (a watch's endurance; None: the default)."""
    ship: BoatSpec | None = None
    """The ship the vehicles stand on (a watch launched from the boat; None: the ground)."""
    watch: WatchSpec | None = None
    radio_specs: list[str] = field(default_factory=list)
    """The scenario's ``radio:`` specs (a command line's come after them)."""

    def describe(self) -> list[str]:
        """What the watch makes the simulator do, one line each (none without a watch)."""
        return describe_watch(self.battery, self.ship, self.watch)

    def make_feed(self, seed: int, anonymous: bool) -> DetectionSource | None:
        """The detection feed (None without a scenario)."""
        return self.feed_factory(seed, anonymous) if self.feed_factory else None

    def vehicle_config(
        self, index: int, *, airborne: bool, airborne_alt_m: float, fast_boot: bool,
        unix_time_at_zero_s: float, wind: WindSpec | None = None, wind_seed: int = 0,
    ) -> VehicleConfig:
        """The configuration of built-in vehicle ``index`` (0-based; system id index + 1);
        ``wind`` None: the scenario's (:attr:`wind`)."""
        x_m, y_m, heading_rad = self.launch[index]
        return VehicleConfig(
            system_id=index + 1,
            origin=self.origin,
            home_lat_deg=self.home[0],
            home_lon_deg=self.home[1],
            cruise_speed_m_s=self.speed_m_s,
            min_turn_radius_m=self.turn_radius_m,
            launch_x_m=x_m,
            launch_y_m=y_m,
            launch_heading_rad=heading_rad,
            airborne=airborne,
            airborne_alt_m=airborne_alt_m,
            fast_boot=fast_boot,
            unix_time_at_zero_s=unix_time_at_zero_s,
            wind=self.wind if wind is None else wind,
            wind_seed=wind_seed,
            battery=self.battery,
            ship=self.ship,
            watch=self.watch if self.ship is not None else None,
            params={"CRASH_DETECT": 1.0} if self.watch is not None else {},
        )


def _event_faults(scenario: Any, count: int) -> tuple[list[str], list[str]]:
    specs: list[str] = []
    skipped: list[str] = []
    events = sorted(scenario.events, key=lambda e: e.t_s)
    for i, ev in enumerate(events):
        if ev.vehicle is None:
            continue
        if not ev.vehicle.isdigit() or not 1 <= int(ev.vehicle) <= count:
            skipped.append(
                f"{ev.kind} at {ev.t_s:g} s: vehicle {ev.vehicle!r} is not a system id 1..{count}"
            )
            continue
        sysid = int(ev.vehicle)
        at_s = float(ev.t_s)
        if ev.kind == "vehicle_lost":
            back = next(
                (
                    e.t_s
                    for e in events[i + 1 :]
                    if e.kind == "vehicle_returned" and e.vehicle == ev.vehicle
                ),
                None,
            )
            duration = (back - ev.t_s) if back is not None else 1e9
            specs.append(fault_spec(sysid, "drop", {"at": at_s, "for": float(duration)}))
        elif ev.kind == "vehicle_rebooted":
            specs.append(fault_spec(sysid, "reboot", {"at": at_s}))
        elif ev.kind == "override":
            specs.append(fault_spec(sysid, "mode", {"at": at_s, "mode": "FBWA"}))
        elif ev.kind == "resume":
            specs.append(fault_spec(sysid, "mode", {"at": at_s, "mode": "AUTO"}))
        elif ev.kind == "battery_low":
            specs.append(fault_spec(sysid, "battery", {"at": at_s, "pct": 10}))
    return specs, skipped


def scenario_setup(
    scenario: Any, count: int, home: tuple[float, float], home_given: bool
) -> SitlSetup:
    """Settings for ``count`` vehicles from ``scenario`` (or None) and the home position."""
    if scenario is None:
        launch = [(0.0, 0.0, 2.0 * math.pi * i / count) for i in range(count)]
        return SitlSetup(GeoOrigin(*home), home, launch=launch)
    origin: GeoOrigin = scenario.origin
    lx, ly = scenario.launch_point()
    if not home_given:
        lat, lon, _ = origin.to_geodetic(lx, ly)
        home = (lat, lon)
    headings = scenario.fleet.launch_headings_rad(count)
    specs, skipped = _event_faults(scenario, count)
    specs += [str(spec) for spec in getattr(scenario, "faults", ()) or ()]

    frames = not scenario.camera.classic  # the paper's camera: no frame lines, as before
    watch: WatchSpec | None = getattr(scenario, "watch", None)
    battery = ship = None
    if watch is not None:
        battery = BatteryModel(endurance_s=float(watch.endurance_s),
                               cruise_speed_m_s=float(scenario.fleet.speed_m_s))
        from_boat = scenario.fleet.launch_x_m is None or scenario.fleet.launch_y_m is None
        if scenario.boat is not None and from_boat:
            ship = scenario.boat

    def factory(seed: int, anonymous: bool) -> DetectionSource:
        return DetectionSource.for_scenario(scenario, seed, origin, anonymous, frames=frames)

    return SitlSetup(
        origin,
        home,
        float(scenario.fleet.speed_m_s),
        float(scenario.fleet.turn_radius_m),
        [(lx, ly, h) for h in headings],
        specs,
        factory,
        skipped,
        scenario.wind,
        battery,
        ship,
        watch,
        radio_specs=[str(spec) for spec in getattr(scenario, "radio", ()) or ()],
    )
