"""The simulated vehicle's stored mission (AP_Mission-like) and MAVLink item conversion.

Items are kept in MISSION_ITEM_INT form: for commands that carry a location, ``x``/``y`` are
latitude/longitude in degE7 and ``z`` the altitude in metres; MISSION_ITEM (float degrees)
answers are converted on the way in and out, as ArduPilot does. Index 0 is home.

Validation follows ArduPilot's ``mavlink_int_to_mission_cmd``: an unknown command is
``MAV_MISSION_UNSUPPORTED``, a location command in an unsupported frame (e.g. BODY_NED) is
``MAV_MISSION_UNSUPPORTED_FRAME``, |lat| > 90 deg (or not finite) is
``MAV_MISSION_INVALID_PARAM5_X`` and |lon| > 180 deg ``MAV_MISSION_INVALID_PARAM6_Y``.

The fence and rally mission types (:mod:`sitl.geo_items`) go through the same conversion
with their ``mission_type``: only that type's commands (:data:`GEO_COMMANDS`), each a
location checked for latitude and longitude, as ArduPilot's
``convert_MISSION_ITEM_to_MISSION_ITEM_INT`` does for them; their parameters, frame and z
are kept as sent (z zeroed when not finite).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

from groundstation.mavlink.codec import mavlink2

__all__ = [
    "COMMAND_NAMES",
    "GEO_COMMANDS",
    "LOCATION_COMMANDS",
    "MAX_MISSION_ITEMS",
    "MissionStore",
    "StoredItem",
    "item_from_message",
    "item_to_message",
]

MAX_MISSION_ITEMS = 655
"""Capacity of ArduPlane SITL's mission storage (items, home included)."""

M = mavlink2
LOCATION_COMMANDS = frozenset(
    {
        M.MAV_CMD_NAV_WAYPOINT,
        M.MAV_CMD_NAV_LOITER_UNLIM,
        M.MAV_CMD_NAV_LOITER_TURNS,
        M.MAV_CMD_NAV_LOITER_TIME,
        M.MAV_CMD_NAV_LAND,
        M.MAV_CMD_NAV_TAKEOFF,
        M.MAV_CMD_NAV_LOITER_TO_ALT,
        M.MAV_CMD_DO_SET_HOME,
    }
)
"""Commands whose x/y/z are a location (checked for frame and range)."""

GEO_COMMANDS: dict[int, frozenset[int]] = {
    M.MAV_MISSION_TYPE_FENCE: frozenset(
        {
            M.MAV_CMD_NAV_FENCE_RETURN_POINT,
            M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
            M.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION,
            M.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION,
        }
    ),
    M.MAV_MISSION_TYPE_RALLY: frozenset({M.MAV_CMD_NAV_RALLY_POINT}),
}
"""Fence and rally mission types -> the commands their items may carry (all locations)."""
_LATLON_COMMANDS = LOCATION_COMMANDS.union(*GEO_COMMANDS.values())

COMMAND_NAMES: dict[int, str] = {
    M.MAV_CMD_NAV_WAYPOINT: "WP",
    M.MAV_CMD_NAV_RETURN_TO_LAUNCH: "RTL",
    M.MAV_CMD_NAV_LOITER_UNLIM: "LoitUnlim",
    M.MAV_CMD_NAV_LOITER_TIME: "LoitTime",
    M.MAV_CMD_NAV_LOITER_TURNS: "LoitTurns",
    M.MAV_CMD_NAV_LOITER_TO_ALT: "LoitAltitude",
    M.MAV_CMD_NAV_TAKEOFF: "Takeoff",
    M.MAV_CMD_NAV_LAND: "Land",
    M.MAV_CMD_DO_CHANGE_SPEED: "ChangeSpeed",
    M.MAV_CMD_DO_SET_HOME: "SetHome",
    M.MAV_CMD_DO_JUMP: "Jump",
    M.MAV_CMD_CONDITION_DELAY: "CondDelay",
    M.MAV_CMD_DO_SET_SERVO: "SetServo",
    M.MAV_CMD_DO_DIGICAM_CONTROL: "DigiCamCtrl",
    M.MAV_CMD_DO_SET_CAM_TRIGG_DIST: "CamTrigDist",
}
"""AP_Mission's short names, used in the "Mission: N <name>" STATUSTEXT."""

