"""floe's mission description and the MAVLink mission items it becomes.

floe describes a mission as a short list of *steps* in the local ENU frame (metres around
the mission origin, altitudes relative to home):

* :class:`Takeoff`, :class:`Waypoint`, :class:`LoiterTime` (the timed loiter over a
  target), :class:`LoiterUnlimited` (the hold that never ends) and :class:`ChangeSpeed`.

:func:`build_mission_items` turns them into MAVLink ``MISSION_ITEM_INT`` items: item 0 is
home (ArduPilot's convention: it is overwritten by the vehicle's own home and reads back as
that), then one item per step. Positions are converted with :class:`GeoOrigin` (pymap3d,
exact on WGS-84) to integer degE7: ``x = round(lat_deg * 1e7)``, ``y = round(lon_deg * 1e7)``,
so the quantisation error is at most 0.5e-7 deg (~1 cm). Navigation items use
``MAV_FRAME_GLOBAL_RELATIVE_ALT_INT``; the DO item uses ``MAV_FRAME_MISSION``.

Items are generated in ArduPlane's *canonical* form, i.e. values ArduPlane stores without
loss (integer seconds and metres, loiter direction as the sign of param3), so a verbatim
store (the built-in simulator) and ArduPlane read back the same thing.

Verification of a read-back mission lives in :mod:`groundstation.mavlink.mission_verify`.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass, replace

from domain.errors import LocalProtocolError
from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import MAVLinkMessage, mavlink2

__all__ = [
    "ChangeSpeed",
    "HomePosition",
    "LoiterTime",
    "LoiterUnlimited",
    "MissionItem",
    "MissionStep",
    "Takeoff",
    "Waypoint",
    "build_mission_items",
    "validate_items",
]

CMD_NAV_WAYPOINT = mavlink2.MAV_CMD_NAV_WAYPOINT  # 16
CMD_NAV_LOITER_UNLIM = mavlink2.MAV_CMD_NAV_LOITER_UNLIM  # 17
CMD_NAV_LOITER_TIME = mavlink2.MAV_CMD_NAV_LOITER_TIME  # 19
CMD_NAV_TAKEOFF = mavlink2.MAV_CMD_NAV_TAKEOFF  # 22
CMD_DO_CHANGE_SPEED = mavlink2.MAV_CMD_DO_CHANGE_SPEED  # 178

FRAME_GLOBAL_INT = mavlink2.MAV_FRAME_GLOBAL_INT  # 5
FRAME_GLOBAL_RELATIVE_ALT_INT = mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT  # 6
FRAME_MISSION = mavlink2.MAV_FRAME_MISSION  # 2

_INT32_MAX = 2**31 - 1
_UINT16_MAX = 65535
_MAX_ALT_M = 100_000.0

# Commands whose x/y/z are a position (ArduPilot's ``stored_in_location``, the subset a
# fixed wing uses). For the others, frame, x, y and z are not compared.
LOCATION_COMMANDS = frozenset({16, 17, 18, 19, 21, 22, 30, 31, 82, 92, 179, 189, 191, 201})
# x/y are not lat/lon for these (AP_Mission's exception list).
NON_GEO_XY_COMMANDS = frozenset({202, 203, 1222, 1000})


def f32(value: float) -> float:
    """Round to the nearest float32 (what the wire carries); inf on overflow."""
    try:
        return float(struct.unpack("<f", struct.pack("<f", value))[0])
    except (OverflowError, struct.error):
        return math.copysign(math.inf, value)


@dataclass(frozen=True)
class MissionItem:
    """One MAVLink mission item, as ``MISSION_ITEM_INT`` carries it.

    ``x``/``y`` are degE7 (int32) for positional commands; ``z`` is metres in ``frame``.
    """

    seq: int
    command: int
    frame: int = FRAME_GLOBAL_RELATIVE_ALT_INT
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: int = 0
    y: int = 0
    z: float = 0.0
    current: int = 0
    autocontinue: int = 1
    mission_type: int = mavlink2.MAV_MISSION_TYPE_MISSION

    def to_message(self, target_system: int, target_component: int) -> MAVLinkMessage:
        """The ``MISSION_ITEM_INT`` message for this item, addressed to the vehicle."""
        return mavlink2.MAVLink_mission_item_int_message(
            target_system,
            target_component,
            self.seq,
            self.frame,
            self.command,
            self.current,
            self.autocontinue,
            self.param1,
            self.param2,
            self.param3,
            self.param4,
            self.x,
            self.y,
            self.z,
            self.mission_type,
        )

    @classmethod
    def from_message(cls, msg: MAVLinkMessage) -> MissionItem | None:
        """Item from a ``MISSION_ITEM_INT`` or ``MISSION_ITEM`` (float lat/lon) message.

        Returns None when the message cannot be an item (wrong type, non-finite lat/lon in a
        ``MISSION_ITEM``); never raises.
        """
        kind = msg.get_type()
        try:
            if kind == "MISSION_ITEM_INT":
                x, y = int(msg.x), int(msg.y)
            elif kind == "MISSION_ITEM":
                if not (math.isfinite(msg.x) and math.isfinite(msg.y)):
                    return None
                scale = 1.0 if int(msg.command) in NON_GEO_XY_COMMANDS else 1e7
                x, y = round(msg.x * scale), round(msg.y * scale)
            else:
                return None
            return cls(
                seq=int(msg.seq),
                command=int(msg.command),
                frame=int(msg.frame),
                param1=float(msg.param1),
                param2=float(msg.param2),
                param3=float(msg.param3),
                param4=float(msg.param4),
                x=x,
                y=y,
                z=float(msg.z),
                current=int(msg.current),
                autocontinue=int(msg.autocontinue),
                mission_type=int(getattr(msg, "mission_type", 0) or 0),
            )
        except (AttributeError, TypeError, ValueError, OverflowError):
            return None


def validate_items(items: Sequence[MissionItem], mission_type: int) -> None:
    """Raise :class:`LocalProtocolError` naming the field unless ``items`` can be uploaded.

    Checks: seq numbers are 0, 1, 2... in order; every item has ``mission_type``; integer
    fields fit their wire types; params fit float32 (NaN allowed: "unset" in MAVLink);
    x/y are valid lat/lon (degE7) for positional commands; z is finite.
    """
    if len(items) > _UINT16_MAX:
        raise LocalProtocolError(f"too many mission items: {len(items)} > {_UINT16_MAX}")
    for index, item in enumerate(items):
        where = f"mission item {index}"
        if not isinstance(item, MissionItem):
            raise LocalProtocolError(f"{where}: not a MissionItem ({type(item).__name__})")
        if item.seq != index:
            raise LocalProtocolError(f"{where}: seq is {item.seq}, expected {index}")
        if item.mission_type != mission_type:
            raise LocalProtocolError(
                f"{where}: mission_type {item.mission_type} != transfer's {mission_type}"
            )
        if not 0 <= item.command <= _UINT16_MAX:
            raise LocalProtocolError(f"{where}: command {item.command} out of range")
        for name in ("frame", "current", "autocontinue"):
            if not 0 <= getattr(item, name) <= 255:
                raise LocalProtocolError(f"{where}: {name} {getattr(item, name)} out of range")
        for name in ("param1", "param2", "param3", "param4"):
            value = getattr(item, name)
            if math.isinf(value) or math.isinf(f32(value)):
                raise LocalProtocolError(f"{where}: {name} {value} does not fit float32")
        for name in ("x", "y"):
            if not -_INT32_MAX - 1 <= getattr(item, name) <= _INT32_MAX:
                raise LocalProtocolError(f"{where}: {name} {getattr(item, name)} not int32")
        if not math.isfinite(item.z) or math.isinf(f32(item.z)):
            raise LocalProtocolError(f"{where}: z {item.z} is not a finite altitude")
        if item.command in LOCATION_COMMANDS:
            if abs(item.x) > 900_000_000:
                raise LocalProtocolError(f"{where}: latitude x={item.x} degE7 beyond 90 deg")
            if abs(item.y) > 1_800_000_000:
                raise LocalProtocolError(f"{where}: longitude y={item.y} degE7 beyond 180 deg")


# --------------------------------------------------------------------------- floe steps


@dataclass(frozen=True)
class Takeoff:
    """Climb to ``alt_m`` (relative to home) with at least ``pitch_deg`` nose-up."""

    alt_m: float
    pitch_deg: float = 15.0


@dataclass(frozen=True)
class Waypoint:
    """Fly to (x_m, y_m) at ``alt_m``; 0 acceptance radius means ArduPlane's WP_RADIUS."""

    x_m: float
    y_m: float
    alt_m: float
    acceptance_radius_m: float = 0.0


