"""Commands, modes, arming, streams and parameters of a simulated ArduPlane.

COMMAND_LONG and COMMAND_INT share one dispatcher; every command is answered with
COMMAND_ACK (UNSUPPORTED for unknown ones, FAILED/DENIED where ArduPlane refuses):

* COMPONENT_ARM_DISARM: arming before GPS/EKF settle -> FAILED + "Arm: <reason>"
  (param2 = 2989 forces); disarming in flight needs param2 = 21196.
* DO_SET_MODE (param1 has MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, param2 mode): unknown mode ->
  FAILED + "No such mode N"; without the custom-mode flag UNSUPPORTED; SET_MODE (message)
  is acked with command = 11 and no target, as ArduPilot does.
* MISSION_START (-> AUTO), NAV_LOITER_UNLIM (-> LOITER), TIMESYNC requests answered;
* DO_SET_MISSION_CURRENT (COMMAND_ACK, then the queued MISSION_CURRENT),
  NAV_RETURN_TO_LAUNCH, DO_CHANGE_SPEED, SET_MESSAGE_INTERVAL, REQUEST_MESSAGE,
  REQUEST_AUTOPILOT_CAPABILITIES, GET_HOME_POSITION, PREFLIGHT_REBOOT_SHUTDOWN;
  DO_REPOSITION only as COMMAND_INT: ACCEPTED if param2 has
  MAV_DO_REPOSITION_FLAGS_CHANGE_MODE or the vehicle already is in GUIDED, else FAILED;
  |lat| > 90 or |lon| > 180 -> DENIED.
* DO_SET_HOME (GCS_MAVLINK::handle_command_do_set_home; COMMAND_LONG is handled as the
  COMMAND_INT it converts to): param1 = 1, or latitude and longitude both 0, -> home = the
  current location; param1 = 0 -> the given point (COMMAND_INT: x/y degE7, z in ``frame``;
  COMMAND_LONG: param5/6 degrees, param7 m AMSL); any other param1 FAILED; an altitude that
  is not finite or beyond LOCATION_ALT_MAX_M, or a frame other than the global ones,
  DENIED; a latitude or longitude out of range (AP_AHRS::set_home's check) or no position
  yet FAILED. Accepted: home moves and is locked, mission item 0 follows, COMMAND_ACK
  ACCEPTED, then HOME_POSITION to every link (AP_AHRS::set_home queues MSG_HOME).
"""

from __future__ import annotations

import math
from typing import Any

from groundstation.mavlink.codec import mavlink2
from sitl.autopilot import AUTO, GUIDED, INITIALISING, LOITER, MODE_NAMES, RTL
from sitl.mission_store import LOCATION_ALT_MAX_M
from sitl.telemetry import STREAMABLE
from sitl.vehicle_messages import autopilot_version, build_message
from sitl.vehicle_state import VehicleView

__all__ = ["guided_item", "handle"]

M = mavlink2
FORCE_ARM = 2989
FORCE_DISARM = 21196


def _int(value: float) -> int:
    """C-like float -> int for a command parameter; NaN, inf or huge values give -1."""
    return int(value) if math.isfinite(value) and abs(value) < 2**31 else -1


def _ack(msg: Any, command: int, result: int) -> Any:
    return M.MAVLink_command_ack_message(
        command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()
    )


def _param_name(raw: Any) -> str:
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", errors="replace")
    return str(raw).rstrip("\x00")


