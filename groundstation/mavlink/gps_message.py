"""GPS_RAW_INT as floe reads it: the fix type, the satellites and the HDOP (sans-IO).

MAVLink's GPS_RAW_INT carries

* ``fix_type``: GPS_FIX_TYPE, 0 NO_GPS, 1 NO_FIX, 2 2D_FIX, 3 3D_FIX, 4 DGPS, 5 RTK_FLOAT,
  6 RTK_FIXED, 7 STATIC, 8 PPP (ArduPilot's ``AP_GPS::GPS_Status`` uses the same numbers
  up to 6); a position is only trusted from 3 (3D) up: :attr:`GpsFix.has_fix`;
* ``satellites_visible``: a count, 255 (UINT8_MAX) = unknown;
* ``eph``: the horizontal dilution of precision times 100, 65535 (UINT16_MAX) = unknown;
  HDOP = ``eph`` / 100.

:func:`parse_gps_raw_int` never raises: a field that is unknown (255, 65535) is None; a
field that is no number, or out of range (a fix type above 8, more satellites than
:data:`MAX_SATELLITES`), is None too and named in the result's ``bad`` list, so the
reducer can report it (``InvalidTelemetry``) and the panel shows it as unknown.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = [
    "FIX_3D",
    "GPS_FIX_NAMES",
    "MAX_SATELLITES",
    "BadGpsField",
    "GpsFix",
    "gps_fix_text",
    "parse_gps_raw_int",
]

GPS_FIX_NAMES: dict[int, str] = {
    0: "no GPS",
    1: "no fix",
    2: "2D fix",
    3: "3D fix",
    4: "DGPS",
    5: "RTK float",
    6: "RTK fixed",
    7: "static",
    8: "PPP",
}
"""GPS_FIX_TYPE as the panel names it."""
FIX_3D = 3
"""GPS_FIX_TYPE_3D_FIX: the lowest fix type a position is trusted from."""
MAX_SATELLITES = 150
"""More satellites than every GNSS constellation has in orbit (GPS, GLONASS, Galileo,
BeiDou, QZSS and SBAS: ~140 together) is no count but garbage."""
_UINT8_UNKNOWN = 255
_UINT16_UNKNOWN = 65535


@dataclass(frozen=True)
class BadGpsField:
    """A GPS_RAW_INT field that was no number or out of range (shown as unknown)."""

    field: str
    value: Any


@dataclass(frozen=True)
class GpsFix:
    """One GPS_RAW_INT's fix: ``fix_type`` (GPS_FIX_TYPE), ``satellites`` and ``hdop``
    (unitless), each None when unknown; ``bad`` the fields refused."""

    fix_type: int | None
    satellites: int | None
    hdop: float | None
    bad: tuple[BadGpsField, ...] = ()

    @property
    def has_fix(self) -> bool:
        """A 3D fix or better (``fix_type`` >= 3); False when unknown."""
        return self.fix_type is not None and self.fix_type >= FIX_3D

    @property
    def name(self) -> str:
        """``3D fix``, ``RTK fixed``, ``no fix`` ... or ``unknown fix``."""
        if self.fix_type is None:
            return "unknown fix"
        return GPS_FIX_NAMES.get(self.fix_type, "unknown fix")


def _integer(value: object) -> int | None:
    """``value`` as an int if it is one (bools, floats and the rest: None)."""
    if isinstance(value, bool) or not isinstance(value, int):
        return None
    return value


def parse_gps_raw_int(msg: Any) -> GpsFix:
    """The fix of one GPS_RAW_INT (module docstring); never raises."""
    bad: list[BadGpsField] = []
    raw_fix = getattr(msg, "fix_type", None)
    fix_type = _integer(raw_fix)
    if fix_type is None or fix_type not in GPS_FIX_NAMES:
        bad.append(BadGpsField("fix_type", raw_fix))
        fix_type = None
    raw_sats = getattr(msg, "satellites_visible", None)
    satellites = _integer(raw_sats)
    if satellites == _UINT8_UNKNOWN:
        satellites = None
    elif satellites is None or not 0 <= satellites <= MAX_SATELLITES:
        bad.append(BadGpsField("satellites_visible", raw_sats))
        satellites = None
    raw_eph = getattr(msg, "eph", None)
    eph = _integer(raw_eph)
    hdop: float | None = None
    if eph is None or not 0 <= eph <= _UINT16_UNKNOWN:
        bad.append(BadGpsField("eph", raw_eph))
    elif eph != _UINT16_UNKNOWN:
        hdop = eph / 100.0
    return GpsFix(fix_type, satellites, hdop, tuple(bad))


def gps_fix_text(fix: GpsFix) -> str:
    """The panel's line: ``3D fix, 14 sats, HDOP 0.8`` (``?`` for what is unknown)."""
    sats = "? sats" if fix.satellites is None else (
        "1 sat" if fix.satellites == 1 else f"{fix.satellites} sats")
    hdop = "HDOP ?" if fix.hdop is None else f"HDOP {fix.hdop:.1f}"
    return f"{fix.name}, {sats}, {hdop}"