@dataclass(frozen=True)
class LoiterTime:
    """Loiter ``time_s`` (whole seconds) around (x_m, y_m).

    ArduPlane's NAV_LOITER_TIME flies the WP_LOITER_RAD parameter and keeps only the sign of
    param3 (the direction); set the radius with PARAM_SET. The timer starts on the circle.
    """

    x_m: float
    y_m: float
    alt_m: float
    time_s: float
    clockwise: bool = True


@dataclass(frozen=True)
class LoiterUnlimited:
    """Circle (x_m, y_m) at ``radius_m`` (whole metres) until told otherwise."""

    x_m: float
    y_m: float
    alt_m: float
    radius_m: float
    clockwise: bool = True


@dataclass(frozen=True)
class ChangeSpeed:
    """Set the target speed (airspeed by default, else ground speed); throttle unchanged."""

    speed_m_s: float
    airspeed: bool = True


MissionStep = Takeoff | Waypoint | LoiterTime | LoiterUnlimited | ChangeSpeed


@dataclass(frozen=True)
class HomePosition:
    """Home in the local frame; ``alt_m`` is above the origin's altitude."""

    x_m: float = 0.0
    y_m: float = 0.0
    alt_m: float = 0.0


def _finite(value: float, name: str, where: str) -> float:
    if not isinstance(value, int | float) or not math.isfinite(value):
        raise LocalProtocolError(f"{where}: {name} must be a finite number, got {value!r}")
    return float(value)


