"""Sans-IO COMMAND_LONG, PARAM_SET and PARAM_REQUEST_READ exchanges (the ones that are not
about the mission).

:class:`CommandLong`: send ``COMMAND_LONG(command, params)`` until a ``COMMAND_ACK`` for
that command, addressed to us, carries a final result (anything but IN_PROGRESS). Silence
for ``timeout_s`` resends it with ``confirmation`` + 1, at most ``retries`` times (defaults
1.0 s x 5, what the daemon used). The ACK's ``MAV_RESULT`` is kept in :attr:`ack_result`;
ACCEPTED ends with SUCCESS, any other final result with its code (FAILED /
TEMPORARILY_REJECTED: COMMAND_FAILED, DENIED, UNSUPPORTED, ...).

:class:`ParamSet`: send ``PARAM_SET(name, value, REAL32)`` until a ``PARAM_VALUE`` of that
name echoes the value (relative and absolute tolerance 1e-6, float32 on the wire). A
``PARAM_VALUE`` of that name with another value (the vehicle clamped or refused it) is
noted and waited past: silence resends, and the retries end it with TIMEOUT.

:class:`ParamRead`: send ``PARAM_REQUEST_READ(name, param_index = -1)`` (by name) until a
``PARAM_VALUE`` of that name arrives; its value is :attr:`ParamRead.value`. ArduPilot
answers a read by name with the parameter's value and ``param_index`` -1 (65535 on the
wire: it echoes the request's index), and does **not answer at all** for a name it does not
have (``GCS_MAVLINK::param_io_timer``: ``AP_Param::find`` returns nothing, no reply), so
an unknown name ends only by the retries, with TIMEOUT. Any PARAM_VALUE of that name counts
(the index is not checked: a by-index answer, or the broadcast after another ground
station's PARAM_SET, carries the same value); a non-finite value is noted and waited past.


:class:`HomeSet`: move the vehicle's home (where its RTL goes, whoever starts it) to a
location, verified like a mission: ``COMMAND_INT(MAV_CMD_DO_SET_HOME, frame GLOBAL, param1
= 0 "use the location given", x/y = lat/lon degE7, z = altitude AMSL)``, resent on silence,
until a final ``COMMAND_ACK``; after ACCEPTED, until a ``HOME_POSITION`` within
``tolerance_m`` of the request (one that already came with the ACK counts). ArduPilot sends
HOME_POSITION when its home changes; silence asks for it with ``MAV_CMD_REQUEST_MESSAGE``
(242), a bounded number of times. When the home's altitude is not known yet (``alt_m``
None) the machine first asks for HOME_POSITION and keeps the vehicle's own altitude: only
the horizontal position moves. ArduPilot handles DO_SET_HOME in COMMAND_INT as in
COMMAND_LONG (``GCS_MAVLINK::handle_command_int_do_set_home``); COMMAND_INT carries the
position as integers, with no float32 rounding (~1 m at 1e7 degE7 in a float).

All four follow :class:`~groundstation.mavlink.mission_transfer.TransferBase`: peer input never
raises, input after the end returns ``[]``; bad arguments raise ``LocalProtocolError``.
"""

from __future__ import annotations

import abc
import enum
import math
from collections.abc import Sequence
from typing import Any, TypeVar

from domain.errors import LocalProtocolError
from groundstation.mavlink.codec import MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_commands import command_result_code, command_result_name
from groundstation.mavlink.mission_items import f32
from groundstation.mavlink.mission_transfer import (
    DEFAULT_RETRIES,
    Action,
    Send,
    TransferBase,
    TransferCode,
    float_field,
    int_field,
)

__all__ = [
    "CommandLong",
    "CommandState",
    "HomeSet",
    "HomeSetState",
    "ParamRead",
    "ParamReadState",
    "ParamSet",
    "ParamSetState",
]

COMMAND_LONG_TIMEOUT_S = 1.0
HOME_TOLERANCE_M = 5.0
"""A HOME_POSITION this close to the requested home confirms it (degE7 rounding and the
autopilot's own float arithmetic are centimetres; a stale home is far)."""
MSG_ID_HOME_POSITION = 242
_EARTH_RADIUS_M = 6_371_000.0
_UINT8_MAX = 255
_UINT16_MAX = 65535
_PARAM_ID_LEN = 16