NAV_COMMANDS = frozenset(
    {
        M.MAV_CMD_NAV_WAYPOINT,
        M.MAV_CMD_NAV_LOITER_UNLIM,
        M.MAV_CMD_NAV_LOITER_TURNS,
        M.MAV_CMD_NAV_LOITER_TIME,
        M.MAV_CMD_NAV_RETURN_TO_LAUNCH,
        M.MAV_CMD_NAV_LAND,
        M.MAV_CMD_NAV_TAKEOFF,
        M.MAV_CMD_NAV_LOITER_TO_ALT,
    }
)

_GLOBAL_FRAMES = frozenset(
    {
        M.MAV_FRAME_GLOBAL,
        M.MAV_FRAME_GLOBAL_RELATIVE_ALT,
        M.MAV_FRAME_GLOBAL_TERRAIN_ALT,
        M.MAV_FRAME_GLOBAL_INT,
        M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        M.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
        M.MAV_FRAME_MISSION,
    }
)


@dataclass(frozen=True)
class StoredItem:
    """One stored mission command (MISSION_ITEM_INT semantics)."""

    command: int
    frame: int = M.MAV_FRAME_GLOBAL_RELATIVE_ALT
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: int = 0
    y: int = 0
    z: float = 0.0
    autocontinue: int = 1

    @property
    def lat_deg(self) -> float:
        """Latitude of a location command."""
        return self.x * 1e-7

    @property
    def lon_deg(self) -> float:
        """Longitude of a location command."""
        return self.y * 1e-7

    @property
    def is_nav(self) -> bool:
        """True for a navigation command (one the plane flies)."""
        return self.command in NAV_COMMANDS

    @property
    def name(self) -> str:
        """AP_Mission's short name for the command."""
        return COMMAND_NAMES.get(self.command, f"Cmd{self.command}")


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


LOCATION_ALT_MAX_M = 83000.0
"""AP_Mission refuses |z| >= this (and NaN) for location commands: INVALID_PARAM7."""
_ABSOLUTE_FRAMES = {
    M.MAV_FRAME_GLOBAL_INT: M.MAV_FRAME_GLOBAL,
    M.MAV_FRAME_MISSION: M.MAV_FRAME_GLOBAL,
    M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: M.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    M.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT: M.MAV_FRAME_GLOBAL_TERRAIN_ALT,
}


def _uint(value: float, high: int) -> float:
    """C float -> unsigned storage: NaN and negatives become 0, the rest truncates/clamps."""
    if not math.isfinite(value) or value <= 0.0:
        return 0.0 if not (math.isinf(value) and value > 0) else float(high)
    return float(min(int(value), high))