def _alt(value: float, where: str) -> float:
    alt_m = _finite(value, "alt_m", where)
    if abs(alt_m) > _MAX_ALT_M:
        raise LocalProtocolError(f"{where}: alt_m {alt_m} out of range")
    return round(alt_m, 2)  # ArduPilot stores centimetres


def _whole(value: float, name: str, where: str, low: int, high: int) -> int:
    number = _finite(value, name, where)
    whole = round(number)
    if not low <= whole <= high:
        raise LocalProtocolError(f"{where}: {name} {number} must round into [{low}, {high}]")
    return whole


def _latlon(origin: GeoOrigin, x_m: float, y_m: float, where: str) -> tuple[int, int]:
    east_m = _finite(x_m, "x_m", where)
    north_m = _finite(y_m, "y_m", where)
    lat_deg, lon_deg, _ = origin.to_geodetic(east_m, north_m, 0.0)
    if not (math.isfinite(lat_deg) and math.isfinite(lon_deg) and abs(lat_deg) <= 90.0):
        raise LocalProtocolError(f"{where}: position ({x_m}, {y_m}) m has no valid lat/lon")
    lon_deg = (lon_deg + 180.0) % 360.0 - 180.0
    return round(lat_deg * 1e7), round(lon_deg * 1e7)


def build_mission_items(
    steps: Sequence[MissionStep],
    origin: GeoOrigin,
    *,
    home: HomePosition | None = None,
    mission_type: int = mavlink2.MAV_MISSION_TYPE_MISSION,
) -> list[MissionItem]:
    """MAVLink items for ``steps``: item 0 is home, then one item per step.

    Home is a NAV_WAYPOINT in ``MAV_FRAME_GLOBAL_INT`` (absolute altitude: origin altitude +
    ``home.alt_m``). Raises :class:`LocalProtocolError` naming the step and field on bad
    input (non-finite numbers, loiter time outside 1..65535 s, radius outside 1..65535 m).
    """
    home = home or HomePosition()
    hx, hy = _latlon(origin, home.x_m, home.y_m, "home")
    items = [
        MissionItem(
            seq=0,
            command=CMD_NAV_WAYPOINT,
            frame=FRAME_GLOBAL_INT,
            x=hx,
            y=hy,
            z=_alt(origin.alt_m + home.alt_m, "home"),
            mission_type=mission_type,
        )
    ]
    for index, step in enumerate(steps, start=1):
        where = f"mission step {index} ({type(step).__name__})"
        base = MissionItem(seq=index, command=0, mission_type=mission_type)
        if isinstance(step, Takeoff):
            pitch = _whole(step.pitch_deg, "pitch_deg", where, 0, 90)
            item = replace(
                base, command=CMD_NAV_TAKEOFF, param1=float(pitch), z=_alt(step.alt_m, where)
            )
        elif isinstance(step, Waypoint):
            x, y = _latlon(origin, step.x_m, step.y_m, where)
            radius = _whole(step.acceptance_radius_m, "acceptance_radius_m", where, 0, 255)
            item = replace(
                base,
                command=CMD_NAV_WAYPOINT,
                param2=float(radius),
                x=x,
                y=y,
                z=_alt(step.alt_m, where),
            )
        elif isinstance(step, LoiterTime):
            x, y = _latlon(origin, step.x_m, step.y_m, where)
            seconds = _whole(step.time_s, "time_s", where, 1, _UINT16_MAX)
            item = replace(
                base,
                command=CMD_NAV_LOITER_TIME,
                param1=float(seconds),
                param3=1.0 if step.clockwise else -1.0,
                x=x,
                y=y,
                z=_alt(step.alt_m, where),
            )
        elif isinstance(step, LoiterUnlimited):
            x, y = _latlon(origin, step.x_m, step.y_m, where)
            radius = _whole(step.radius_m, "radius_m", where, 1, _UINT16_MAX)
            item = replace(
                base,
                command=CMD_NAV_LOITER_UNLIM,
                param3=float(radius if step.clockwise else -radius),
                x=x,
                y=y,
                z=_alt(step.alt_m, where),
            )
        elif isinstance(step, ChangeSpeed):
            speed = _finite(step.speed_m_s, "speed_m_s", where)
            if not 0.0 < speed < 200.0:
                raise LocalProtocolError(f"{where}: speed_m_s {speed} out of (0, 200)")
            item = replace(
                base,
                command=CMD_DO_CHANGE_SPEED,
                frame=FRAME_MISSION,
                param1=0.0 if step.airspeed else 1.0,
                param2=speed,
                param3=-1.0,
            )
        else:
            raise LocalProtocolError(f"{where}: unknown mission step")
        items.append(item)
    validate_items(items, mission_type)
    return items
