"""ArduPlane-like parameter store for the built-in simulator (the PARAM protocol's data).

Only the parameters the ground station, QGroundControl and MAVProxy look at are kept; names
follow ArduPlane 4.7 (``MAV_SYSID``; 4.6 and older call it ``SYSID_THISMAV``, also listed so
either ground-station convention finds it). Values are floats on the wire
(``MAV_PARAM_TYPE_REAL32`` or an integer type, sent as the float of the integer, which is how
ArduPilot sends them).

Bad input never raises: an unknown name, a NaN or an out-of-range value is refused
(:meth:`ParamStore.set` returns ``None``) and the caller answers with the current value,
as ArduPilot does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from domain.limits import MAX_WIND_M_S
from domain.modes import ArduPlaneMode
from groundstation.mavlink.codec import mavlink2

__all__ = ["ParamSpec", "ParamStore", "default_param_specs"]

_REAL32 = mavlink2.MAV_PARAM_TYPE_REAL32
_INT8 = mavlink2.MAV_PARAM_TYPE_INT8
_INT16 = mavlink2.MAV_PARAM_TYPE_INT16
_INT32 = mavlink2.MAV_PARAM_TYPE_INT32
_BY_NAME_INDEX = 65535  # -1 as MAVLink's uint16 param_index


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: name (<= 16 chars), default, wire type and accepted range."""

    name: str
    default: float
    param_type: int = _REAL32
    min_value: float = -1e9
    max_value: float = 1e9


def default_param_specs(system_id: int, cruise_speed_m_s: float) -> list[ParamSpec]:
    """The parameter set of one simulated ArduPlane."""
    return [
        ParamSpec("FORMAT_VERSION", 13, _INT16, 0, 32767),
        ParamSpec("MAV_SYSID", system_id, _INT16, 1, 255),
        ParamSpec("SYSID_THISMAV", system_id, _INT16, 1, 255),
        ParamSpec("MAV_GCS_SYSID", 255, _INT16, 1, 255),
        ParamSpec("SYSID_MYGCS", 255, _INT16, 1, 255),
        ParamSpec("INITIAL_MODE", ArduPlaneMode.MANUAL, _INT8, 0, 25),
        ParamSpec("WP_LOITER_RAD", 60, _INT16, -32767, 32767),
        ParamSpec("WP_RADIUS", 90, _INT16, 1, 32767),
        ParamSpec("WP_MAX_RADIUS", 0, _INT16, 0, 32767),
        ParamSpec("RTL_RADIUS", 0, _INT16, -32767, 32767),
        ParamSpec("RTL_AUTOLAND", 0, _INT8, 0, 3),
        ParamSpec("ALT_HOLD_RTL", 10000, _INT32, -1, 1e6),
        ParamSpec("TKOFF_ALT", 50, _INT16, 0, 32767),
        ParamSpec("AIRSPEED_CRUISE", cruise_speed_m_s, _REAL32, 5, 100),
        ParamSpec("AIRSPEED_MIN", 12, _REAL32, 5, 100),
        ParamSpec("AIRSPEED_MAX", 30, _REAL32, 5, 100),
        ParamSpec("ARSPD_TYPE", 100, _INT8, 0, 127),
        ParamSpec("ARSPD_USE", 1, _INT8, 0, 2),
        ParamSpec("LIM_ROLL_CD", 4500, _INT16, 0, 9000),
        ParamSpec("BATT_MONITOR", 4, _INT8, 0, 30),
        ParamSpec("BATT_CAPACITY", 10000, _INT32, 0, 1e6),
        ParamSpec("BATT_LOW_VOLT", 10.5, _REAL32, 0, 100),
        ParamSpec("BATT_CRT_VOLT", 10.0, _REAL32, 0, 100),
        ParamSpec("BATT_LOW_MAH", 0, _REAL32, 0, 1e6),
        ParamSpec("BATT_CRT_MAH", 0, _REAL32, 0, 1e6),
        ParamSpec("BATT_FS_LOW_ACT", 0, _INT8, 0, 6),
        ParamSpec("BATT_FS_CRT_ACT", 0, _INT8, 0, 6),
        ParamSpec("FS_SHORT_ACTN", 0, _INT8, 0, 4),
        ParamSpec("FS_SHORT_TIMEOUT", 1.5, _REAL32, 1, 100),
        ParamSpec("FS_LONG_ACTN", 0, _INT8, 0, 4),
        ParamSpec("FS_LONG_TIMEOUT", 5, _REAL32, 1, 300),
        ParamSpec("FS_GCS_ENABL", 0, _INT8, 0, 3),
        ParamSpec("THR_FAILSAFE", 1, _INT8, 0, 2),
        ParamSpec("ARMING_CHECK", 1, _INT32, 0, 1e7),
        ParamSpec("ARMING_REQUIRE", 1, _INT8, 0, 2),
        ParamSpec("SIM_SPEEDUP", 1, _REAL32, 0, 1000),
        # ArduPilot SITL's wind (sitl.sim_wind): m/s, true degrees it comes FROM, m/s
        ParamSpec("SIM_WIND_SPD", 0, _REAL32, 0, MAX_WIND_M_S),
        ParamSpec("SIM_WIND_DIR", 180, _REAL32, -360, 720),
        ParamSpec("SIM_WIND_TURB", 0, _REAL32, 0, MAX_WIND_M_S),
        # ArduPlane's crash check (is_flying.cpp): bit 0 disarms; off by default
        ParamSpec("CRASH_DETECT", 0, _INT8, 0, 1),
        # AP_Rally, ArduPlane's defaults: points loaded, 5 km limit, home not a rally point
        ParamSpec("RALLY_TOTAL", 0, _INT8, 0, 100),
        ParamSpec("RALLY_LIMIT_KM", 5.0, _REAL32, 0, 1000),
        ParamSpec("RALLY_INCL_HOME", 0, _INT8, 0, 1),
        # AC_Fence, ArduPlane's defaults: off; the polygon type (inclusion/exclusion
        # items, circles too); RTL on a breach (sitl.fence)
        ParamSpec("FENCE_ENABLE", 0, _INT8, 0, 1),
        ParamSpec("FENCE_TYPE", 4, _INT8, 0, 15),
        ParamSpec("FENCE_ACTION", 1, _INT8, 0, 7),
        ParamSpec("Q_ENABLE", 0, _INT8, 0, 2),
        ParamSpec("FLTMODE_CH", 8, _INT8, 1, 16),
        ParamSpec("FLTMODE1", ArduPlaneMode.AUTO, _INT8, 0, 25),
        ParamSpec("FLTMODE2", ArduPlaneMode.RTL, _INT8, 0, 25),
        ParamSpec("FLTMODE3", ArduPlaneMode.LOITER, _INT8, 0, 25),
        ParamSpec("FLTMODE4", ArduPlaneMode.FBWA, _INT8, 0, 25),
        ParamSpec("FLTMODE5", ArduPlaneMode.STABILIZE, _INT8, 0, 25),
        ParamSpec("FLTMODE6", ArduPlaneMode.MANUAL, _INT8, 0, 25),
        ParamSpec("TRIM_THROTTLE", 45, _INT8, 0, 100),
        ParamSpec("THR_MAX", 100, _INT8, 0, 100),
        ParamSpec("STALL_PREVENTION", 1, _INT8, 0, 1),
        ParamSpec("SERIAL0_PROTOCOL", 2, _INT8, -1, 50),
        ParamSpec("SERIAL1_PROTOCOL", 2, _INT8, -1, 50),
        ParamSpec("SR0_EXT_STAT", 1, _INT16, 0, 50),
        ParamSpec("SR0_POSITION", 1, _INT16, 0, 50),
        ParamSpec("SR0_EXTRA1", 1, _INT16, 0, 50),
        ParamSpec("SR0_EXTRA2", 1, _INT16, 0, 50),
        ParamSpec("SR0_EXTRA3", 1, _INT16, 0, 50),
    ]


