"""Shared pieces of the sans-IO transfer state machines.

The state machines (``MissionUpload``, ``MissionDownload``, ``MissionClear``, ``SetCurrent``,
and ``CommandLong``/``ParamSet`` in :mod:`groundstation.mavlink.vehicle_commands`) follow
h11's pattern: no sockets, no clock, no sleeping. The caller feeds them what arrived and the
time (mission seconds), and they answer with :data:`Action` values:

* :class:`Send` -- a pymavlink message to encode (with the caller's ``MavlinkEncoder``) and
  send to the vehicle;
* :class:`Finished` -- the transfer ended; ``result`` says how. Always the last action.

Their common interface is :class:`TransferBase` (``start``, ``receive``, ``poll``,
``cancel``, ``notify_vehicle_rebooted``, ``next_deadline_s``, ``done``, ``result``,
``state``). Drive loop (one owner: only this loop calls the machine)::

    actions = sm.start(now_s)
    while True:
        perform(actions)                       # returns on Finished
        if rebooted: actions = sm.notify_vehicle_rebooted(now_s)
        elif msg := inbox.pop(): actions = sm.receive(msg, now_s)
        elif now_s >= sm.next_deadline_s(): actions = sm.poll(now_s)
        else: await wake-up or sm.next_deadline_s()

Peer input never raises: misbehaviour ends the transfer with a failed
:class:`TransferResult` (a :class:`~domain.errors.RemoteProtocolError` *as
data*), and unreadable messages (wrong field types, out-of-range values, other sources)
are ignored. After the end every input (``receive``, ``poll``, ``cancel``,
``notify_vehicle_rebooted``) returns ``[]``, as h11 answers input after DONE with a state.
Local misuse raises :class:`~domain.errors.LocalProtocolError`: ``receive``
before ``start``, ``start`` twice, invalid constructor arguments (items, target, timeout).

Timing defaults (mission seconds, i.e. on the vehicle's own clock under a speed-up):

* :data:`DEFAULT_TIMEOUT_S` = 1.5 s, :data:`DEFAULT_RETRIES` = 5, the values in use in
  MAVSDK-style clients (design.md). ArduPlane re-requests an item about every 1 s of silence,
  so 1.5 s without a message means at least one of its re-requests was lost; and ArduPlane
  cancels an upload after 8 s of silence, so giving up after (5 + 1) x 1.5 s = 9 s of
  silence never abandons an upload the vehicle still runs.
* :data:`COMMAND_TIMEOUT_S` = 0.5 s (x 5) for the short, idempotent exchanges (clear, set
  current) where ArduPlane answers within one scheduler loop.
"""

from __future__ import annotations

import abc
import enum
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Generic, TypeVar

from domain.errors import LocalProtocolError, RemoteProtocolError
from groundstation.mavlink.codec import MAVLinkMessage, mavlink2

if TYPE_CHECKING:
    from groundstation.mavlink.mission_items import MissionItem

__all__ = [
    "COMMAND_TIMEOUT_S",
    "DEFAULT_RETRIES",
    "DEFAULT_TIMEOUT_S",
    "Action",
    "Finished",
    "Send",
    "TransferBase",
    "TransferCode",
    "TransferResult",
    "code_for_mission_ack",
    "float_field",
    "int_field",
    "message_type",
]

DEFAULT_TIMEOUT_S = 1.5
DEFAULT_RETRIES = 5
COMMAND_TIMEOUT_S = 0.5


class TransferCode(enum.Enum):
    """How a transfer ended. Codes after PROTOCOL_ERROR name the vehicle's error ACK."""

    SUCCESS = "success"
    TIMEOUT = "timeout"  # the vehicle went silent longer than timeout_s x (retries + 1)
    CANCELLED = "cancelled"  # we cancelled (cancel())
    VEHICLE_REBOOTED = "vehicle_rebooted"  # the caller reported a reboot mid-transfer
    PROTOCOL_ERROR = "protocol_error"  # the vehicle broke the protocol (early ACK, bad seq)
    MISSION_TYPE_MISMATCH = "mission_type_mismatch"  # an answer for another mission type
    NO_SPACE = "no_space"  # MAV_MISSION_NO_SPACE (also: autopilot not ready yet)
    DENIED = "denied"  # MAV_MISSION_DENIED / MAV_RESULT_DENIED (e.g. another GCS uploads)
    UNSUPPORTED = "unsupported"  # MAV_MISSION_UNSUPPORTED / MAV_RESULT_UNSUPPORTED
    UNSUPPORTED_FRAME = "unsupported_frame"
    INVALID_PARAM = "invalid_param"  # MAV_MISSION_INVALID, _INVALID_PARAM1.._PARAM7
    INVALID_SEQUENCE = "invalid_sequence"
    REMOTE_CANCELLED = "remote_cancelled"  # MAV_MISSION_OPERATION_CANCELLED (its timeout)
    REMOTE_ERROR = "remote_error"  # MAV_MISSION_ERROR or an unknown result code
    COMMAND_FAILED = "command_failed"  # COMMAND_ACK FAILED / TEMPORARILY_REJECTED / ...