class CommandState(enum.Enum):
    """Where a command is."""

    IDLE = "idle"
    WAITING_ACK = "waiting_ack"  # COMMAND_LONG sent (silence resends it)
    DONE = "done"


class CommandLong(TransferBase[CommandState]):
    """One COMMAND_LONG and its final COMMAND_ACK."""

    default_timeout_s = COMMAND_LONG_TIMEOUT_S
    _IDLE = CommandState.IDLE
    _DONE = CommandState.DONE
    _HANDLED = frozenset({"COMMAND_ACK"})
    _WHAT = "command"

    def __init__(
        self,
        target_system: int,
        target_component: int,
        command: int,
        params: Sequence[float] = (),
        *,
        timeout_s: float = COMMAND_LONG_TIMEOUT_S,
        retries: int = DEFAULT_RETRIES,
        own_system: int | None = None,
        own_component: int | None = None,
    ) -> None:
        super().__init__(
            target_system,
            target_component,
            timeout_s=timeout_s,
            retries=retries,
            own_system=own_system,
            own_component=own_component,
        )
        if not 0 <= command <= _UINT16_MAX:
            raise LocalProtocolError(f"command must be in 0..65535, got {command}")
        if len(params) > 7:
            raise LocalProtocolError(f"COMMAND_LONG has 7 params, got {len(params)}")
        self.command = command
        self.params: tuple[float, ...] = tuple(float(p) for p in params) + (0.0,) * (
            7 - len(params)
        )
        self._confirmation = 0
        self.ack_result: int | None = None
        """The MAV_RESULT of the final COMMAND_ACK, once one arrived."""

    def start(self, now_s: float) -> list[Action]:
        """Begin: send the COMMAND_LONG."""
        self._begin(now_s, CommandState.WAITING_ACK)
        return [Send(self._message())]

    def _on_silence(self, now_s: float, *, give_up: bool) -> list[Action]:
        if give_up:
            return self._finish(
                TransferCode.TIMEOUT,
                f"no COMMAND_ACK for command {self.command} after {self.retries + 1} tries",
            )
        self._confirmation = min(self._confirmation + 1, _UINT8_MAX)
        return [Send(self._message())]

    def _on_message(self, kind: str, msg: MAVLinkMessage, now_s: float) -> list[Action]:
        if int_field(msg, "command") != self.command:
            return []
        result = int_field(msg, "result", 0, _UINT8_MAX)
        if result is None or result == mavlink2.MAV_RESULT_IN_PROGRESS:
            return []
        self.ack_result = result
        name = command_result_name(result)
        return self._finish(
            command_result_code(result),
            f"vehicle answered {name} to command {self.command}",
            remote_code=name,
        )

    def _message(self) -> MAVLinkMessage:
        return mavlink2.MAVLink_command_long_message(
            self.target_system,
            self.target_component,
            self.command,
            self._confirmation,
            *self.params,
        )


class ParamSetState(enum.Enum):
    """Where a parameter set is."""

    IDLE = "idle"
    WAITING_VALUE = "waiting_value"  # PARAM_SET sent (silence resends it)
    DONE = "done"


class ParamReadState(enum.Enum):
    """Where a parameter read is."""

    IDLE = "idle"
    WAITING_VALUE = "waiting_value"  # PARAM_REQUEST_READ sent (silence resends it)
    DONE = "done"


_P = TypeVar("_P", ParamSetState, ParamReadState)