def handle(v: VehicleView, msg: Any, t_s: float) -> list[Any]:
    """Answer a non-mission message (unknown types are ignored)."""
    kind = msg.get_type()
    if kind == "COMMAND_LONG":
        p = [
            float(msg.param1),
            float(msg.param2),
            float(msg.param3),
            float(msg.param4),
            float(msg.param5),
            float(msg.param6),
            float(msg.param7),
        ]
        return _command(v, msg, int(msg.command), p, None, t_s)
    if kind == "COMMAND_INT":
        p = [
            float(msg.param1),
            float(msg.param2),
            float(msg.param3),
            float(msg.param4),
            float(msg.x),
            float(msg.y),
            float(msg.z),
        ]
        return _command(v, msg, int(msg.command), p, int(msg.frame), t_s)
    if kind == "SET_MODE":
        # ArduPilot acks SET_MODE with command = 11 and no target (to every link)
        ack_id = M.MAVLINK_MSG_ID_SET_MODE
        if not int(msg.base_mode) & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return [M.MAVLink_command_ack_message(ack_id, M.MAV_RESULT_UNSUPPORTED)]
        result, out = _set_mode(v, int(msg.custom_mode))
        return [*out, M.MAVLink_command_ack_message(ack_id, result)]
    if kind == "TIMESYNC":  # answer requests (tc1 = 0) with our clock, as ArduPilot does
        if int(msg.tc1) != 0:
            return []
        return [M.MAVLink_timesync_message(int(v.t_s * 1e9), int(msg.ts1))]
    if kind in ("RADIO_STATUS", "RADIO"):  # our radio's buffer: ArduPilot's flow control
        v.streams.radio_status(int(msg.txbuf))
        return []
    if kind == "REQUEST_DATA_STREAM":
        v.streams.set_group(
            int(msg.req_stream_id), float(msg.req_message_rate), bool(msg.start_stop), t_s
        )
        return []
    if kind == "PARAM_REQUEST_LIST":
        return [v.params.param_value(name) for name in v.params.names()]
    if kind == "PARAM_REQUEST_READ":
        # as ArduPilot (GCS_MAVLINK::param_io_timer): index -1 reads by name, any other
        # index by index (a negative one names nothing); no answer for what does not exist;
        # the answer echoes the request's index (by name: -1, 65535 on the wire)
        index = int(msg.param_index)
        name = _param_name(msg.param_id) if index == -1 else v.params.name_at(index)
        if name is None or v.params.index_of(name) is None:
            return []
        return [v.params.param_value(name, by_name=index == -1)]
    if kind == "PARAM_SET":
        name = _param_name(msg.param_id)
        if v.params.index_of(name) is None:
            return []
        v.params.set(name, float(msg.param_value))
        return [v.params.param_value(name)]
    return []


def _set_mode(v: VehicleView, mode: int) -> tuple[int, list[Any]]:
    if mode not in MODE_NAMES or mode == INITIALISING:
        return M.MAV_RESULT_FAILED, v.text.make(f"No such mode {mode}", M.MAV_SEVERITY_WARNING)
    if not v.ready_flags["init"]:
        return M.MAV_RESULT_FAILED, []
    if mode == v.autopilot.mode:
        return M.MAV_RESULT_ACCEPTED, []
    out = v.autopilot.set_mode(mode, v.airframe)
    return M.MAV_RESULT_ACCEPTED, out


def _arm(v: VehicleView, msg: Any, p: list[float]) -> list[Any]:
    cmd = M.MAV_CMD_COMPONENT_ARM_DISARM
    ap = v.autopilot
    if p[0] == 1.0:
        if ap.armed:
            return [_ack(msg, cmd, M.MAV_RESULT_ACCEPTED)]
        reason = v.prearm_failure()
        if reason is not None and _int(p[1]) != FORCE_ARM:
            return [
                *v.text.make(f"Arm: {reason}", M.MAV_SEVERITY_CRITICAL),
                _ack(msg, cmd, M.MAV_RESULT_FAILED),
            ]
        ap.armed = True
        v.home_on_arming()
        return [*v.text.make("Throttle armed"), _ack(msg, cmd, M.MAV_RESULT_ACCEPTED),
                *_drain(v)]
    if p[0] == 0.0:
        if not v.airframe.on_ground and _int(p[1]) != FORCE_DISARM:
            return [_ack(msg, cmd, M.MAV_RESULT_FAILED)]
        ap.armed = False
        v.airframe.on_ground = True
        v.airframe.alt_m = 0.0
        return [*v.text.make("Throttle disarmed"), _ack(msg, cmd, M.MAV_RESULT_ACCEPTED)]
    return [_ack(msg, cmd, M.MAV_RESULT_DENIED)]


def _request_message(v: VehicleView, msg_id: int) -> Any:
    if msg_id == M.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
        return autopilot_version(v)
    if msg_id in STREAMABLE or msg_id in (M.MAVLINK_MSG_ID_HOME_POSITION,):
        return build_message(v, msg_id)
    return None


_REPOSITION_FRAMES = frozenset(
    {
        M.MAV_FRAME_GLOBAL,
        M.MAV_FRAME_GLOBAL_INT,
        M.MAV_FRAME_GLOBAL_RELATIVE_ALT,
        M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        M.MAV_FRAME_GLOBAL_TERRAIN_ALT,
        M.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
    }
)