_RETRYABLE = frozenset(
    {
        TransferCode.TIMEOUT,
        TransferCode.VEHICLE_REBOOTED,
        TransferCode.PROTOCOL_ERROR,
        TransferCode.NO_SPACE,
        TransferCode.DENIED,
        TransferCode.INVALID_SEQUENCE,
        TransferCode.REMOTE_CANCELLED,
        TransferCode.REMOTE_ERROR,
        TransferCode.COMMAND_FAILED,
    }
)


@dataclass(frozen=True)
class TransferResult:
    """The outcome of one transfer.

    ``remote_code`` is the name of the vehicle's ACK result when it sent one (e.g.
    ``"MAV_MISSION_NO_SPACE"``). ``retries_used`` counts timeouts that led to a retry.
    ``items`` is the downloaded mission (download only). ``maybe_stored`` is True when an
    upload timed out after every item had been requested: only the final ACK is missing, so
    the vehicle probably holds the mission; verify by download before uploading again.
    """

    ok: bool
    code: TransferCode
    message: str
    retries_used: int = 0
    remote_code: str | None = None
    items: tuple[MissionItem, ...] | None = None
    notes: tuple[str, ...] = field(default_factory=tuple)
    maybe_stored: bool = False

    @property
    def retryable(self) -> bool:
        """Whether running the same transfer again may succeed.

        True for silence, reboots, protocol hiccups, the vehicle's own cancel and NO_SPACE
        (ArduPlane answers "Only 0 items are supported" until it is ready) and DENIED
        (another ground station was uploading). False for content the vehicle rejects
        (UNSUPPORTED, UNSUPPORTED_FRAME, INVALID_PARAM), a mission-type mix-up and our own
        cancel.
        """
        return self.code in _RETRYABLE

    def raise_for_failure(self) -> None:
        """Raise :class:`RemoteProtocolError` unless ok (for sessions that prefer exceptions)."""
        if not self.ok:
            raise RemoteProtocolError(f"{self.code.value}: {self.message}", self)


@dataclass(frozen=True)
class Send:
    """Send ``msg`` to the vehicle."""

    msg: MAVLinkMessage


@dataclass(frozen=True)
class Finished:
    """The transfer is over."""

    result: TransferResult


Action = Send | Finished

_MISSION_RESULT_NAMES: dict[int, str] = {
    int(value): entry.name for value, entry in mavlink2.enums["MAV_MISSION_RESULT"].items()
}
_ACK_CODES: dict[int, TransferCode] = {
    mavlink2.MAV_MISSION_ERROR: TransferCode.REMOTE_ERROR,
    mavlink2.MAV_MISSION_UNSUPPORTED_FRAME: TransferCode.UNSUPPORTED_FRAME,
    mavlink2.MAV_MISSION_UNSUPPORTED: TransferCode.UNSUPPORTED,
    mavlink2.MAV_MISSION_NO_SPACE: TransferCode.NO_SPACE,
    mavlink2.MAV_MISSION_INVALID_SEQUENCE: TransferCode.INVALID_SEQUENCE,
    mavlink2.MAV_MISSION_DENIED: TransferCode.DENIED,
    mavlink2.MAV_MISSION_OPERATION_CANCELLED: TransferCode.REMOTE_CANCELLED,
}


def mission_result_name(ack_type: int) -> str:
    """``MAV_MISSION_*`` name of a MISSION_ACK type (``"MAV_MISSION_RESULT_<n>"`` if unknown)."""
    name = _MISSION_RESULT_NAMES.get(ack_type)
    if name is None or name.endswith("ENUM_END"):
        return f"MAV_MISSION_RESULT_{ack_type}"
    return name


