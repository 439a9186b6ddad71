"""The ship watch inside the decision core: homes on the ship, energy, relief, alarms.

Once a mission second (``tick``), for the vehicles the core knows:

1. **The ship** (``core/ship.py``) is predicted to now. A vehicle's *return* is its flight
   to the ship's predicted position when it would get there (``core/intercept.py`` with
   the ship's velocity, in the planning wind); without a ship fix, to the origin (the
   energy rules use it; no home is moved).
2. **Homes**: every vehicle in the air (in the plan, sent home, or taken over: moving its
   home changes no mode, and it makes the pilot's or a failsafe's RTL go to the ship) gets a
   ``SetHome`` at its return's aim point when that moved more than ``home_update_m`` from
   the last one sent.
3. **Energy** (``core/energy.py``): a vehicle in the plan whose spare time is gone is sent
   home (``SendHome``, reason ``energy``) with a fresh home first.
4. **Relief** (``core/relief.py``): spares on deck are launched (``LaunchVehicle``) to fill
   the station up to ``on_station``, and one is launched ``launch_s`` before the next
   staggered return; the vehicle it relieves goes home once the relief has joined the plan,
   or at its own turn-home time, whichever comes first.
5. **Alarms** (``Note`` ``watch_alarm`` / ``watch_clear``, said once each time they change):
   no vehicle in the plan, fewer on station than planned (after a grace of ``launch_s`` +
   :data:`SHORTFALL_GRACE_S`), a vehicle that can no longer reach the ship with its charge.

A vehicle that comes down (``VehicleLanded``) within ``recovery_radius_m`` (plus the ship's
prediction's 2 sigma) of the ship is recovered (status ``deck``), else ``down``; a spare on
deck reported ready (``VehicleOnDeck``) is a ``spare``; a launched spare is ``launching``
until it joins.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from groundstation.core.commands import Command, LaunchVehicle, Note, SendHome, SetHome
from groundstation.core.config import WatchConfig
from groundstation.core.energy import EnergyView, VehicleEnergy
from groundstation.core.events import (
    BatteryReport,
    VehicleLanded,
    VehicleOnDeck,
)
from groundstation.core.fleet import FleetStatus, VehicleRecord
from groundstation.core.relief import relief_spacing_s, staggered_returns
from groundstation.core.ship import ShipPrediction, ShipTrack

__all__ = ["WatchKeeper", "WatchView"]

TICK_S = 1.0
SHORTFALL_GRACE_S = 30.0
REAIM_EVERY_S = 20.0
LAUNCH_TIMEOUT_S = 180.0
"""A launch order not followed by the vehicle joining within ``launch_s`` + this is
dropped (``launch_timeout`` note) and the spare may be ordered again."""

Intercept = Callable[[VehicleRecord, tuple[float, float], tuple[float, float]],
                     tuple[float, float, float]]
"""(record, point, velocity) -> (aim x, aim y, flight time s): the core's intercept."""

FLYING = (FleetStatus.ACTIVE, FleetStatus.HOME, FleetStatus.OVERRIDDEN)


@dataclass(frozen=True)
class WatchView:
    """The watch for displays: the ship, each vehicle's energy, spares, the next relief."""

    ship: ShipPrediction | None
    energy: dict[str, EnergyView]
    spares: tuple[str, ...]
    on_station: int
    planned_on_station: int
    next_relief: tuple[str, float] | None
    """(vehicle, mission time of its planned return), the earliest."""
    alarms: tuple[str, ...]
    reliefs: int