def _reposition(v: VehicleView, msg: Any, p: list[float], frame: int | None) -> list[Any]:
    """ArduPlane's handle_command_int_do_reposition: param3 > 0 sets the loiter radius,
    param4 != 0 loiters counter-clockwise; accepted only with the change-mode flag in
    param2 or when already in GUIDED."""
    cmd = M.MAV_CMD_DO_REPOSITION
    if frame is None:
        return [_ack(msg, cmd, M.MAV_RESULT_UNSUPPORTED)]
    lat, lon = p[4] * 1e-7, p[5] * 1e-7
    if (
        abs(lat) > 90.0
        or abs(lon) > 180.0
        or frame not in _REPOSITION_FRAMES
        or (not math.isfinite(p[6]))
    ):
        return [_ack(msg, cmd, M.MAV_RESULT_DENIED)]
    change_mode = max(0, _int(p[1])) & M.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE
    if not (change_mode or v.autopilot.mode == GUIDED) or not v.ready_flags["init"]:
        return [_ack(msg, cmd, M.MAV_RESULT_FAILED)]
    out: list[Any] = []
    if v.autopilot.mode != GUIDED:
        out += v.autopilot.set_mode(GUIDED, v.airframe)
    x_m, y_m, _ = v.config.origin.to_local(lat, lon)
    alt_m = p[6]
    if frame in (M.MAV_FRAME_GLOBAL, M.MAV_FRAME_GLOBAL_INT):
        alt_m -= v.config.home_amsl_m
    radius = p[2] if math.isfinite(p[2]) and p[2] > 0 else 0.0
    counter_clockwise = math.isfinite(p[3]) and p[3] != 0.0
    if radius == 0.0:
        radius = abs(v.params.get("WP_LOITER_RAD"))
    v.autopilot.set_guided_target(x_m, y_m, alt_m, -radius if counter_clockwise else radius)
    return [*out, _ack(msg, cmd, M.MAV_RESULT_ACCEPTED)]


_HOME_FRAMES = frozenset(
    {
        M.MAV_FRAME_GLOBAL,
        M.MAV_FRAME_GLOBAL_INT,
        M.MAV_FRAME_GLOBAL_RELATIVE_ALT,
        M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    }
)


def _set_home(v: VehicleView, msg: Any, p: list[float], frame: int | None) -> list[Any]:
    """MAV_CMD_DO_SET_HOME (module docstring)."""
    cmd = M.MAV_CMD_DO_SET_HOME
    is_int = frame is not None
    if is_int:
        lat_deg, lon_deg = p[4] * 1e-7, p[5] * 1e-7
    else:
        lat_deg, lon_deg = p[4], p[5]
    if p[0] == 1.0 or (lat_deg == 0.0 and lon_deg == 0.0):
        ok = v.home_from_current(lock=True)
        return [_ack(msg, cmd, M.MAV_RESULT_ACCEPTED if ok else M.MAV_RESULT_FAILED), *_drain(v)]
    if p[0] != 0.0:
        return [_ack(msg, cmd, M.MAV_RESULT_FAILED)]
    if not math.isfinite(p[6]) or abs(p[6]) >= LOCATION_ALT_MAX_M:
        return [_ack(msg, cmd, M.MAV_RESULT_DENIED)]
    if is_int and frame not in _HOME_FRAMES:
        return [_ack(msg, cmd, M.MAV_RESULT_DENIED)]
    amsl_m = p[6]
    if frame in (M.MAV_FRAME_GLOBAL_RELATIVE_ALT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT):
        amsl_m += v.home_amsl_m
    if not v.ready_flags["gps"] or not v.set_home(lat_deg, lon_deg, amsl_m, lock=True):
        return [_ack(msg, cmd, M.MAV_RESULT_FAILED)]
    return [_ack(msg, cmd, M.MAV_RESULT_ACCEPTED), *_drain(v)]


def _drain(v: VehicleView) -> list[Any]:
    """The vehicle's pending broadcasts (a new home's HOME_POSITION), sent after the ack."""
    return v.take_pending()