def code_for_mission_ack(ack_type: int) -> TransferCode:
    """The result code for an error MISSION_ACK (ACCEPTED is not an error: SUCCESS)."""
    if ack_type == mavlink2.MAV_MISSION_ACCEPTED:
        return TransferCode.SUCCESS
    if mavlink2.MAV_MISSION_INVALID <= ack_type <= mavlink2.MAV_MISSION_INVALID_PARAM7:
        return TransferCode.INVALID_PARAM
    return _ACK_CODES.get(ack_type, TransferCode.REMOTE_ERROR)


def int_field(
    msg: object, name: str, low: int | None = None, high: int | None = None
) -> int | None:
    """An integer field of a decoded message, or None if missing, not an int, or out of range.

    ``low``/``high`` (inclusive) state the field's wire range: a frame with a wrong length
    but a valid CRC decodes with truncated or zero-filled fields, and a message built by
    hand may carry anything, so every field a machine reads goes through this (or
    :func:`float_field`) and out-of-range values read as "unreadable".
    """
    value = getattr(msg, name, None)
    if isinstance(value, bool) or not isinstance(value, int):
        return None
    if (low is not None and value < low) or (high is not None and value > high):
        return None
    return value


def float_field(msg: object, name: str) -> float | None:
    """A finite numeric field of a decoded message, or None (missing, not a number, NaN, inf)."""
    value = getattr(msg, name, None)
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    result = float(value)
    return result if math.isfinite(result) else None


def message_type(msg: object) -> str | None:
    """``msg.get_type()``, or None for anything that is not a readable MAVLink message."""
    try:
        kind = msg.get_type()  # type: ignore[attr-defined]
    except Exception:  # peer input never raises: an unreadable object is ignored
        return None
    return kind if isinstance(kind, str) else None


S = TypeVar("S", bound=enum.Enum)