class ParamStore:
    """Ordered name -> value store with ArduPilot's PARAM_VALUE indexing."""

    def __init__(self, specs: list[ParamSpec]) -> None:
        self._specs = {s.name: s for s in specs}
        self._names = [s.name for s in specs]
        self._values = {s.name: float(s.default) for s in specs}
        self.version = 0
        """Counts the stores (:meth:`set`): a reader that caches values derived from
        parameters reads them again when it changes."""

    def __len__(self) -> int:
        return len(self._names)

    def names(self) -> list[str]:
        """Parameter names in index order."""
        return list(self._names)

    def get(self, name: str) -> float:
        """Current value (KeyError for an unknown name)."""
        return self._values[name]

    def index_of(self, name: str) -> int | None:
        """Index of ``name`` or None."""
        return self._names.index(name) if name in self._values else None

    def name_at(self, index: int) -> str | None:
        """Name at ``index`` or None when out of range."""
        return self._names[index] if 0 <= index < len(self._names) else None

    def set(self, name: str, value: float) -> float | None:
        """Set ``name``; returns the stored value or None when refused (unknown, NaN, range)."""
        spec = self._specs.get(name)
        if spec is None or not math.isfinite(value):
            return None
        if not (spec.min_value <= value <= spec.max_value):
            return None
        if spec.param_type != _REAL32:
            value = float(round(value))
        self._values[name] = float(value)
        self.version += 1
        if name in ("MAV_SYSID", "SYSID_THISMAV"):  # one parameter under two names
            self._values["MAV_SYSID"] = self._values["SYSID_THISMAV"] = float(value)
        return self._values[name]

    def param_value(
        self, name: str, *, by_name: bool = False
    ) -> mavlink2.MAVLink_param_value_message:
        """The PARAM_VALUE message for ``name``. ``by_name``: the answer to a
        PARAM_REQUEST_READ by name, whose ``param_index`` ArduPilot sets to the request's
        -1 (65535 on the wire, a uint16); otherwise the parameter's index."""
        spec = self._specs[name]
        return mavlink2.MAVLink_param_value_message(
            name.encode("ascii"),
            self._values[name],
            spec.param_type,
            len(self._names),
            _BY_NAME_INDEX if by_name else self._names.index(name),
        )