class WatchKeeper:
    """The watch's state and rules (module docstring)."""

    def __init__(self, config: WatchConfig, loiter_s: float, ship: ShipTrack) -> None:
        self.config = config
        self.loiter_s = loiter_s
        self.ship = ship
        """The core's track of the ship (``core/ship.py``): the watch reads it."""
        self.energy: dict[str, VehicleEnergy] = {}
        self.homes: dict[str, tuple[float, float]] = {}
        self.launching: dict[str, float] = {}
        """Spare -> when its launch was ordered."""
        self.relieves: dict[str, str] = {}
        """Launched spare -> the vehicle it relieves."""
        self.returns: dict[str, float] = {}
        self.rtl_targets: dict[str, tuple[float, float]] = {}
        """A vehicle floe sent home -> where that RTL goes (ArduPlane fixes an RTL's
        target when the mode is entered; a new home needs a new RTL)."""
        self.reliefs = 0
        self._alarms: dict[str, str] = {}
        self._next_tick_s = 0.0
        self._short_since_s: float | None = None
        self._last_relief_s: float | None = None
        self._reaimed_s: dict[str, float] = {}

    # ------------------------------------------------------------------ inputs
    def _energy(self, vehicle: str) -> VehicleEnergy:
        e = self.energy.get(vehicle)
        if e is None:
            e = self.energy[vehicle] = VehicleEnergy(self.config.endurance_s,
                                                     self.config.reserve_pct)
        return e

    def battery(self, event: BatteryReport) -> bool:
        return self._energy(event.vehicle).report(event.t_s, event.remaining_pct)

    def joined(self, t_s: float, vehicle: str) -> None:
        self._energy(vehicle).flying(t_s)
        self.launching.pop(vehicle, None)

    def on_deck(self, event: VehicleOnDeck, record: VehicleRecord) -> str | None:
        """A vehicle on deck: ``spare`` when ready, else ``deck``; the new status's name
        when it changed."""
        if record.status in FLYING and record.status is not FleetStatus.HOME:
            return None  # a vehicle in the air is not on deck: the frontend is behind
        status = FleetStatus.SPARE if event.ready else FleetStatus.DECK
        if event.ready:
            self._energy(event.vehicle).fresh(event.t_s, event.battery_pct)
        if record.status is status:
            return None
        record.status, record.busy, record.target = status, False, None
        return str(status)

    def landed(self, event: VehicleLanded, record: VehicleRecord) -> Note:
        """Recovered (near the ship's prediction) or down."""
        self._energy(event.vehicle).landed()
        self.homes.pop(event.vehicle, None)
        self.returns.pop(event.vehicle, None)
        self.rtl_targets.pop(event.vehicle, None)
        ship = self.ship.predict(event.t_s)
        if ship is None:
            distance = math.hypot(event.x_m, event.y_m)
            slack = 0.0
        else:
            distance = math.hypot(event.x_m - ship.x_m, event.y_m - ship.y_m)
            slack = 2.0 * ship.sigma_m
        record.busy, record.target = False, None
        if distance <= self.config.recovery_radius_m + slack:
            record.status = FleetStatus.DECK
            return Note(event.t_s, "vehicle_recovered", event.vehicle,
                        detail=f"{distance:.0f} m from the ship")
        record.status = FleetStatus.DOWN
        return Note(event.t_s, "vehicle_down", event.vehicle,
                    detail=f"came down {distance:.0f} m from the ship")

    # ------------------------------------------------------------------ the second's rules
    def due(self, t_s: float) -> bool:
        if t_s + 1e-9 < self._next_tick_s:
            return False
        while self._next_tick_s <= t_s + 1e-9:
            self._next_tick_s += TICK_S
        return True

    def return_to_ship(self, t_s: float, record: VehicleRecord,
                       intercept: Intercept) -> tuple[float, float, float]:
        """(aim x, aim y, flight s) of ``record``'s return to the ship now."""
        ship = self.ship.predict(t_s)
        if ship is None:
            return intercept(record, (0.0, 0.0), (0.0, 0.0))
        return intercept(record, ship.xy_m, ship.v_m_s)

    def tick(self, t_s: float, records: Iterable[VehicleRecord],
             intercept: Intercept) -> list[Command]:
        """The second's rules (module docstring, 2-5)."""
        vehicles = sorted(records, key=lambda r: r.id)
        out: list[Command] = []
        returns: dict[str, tuple[float, float, float]] = {}
        for record in vehicles:
            if record.status in FLYING:
                self._energy(record.id).flying(t_s)
                returns[record.id] = self.return_to_ship(t_s, record, intercept)
        out += self._homes(t_s, vehicles, returns)
        out += self._reaim(t_s, vehicles, returns, intercept)
        active = [r for r in vehicles if r.status is FleetStatus.ACTIVE]
        due: dict[str, tuple[float, float]] = {}
        for record in active:
            energy = self._energy(record.id)
            spare = energy.spare_s(t_s, returns[record.id][2])
            if spare <= 0.0:
                out += self._send_home(t_s, record, returns[record.id], "energy")
            else:
                expected = energy.expected_spare_s(t_s, returns[record.id][2])
                due[record.id] = (t_s + spare, t_s + max(spare, expected))
        out += self._relief(t_s, vehicles, due, returns)
        out += self._check_alarms(t_s, vehicles, returns)
        return out

    def _homes(self, t_s: float, vehicles: list[VehicleRecord],
               returns: dict[str, tuple[float, float, float]]) -> list[Command]:
        out: list[Command] = []
        if not self.ship.known:
            return out  # no ship fix yet: the homes stay where the vehicles launched
        for record in vehicles:
            if record.id not in returns or (
                record.status is FleetStatus.HOME and record.id in self.rtl_targets
            ):
                continue  # a return floe started keeps its home (re-aimed by _reaim)
            aim = returns[record.id][:2]
            home = self.homes.get(record.id)
            if home is None or math.dist(home, aim) > self.config.home_update_m:
                self.homes[record.id] = aim
                out.append(SetHome(t_s, record.id, aim[0], aim[1]))
        return out

    def _reaim(self, t_s: float, vehicles: list[VehicleRecord],
               returns: dict[str, tuple[float, float, float]],
               intercept: Intercept) -> list[Command]:
        """A vehicle floe sent home whose RTL target will be farther than
        ``recovery_radius_m`` from the ship when the vehicle gets there (the ship turned,
        or the prediction was poor) is sent home again, to a fresh home; not within
        :data:`REAIM_EVERY_S` of the last send (the vehicle is still turning for home, and
        each re-aim is a home set and two mode changes)."""
        out: list[Command] = []
        for record in vehicles:
            target = self.rtl_targets.get(record.id)
            if record.status is not FleetStatus.HOME or target is None or (
                t_s - self._reaimed_s.get(record.id, -math.inf) < REAIM_EVERY_S
            ):
                continue
            now = self.ship.predict(t_s)
            if now is not None and math.dist((record.x_m, record.y_m), now.xy_m) <= (
                2.0 * self.config.recovery_radius_m
            ):
                continue  # at the ship: it is being recovered
            eta_s = intercept(record, target, (0.0, 0.0))[2]
            ship = self.ship.predict(t_s + eta_s)
            if ship is None or math.dist(target, ship.xy_m) <= self.config.recovery_radius_m:
                continue
            self._reaimed_s[record.id] = t_s
            out += self._send_home(t_s, record, returns[record.id],
                                   "return re-aimed at the ship")
        return out

    def _send_home(self, t_s: float, record: VehicleRecord,
                   ret: tuple[float, float, float], why: str) -> list[Command]:
        e = self._energy(record.id)
        record.status, record.busy, record.target = FleetStatus.HOME, False, None
        self.homes[record.id] = self.rtl_targets[record.id] = ret[:2]
        self._reaimed_s[record.id] = t_s  # judged again once it has turned for home
        detail = (f"{why}: {e.remaining_pct(t_s):.0f} % left, {ret[2]:.0f} s to the ship")
        return [SetHome(t_s, record.id, ret[0], ret[1]), SendHome(t_s, record.id, detail)]

    def _relief(self, t_s: float, vehicles: list[VehicleRecord],
                due: dict[str, tuple[float, float]],
                returns: dict[str, tuple[float, float, float]]) -> list[Command]:
        """Fill the station; send home the vehicles whose relief joined; launch the next
        relief. ``due``: each active vehicle's turn-home time at the cautious rate (when it
        must go) and at the learnt rate (what reliefs are planned on, so that a model still
        unsure of its rate does not bring every relief forward); reliefs ordered by the
        stagger alone are at least half a spacing apart, those its energy forces are not."""
        out: list[Command] = []
        by_id = {r.id: r for r in vehicles}
        for spare, ordered in list(self.launching.items()):
            record = by_id.get(spare)
            if record is None or record.status is not FleetStatus.LAUNCHING:
                self.launching.pop(spare, None)
            elif t_s - ordered > self.config.launch_s + LAUNCH_TIMEOUT_S:
                self.launching.pop(spare, None)
                self.relieves.pop(spare, None)
                record.status = FleetStatus.SPARE
                out.append(Note(t_s, "launch_timeout", spare,
                                detail="ordered, but not in the air; it may be ordered again"))
        spares = [r for r in vehicles if r.status is FleetStatus.SPARE]
        active = [r for r in vehicles if r.status is FleetStatus.ACTIVE]
        wanted = self.config.on_station if self.config.on_station is not None else len(vehicles)
        relieving = set(self.relieves.values())
        # fill the station
        while spares and len(active) + len(self.launching) - len(relieving) < wanted:
            out.append(self._launch(t_s, spares.pop(0), "on station", None))
        # the vehicles whose relief has joined go home
        for spare, vehicle in list(self.relieves.items()):
            record = by_id.get(vehicle)
            relief = by_id.get(spare)
            if record is None or record.status is not FleetStatus.ACTIVE:
                self.relieves.pop(spare, None)
                continue
            if relief is not None and relief.status is FleetStatus.ACTIVE:
                self.relieves.pop(spare, None)
                self.reliefs += 1
                out += self._send_home(t_s, record, returns[vehicle], f"relieved by {spare}")
        # the next staggered return, and its relief's launch
        spacing = relief_spacing_s(self.config.endurance_s, self.config.reserve_pct,
                                   max(1, wanted))
        staggered = staggered_returns(
            {v: d[1] for v, d in due.items() if v not in relieving}, spacing)
        plan = {v: min(r, due[v][0]) for v, r in staggered.items()}
        self.returns = plan
        if plan and spares:
            vehicle = min(plan, key=lambda v: (plan[v], v))
            forced = t_s >= due[vehicle][0] - self.config.launch_s
            spaced = (self._last_relief_s is None
                      or t_s - self._last_relief_s >= 0.5 * spacing)
            if t_s >= plan[vehicle] - self.config.launch_s and (forced or spaced):
                out.append(self._launch(t_s, spares.pop(0), "relief", vehicle))
                self._last_relief_s = t_s
        return out

    def _launch(self, t_s: float, spare: VehicleRecord, reason: str,
                relieves: str | None) -> LaunchVehicle:
        spare.status = FleetStatus.LAUNCHING
        self.launching[spare.id] = t_s
        if relieves is not None:
            self.relieves[spare.id] = relieves
        return LaunchVehicle(t_s, spare.id, reason, relieves)

    def _check_alarms(self, t_s: float, vehicles: list[VehicleRecord],
                      returns: dict[str, tuple[float, float, float]]) -> list[Command]:
        now: dict[str, str] = {}
        active = [r for r in vehicles if r.status is FleetStatus.ACTIVE]
        wanted = self.config.on_station if self.config.on_station is not None else len(vehicles)
        if vehicles and not active and not self.launching:
            now["no_vehicle"] = "no vehicle in the plan"
        if len(active) < min(wanted, len(vehicles)):
            if self._short_since_s is None:
                self._short_since_s = t_s
            if t_s - self._short_since_s >= self.config.launch_s + SHORTFALL_GRACE_S:
                now["short"] = f"{len(active)} of {wanted} on station"
        else:
            self._short_since_s = None
        for record in vehicles:
            if record.id in returns:
                e = self._energy(record.id)
                if e.remaining_pct(t_s) / e.cautious_rate_pct_s < returns[record.id][2]:
                    now[f"reach:{record.id}"] = (f"vehicle {record.id} may not reach the ship: "
                                                 f"{e.remaining_pct(t_s):.0f} % left, "
                                                 f"{returns[record.id][2]:.0f} s away")
        out: list[Command] = []
        for key in sorted(set(now) | set(self._alarms)):
            vehicle = key.split(":", 1)[1] if key.startswith("reach:") else None
            if key in now and self._alarms.get(key) is None:
                out.append(Note(t_s, "watch_alarm", vehicle, detail=now[key]))
            elif key not in now:
                out.append(Note(t_s, "watch_clear", vehicle, detail=self._alarms[key]))
        self._alarms = now
        return out

    # ------------------------------------------------------------------ planning, views
    def leg_ok(self, t_s: float, record: VehicleRecord, aim_xy_m: tuple[float, float],
               eta_s: float, intercept: Intercept) -> bool:
        """A leg to ``aim_xy_m`` arriving at ``eta_s`` (then the loiter) leaves ``record``
        enough charge to reach the ship's predicted position after it with the reserve."""
        end_s = eta_s + self.loiter_s
        ship = self.ship.predict(end_s)
        at_aim = VehicleRecord(record.id, aim_xy_m[0], aim_xy_m[1], record.heading_rad,
                               record.speed_m_s, end_s)
        if ship is None:
            back = intercept(at_aim, (0.0, 0.0), (0.0, 0.0))[2]
        else:
            back = intercept(at_aim, ship.xy_m, ship.v_m_s)[2]
        return self._energy(record.id).leg_ok(t_s, end_s - t_s, back)

    def send_home_instead(self, t_s: float, record: VehicleRecord,
                          intercept: Intercept) -> list[Command]:
        """The plan's leg for ``record`` is not flyable: home now, not there."""
        return self._send_home(t_s, record, self.return_to_ship(t_s, record, intercept),
                               "energy (no flyable leg)")

    def view(self, t_s: float, records: Iterable[VehicleRecord],
             intercept: Intercept) -> WatchView:
        vehicles = sorted(records, key=lambda r: r.id)
        energy = {}
        for record in vehicles:
            if record.id not in self.energy:
                continue
            ret = (self.return_to_ship(t_s, record, intercept)[2]
                   if record.status in FLYING else None)
            energy[record.id] = self.energy[record.id].view(t_s, ret)
        spares = tuple(r.id for r in vehicles if r.status is FleetStatus.SPARE)
        on_station = sum(1 for r in vehicles if r.status is FleetStatus.ACTIVE)
        wanted = self.config.on_station if self.config.on_station is not None else len(vehicles)
        nxt = min(self.returns.items(), key=lambda kv: (kv[1], kv[0])) if self.returns else None
        return WatchView(self.ship.predict(t_s), energy, spares, on_station, wanted, nxt,
                         tuple(self._alarms.values()), self.reliefs)
