"""What the command handler and the telemetry builder may see of a simulated vehicle.

:class:`VehicleConfig` (everything that defines one vehicle) and :class:`VehicleView` (the
state and operations of a running one, as a structural Protocol) live here so that
``sitl.vehicle`` can import ``sitl.command_handler`` and ``sitl.vehicle_messages`` while
neither imports ``sitl.vehicle`` back (not even for type checking): the import graph of
``sitl`` has no cycle.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

from domain.geodesy import GeoOrigin
from sitl.airframe import Airframe
from sitl.autopilot import Autopilot
from sitl.fence import SimFence
from sitl.mission_store import MissionStore
from sitl.params import ParamStore
from sitl.sim_airspeed import AirspeedSensor
from sitl.sim_wind import EkfWindModel
from sitl.statustext import StatusTextFactory
from sitl.telemetry import StreamScheduler
from world.battery import BatteryModel
from world.scenario import BoatSpec, WatchSpec
from world.wind import WindSpec

__all__ = ["DEFAULT_ENDURANCE_S", "VehicleConfig", "VehicleView"]

DEFAULT_ENDURANCE_S = 2400.0
"""The pack's flight time at cruise in still air without a watch: the 10 000 mAh pack at
15 A (``3.6 * 10000 / 15`` s), the figures the simulator used before the battery model."""


@dataclass(frozen=True)
class VehicleConfig:
    """Everything that defines one simulated vehicle. ``wind``: the wind it flies in
    (``WindField(wind, wind_seed)``, the SIM_WIND_* parameters' initial values; calm by
    default). ``battery``: the pack's model (None: ``BatteryModel(DEFAULT_ENDURANCE_S,
    cruise_speed_m_s)``). ``ship``: the ship it stands on when on the ground (a watch's
    deck, :mod:`sitl.ship`; None: the ground at its launch point). ``watch``: the scenario's
    watch (recovery radius, turnaround; None: no recovery, today's behaviour)."""

    system_id: int
    origin: GeoOrigin
    home_lat_deg: float
    home_lon_deg: float
    home_amsl_m: float = 0.0
    cruise_speed_m_s: float = 22.0
    min_turn_radius_m: float = 105.0
    launch_x_m: float | None = None
    launch_y_m: float | None = None
    launch_heading_rad: float = 0.0
    airborne: bool = False
    airborne_alt_m: float = 100.0
    fast_boot: bool = False
    unix_time_at_zero_s: float = 1.7e9
    component_id: int = 1
    params: dict[str, float] = field(default_factory=dict)
    wind: WindSpec = field(default_factory=WindSpec)
    wind_seed: int = 0
    battery: BatteryModel | None = None
    ship: BoatSpec | None = None
    watch: WatchSpec | None = None

    def battery_model(self) -> BatteryModel:
        """The pack's model (``battery``, else the default at this cruise airspeed)."""
        if self.battery is not None:
            return self.battery
        return BatteryModel(endurance_s=DEFAULT_ENDURANCE_S,
                            cruise_speed_m_s=self.cruise_speed_m_s)

    @property
    def boot_times_s(self) -> tuple[float, float, float]:
        """(init, GPS fix, EKF ready) seconds after boot."""
        return (0.5, 1.0, 2.0) if self.fast_boot else (2.0, 10.0, 20.0)


class VehicleView(Protocol):
    """The parts of :class:`sitl.vehicle.SimVehicle` that message handlers use."""

    config: VehicleConfig
    params: ParamStore
    text: StatusTextFactory
    store: MissionStore
    streams: StreamScheduler
    autopilot: Autopilot
    airframe: Airframe
    ready_flags: dict[str, bool]
    home_set: bool
    home_lat_deg: float
    home_lon_deg: float
    home_amsl_m: float
    battery_low_sent: bool
    crashed: bool
    battery_used_mah: float
    t_s: float
    wind_estimate: EkfWindModel
    airspeed_sensor: AirspeedSensor
    fence: SimFence

    @property
    def system_id(self) -> int: ...

    @property
    def time_boot_ms(self) -> int: ...

    @property
    def prearm_ok(self) -> bool: ...

    @property
    def battery_remaining(self) -> float: ...

    @property
    def battery_voltage_v(self) -> float: ...

    @property
    def battery_current_a(self) -> float: ...

    @property
    def battery_energy_wh(self) -> float: ...

    @property
    def failsafe_active(self) -> bool: ...

    def position_geodetic(self) -> tuple[float, float, float]: ...

    def mode_of_custom(self) -> tuple[int, int]: ...

    def heading_deg(self) -> float: ...

    def groundspeed_vector_m_s(self) -> tuple[float, float]: ...

    def prearm_failure(self) -> str | None: ...

    def reboot(self, t_s: float) -> list[Any]: ...

    def set_home(self, lat_deg: float, lon_deg: float, amsl_m: float, *, lock: bool) -> bool: ...

    def home_from_current(self, *, lock: bool = False) -> bool: ...

    def take_pending(self) -> list[Any]: ...

    def home_on_arming(self) -> None: ...
