"""One simulated ArduPlane, sans-IO and clock-free: ``receive(msg, t_s)`` and
``step(t_s)`` return the MAVLink messages the vehicle sends (to every link).

Boot as ArduPlane SITL: INITIALISING for ``init_s`` (mission storage not ready: uploads get
NO_SPACE), then MANUAL; GPS 3D fix after ``gps_fix_s``; the EKF uses GPS and home is set
after ``ekf_s`` and only then is the pre-arm-check bit (0x10000000) of SYS_STATUS health
set. ``fast_boot`` shortens the three to 0.5, 1 and 2 s. ``airborne`` starts flying at
``airborne_alt_m``, armed, in AUTO on item 1 of the mission [home, NAV_LOITER_UNLIM over
home], like a UAV launched before the ground station took over.

Battery: the pack is a ``world.battery.Battery`` drained every physics step with the
airspeed flown, the wind's speed where the plane flies, its climb rate and whether the motor
runs (``I = I_c (0.6 (v/v_c)^3 + 0.4 v_c/v) + m g max(0, climb) / (eta U)``, times
``1 + 0.01 w`` in a wind of ``w`` m/s; the idle current on the ground or gliding with the
throttle closed; world/battery.py). ``I_c = 3.6 capacity_mAh / endurance_s``: the watch's
``endurance_s``, else ``DEFAULT_ENDURANCE_S`` (2400 s: 15 A at cruise, as before).
Reported as ArduPlane's analog monitor reports it: ``remaining = 1 - used_mAh /
BATT_CAPACITY``, ``voltage = empty_v + (full_v - empty_v) (1 - used/capacity)`` (12.6 V full,
10.2 V empty; BATT_LOW_VOLT 10.5 V at 12.5 %). Below BATT_LOW_VOLT: "Battery 1 is low ..."
and the BATT_FS_LOW_ACT action (1 or 2: RTL).

At 0 % the motor stops ("Battery 1 is critical ..."): the plane glides wings level
(sinking ``V / 10``) to the ground ("SIM Hit ground at X m/s"); with CRASH_DETECT set,
ArduPlane's crash check says "Crash detected" and (disarm bit) disarms
(:meth:`SimVehicle._crash`); it lies there, sending telemetry. :attr:`SimVehicle.events`
records it (``motor_stopped``, ``fell``).

The ship (``config.ship``, a watch's deck): on the ground on deck the vehicle's position is
the ship's, every step, and its ground velocity the ship's; home is set where it gets its
fix (the EKF's ready, ``ekf_s``) and, while disarmed and unlocked, follows it every 5 s
(ArduPlane's ``update_home`` in ``one_second_loop``) and at arming (``AP_Arming_Plane::arm``).
DO_SET_HOME locks home.
Recovery (``config.watch``): armed, flying, in RTL or on a NAV_LAND item, within
``recovery_radius_m`` of the ship: on deck, disarmed ("SIM Recovered on deck"); after
``turnaround_s`` it reboots with a fresh pack (new boot, on deck, home at its fix).

Kill/restart (:meth:`SimVehicle.kill`): the autopilot process is dead for a while (sends
and hears nothing), then powers up on the ground where the aircraft came down: disarmed,
``time_boot_ms`` from 0, INITIALISING then MANUAL, mission and parameters from storage.
Every command-like message received is logged in :attr:`SimVehicle.received`.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

from domain.geodesy import compass_deg_from_enu_rad
from domain.modes import ArduPlaneMode
from groundstation.mavlink.codec import mavlink2
from sitl import command_handler
from sitl.airframe import GLIDE, GROUND, Airframe
from sitl.autopilot import AUTO, GUIDED, INITIALISING, LOITER, MANUAL, MODE_NAMES, RTL, Autopilot
from sitl.faults import FaultEvent
from sitl.fence import SimFence
from sitl.geo_items import GeoItemsServer
from sitl.mission_protocol import REREQUEST_S, UPLOAD_TIMEOUT_S, MissionEvents, MissionServer
from sitl.mission_store import MAX_MISSION_ITEMS, MissionStore, StoredItem
from sitl.params import ParamStore, default_param_specs
from sitl.ship import SimShip
from sitl.sim_airspeed import AirspeedSensor
from sitl.sim_wind import EkfWindModel, FlownWind, wind_param_values
from sitl.statustext import StatusTextFactory
from sitl.telemetry import StreamScheduler
from sitl.vehicle_messages import build_message
from sitl.vehicle_state import VehicleConfig
from world.battery import Battery

__all__ = ["ReceivedCommand", "SimEvent", "SimVehicle", "VehicleConfig"]

M = mavlink2
PHYSICS_DT_S = 0.1
PREARM_REPORT_S = 30.0
MISSION_MESSAGES = frozenset(
    {
        "MISSION_COUNT",
        "MISSION_ITEM",
        "MISSION_ITEM_INT",
        "MISSION_REQUEST_LIST",
        "MISSION_REQUEST",
        "MISSION_REQUEST_INT",
        "MISSION_CLEAR_ALL",
        "MISSION_ACK",
    }
)
# what a ground station asks the vehicle to do (kept in SimVehicle.received for tests)
COMMAND_MESSAGES = frozenset(
    {
        "COMMAND_LONG",
        "COMMAND_INT",
        "SET_MODE",
        "MISSION_COUNT",
        "MISSION_CLEAR_ALL",
        "MISSION_SET_CURRENT",
        "PARAM_SET",
    }
)
RECEIVED_LOG_SIZE = 10_000
HOME_UPDATE_S = 5.0
"""ArduPlane moves an unlocked home to the disarmed plane's position every 5 s at most."""
CRASH_DETECT_DISARM = 1
"""CRASH_DETECT's action bit: disarm on a detected crash."""