class _ParamExchange(TransferBase[_P]):
    """One message about parameter ``name``, resent on silence until a PARAM_VALUE of that
    name settles it (:meth:`_on_value`); the retries end it with TIMEOUT (``_gave_up``)."""

    default_timeout_s = COMMAND_LONG_TIMEOUT_S
    _HANDLED = frozenset({"PARAM_VALUE"})
    _WAITING: _P

    def __init__(
        self,
        target_system: int,
        target_component: int,
        name: str,
        *,
        timeout_s: float = COMMAND_LONG_TIMEOUT_S,
        retries: int = DEFAULT_RETRIES,
        own_system: int | None = None,
        own_component: int | None = None,
    ) -> None:
        super().__init__(
            target_system,
            target_component,
            timeout_s=timeout_s,
            retries=retries,
            own_system=own_system,
            own_component=own_component,
        )
        if not (name and name.isascii() and len(name) <= _PARAM_ID_LEN and "\x00" not in name):
            raise LocalProtocolError(f"parameter name must be 1..16 ASCII characters: {name!r}")
        self.name = name

    def start(self, now_s: float) -> list[Action]:
        """Begin: send the message."""
        self._begin(now_s, self._WAITING)
        return [Send(self._message())]

    def _on_silence(self, now_s: float, *, give_up: bool) -> list[Action]:
        if give_up:
            return self._finish(TransferCode.TIMEOUT, self._gave_up())
        return [Send(self._message())]

    def _on_message(self, kind: str, msg: MAVLinkMessage, now_s: float) -> list[Action]:
        if _param_id(msg) != self.name:
            return []
        value = float_field(msg, "param_value")
        if value is None:  # not a finite number
            self._notes.append(f"PARAM_VALUE {self.name} at t={now_s:.3f}s: no finite value")
            return []
        return self._on_value(value, now_s)

    @abc.abstractmethod
    def _message(self) -> MAVLinkMessage: ...

    @abc.abstractmethod
    def _gave_up(self) -> str: ...

    @abc.abstractmethod
    def _on_value(self, value: float, now_s: float) -> list[Action]: ...


class ParamSet(_ParamExchange[ParamSetState]):
    """Set parameter ``name`` to ``value`` (REAL32) and confirm it by PARAM_VALUE."""

    _IDLE = ParamSetState.IDLE
    _DONE = ParamSetState.DONE
    _WAITING = ParamSetState.WAITING_VALUE
    _WHAT = "parameter set"

    def __init__(
        self,
        target_system: int,
        target_component: int,
        name: str,
        value: float,
        **options: Any,
    ) -> None:
        super().__init__(target_system, target_component, name, **options)
        if not math.isfinite(f32(float(value))):
            raise LocalProtocolError(f"parameter {name} value must fit a float32: {value!r}")
        self.value = float(value)

    def _gave_up(self) -> str:
        return f"no PARAM_VALUE {self.name}={self.value:g} after {self.retries + 1} PARAM_SET"

    def _on_value(self, value: float, now_s: float) -> list[Action]:
        if not math.isclose(value, self.value, rel_tol=1e-6, abs_tol=1e-6):
            self._notes.append(f"PARAM_VALUE {self.name}={value:g} at t={now_s:.3f}s (not ours)")
            return []
        return self._finish(TransferCode.SUCCESS, f"{self.name} = {value:g}")

    def _message(self) -> MAVLinkMessage:
        return mavlink2.MAVLink_param_set_message(
            self.target_system,
            self.target_component,
            self.name.encode("ascii"),
            self.value,
            mavlink2.MAV_PARAM_TYPE_REAL32,
        )


class ParamRead(_ParamExchange[ParamReadState]):
    """Read parameter ``name`` by name (PARAM_REQUEST_READ, index -1) from its PARAM_VALUE
    (module docstring); :attr:`value` once it succeeded."""

    _IDLE = ParamReadState.IDLE
    _DONE = ParamReadState.DONE
    _WAITING = ParamReadState.WAITING_VALUE
    _WHAT = "parameter read"

    def __init__(self, target_system: int, target_component: int, name: str,
                 **options: Any) -> None:  # fmt: skip
        super().__init__(target_system, target_component, name, **options)
        self.value: float | None = None
        """The value the vehicle answered (float32 on the wire), once it did."""

    def _gave_up(self) -> str:
        return (f"no PARAM_VALUE {self.name} after {self.retries + 1} PARAM_REQUEST_READ "
                "(ArduPilot does not answer a name it does not have)")

    def _on_value(self, value: float, now_s: float) -> list[Action]:
        self.value = value
        return self._finish(TransferCode.SUCCESS, f"{self.name} = {value:g}")

    def _message(self) -> MAVLinkMessage:
        return mavlink2.MAVLink_param_request_read_message(
            self.target_system, self.target_component, self.name.encode("ascii"), -1
        )


def _param_id(msg: MAVLinkMessage) -> str | None:
    """A PARAM_VALUE's name (NUL padding stripped), or None when unreadable."""
    raw = getattr(msg, "param_id", None)
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", "replace")
    return raw.rstrip("\x00") if isinstance(raw, str) else None