def _command(
    v: VehicleView, msg: Any, cmd: int, p: list[float], frame: int | None, t_s: float
) -> list[Any]:
    ap, af = v.autopilot, v.airframe
    if cmd == M.MAV_CMD_COMPONENT_ARM_DISARM:
        return _arm(v, msg, p)
    if cmd == M.MAV_CMD_DO_SET_MODE:
        if not max(0, _int(p[0])) & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return [_ack(msg, cmd, M.MAV_RESULT_UNSUPPORTED)]  # ArduPilot: custom modes only
        result, out = _set_mode(v, _int(p[1]))
        return [*out, _ack(msg, cmd, result)]
    if cmd == M.MAV_CMD_DO_SET_MISSION_CURRENT:
        ok = math.isfinite(p[0]) and 0 <= p[0] < 65536
        out = []
        if ok:
            ok, out = ap.set_current_item(int(p[0]), af)
        if not ok:
            return [*out, _ack(msg, cmd, M.MAV_RESULT_FAILED)]
        # GCS_MAVLINK::handle_command_do_set_mission_current queues MISSION_CURRENT
        # (send_message: out at the channel's next update), after the ACK it returns
        return [*out, _ack(msg, cmd, M.MAV_RESULT_ACCEPTED),
                build_message(v, M.MAVLINK_MSG_ID_MISSION_CURRENT)]
    if cmd in (M.MAV_CMD_MISSION_START, M.MAV_CMD_NAV_LOITER_UNLIM):
        result, out = _set_mode(v, AUTO if cmd == M.MAV_CMD_MISSION_START else LOITER)
        return [*out, _ack(msg, cmd, result)]
    if cmd == M.MAV_CMD_NAV_RETURN_TO_LAUNCH:
        result, out = _set_mode(v, RTL)
        return [*out, _ack(msg, cmd, result)]
    if cmd == M.MAV_CMD_DO_CHANGE_SPEED:
        lo, hi = v.params.get("AIRSPEED_MIN"), v.params.get("AIRSPEED_MAX")
        if not (math.isfinite(p[1]) and lo <= p[1] <= hi):
            return [_ack(msg, cmd, M.MAV_RESULT_FAILED)]
        ap.speed_cmd_m_s = p[1]
        return [_ack(msg, cmd, M.MAV_RESULT_ACCEPTED)]
    if cmd == M.MAV_CMD_SET_MESSAGE_INTERVAL:
        if not (math.isfinite(p[0]) and math.isfinite(p[1])):
            return [_ack(msg, cmd, M.MAV_RESULT_FAILED)]
        msg_id, interval_us = _int(p[0]), p[1]
        if interval_us == 0:
            ok = v.streams.set_default(msg_id, t_s)
        elif interval_us < 0:
            ok = v.streams.set_interval(msg_id, None, t_s)
        else:
            ok = v.streams.set_interval(msg_id, max(interval_us * 1e-6, 0.01), t_s)
        return [_ack(msg, cmd, M.MAV_RESULT_ACCEPTED if ok else M.MAV_RESULT_FAILED)]
    if cmd in (
        M.MAV_CMD_REQUEST_MESSAGE,
        M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES,
        M.MAV_CMD_GET_HOME_POSITION,
    ):
        msg_id = {
            M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: M.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
            M.MAV_CMD_GET_HOME_POSITION: M.MAVLINK_MSG_ID_HOME_POSITION,
        }.get(cmd, int(p[0]) if math.isfinite(p[0]) else -1)
        answer = _request_message(v, msg_id)
        if answer is None:
            return [_ack(msg, cmd, M.MAV_RESULT_FAILED)]
        return [_ack(msg, cmd, M.MAV_RESULT_ACCEPTED), answer]
    if cmd == M.MAV_CMD_DO_REPOSITION:
        return _reposition(v, msg, p, frame)
    if cmd == M.MAV_CMD_DO_SET_HOME:
        return _set_home(v, msg, p, frame)
    if cmd == M.MAV_CMD_DO_FENCE_ENABLE:
        # AC_Fence: 0 disables, 1 enables (FENCE_ENABLE, not saved); 2 (the floor only)
        # has nothing to disable on a fence of inclusion items
        if p[0] not in (0.0, 1.0, 2.0):
            return [_ack(msg, cmd, M.MAV_RESULT_FAILED)]
        if p[0] != 2.0:
            v.params.set("FENCE_ENABLE", p[0])
        return [_ack(msg, cmd, M.MAV_RESULT_ACCEPTED)]
    if cmd == M.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN:
        if p[0] != 1.0 or ap.armed:
            return [_ack(msg, cmd, M.MAV_RESULT_FAILED)]
        return [_ack(msg, cmd, M.MAV_RESULT_ACCEPTED), *v.reboot(t_s)]
    return [_ack(msg, cmd, M.MAV_RESULT_UNSUPPORTED)]


def guided_item(v: VehicleView, msg: Any) -> list[Any]:
    """A guided MISSION_ITEM(_INT) (current = 2: go to, 3: change altitude)."""
    peer = (msg.get_srcSystem(), msg.get_srcComponent())
    ap = v.autopilot
    if ap.mode != GUIDED or int(msg.command) != M.MAV_CMD_NAV_WAYPOINT or ap.nav is None:
        return [M.MAVLink_mission_ack_message(peer[0], peer[1], M.MAV_MISSION_ERROR, 0)]
    if msg.get_type() == "MISSION_ITEM_INT":
        lat, lon = int(msg.x) * 1e-7, int(msg.y) * 1e-7
    else:
        lat, lon = float(msg.x), float(msg.y)
    alt = float(msg.z)
    if (
        not (math.isfinite(lat) and math.isfinite(lon) and math.isfinite(alt))
        or abs(lat) > 90
        or abs(lon) > 180
    ):
        return [M.MAVLink_mission_ack_message(peer[0], peer[1], M.MAV_MISSION_INVALID_PARAM5_X, 0)]
    if int(msg.current) == 3:
        ap.nav.alt_m = alt
    else:
        x_m, y_m, _ = v.config.origin.to_local(lat, lon)
        ap.set_guided_target(x_m, y_m, alt, 0.0)
    return [M.MAVLink_mission_ack_message(peer[0], peer[1], M.MAV_MISSION_ACCEPTED, 0)]