@dataclass(frozen=True)
class SimEvent:
    """Something the simulator records about a vehicle (its journal: the server logs it):
    ``kind`` is ``motor_stopped`` (battery empty), ``fell`` (came down after that),
    ``recovered`` (on deck), ``turnaround`` (rebooted with a fresh pack); ``t_s`` the
    simulator's time."""

    t_s: float
    system_id: int
    kind: str
    text: str


@dataclass(frozen=True)
class ReceivedCommand:
    """One command-like message the vehicle received (time in the vehicle's simulated
    seconds since the simulator started, not since boot)."""

    t_s: float
    kind: str
    src_system: int
    src_component: int
    command: int = 0
    armed: bool = False
    on_ground: bool = True
    mode: int = 0
    params: tuple[float, ...] = ()


class SimVehicle:
    """ArduPlane-compatible vehicle: protocol, autopilot and airframe in virtual time."""

    def __init__(self, config: VehicleConfig, t_s: float = 0.0) -> None:
        self.config = config
        self.params = ParamStore(default_param_specs(config.system_id, config.cruise_speed_m_s))
        for name, value in {**wind_param_values(config.wind), **config.params}.items():
            self.params.set(name, value)
        self.wind = FlownWind(config.wind, config.wind_seed)  # the air does not reboot
        self.airspeed_sensor = AirspeedSensor()  # a faulty pitot stays faulty at a reboot
        self.text = StatusTextFactory()
        self.home_lat_deg = config.home_lat_deg
        self.home_lon_deg = config.home_lon_deg
        self.home_amsl_m = config.home_amsl_m
        self.home_locked = False
        hx, hy, _ = config.origin.to_local(config.home_lat_deg, config.home_lon_deg)
        self.home_xy_m = (hx, hy)
        self.store = MissionStore(self._home_item())
        model = config.battery_model()
        self.battery = Battery(model)  # the pack is hardware: it survives reboots
        self.battery_energy_wh = 0.0
        """Energy drawn from the pack (``sum U I dt``; BATTERY_STATUS energy_consumed)."""
        if "BATT_CAPACITY" not in config.params:
            self.params.set("BATT_CAPACITY", model.capacity_mah)
        # rally points and the fence are stored in EEPROM: they survive reboots
        self.geo = GeoItemsServer(rerequest_s=REREQUEST_S, upload_timeout_s=UPLOAD_TIMEOUT_S)
        self.fence = SimFence(config.origin, lambda: self.geo.stores[M.MAV_MISSION_TYPE_FENCE],
                              self.params.get)
        self.ship = SimShip(config.ship, t_s) if config.ship is not None else None
        self.events: list[SimEvent] = []
        self.crashed = False
        self._turnaround_at_s: float | None = None
        self.reboots = 0
        self.kills = 0
        self.received: deque[ReceivedCommand] = deque(maxlen=RECEIVED_LOG_SIZE)
        self._dead_until_s: float | None = None
        self.handler_errors = 0
        self.last_handler_error = ""
        self._geodetic_cache: tuple[tuple[float, float], tuple[float, float]] = (
            (math.nan, math.nan),
            (0.0, 0.0),
        )
        self._boot(t_s)

    # ------------------------------------------------------------------ boot
    def _home_item(self) -> StoredItem:
        return StoredItem(
            M.MAV_CMD_NAV_WAYPOINT,
            M.MAV_FRAME_GLOBAL,
            x=round(self.home_lat_deg * 1e7),
            y=round(self.home_lon_deg * 1e7),
            z=self.home_amsl_m,
        )

    def _boot(self, t_s: float, airborne: bool | None = None) -> None:
        c = self.config
        self.t_boot_s = t_s
        self.t_s = t_s
        self.geo.reset()
        self.mission = MissionServer(self.store, self.text, self.geo)
        # de-phase the vehicles' 1 Hz streams (like independent autopilots) so that N
        # vehicles do not all burst in the same tick
        self.streams = StreamScheduler(t_s + (c.system_id * 0.137) % 1.0)
        self.autopilot = Autopilot(
            self.store,
            self.params,
            self.text,
            c.origin,
            self.home_xy_m,
            c.home_amsl_m,
            c.cruise_speed_m_s,
            rally_points=lambda: self.geo.stores[M.MAV_MISSION_TYPE_RALLY],
        )
        x0 = c.launch_x_m if c.launch_x_m is not None else self.home_xy_m[0]
        y0 = c.launch_y_m if c.launch_y_m is not None else self.home_xy_m[1]
        self.airframe = Airframe(x0, y0, c.launch_heading_rad, 0.0, 0.0, c.min_turn_radius_m)
        self.on_deck = self.ship is not None
        self.motor_stopped = False
        self.crashed = False
        self._next_home_update_s = t_s
        if self.ship is not None:
            self.home_locked = False  # a lock is RAM state: a reboot forgets it
            self._place_on_deck(t_s)
        self.wind_estimate = EkfWindModel()  # the EKF starts again at zero
        self.airspeed_sensor.booted()
        self.ready_flags = {"init": False, "gps": False, "ekf": False}
        self.home_set = False
        self.battery_low_sent = False
        self._next_prearm_report_s = t_s + PREARM_REPORT_S
        self._pending: list[Any] = []
        if c.airborne if airborne is None else airborne:
            self._start_airborne()

    def _start_airborne(self) -> None:
        c = self.config
        self.ready_flags = dict.fromkeys(self.ready_flags, True)
        self.home_set = True
        self.store.capacity = MAX_MISSION_ITEMS
        if len(self.store) <= 1:
            self.store.write(
                1,
                StoredItem(
                    M.MAV_CMD_NAV_LOITER_UNLIM,
                    M.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                    x=round(c.home_lat_deg * 1e7),
                    y=round(c.home_lon_deg * 1e7),
                    z=c.airborne_alt_m,
                ),
            )
        af = self.airframe
        af.on_ground, af.alt_m, af.speed_m_s = False, c.airborne_alt_m, c.cruise_speed_m_s
        self.on_deck = False
        self.autopilot.armed = True
        self.autopilot.current_seq = 1
        self._pending += self.autopilot.set_mode(AUTO, af)

    def reboot(self, t_s: float) -> list[Any]:
        """Restart the autopilot (mission and parameters persist, as in EEPROM). A vehicle
        configured ``airborne`` comes back armed in AUTO on item 1 where it was flying;
        otherwise it restarts on the ground at its launch point and boots as at power-on."""
        self.reboots += 1
        self.store.capacity = 0
        flying = None if self.airframe.on_ground else self.airframe
        self._boot(t_s)
        if flying is not None and self.config.airborne:
            # an airborne vehicle keeps flying where it was (the physics does not reboot)
            af = self.airframe
            af.x_m, af.y_m, af.heading_rad = flying.x_m, flying.y_m, flying.heading_rad
            af.alt_m, af.speed_m_s = flying.alt_m, flying.speed_m_s
        return self._drain()

    # ------------------------------------------------------------ kill/restart
    @property
    def alive(self) -> bool:
        """False while the autopilot process is dead (a ``kill`` fault)."""
        return self._dead_until_s is None

    def kill(self, t_s: float, for_s: float) -> None:
        """The autopilot process dies at ``t_s``: it sends nothing and hears nothing for
        ``for_s`` seconds, then restarts (see :meth:`_restart`)."""
        self.kills += 1
        self._pending = []
        self._dead_until_s = t_s + max(0.0, for_s)

    def _restart(self, t_s: float) -> None:
        """Power-on after a kill: on the ground where the aircraft came down, disarmed,
        ``time_boot_ms`` from 0, INITIALISING then MANUAL, the mission reloaded from
        storage (EEPROM), parameters kept, the same battery pack."""
        where = self.airframe
        was_on_deck = self.on_deck
        self._dead_until_s = None
        self.reboots += 1
        self.store.capacity = 0
        self._boot(t_s, airborne=False)
        if not (self.ship is not None and was_on_deck):
            af = self.airframe
            af.x_m, af.y_m, af.heading_rad = where.x_m, where.y_m, where.heading_rad
            self.on_deck = False

    def apply_fault(self, event: FaultEvent, t_s: float) -> list[Any]:
        """Apply a scheduled fault: kill, reboot, operator mode switch, low battery, or the
        airspeed sensor's fault starting or ending (:mod:`sitl.sim_airspeed`)."""
        out = self.step(t_s)
        if not self.alive:
            return out
        if event.kind == "kill":
            self.kill(t_s, event.duration_s)
            return []
        if event.kind == "reboot":
            return out + self.reboot(t_s)
        if event.kind == "mode" and self.ready_flags["init"] and event.mode in MODE_NAMES:
            return out + self.autopilot.set_mode(event.mode, self.airframe)
        if event.kind == "battery":
            return out + self.set_battery_remaining(event.fraction)
        if event.kind in ("airspeed", "airspeed_ok"):  # the health check notices it
            self.airspeed_sensor.faulty = event.kind == "airspeed"
        return out

    def _drain(self) -> list[Any]:
        out, self._pending = self._pending, []
        return out

    def take_pending(self) -> list[Any]:
        """What the vehicle has queued to send to every link (e.g. a new HOME_POSITION)."""
        return self._drain()

    # ----------------------------------------------------------- properties
    @property
    def system_id(self) -> int:
        """MAVLink system id."""
        return self.config.system_id

    @property
    def time_boot_ms(self) -> int:
        """Milliseconds since (re)boot in simulated time."""
        return self._time_boot_ms()

    def _time_boot_ms(self) -> int:
        return max(0, round((self.t_s - self.t_boot_s) * 1000.0))

    @property
    def prearm_ok(self) -> bool:
        """GPS and EKF settled: ready to arm."""
        return all(self.ready_flags.values())

    @property
    def battery_used_mah(self) -> float:
        """Charge drawn from the pack (mAh)."""
        return self.battery.used_mah

    @battery_used_mah.setter
    def battery_used_mah(self, value: float) -> None:
        self.battery.used_mah = min(self.battery.model.capacity_mah, max(0.0, value))

    @property
    def battery_remaining(self) -> float:
        """Remaining charge fraction in [0, 1] as the monitor reports it:
        ``1 - used_mAh / BATT_CAPACITY``."""
        cap = max(1.0, self.params.get("BATT_CAPACITY"))
        return max(0.0, 1.0 - self.battery_used_mah / cap)

    @property
    def battery_voltage_v(self) -> float:
        """Pack voltage (``world.battery.Battery.voltage_v``: linear in the charge left)."""
        return self.battery.voltage_v

    @property
    def failsafe_active(self) -> bool:
        """A failsafe (here: the low-battery one) has triggered."""
        return self.battery_low_sent

    @property
    def battery_current_a(self) -> float:
        """Pack current in the last physics step (the idle current before the first)."""
        if self.battery.current_a == 0.0 and not self.battery.empty:
            return self.battery.model.idle_current_a
        return self.battery.current_a

    def position_geodetic(self) -> tuple[float, float, float]:
        """(lat_deg, lon_deg, alt_amsl_m) of the aircraft."""
        af = self.airframe
        key = (af.x_m, af.y_m)
        if self._geodetic_cache[0] != key:  # GPS_RAW_INT and GLOBAL_POSITION_INT share it
            lat, lon, _ = self.config.origin.to_geodetic(af.x_m, af.y_m)
            self._geodetic_cache = (key, (lat, lon))
        lat, lon = self._geodetic_cache[1]
        return lat, lon, self.config.home_amsl_m + af.alt_m

    # ------------------------------------------------------------------ home
    def set_home(self, lat_deg: float, lon_deg: float, amsl_m: float, *, lock: bool) -> bool:
        """Move home (AP_AHRS::set_home): refused (False) for a latitude or longitude out
        of range or not finite, or an altitude not finite; mission item 0 follows (AP_Mission
        reads item 0 from the AHRS home); HOME_POSITION is sent to every link; ``lock``
        (DO_SET_HOME) stops the disarmed plane's home from following it."""
        if not (math.isfinite(lat_deg) and math.isfinite(lon_deg) and math.isfinite(amsl_m)):
            return False
        if abs(lat_deg) > 90.0 or abs(lon_deg) > 180.0:
            return False
        self.home_lat_deg, self.home_lon_deg, self.home_amsl_m = lat_deg, lon_deg, amsl_m
        hx, hy, _ = self.config.origin.to_local(lat_deg, lon_deg)
        self.home_xy_m = (hx, hy)
        self.autopilot.home_xy_m = self.home_xy_m
        self.store.set_home(self._home_item())
        self.home_set = True
        self.home_locked = self.home_locked or lock
        self._pending.append(build_message(self, M.MAVLINK_MSG_ID_HOME_POSITION))
        return True

    def home_from_current(self, *, lock: bool = False) -> bool:
        """Home = where the plane is now (DO_SET_HOME param1 = 1; the first fix); False
        without a GPS fix."""
        if not self.ready_flags["gps"]:
            return False
        lat, lon, _ = self.position_geodetic()
        return self.set_home(lat, lon, self.config.home_amsl_m, lock=lock)

    def home_on_arming(self) -> None:
        """AP_Arming_Plane::arm calls update_home: an unlocked home moves to the plane (on
        a ship's deck; elsewhere the simulator keeps its home, as before)."""
        if self.ship is not None and self.home_set and not self.home_locked:
            self.home_from_current()

    # ------------------------------------------------------------------ ship
    def _near_ship(self, af: Airframe, radius_m: float) -> bool:
        if self.ship is None:
            return False
        sx, sy = self.ship.position_m(self.t_s)
        return math.hypot(af.x_m - sx, af.y_m - sy) <= radius_m

    def _place_on_deck(self, t_s: float) -> None:
        """Stand on the ship: its position, its ground velocity, on the ground."""
        assert self.ship is not None
        af = self.airframe
        af.x_m, af.y_m = self.ship.position_m(t_s)
        af.on_ground, af.alt_m, af.speed_m_s, af.climb_m_s = True, 0.0, 0.0, 0.0
        af.turn_rate_rad_s = 0.0
        af.drift_xy_m_s = self.ship.velocity_m_s(t_s)
        self.on_deck = True

    def _record(self, kind: str, text: str) -> None:
        self.events.append(SimEvent(self.t_s, self.system_id, kind, text))

    @property
    def mode_name(self) -> str:
        """Name of the current mode."""
        return MODE_NAMES.get(self.autopilot.mode, str(self.autopilot.mode))

    # ------------------------------------------------------------------ step
    def step(self, t_s: float) -> list[Any]:
        """Advance to ``t_s`` (simulated seconds) and return what the vehicle sends."""
        if self._dead_until_s is not None:
            if t_s < self._dead_until_s:
                self.t_s = max(self.t_s, t_s)
                return []
            self._restart(self._dead_until_s)
        before: list[Any] = []
        if self._turnaround_at_s is not None and t_s >= self._turnaround_at_s:
            at_s, self._turnaround_at_s = self._turnaround_at_s, None
            before = self.step(at_s)
            self._turnaround(at_s)
        out = before + self._drain()
        while self.t_s < t_s - 1e-9:  # telemetry per physics step: rates hold at any tick
            dt = min(PHYSICS_DT_S, t_s - self.t_s)
            self.t_s += dt
            out += self._physics(dt)
            out += self._periodic()
        self.t_s = max(self.t_s, t_s)
        return out + self._periodic()

    def _periodic(self) -> list[Any]:
        out = self._boot_progress()
        out += self.mission.step(self.t_s)
        out += self._prearm_report()
        ap = self.autopilot
        if ap.current_changed:
            ap.current_changed = False
            out.append(build_message(self, M.MAVLINK_MSG_ID_MISSION_CURRENT))
        for msg_id in self.streams.due(self.t_s):
            msg = build_message(self, msg_id)
            if msg is not None:
                out.append(msg)
            if msg_id == M.MAVLINK_MSG_ID_SYS_STATUS and self.fence.enabled:
                out.append(self.fence.status_message())  # ArduPlane: EXTENDED_STATUS
        return out

    def _physics(self, dt_s: float) -> list[Any]:
        ap, af = self.autopilot, self.airframe
        if self.on_deck and af.on_ground:
            self._place_on_deck(self.t_s - dt_s)
        guidance, alt_cmd = ap.guidance(af)
        if self.motor_stopped:  # no thrust: wings level, sinking V / 10; no take-off
            guidance = GROUND if af.on_ground else GLIDE
        was_on_ground = af.on_ground
        alt0_m = af.alt_m
        wind = self.wind.at(self.t_s - dt_s, self.params)
        af.step(guidance, alt_cmd, ap.airspeed_cmd_m_s(), dt_s, wind)
        if self.on_deck:
            if af.on_ground:
                self._place_on_deck(self.t_s)
            else:
                self.on_deck = False  # took off from the deck
        sensor = self.airspeed_sensor
        self.wind_estimate.update(sensor.estimate_target(wind), dt_s, flying=not af.on_ground)
        out = self._drain_battery(dt_s, guidance.kind, (af.alt_m - alt0_m) / dt_s, wind)
        out += ap.update(self.t_s, af)
        for severity, text in sensor.step(dt_s, flying=not af.on_ground):
            out += self.text.make(text, severity)
        if af.on_ground and not was_on_ground and af.touchdown_sink_m_s is not None:
            # ArduPilot SITL prints this on its console; the built-in one sends it too
            out += self.text.make(
                f"SIM Hit ground at {af.touchdown_sink_m_s:.1f} m/s", M.MAV_SEVERITY_CRITICAL
            )
            if self.motor_stopped:
                out += self._crash()
        if not self.battery_low_sent and self.battery.voltage_v < self.params.get("BATT_LOW_VOLT"):
            out += self.battery_low()
        out += self._recovery()
        out += self._update_home()
        out += self._fence_check()  # every physics step: ArduPlane's 10 Hz
        return out

    def _fence_check(self) -> list[Any]:
        """ArduPlane's 10 Hz fence check (:mod:`sitl.fence`): a new breach acts by
        ``FENCE_ACTION`` (RTL, or GUIDED to the fence's return point)."""
        ap, af = self.autopilot, self.airframe
        mode, texts = self.fence.check(af.x_m, af.y_m, armed=ap.armed, mode=ap.mode,
                                       time_boot_ms=self._time_boot_ms)
        if mode is None and not texts:
            return []  # most steps: nothing to say or do
        out: list[Any] = []
        for text in texts:
            out += self.text.make(text, M.MAV_SEVERITY_NOTICE)
        if mode is not None:
            if mode != ap.mode:  # (ArduPlane ignores a switch to the mode it is in)
                out += ap.set_mode(mode, af)
            if mode == ArduPlaneMode.GUIDED:  # set_guided_WP: the return point, always
                ret = self.fence.return_point() or self.home_xy_m
                alt_cm = self.params.get("ALT_HOLD_RTL")
                alt_m = af.alt_m if alt_cm < 0 else alt_cm / 100.0
                ap.set_guided_target(ret[0], ret[1], alt_m, 0.0)
            self._record("fence", f"breach: {self.mode_name}")
        return out

    def _drain_battery(
        self, dt_s: float, guidance_kind: str, climb_m_s: float, wind: tuple[float, float]
    ) -> list[Any]:
        """Drain the pack for one step (module docstring); at 0 % the motor stops."""
        af = self.airframe
        motor_on = not af.on_ground and guidance_kind != "glide" and not self.motor_stopped
        battery = self.battery
        voltage_v = battery.drain(dt_s, af.speed_m_s, math.hypot(wind[0], wind[1]), climb_m_s,
                                  motor_on)
        self.battery_energy_wh += voltage_v * battery.current_a * dt_s / 3600.0
        if not battery.empty or self.motor_stopped or af.on_ground:
            return []
        self.motor_stopped = True
        text = (f"vehicle {self.system_id}: battery empty at t={self.t_s:.1f} s, "
                f"motor stopped at {af.alt_m:.0f} m")
        self._record("motor_stopped", text)
        return self.text.make(
            f"Battery 1 is critical {self.battery_voltage_v:.2f}V used "
            f"{self.battery_used_mah:.0f} mAh", M.MAV_SEVERITY_CRITICAL
        )

    def _crash(self) -> list[Any]:
        """The plane came down with a flat pack. ArduPlane's crash check
        (``crash_detection_update``): with CRASH_DETECT 0 (its default) nothing; otherwise
        "Crash detected" (EMERGENCY), HEARTBEAT EMERGENCY unless a failsafe shows CRITICAL,
        and with the disarm bit (a watch's vehicles have it) the plane disarms ("Throttle
        disarmed"). ArduPlane runs the check in AUTO only; here it runs after a
        battery-empty fall in any mode (docs/sitl.md, "Battery and the fall")."""
        af = self.airframe
        self._record("fell", f"vehicle {self.system_id} fell at t={self.t_s:.1f} s "
                             f"(battery empty) at x={af.x_m:.0f} m, y={af.y_m:.0f} m")
        action = int(self.params.get("CRASH_DETECT"))
        if action == 0:
            return []
        self.crashed = True
        out = self.text.make("Crash detected", M.MAV_SEVERITY_EMERGENCY)
        if action & CRASH_DETECT_DISARM:
            self.autopilot.armed = False
            out += self.text.make("Throttle disarmed")
        return out

    def _recovery(self) -> list[Any]:
        """A watch's recovery: armed, flying, in RTL or on a NAV_LAND item, within
        ``recovery_radius_m`` of the ship -> on deck, disarmed; the turnaround starts."""
        watch, ap, af = self.config.watch, self.autopilot, self.airframe
        if watch is None or self.ship is None or af.on_ground or not ap.armed:
            return []
        nav = ap.nav
        landing = ap.mode == AUTO and nav is not None and nav.kind in ("land", "landing")
        if not (ap.mode == RTL or landing) or not self._near_ship(af, watch.recovery_radius_m):
            return []
        ap.armed = False
        self._place_on_deck(self.t_s)
        self._turnaround_at_s = self.t_s + watch.turnaround_s
        self._record("recovered", f"vehicle {self.system_id} recovered on deck at "
                                  f"t={self.t_s:.1f} s, {100 * self.battery_remaining:.0f} % "
                                  f"left; ready again at t={self._turnaround_at_s:.1f} s")
        return [*self.text.make("SIM Recovered on deck"), *self.text.make("Throttle disarmed")]

    def _turnaround(self, t_s: float) -> None:
        """The battery swap is done: a fresh pack and a new boot on deck (home at the fix)."""
        self._turnaround_at_s = None
        self.battery.swap()
        self.battery_energy_wh = 0.0
        self.reboots += 1
        self.store.capacity = 0
        self._boot(t_s, airborne=False)
        self._record("turnaround", f"vehicle {self.system_id} rebooted on deck with a fresh "
                                   f"pack at t={t_s:.1f} s")

    def _update_home(self) -> list[Any]:
        """ArduPlane's update_home: on deck, disarmed, home set and not locked, home moves
        to the plane every 5 s."""
        if self.ship is None or not self.home_set or self.home_locked or self.autopilot.armed:
            return []
        if self.t_s < self._next_home_update_s:
            return []
        self._next_home_update_s = self.t_s + HOME_UPDATE_S
        self.home_from_current()
        return self._drain()

    def battery_low(self) -> list[Any]:
        """The low-battery failsafe: warn once, then the BATT_FS_LOW_ACT action."""
        self.battery_low_sent = True
        out = self.text.make(
            f"Battery 1 is low {self.battery_voltage_v:.2f}V used {self.battery_used_mah:.0f} mAh",
            M.MAV_SEVERITY_CRITICAL,
        )
        action = int(self.params.get("BATT_FS_LOW_ACT"))
        if action in (1, 2) and self.autopilot.armed and not self.airframe.on_ground:
            out += self.autopilot.set_mode(RTL, self.airframe)
        return out

    def set_battery_remaining(self, fraction: float) -> list[Any]:
        """Fault: drop the battery to ``fraction`` remaining."""
        cap = self.params.get("BATT_CAPACITY")
        self.battery_used_mah = max(self.battery_used_mah, (1.0 - fraction) * cap)
        return []

    def _boot_progress(self) -> list[Any]:
        flags = self.ready_flags
        if flags["init"] and flags["gps"] and flags["ekf"]:
            return []  # booted: nothing more to report until the next boot
        init_s, gps_s, ekf_s = self.config.boot_times_s
        age = self.t_s - self.t_boot_s
        out: list[Any] = []
        if not flags["init"] and age >= init_s:
            flags["init"] = True
            self.store.capacity = MAX_MISSION_ITEMS
            mode = int(self.params.get("INITIAL_MODE"))
            self.autopilot.mode = mode if mode in MODE_NAMES and mode != INITIALISING else MANUAL
            out += self.text.make("ArduPlane V4.7.0-dev (floe-sim)")
            out += self.text.make("Ready to FLY")
        if not flags["gps"] and age >= gps_s:
            flags["gps"] = True
            out += self.text.make("GPS 1: detected u-blox")
        if not flags["ekf"] and age >= ekf_s and flags["gps"]:
            flags["ekf"] = True
            self.home_set = True
            out += self.text.make("EKF3 IMU0 is using GPS")
            if self.ship is not None:  # home where it gets its fix: the deck, now
                self.home_from_current()
                self._pending.clear()  # the HOME_POSITION below is the one
                self._next_home_update_s = self.t_s + HOME_UPDATE_S
            out.append(build_message(self, M.MAVLINK_MSG_ID_HOME_POSITION))
        return out

    def prearm_failure(self) -> str | None:
        """Why arming is refused now, or None."""
        if not self.ready_flags["init"]:
            return "System not initialised"
        if not self.ready_flags["gps"]:
            return "GPS 1: Bad fix"
        if not self.ready_flags["ekf"]:
            return "AHRS: waiting for home"
        return None

    def _prearm_report(self) -> list[Any]:
        if self.t_s < self._next_prearm_report_s:
            return []
        self._next_prearm_report_s = self.t_s + PREARM_REPORT_S
        reason = self.prearm_failure()
        if reason is None or self.autopilot.armed:
            return []
        return self.text.make(f"PreArm: {reason}", M.MAV_SEVERITY_CRITICAL)

    # --------------------------------------------------------------- receive
    def receive(self, msg: Any, t_s: float) -> list[Any]:
        """Handle one message from a ground station; returns the answers. Never raises.
        A dead vehicle (``kill``) hears nothing."""
        if self._dead_until_s is not None:
            return []
        try:
            return self._receive(msg, max(t_s, self.t_s))
        except Exception as exc:  # defensive: bad peer input must never take the vehicle down
            self.handler_errors += 1  # counted (and kept) so tests and logs can see them
            self.last_handler_error = f"{msg.get_type()}: {exc!r}"
            return []

    def _receive(self, msg: Any, t_s: float) -> list[Any]:
        kind = msg.get_type()
        target = getattr(msg, "target_system", 0)
        if target not in (0, self.system_id) or kind == "BAD_DATA":
            return []
        if msg.get_srcSystem() == self.system_id and kind == "HEARTBEAT":
            return []
        if kind in COMMAND_MESSAGES:
            self._log_command(msg, kind, t_s)
        if kind in ("MISSION_ITEM", "MISSION_ITEM_INT") and int(msg.current) in (2, 3):
            return command_handler.guided_item(self, msg)
        if kind in MISSION_MESSAGES:
            events = MissionEvents()
            out = self.mission.handle(msg, t_s, events)
            rally = len(self.geo.stores[M.MAV_MISSION_TYPE_RALLY])
            if rally != self.params.get("RALLY_TOTAL"):  # AP_Rally counts what is stored
                self.params.set("RALLY_TOTAL", rally)
            return out
        if kind == "MISSION_SET_CURRENT":
            # GCS_MAVLINK::handle_mission_set_current: no ACK for a message, so ArduPilot
            # answers with MISSION_CURRENT carrying exactly the seq asked for
            ok, out = self.autopilot.set_current_item(int(msg.seq), self.airframe)
            if not ok:
                return out
            answer = build_message(self, M.MAVLINK_MSG_ID_MISSION_CURRENT)
            answer.seq = int(msg.seq)
            return [*out, answer]
        return command_handler.handle(self, msg, t_s)

    def _log_command(self, msg: Any, kind: str, t_s: float) -> None:
        command = int(getattr(msg, "command", 0) or 0)
        params: tuple[float, ...] = ()
        if kind == "SET_MODE":
            command = int(msg.custom_mode)
        elif kind in ("COMMAND_LONG", "COMMAND_INT"):
            params = tuple(float(getattr(msg, f"param{i}")) for i in range(1, 5))
            if kind == "COMMAND_LONG":
                params += tuple(float(getattr(msg, f"param{i}")) for i in range(5, 8))
        self.received.append(
            ReceivedCommand(
                t_s,
                kind,
                msg.get_srcSystem(),
                msg.get_srcComponent(),
                command,
                self.autopilot.armed,
                self.airframe.on_ground,
                self.autopilot.mode,
                params,
            )
        )

    def mode_of_custom(self) -> tuple[int, int]:
        """(base_mode, custom_mode) for HEARTBEAT."""
        ap = self.autopilot
        base = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | M.MAV_MODE_FLAG_STABILIZE_ENABLED
        if ap.mode in (AUTO, RTL, LOITER, GUIDED):
            base |= M.MAV_MODE_FLAG_GUIDED_ENABLED
        if ap.mode == AUTO:
            base |= M.MAV_MODE_FLAG_AUTO_ENABLED
        if ap.mode == MANUAL:
            base |= M.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
        if ap.armed:
            base |= M.MAV_MODE_FLAG_SAFETY_ARMED
        return base, ap.mode

    def heading_deg(self) -> float:
        """Compass heading."""
        return compass_deg_from_enu_rad(self.airframe.heading_rad)

    def groundspeed_vector_m_s(self) -> tuple[float, float]:
        """(east, north) ground velocity (air velocity plus wind)."""
        return self.airframe.ground_velocity_m_s