class HomeSetState(enum.Enum):
    """Where a home set is."""

    IDLE = "idle"
    READING_HOME = "reading_home"  # the home's altitude unknown: HOME_POSITION asked for
    WAITING_ACK = "waiting_ack"  # COMMAND_INT DO_SET_HOME sent (silence resends it)
    CONFIRMING = "confirming"  # ACCEPTED: waiting for HOME_POSITION at the new home
    DONE = "done"


def ground_distance_m(lat1_deg: float, lon1_deg: float, lat2_deg: float,
                      lon2_deg: float) -> float:
    """Horizontal distance (m) between two nearby points (equirectangular: exact to well
    under a centimetre over the few kilometres that matter here)."""
    lat_mid = math.radians((lat1_deg + lat2_deg) / 2.0)
    dx = math.radians(lon2_deg - lon1_deg) * math.cos(lat_mid) * _EARTH_RADIUS_M
    dy = math.radians(lat2_deg - lat1_deg) * _EARTH_RADIUS_M
    return math.hypot(dx, dy)


class HomeSet(TransferBase[HomeSetState]):
    """MAV_CMD_DO_SET_HOME to (``lat_deg``, ``lon_deg``, ``alt_m`` AMSL), confirmed by
    HOME_POSITION (module docstring). Once done: :attr:`ack_result`, :attr:`home` (the
    confirmed lat, lon, alt) and :attr:`error_m` (its distance from the request)."""

    default_timeout_s = COMMAND_LONG_TIMEOUT_S
    _IDLE = HomeSetState.IDLE
    _DONE = HomeSetState.DONE
    _HANDLED = frozenset({"COMMAND_ACK", "HOME_POSITION"})
    _WHAT = "home set"

    def __init__(
        self,
        target_system: int,
        target_component: int,
        lat_deg: float,
        lon_deg: float,
        alt_m: float | None,
        *,
        tolerance_m: float = HOME_TOLERANCE_M,
        timeout_s: float = COMMAND_LONG_TIMEOUT_S,
        retries: int = DEFAULT_RETRIES,
        own_system: int | None = None,
        own_component: int | None = None,
    ) -> None:
        super().__init__(
            target_system,
            target_component,
            timeout_s=timeout_s,
            retries=retries,
            own_system=own_system,
            own_component=own_component,
        )
        if not (math.isfinite(lat_deg) and -90.0 <= lat_deg <= 90.0
                and math.isfinite(lon_deg) and -180.0 <= lon_deg <= 180.0):
            raise LocalProtocolError(f"home must be a valid lat/lon, got {lat_deg}, {lon_deg}")
        if alt_m is not None and not (math.isfinite(alt_m) and abs(alt_m) < 20_000.0):
            raise LocalProtocolError(f"home altitude must be finite metres, got {alt_m!r}")
        if not (tolerance_m > 0.0 and math.isfinite(tolerance_m)):
            raise LocalProtocolError(f"tolerance_m must be > 0, got {tolerance_m}")
        self.lat_deg = float(lat_deg)
        self.lon_deg = float(lon_deg)
        self.alt_m = None if alt_m is None else float(alt_m)
        self.tolerance_m = float(tolerance_m)
        self.ack_result: int | None = None
        """The MAV_RESULT of the final COMMAND_ACK, once one arrived."""
        self.home: tuple[float, float, float] | None = None
        """The HOME_POSITION that confirmed the request (lat_deg, lon_deg, alt_m)."""
        self.error_m: float | None = None
        """Its horizontal distance from the request (m); for a refused or unconfirmed
        request, that of the last HOME_POSITION seen (None when none came)."""
        self._early: tuple[float, float, float, float] | None = None  # near one before the ACK

    def start(self, now_s: float) -> list[Action]:
        """Begin: send DO_SET_HOME (or, with the home's altitude unknown, ask for it)."""
        if self.alt_m is None:
            self._begin(now_s, HomeSetState.READING_HOME)
            return [Send(self._request_home())]
        self._begin(now_s, HomeSetState.WAITING_ACK)
        return [Send(self._set_home())]

    def _on_silence(self, now_s: float, *, give_up: bool) -> list[Action]:
        state = self._state
        if give_up:
            why = {
                HomeSetState.READING_HOME: "no HOME_POSITION: the home's altitude is unknown",
                HomeSetState.WAITING_ACK: "no COMMAND_ACK for DO_SET_HOME",
            }.get(state)
            if why is None:
                last = ("none came" if self.error_m is None
                        else f"the last was {self.error_m:.1f} m off")
                why = f"no HOME_POSITION within {self.tolerance_m:g} m of the request ({last})"
            return self._finish(TransferCode.TIMEOUT, f"{why} after {self.retries + 1} tries")
        if state is HomeSetState.WAITING_ACK:
            return [Send(self._set_home())]
        return [Send(self._request_home())]

    def _on_message(self, kind: str, msg: MAVLinkMessage, now_s: float) -> list[Action]:
        if kind == "HOME_POSITION":
            return self._on_home(msg, now_s)
        if int_field(msg, "command") != mavlink2.MAV_CMD_DO_SET_HOME:
            return []
        if self._state is not HomeSetState.WAITING_ACK:
            return []  # a duplicate ACK of a resend
        result = int_field(msg, "result", 0, _UINT8_MAX)
        if result is None or result == mavlink2.MAV_RESULT_IN_PROGRESS:
            return []
        self.ack_result = result
        name = command_result_name(result)
        if result != mavlink2.MAV_RESULT_ACCEPTED:
            return self._finish(command_result_code(result),
                                f"vehicle answered {name} to DO_SET_HOME", remote_code=name)
        if self._early is not None:
            return self._confirmed(*self._early)
        self._state = HomeSetState.CONFIRMING
        self._arm(now_s)
        return []

    def _on_home(self, msg: MAVLinkMessage, now_s: float) -> list[Action]:
        lat, lon, alt_mm = (int_field(msg, "latitude"), int_field(msg, "longitude"),
                            int_field(msg, "altitude"))
        if lat is None or lon is None or alt_mm is None or (lat == 0 and lon == 0):
            self._notes.append(f"HOME_POSITION at t={now_s:.3f}s: no position")
            return []
        lat_deg, lon_deg, alt_m = lat * 1e-7, lon * 1e-7, alt_mm / 1000.0
        if self._state is HomeSetState.READING_HOME:
            self.alt_m = alt_m
            self._state = HomeSetState.WAITING_ACK
            self._arm(now_s)
            return [Send(self._set_home())]
        error_m = ground_distance_m(self.lat_deg, self.lon_deg, lat_deg, lon_deg)
        self.error_m = error_m
        if error_m > self.tolerance_m:
            self._notes.append(f"HOME_POSITION at t={now_s:.3f}s {error_m:.1f} m off (not ours)")
            return []
        if self._state is HomeSetState.WAITING_ACK:
            self._early = (lat_deg, lon_deg, alt_m, error_m)  # the ACK decides
            return []
        return self._confirmed(lat_deg, lon_deg, alt_m, error_m)

    def _confirmed(self, lat_deg: float, lon_deg: float, alt_m: float,
                   error_m: float) -> list[Action]:
        self.home = (lat_deg, lon_deg, alt_m)
        self.error_m = error_m
        return self._finish(TransferCode.SUCCESS, f"home at {lat_deg:.7f}, {lon_deg:.7f} "
                            f"({error_m:.2f} m from the request)")

    def _set_home(self) -> MAVLinkMessage:
        assert self.alt_m is not None
        return mavlink2.MAVLink_command_int_message(
            self.target_system,
            self.target_component,
            mavlink2.MAV_FRAME_GLOBAL,
            mavlink2.MAV_CMD_DO_SET_HOME,
            0,  # current (unused)
            0,  # autocontinue (unused)
            0.0,  # param1: 0 = use the location given (1 = the vehicle's current one)
            0.0,
            0.0,
            math.nan,  # param4: yaw, unchanged
            round(self.lat_deg * 1e7),
            round(self.lon_deg * 1e7),
            self.alt_m,
        )

    def _request_home(self) -> MAVLinkMessage:
        return mavlink2.MAVLink_command_long_message(
            self.target_system,
            self.target_component,
            mavlink2.MAV_CMD_REQUEST_MESSAGE,
            0,
            float(MSG_ID_HOME_POSITION),
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
        )
