"""Builds the telemetry messages of a simulated vehicle (:class:`sitl.vehicle_state.VehicleView`)
from its state.

In wind, as ArduPlane: VFR_HUD ``airspeed`` is the airspeed and ``groundspeed`` the ground
speed, ``heading`` the yaw; GLOBAL_POSITION_INT ``vx``/``vy`` are the ground velocity and
``hdg`` the yaw; GPS_RAW_INT ``vel`` is the ground speed and ``cog`` the course over
ground; ATTITUDE ``yaw`` the heading; WIND the vehicle's wind estimate
(:class:`sitl.sim_wind.EkfWindModel`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from domain.geodesy import compass_deg_from_enu_rad
from domain.modes import ArduPlaneMode
from groundstation.mavlink.codec import mavlink2
from sitl.vehicle_state import VehicleView

__all__ = ["autopilot_version", "build_message", "landed_state", "system_status"]

M = mavlink2
PREARM_BIT = M.MAV_SYS_STATUS_PREARM_CHECK
_SENSORS = (
    M.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | M.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | M.MAV_SYS_STATUS_SENSOR_3D_MAG
    | M.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | M.MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE
    | M.MAV_SYS_STATUS_SENSOR_GPS
    | M.MAV_SYS_STATUS_AHRS
    | M.MAV_SYS_STATUS_SENSOR_BATTERY
    | PREARM_BIT
)
CAPABILITIES = (
    M.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
    | M.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    | M.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    | M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
    | M.MAV_PROTOCOL_CAPABILITY_MAVLINK2
)
FLIGHT_SW_VERSION = (4 << 24) | (7 << 16) | (0 << 8) | M.FIRMWARE_VERSION_TYPE_DEV


def autopilot_version(v: VehicleView) -> Any:
    """AUTOPILOT_VERSION: ArduPlane 4.7.0-dev with the MISSION_INT capability."""
    return M.MAVLink_autopilot_version_message(
        CAPABILITIES,
        FLIGHT_SW_VERSION,
        0,
        0,
        0,
        [0] * 8,
        [0] * 8,
        [0] * 8,
        0x1209,
        0x5740,
        0xF10E0000 + v.system_id,
    )


GEOFENCE_HEALTH = M.MAV_SYS_STATUS_GEOFENCE
"""The geofence bits come from :meth:`sitl.fence.SimFence.status_bits`. ArduPlane without a
configured fence (FENCE_ENABLE 0, the default) reports the geofence not present, not
enabled, and healthy: AC_Fence::sys_status_failed() is false when the fence
is not present, and GCS_MAVLINK sets the health bit unless it failed. MAVProxy's fence
module says "fence breach" when that health bit goes from set to clear (it starts set), so
a vehicle that never sets it is reported breached on every connection."""


def _sys_status(v: VehicleView) -> Any:
    flags = v.ready_flags
    health = _SENSORS & ~(M.MAV_SYS_STATUS_SENSOR_GPS | M.MAV_SYS_STATUS_AHRS | PREARM_BIT)
    present, fence_enabled, fence_health = v.fence.status_bits()
    health |= fence_health
    if flags["gps"]:
        health |= M.MAV_SYS_STATUS_SENSOR_GPS
    if flags["ekf"]:
        health |= M.MAV_SYS_STATUS_AHRS
    if v.prearm_ok:
        health |= PREARM_BIT
    enabled = _SENSORS | fence_enabled
    if not v.airspeed_sensor.in_use:  # disabled by the health check: present, healthy
        enabled &= ~M.MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE
    return M.MAVLink_sys_status_message(
        _SENSORS | present,
        enabled,
        health,
        200,
        round(v.battery_voltage_v * 1000),  # mV
        round(v.battery_current_a * 100),  # cA
        round(v.battery_remaining * 100),  # %
        0,
        0,
        0,
        0,
        0,
        0,
    )


UINT16_UNKNOWN = 65535
INT16_UNKNOWN = 32767


def _battery(v: VehicleView) -> Any:
    """BATTERY_STATUS as ArduPlane's analog monitor (BATT_MONITOR 4) sends it
    (GCS_MAVLINK::send_battery_status): function and type UNKNOWN, temperature INT16_MAX
    (no sensor), no cell voltages so the pack's voltage in ``voltages[0]`` (mV) and
    UINT16_MAX in the other cells (MAVLink's rule), current in cA, consumed mAh, consumed
    energy in hJ (``consumed_wh * 36``), remaining %."""
    voltage_mv = min(65534, round(v.battery_voltage_v * 1000))
    energy_hj = round(v.battery_energy_wh * 36)
    return M.MAVLink_battery_status_message(
        0,
        M.MAV_BATTERY_FUNCTION_UNKNOWN,
        M.MAV_BATTERY_TYPE_UNKNOWN,
        INT16_UNKNOWN,
        [voltage_mv] + [UINT16_UNKNOWN] * 9,
        round(v.battery_current_a * 100),
        round(v.battery_used_mah),
        energy_hj,
        round(v.battery_remaining * 100),
    )


GPS_FIX_LOCKED = M.GPS_FIX_TYPE_RTK_FIXED
"""GPS_RAW_INT ``fix_type`` with a lock, as ArduPlane SITL reports it: its simulated u-blox
(SIM_GPS1_TYPE 1, the default) sends NAV-PVT with a 3D fix and the carrier solution
"fixed" flag, which AP_GPS_UBLOX reads as GPS_OK_FIX_3D_RTK_FIXED (6)."""
GPS_FIX_SEARCHING = M.GPS_FIX_TYPE_NO_FIX
"""``fix_type`` before the lock (SIM_GPS1_LCKTIME): NAV-PVT fix type 0, read as NO_FIX (1)."""
GPS_SATELLITES_LOCKED = 10
"""``satellites_visible`` with a lock: SIM_GPS1_NUMSATS, 10 by default."""
GPS_SATELLITES_SEARCHING = 3
"""``satellites_visible`` before the lock: the simulated u-blox reports 3."""
GPS_HDOP_X100 = 121
GPS_VDOP_X100 = 200
"""``eph``/``epv``: the simulated u-blox's NAV-DOP (hDOP 1.21, vDOP 2.00), locked or not."""


def _gps(v: VehicleView) -> Any:
    """GPS_RAW_INT as ArduPlane SITL sends it (the constants above): no fix and 3
    satellites until the simulated lock, then an RTK fixed fix with 10."""
    t_us = int(v.t_s * 1e6)
    if not v.ready_flags["gps"]:
        return M.MAVLink_gps_raw_int_message(
            t_us, GPS_FIX_SEARCHING, 0, 0, 0, GPS_HDOP_X100, GPS_VDOP_X100, 0, 0,
            GPS_SATELLITES_SEARCHING)
    lat, lon, alt = v.position_geodetic()
    af = v.airframe
    course_deg = v.heading_deg()
    if af.course_rad != af.heading_rad:
        course_deg = compass_deg_from_enu_rad(af.course_rad)
    return M.MAVLink_gps_raw_int_message(
        t_us,
        GPS_FIX_LOCKED,
        round(lat * 1e7),
        round(lon * 1e7),
        round(alt * 1000),
        GPS_HDOP_X100,
        GPS_VDOP_X100,
        round(af.ground_speed_m_s * 100),
        round(course_deg * 100) % 36000,
        GPS_SATELLITES_LOCKED,
    )


def _global_position(v: VehicleView) -> Any:
    if not v.ready_flags["ekf"]:
        return M.MAVLink_global_position_int_message(v.time_boot_ms, 0, 0, 0, 0, 0, 0, 0, 0)
    lat, lon, alt = v.position_geodetic()
    ve, vn = v.groundspeed_vector_m_s()
    return M.MAVLink_global_position_int_message(
        v.time_boot_ms,
        round(lat * 1e7),
        round(lon * 1e7),
        round(alt * 1000),
        round(v.airframe.alt_m * 1000),
        round(vn * 100),
        round(ve * 100),
        round(-v.airframe.climb_m_s * 100),
        round(v.heading_deg() * 100) % 36000,
    )


def _attitude(v: VehicleView) -> Any:
    af = v.airframe
    yaw = math.radians(v.heading_deg())
    yaw = yaw - 2 * math.pi if yaw > math.pi else yaw
    pitch = math.atan2(af.climb_m_s, max(af.speed_m_s, 1.0))
    return M.MAVLink_attitude_message(
        v.time_boot_ms, af.roll_rad, pitch, yaw, 0.0, 0.0, -af.turn_rate_rad_s
    )


def _vfr_hud(v: VehicleView) -> Any:
    af = v.airframe
    throttle = 0 if af.on_ground else 60
    return M.MAVLink_vfr_hud_message(
        af.speed_m_s,
        af.ground_speed_m_s,
        round(v.heading_deg()) % 360,
        throttle,
        v.config.home_amsl_m + af.alt_m,
        af.climb_m_s,
    )


def _wind(v: VehicleView) -> Any:
    return M.MAVLink_wind_message(*v.wind_estimate.message_fields())


def _home(v: VehicleView) -> Any:
    if not v.home_set:
        return None
    return M.MAVLink_home_position_message(
        round(v.home_lat_deg * 1e7),
        round(v.home_lon_deg * 1e7),
        round(v.home_amsl_m * 1000),
        0.0,
        0.0,
        0.0,
        [1.0, 0.0, 0.0, 0.0],
        0.0,
        0.0,
        0.0,
        int(v.t_s * 1e6),
    )


def _mission_current(v: VehicleView) -> Any:
    ap = v.autopilot
    total = max(0, len(v.store) - 1)
    auto = ap.mode == ArduPlaneMode.AUTO
    if total == 0:
        state = M.MISSION_STATE_NO_MISSION
    elif ap.mission_complete:
        state = M.MISSION_STATE_COMPLETE
    elif auto:
        state = M.MISSION_STATE_ACTIVE
    else:
        state = M.MISSION_STATE_PAUSED if ap.current_seq > 1 else M.MISSION_STATE_NOT_STARTED
    return M.MAVLink_mission_current_message(ap.current_seq, total, state, int(auto))


def _nav_controller(v: VehicleView) -> Any:
    nav = v.autopilot.nav
    af = v.airframe
    if nav is None:
        return M.MAVLink_nav_controller_output_message(0, 0, 0, 0, 0, 0, 0, 0)
    bearing = math.degrees(math.atan2(nav.x_m - af.x_m, nav.y_m - af.y_m)) % 360
    return M.MAVLink_nav_controller_output_message(
        math.degrees(af.roll_rad),
        0.0,
        round(bearing),
        round(bearing),
        min(65535, round(af.distance_to_m(nav.x_m, nav.y_m))),
        nav.alt_m - af.alt_m,
        0.0,
        0.0,
    )


def system_status(v: VehicleView) -> int:
    """HEARTBEAT ``system_status`` as ArduPlane's ``vehicle_system_status()``: CALIBRATING
    while INITIALISING, CRITICAL while a failsafe is active, EMERGENCY once a crash was
    detected (needs CRASH_DETECT, 0 by default: only the fall at 0 % with it set), ACTIVE
    while flying, else STANDBY (armed or not: a plane armed on the ground, or one that came
    down, is STANDBY)."""
    if not v.ready_flags["init"]:
        return int(M.MAV_STATE_CALIBRATING)
    if v.failsafe_active:
        return int(M.MAV_STATE_CRITICAL)
    if v.crashed:
        return int(M.MAV_STATE_EMERGENCY)
    if not v.airframe.on_ground:
        return int(M.MAV_STATE_ACTIVE)
    return int(M.MAV_STATE_STANDBY)


def landed_state(v: VehicleView) -> int:
    """EXTENDED_SYS_STATE ``landed_state`` as ArduPlane's ``landed_state()``: ON_GROUND
    unless flying; flying: TAKEOFF on a NAV_TAKEOFF item, LANDING on a NAV_LAND item,
    else IN_AIR."""
    if v.airframe.on_ground:
        return int(M.MAV_LANDED_STATE_ON_GROUND)
    nav = v.autopilot.nav if v.autopilot.mode == ArduPlaneMode.AUTO else None
    if nav is not None and nav.kind == "takeoff":
        return int(M.MAV_LANDED_STATE_TAKEOFF)
    if nav is not None and nav.kind in ("land", "landing"):
        return int(M.MAV_LANDED_STATE_LANDING)
    return int(M.MAV_LANDED_STATE_IN_AIR)


def _heartbeat(v: VehicleView) -> Any:
    base, custom = v.mode_of_custom()
    return M.MAVLink_heartbeat_message(
        M.MAV_TYPE_FIXED_WING, M.MAV_AUTOPILOT_ARDUPILOTMEGA, base, custom, system_status(v), 3
    )


def _system_time(v: VehicleView) -> Any:
    unix_us = int((v.config.unix_time_at_zero_s + v.t_s) * 1e6)
    return M.MAVLink_system_time_message(unix_us, v.time_boot_ms)


def _extended_sys_state(v: VehicleView) -> Any:
    return M.MAVLink_extended_sys_state_message(M.MAV_VTOL_STATE_UNDEFINED, landed_state(v))


_BUILDERS: dict[int, Callable[[VehicleView], Any]] = {
    M.MAVLINK_MSG_ID_HEARTBEAT: _heartbeat,
    M.MAVLINK_MSG_ID_SYS_STATUS: _sys_status,
    M.MAVLINK_MSG_ID_BATTERY_STATUS: _battery,
    M.MAVLINK_MSG_ID_GPS_RAW_INT: _gps,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: _global_position,
    M.MAVLINK_MSG_ID_ATTITUDE: _attitude,
    M.MAVLINK_MSG_ID_VFR_HUD: _vfr_hud,
    M.MAVLINK_MSG_ID_WIND: _wind,
    M.MAVLINK_MSG_ID_HOME_POSITION: _home,
    M.MAVLINK_MSG_ID_MISSION_CURRENT: _mission_current,
    M.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT: _nav_controller,
    M.MAVLINK_MSG_ID_AUTOPILOT_VERSION: autopilot_version,
    M.MAVLINK_MSG_ID_SYSTEM_TIME: _system_time,
    M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: _extended_sys_state,
}
"""The builder of each message id the vehicle can send (built once, not per message)."""


def build_message(v: VehicleView, msg_id: int) -> Any:
    """The message ``msg_id`` as the vehicle would send it now (None if it has none)."""
    builder = _BUILDERS.get(msg_id)
    return builder(v) if builder is not None else None
