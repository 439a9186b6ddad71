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

All three follow :class:`~groundstation.mavlink.mission_transfer.TransferBase`: peer input never
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
    "ParamRead",
    "ParamReadState",
    "ParamSet",
    "ParamSetState",
]

COMMAND_LONG_TIMEOUT_S = 1.0
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