def stored_form(item: StoredItem) -> StoredItem:
    """What AP_Mission keeps of an item (``mavlink_int_to_mission_cmd``), i.e. what a
    download returns and what the plane flies (``mission_cmd_to_mavlink_int``):

    NAV_WAYPOINT: param2 acceptance and param3 pass-by as bytes (param1, param4 dropped);
    NAV_LOITER_UNLIM: +-|param3| as uint16; NAV_LOITER_TURNS: param1 turns (byte), param3
    radius as a byte (above 255 m in tens of metres), param4 > 0; NAV_LOITER_TIME: param1
    uint16 seconds, param3 only its sign (+-1), param4 > 0; NAV_TAKEOFF: param1 (pitch);
    NAV_LAND: param1, param4 sign; NAV_LOITER_TO_ALT: +-|param2|; DO_CHANGE_SPEED: param1
    (byte), param2, param3 (byte); DO_JUMP: param1 target, param2 count. Locations come back
    in the non-INT frame with z truncated to centimetres; other items with frame, x, y, z = 0.
    """
    p1, p2, p3, p4 = item.param1, item.param2, item.param3, item.param4
    cmd = item.command
    q: tuple[float, float, float, float]
    if cmd == M.MAV_CMD_NAV_WAYPOINT:
        q = (0.0, _uint(p2, 255), _uint(p3, 255), 0.0)
    elif cmd == M.MAV_CMD_NAV_LOITER_UNLIM:
        r = _uint(abs(p3), 65535)
        q = (0.0, 0.0, -r if p3 < 0 else r, 0.0)
    elif cmd == M.MAV_CMD_NAV_LOITER_TURNS:
        radius = abs(p3) if math.isfinite(p3) else 0.0
        r = _uint(radius, 255) if radius <= 255 else 10.0 * _uint(radius * 0.1, 255)
        q = (_uint(p1, 255), 0.0, -r if p3 < 0 else r, 1.0 if p4 > 0 else 0.0)
    elif cmd == M.MAV_CMD_NAV_LOITER_TIME:
        q = (_uint(p1, 65535), 0.0, -1.0 if p3 < 0 else 1.0, 1.0 if p4 > 0 else 0.0)
    elif cmd == M.MAV_CMD_NAV_TAKEOFF:
        q = (_uint(p1, 65535), 0.0, 0.0, 0.0)
    elif cmd == M.MAV_CMD_NAV_LAND:
        q = (_uint(p1, 65535), 0.0, 0.0, -1.0 if p4 < 0 else 1.0)
    elif cmd == M.MAV_CMD_NAV_LOITER_TO_ALT:
        r = _uint(abs(p2), 65535)
        q = (0.0, -r if p2 < 0 else r, 0.0, 1.0 if p4 > 0 else 0.0)
    elif cmd == M.MAV_CMD_DO_CHANGE_SPEED:
        q = (_uint(p1, 255), p2, _uint(p3, 255), 0.0)
    elif cmd == M.MAV_CMD_DO_JUMP:
        count = float(int(p2)) if math.isfinite(p2) and abs(p2) < 32768 else 0.0
        q = (_uint(p1, 65535), count, 0.0, 0.0)
    elif cmd == M.MAV_CMD_DO_SET_HOME:
        q = (_uint(p1, 65535), 0.0, 0.0, 0.0)
    elif cmd == M.MAV_CMD_DO_SET_SERVO:
        q = (_uint(p1, 255), _uint(p2, 65535), 0.0, 0.0)
    elif cmd == M.MAV_CMD_DO_SET_CAM_TRIGG_DIST:
        q = (p1, 0.0, _uint(p3, 255), 0.0)
    elif cmd == M.MAV_CMD_CONDITION_DELAY:
        q = (p1, 0.0, 0.0, 0.0)
    else:
        q = (p1, p2, p3, p4)
    if cmd in LOCATION_COMMANDS:
        frame = _ABSOLUTE_FRAMES.get(item.frame, item.frame)
        z_m = math.trunc(item.z * 100.0) / 100.0
        return replace(
            item,
            frame=frame,
            param1=q[0],
            param2=q[1],
            param3=q[2],
            param4=q[3],
            z=z_m,
            autocontinue=1,
        )
    keep_xy = cmd == M.MAV_CMD_DO_DIGICAM_CONTROL
    return replace(
        item,
        frame=0,
        param1=q[0],
        param2=q[1],
        param3=q[2],
        param4=q[3],
        x=item.x if keep_xy else 0,
        y=item.y if keep_xy else 0,
        z=0.0,
        autocontinue=1,
    )


def _latlon_e7(msg: Any, is_int: bool) -> tuple[int, int] | int:
    """The item's latitude/longitude in degE7, or the MAV_MISSION_RESULT refusing them."""
    if is_int:
        lat_deg, lon_deg = int(msg.x) * 1e-7, int(msg.y) * 1e-7
    else:
        lat_deg, lon_deg = float(msg.x), float(msg.y)
    if not _finite(lat_deg) or abs(lat_deg) > 90.0:
        return M.MAV_MISSION_INVALID_PARAM5_X
    if not _finite(lon_deg) or abs(lon_deg) > 180.0:
        return M.MAV_MISSION_INVALID_PARAM6_Y
    return round(lat_deg * 1e7), round(lon_deg * 1e7)