class TransferBase(abc.ABC, Generic[S]):
    """The transfer-machine interface, its retry timer, addressing and bookkeeping.

    Every machine declares its own state enum ``S`` with at least ``IDLE`` (before
    :meth:`start`) and ``DONE`` (after the end) and exposes it as :attr:`state`. The public
    interface, the same for every machine:

    * :meth:`start` (abstract): begin, return the first sends. Raises
      :class:`LocalProtocolError` when called twice.
    * :meth:`receive`: one message from the link. Before :meth:`start` it raises
      :class:`LocalProtocolError` (a programming error). Otherwise it **never raises**:
      anything not for this transfer (other systems, other components, other ground
      stations, unhandled types, unreadable fields) is ignored, and after the end every
      input returns ``[]``, as h11 answers input after DONE with a state, not an exception.
    * :meth:`poll`: the time passed; resends or gives up. ``[]`` before start and after end.
    * :meth:`cancel`: we abandon the transfer; ``[]`` before start and after end.
    * :meth:`notify_vehicle_rebooted`: the vehicle rebooted; ``[]`` before start and after end.
    * :meth:`next_deadline_s`, :attr:`done`, :attr:`result`.

    Subclasses implement ``start``, ``_on_message`` (a message of a ``_HANDLED`` type from
    our vehicle, addressed to us), ``_on_silence`` (the timer expired; ``give_up`` when the
    retries are spent) and may override ``_cancel_actions``.

    ``target_system``/``target_component`` identify the vehicle; messages from any other
    source are ignored (component 0 accepts any component of that system). When
    ``own_system`` (and optionally ``own_component``) is given, messages addressed to
    another ground station (a non-zero target that is not us) are ignored too: the daemon
    should pass them, since with ``--out`` forwarding another GCS's transfer passes by.
    """

    default_timeout_s: float = DEFAULT_TIMEOUT_S
    """Timeout per attempt when none is given (subclasses set their own)."""

    _IDLE: S
    """The subclass's state before start."""
    _DONE: S
    """The subclass's state after the end."""
    _HANDLED: frozenset[str] = frozenset()
    """Message types the subclass reads; every other type is ignored."""
    _WHAT: str = "transfer"
    """What the machine does, for messages (``"upload"``)."""

    def __init__(
        self,
        target_system: int,
        target_component: int,
        *,
        mission_type: int = mavlink2.MAV_MISSION_TYPE_MISSION,
        timeout_s: float | None = None,
        retries: int = DEFAULT_RETRIES,
        own_system: int | None = None,
        own_component: int | None = None,
    ) -> None:
        if timeout_s is None:
            timeout_s = self.default_timeout_s
        if not (0 < target_system < 256 and 0 <= target_component < 256):
            raise LocalProtocolError(
                f"invalid target {target_system}/{target_component}: system 1..255, "
                "component 0..255"
            )
        if not 0 <= mission_type <= 255:
            raise LocalProtocolError(f"invalid mission_type {mission_type}")
        if not (timeout_s > 0.0 and math.isfinite(timeout_s)):
            raise LocalProtocolError(f"timeout_s must be > 0, got {timeout_s}")
        if retries < 0:
            raise LocalProtocolError(f"retries must be >= 0, got {retries}")
        self.target_system = target_system
        self.target_component = target_component
        self.mission_type = mission_type
        self.timeout_s = float(timeout_s)
        self.retries = retries
        self.own_system = own_system
        self.own_component = own_component
        self._state: S = self._IDLE
        self._result: TransferResult | None = None
        self._deadline_s: float | None = None
        self._retries_left = retries
        self._retries_used = 0
        self._notes: list[str] = []
        self._sent_s: float | None = None  # when the request now awaiting an answer went
        self._resent = False  # it went more than once (Karn: its answer is no sample)
        self.rtt_samples_s: list[float] = []
        """Round trips measured so far (request sent once -> its answer, mission s); the
        driver feeds them to the link's :class:`~groundstation.mavlink.link_budget.RttEstimator`."""

    # -- public interface -----------------------------------------------------------------

    @property
    def state(self) -> S:
        """Where the transfer is (the subclass's state enum)."""
        return self._state

    @property
    def done(self) -> bool:
        """True once the transfer has finished (successfully or not)."""
        return self._state is self._DONE

    @property
    def result(self) -> TransferResult | None:
        """The outcome once done, else None."""
        return self._result

    def next_deadline_s(self) -> float | None:
        """Mission time at which :meth:`poll` must be called next (None when idle or done)."""
        return None if self._state in (self._IDLE, self._DONE) else self._deadline_s

    @abc.abstractmethod
    def start(self, now_s: float) -> list[Action]:
        """Begin the transfer: the first messages to send."""

    def receive(self, msg: MAVLinkMessage, now_s: float) -> list[Action]:
        """Handle one message from the link (see the class docstring: never raises on it)."""
        if self._state is self._IDLE:
            raise LocalProtocolError(f"{type(self).__name__}.receive() before start()")
        if self.done:
            return []
        kind = message_type(msg)
        if kind is None or kind not in self._HANDLED or not self._from_vehicle(msg):
            return []
        actions = self._on_message(kind, msg, now_s)
        if any(isinstance(a, Send) for a in actions):
            self._sent_s, self._resent = now_s, False
        return actions

    def poll(self, now_s: float) -> list[Action]:
        """Handle the timer: resend, or give up (TIMEOUT) once the retries are spent."""
        due = self._timed_out(now_s)
        if due is None:
            return []
        actions = self._on_silence(now_s, give_up=due)
        if any(isinstance(a, Send) for a in actions):
            self._sent_s, self._resent = now_s, True
        return actions

    def cancel(self, now_s: float) -> list[Action]:
        """Abandon the transfer (CANCELLED), telling the vehicle where the protocol says so."""
        if self._state in (self._IDLE, self._DONE):
            return []
        return self._cancel_actions(now_s)

    def notify_vehicle_rebooted(self, now_s: float) -> list[Action]:
        """The caller saw the vehicle reboot (time_boot_ms went back): fail the transfer.

        A rebooted autopilot has forgotten the transfer; whatever it stored is suspect.
        Nothing is sent: the rebooted vehicle has no transfer to cancel.
        """
        if self._state in (self._IDLE, self._DONE):
            return []
        return self._finish(TransferCode.VEHICLE_REBOOTED, f"vehicle rebooted mid-{self._WHAT}")

    # -- for subclasses -------------------------------------------------------------------

    @abc.abstractmethod
    def _on_message(self, kind: str, msg: MAVLinkMessage, now_s: float) -> list[Action]:
        """A ``kind`` message (one of ``_HANDLED``) from our vehicle, addressed to us."""

    @abc.abstractmethod
    def _on_silence(self, now_s: float, *, give_up: bool) -> list[Action]:
        """The timer expired: retry (``give_up`` False) or finish with TIMEOUT."""

    def _cancel_actions(self, now_s: float) -> list[Action]:
        """Default cancel: stop waiting, nothing to tell the vehicle."""
        return self._finish(TransferCode.CANCELLED, f"{self._WHAT} cancelled by the ground station")

    def _begin(self, now_s: float, state: S) -> None:
        if self._state is not self._IDLE:
            raise LocalProtocolError(f"{type(self).__name__}.start() called twice")
        self._state = state
        self._sent_s, self._resent = now_s, False
        self._arm(now_s)

    def _answered(self, now_s: float) -> None:
        """The vehicle answered the request awaiting an answer: one round-trip sample,
        unless that request was resent (Karn's rule); either way it is answered."""
        if self._sent_s is not None and not self._resent:
            self.rtt_samples_s.append(now_s - self._sent_s)
        self._sent_s = None

    def _arm(self, now_s: float, *, reset_retries: bool = True) -> None:
        """(Re)start the silence timer; progress resets the retry budget."""
        self._deadline_s = now_s + self.timeout_s
        if reset_retries:
            self._retries_left = self.retries

    def _timed_out(self, now_s: float) -> bool | None:
        """None: not yet due (or idle/done). True: due, retries spent. False: due, retry."""
        if self._state in (self._IDLE, self._DONE) or self._deadline_s is None:
            return None
        if now_s < self._deadline_s:
            return None
        if self._retries_left <= 0:
            return True
        self._retries_left -= 1
        self._retries_used += 1
        self._arm(now_s, reset_retries=False)
        return False

    def _from_vehicle(self, msg: MAVLinkMessage) -> bool:
        """True if ``msg`` comes from our vehicle and is addressed to us (or to everyone)."""
        try:
            src_system = msg.get_srcSystem()
            src_component = msg.get_srcComponent()
        except Exception:  # not a decoded message: not from our vehicle
            return False
        if src_system != self.target_system:
            return False
        if self.target_component not in (0, src_component):
            return False
        if self.own_system is not None:
            target_system = int_field(msg, "target_system")
            if target_system not in (None, 0, self.own_system):
                return False
            target_component = int_field(msg, "target_component")
            if self.own_component is not None and target_component not in (
                None,
                0,
                self.own_component,
            ):
                return False
        return True

    def _mission_type_mismatch(self, kind: str, msg: MAVLinkMessage) -> list[Action] | None:
        """Finish with MISSION_TYPE_MISMATCH unless ``msg`` is for our mission type."""
        mission_type = int_field(msg, "mission_type")
        if mission_type == self.mission_type:
            return None
        return self._finish(
            TransferCode.MISSION_TYPE_MISMATCH,
            f"{kind} for mission type {mission_type}, {self._WHAT} of type {self.mission_type}",
        )

    def _mission_ack(self, ack_type: int) -> MAVLinkMessage:
        return mavlink2.MAVLink_mission_ack_message(
            self.target_system, self.target_component, ack_type, self.mission_type
        )

    def _finish(
        self,
        code: TransferCode,
        message: str,
        *,
        remote_code: str | None = None,
        items: tuple[MissionItem, ...] | None = None,
        send: MAVLinkMessage | None = None,
        maybe_stored: bool = False,
    ) -> list[Action]:
        self._result = TransferResult(
            ok=code is TransferCode.SUCCESS,
            code=code,
            message=message,
            retries_used=self._retries_used,
            remote_code=remote_code,
            items=items,
            notes=tuple(self._notes),
            maybe_stored=maybe_stored,
        )
        self._state = self._DONE
        self._deadline_s = None
        actions: list[Action] = [] if send is None else [Send(send)]
        actions.append(Finished(self._result))
        return actions

    def _finish_for_ack(self, ack_type: int, what: str) -> list[Action]:
        name = mission_result_name(ack_type)
        return self._finish(
            code_for_mission_ack(ack_type), f"vehicle answered {name} {what}", remote_code=name
        )
