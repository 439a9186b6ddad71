"""Events and the snapshot that the telemetry reducer (:mod:`.telemetry`) produces.

Every event carries ``t_s``, the mission time at which the message that caused it arrived.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from domain.modes import ARDUPLANE_MODES, mode_name
from groundstation.mavlink.gps_message import GpsFix

__all__ = [
    "ARDUPLANE_MODES",
    "Armed",
    "BatteryBelowThreshold",
    "Disarmed",
    "InvalidTelemetry",
    "MissionCurrentChanged",
    "MissionItemReached",
    "ModeChanged",
    "PrearmChanged",
    "Rebooted",
    "StatusText",
    "TelemetryEvent",
    "VehicleSnapshot",
    "WindReported",
    "mode_name",
]

# --------------------------------------------------------------------------- events


@dataclass(frozen=True)
class ModeChanged:
    t_s: float
    old: int | None
    new: int
    old_name: str | None
    new_name: str


@dataclass(frozen=True)
class Armed:
    t_s: float


@dataclass(frozen=True)
class Disarmed:
    t_s: float


@dataclass(frozen=True)
class MissionItemReached:
    t_s: float
    seq: int


@dataclass(frozen=True)
class MissionCurrentChanged:
    t_s: float
    old: int | None
    seq: int
    total: int | None


@dataclass(frozen=True)
class StatusText:
    """A whole STATUSTEXT (chunks reassembled); ``complete`` False if chunks went missing."""

    t_s: float
    severity: int
    text: str
    complete: bool = True


@dataclass(frozen=True)
class Rebooted:
    t_s: float
    previous_time_boot_ms: int
    time_boot_ms: int


@dataclass(frozen=True)
class BatteryBelowThreshold:
    t_s: float
    remaining_pct: float | None
    voltage_v: float | None
    threshold_pct: float


@dataclass(frozen=True)
class PrearmChanged:
    t_s: float
    ok: bool


@dataclass(frozen=True)
class InvalidTelemetry:
    """A value that was dropped instead of stored."""

    t_s: float
    message: str
    field: str
    value: Any


@dataclass(frozen=True)
class WindReported:
    """The vehicle's own wind estimate, accepted on evidence (:class:`~groundstation.mavlink.
    evidence.WindEvidence`): the ENU vector the air moves towards (m/s), and the vertical
    wind (m/s, as the WIND message's ``speed_z``: positive down in ArduPilot's NED)."""

    t_s: float
    wx_m_s: float
    wy_m_s: float
    speed_z_m_s: float


TelemetryEvent = (
    ModeChanged
    | Armed
    | Disarmed
    | MissionItemReached
    | MissionCurrentChanged
    | StatusText
    | Rebooted
    | BatteryBelowThreshold
    | PrearmChanged
    | InvalidTelemetry
    | WindReported
)


@dataclass(frozen=True)
class VehicleSnapshot:
    """The latest known state of one vehicle (None: not heard yet).

    ``system_status``: HEARTBEAT MAV_STATE_* (ArduPlane: CRITICAL while a failsafe is
    active); ``landed_state``: EXTENDED_SYS_STATE MAV_LANDED_STATE_* (None where the
    autopilot reports none); ``reboot_suspected``: ``time_boot_ms`` went back and the
    reducer waits for evidence (see :class:`~groundstation.mavlink.evidence.RebootEvidence`);
    ``wind_xy_m_s``: the WIND message's estimate, accepted over several frames (ENU m/s the
    air moves towards; ``last_wind_s`` when it was last accepted).
    """

    system_id: int
    x_m: float | None = None
    y_m: float | None = None
    alt_m: float | None = None
    ve_m_s: float | None = None
    vn_m_s: float | None = None
    heading_rad: float | None = None
    speed_m_s: float | None = None
    airspeed_m_s: float | None = None
    mode: int | None = None
    mode_name: str | None = None
    armed: bool | None = None
    mission_current_seq: int | None = None
    mission_total: int | None = None
    mission_state: int | None = None
    """MISSION_CURRENT's ``mission_state`` (MAVLink 2 extension, MISSION_STATE_*); None
    where the autopilot does not report it (0, UNKNOWN, or a MAVLink 1 frame)."""
    battery_remaining_pct: float | None = None
    battery_voltage_v: float | None = None
    battery_current_a: float | None = None
    """SYS_STATUS / BATTERY_STATUS ``current_battery`` (cA -> A); None where the autopilot
    says it does not know (-1), or before it said anything."""
    home: tuple[float, float, float] | None = None
    """The autopilot's home as its last HOME_POSITION said: (lat_deg, lon_deg, alt_m AMSL)."""
    home_xy_m: tuple[float, float] | None = None
    """That home in local ENU (m), with the mission origin."""
    last_home_s: float | None = None
    """When the last valid HOME_POSITION arrived (mission s)."""
    prearm_ok: bool | None = None
    last_heard_s: float | None = None
    last_heartbeat_s: float | None = None
    last_position_s: float | None = None
    position_boot_ms: int | None = None
    """The ``time_boot_ms`` of the position (``x_m``, ``y_m``): the vehicle's own time of the
    fix, which telemetry age is measured with (None after a reboot until the next fix)."""
    time_boot_ms: int | None = None
    system_status: int | None = None
    landed_state: int | None = None
    reboot_suspected: bool = False
    wind_xy_m_s: tuple[float, float] | None = None
    """The vehicle's own wind estimate (ENU, towards), once accepted on evidence."""
    last_wind_s: float | None = None
    sensors: tuple[int, int, int] | None = None
    """SYS_STATUS ``onboard_control_sensors_present``, ``_enabled``, ``_health`` (the last)."""
    gps_fix: GpsFix | None = None
    """The last GPS_RAW_INT's fix type, satellites and HDOP (:mod:`.gps_message`; a field
    that was unknown or garbage is None); None before the first, and after a reboot."""
    last_gps_s: float | None = None
    """When that GPS_RAW_INT arrived (mission s)."""

    @property
    def course_rad(self) -> float | None:
        """ENU course over ground from the velocity, when moving faster than 1 m/s."""
        if self.ve_m_s is None or self.vn_m_s is None:
            return None
        if math.hypot(self.ve_m_s, self.vn_m_s) < 1.0:
            return None
        return math.atan2(self.vn_m_s, self.ve_m_s)