def item_from_message(
    msg: Any, mission_type: int = M.MAV_MISSION_TYPE_MISSION
) -> tuple[StoredItem | None, int]:
    """Convert a MISSION_ITEM or MISSION_ITEM_INT of ``mission_type`` to its stored form;
    returns (item, MAV_MISSION_RESULT). NaN parameters are accepted (QGroundControl sends
    NaN for "unchanged" yaw), as ArduPilot does; they are dropped or zeroed by
    :func:`stored_form`. Fence and rally items: see the module docstring."""
    is_int = msg.get_type() == "MISSION_ITEM_INT"
    command = int(msg.command)
    params = (float(msg.param1), float(msg.param2), float(msg.param3), float(msg.param4))
    z = float(msg.z)
    if mission_type != M.MAV_MISSION_TYPE_MISSION:
        if command not in GEO_COMMANDS.get(mission_type, frozenset()):
            return None, M.MAV_MISSION_UNSUPPORTED
        latlon = _latlon_e7(msg, is_int)
        if isinstance(latlon, int):
            return None, latlon
        x, y = latlon
        return StoredItem(
            command, int(msg.frame), *params, x=x, y=y, z=z if _finite(z) else 0.0
        ), M.MAV_MISSION_ACCEPTED
    if command not in COMMAND_NAMES:
        return None, M.MAV_MISSION_UNSUPPORTED
    if command in LOCATION_COMMANDS:
        latlon = _latlon_e7(msg, is_int)
        if isinstance(latlon, int):
            return None, latlon
        if not _finite(z) or abs(z) >= LOCATION_ALT_MAX_M:
            return None, M.MAV_MISSION_INVALID_PARAM7
        if int(msg.frame) not in _GLOBAL_FRAMES:
            return None, M.MAV_MISSION_UNSUPPORTED_FRAME
        x, y = latlon
    else:
        fx, fy = float(msg.x), float(msg.y)
        x = int(fx) if _finite(fx) and abs(fx) < 2**31 else 0
        y = int(fy) if _finite(fy) and abs(fy) < 2**31 else 0
    item = StoredItem(command, int(msg.frame), *params, x=x, y=y, z=z if _finite(z) else 0.0)
    return stored_form(item), M.MAV_MISSION_ACCEPTED


def item_to_message(
    item: StoredItem,
    seq: int,
    target: tuple[int, int],
    as_int: bool,
    current: bool,
    mission_type: int = M.MAV_MISSION_TYPE_MISSION,
) -> Any:
    """MISSION_ITEM_INT (``as_int``) or MISSION_ITEM of ``mission_type`` for a download
    answer."""
    common = (
        target[0],
        target[1],
        seq,
        item.frame,
        item.command,
        int(current),
        item.autocontinue,
        item.param1,
        item.param2,
        item.param3,
        item.param4,
    )
    if as_int:
        return M.MAVLink_mission_item_int_message(*common, item.x, item.y, item.z, mission_type)
    if item.command in _LATLON_COMMANDS:
        fx, fy = item.x * 1e-7, item.y * 1e-7
    else:
        fx, fy = float(item.x), float(item.y)
    return M.MAVLink_mission_item_message(*common, fx, fy, item.z, mission_type)


class MissionStore:
    """The mission in (simulated) EEPROM: item 0 is home.

    ``capacity`` is 0 until the autopilot has initialised its storage (then uploads are
    refused with NO_SPACE, "Only 0 items are supported"), MAX_MISSION_ITEMS afterwards.
    """

    def __init__(self, home: StoredItem) -> None:
        self.items: list[StoredItem] = [home]
        self.capacity = 0

    def __len__(self) -> int:
        return len(self.items)

    def set_home(self, home: StoredItem) -> None:
        """Replace item 0."""
        self.items[0] = home

    def truncate(self, count: int) -> None:
        """Keep the first ``count`` items (home always stays)."""
        del self.items[max(1, count) :]

    def clear(self) -> None:
        """Remove everything but home."""
        self.truncate(1)

    def write(self, seq: int, item: StoredItem) -> None:
        """Store ``item`` at ``seq`` (append when ``seq == len``). Item 0 always reads back
        as the vehicle's home, whatever was uploaded there (AP_Mission)."""
        if seq == 0:
            return
        if seq < len(self.items):
            self.items[seq] = item
        elif seq == len(self.items):
            self.items.append(item)
