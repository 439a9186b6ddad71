"""Sans-IO short mission exchanges: clear the mission, set the current item.

:class:`MissionClear`: ``MISSION_CLEAR_ALL`` -> ``MISSION_ACK``. Clearing is idempotent, so
silence resends it (default 0.5 s x 5, :data:`COMMAND_TIMEOUT_S`: ArduPlane answers within
one loop).

:class:`MissionSetCurrent`: ``COMMAND_LONG(MAV_CMD_DO_SET_MISSION_CURRENT, param1=seq)`` (or the
older ``MISSION_SET_CURRENT`` message), confirmed by ``COMMAND_ACK ACCEPTED`` and then by
``MISSION_CURRENT.seq == seq``. ``MISSION_CURRENT`` reaching ``seq`` also confirms on its own
when the ACK was lost, but only if it is news: the vehicle was known to be on another item
(``known_current_seq``) or a ``MISSION_CURRENT`` with another seq was seen since start.
(Re-sending the current seq reloads the item, design.md, so a stale ``MISSION_CURRENT``
equal to ``seq`` must not count.) Silence before the ACK resends the command with
``confirmation`` + 1, up to ``command_retries`` times (default twice ``retries``: at 20 %
loss each way a round trip fails with probability 0.36, so 6 attempts failed 0.2 % of the
set-currents whose vehicle was already on ``seq``, where no MISSION_CURRENT is news; 11
fail 1e-5). After the ACK the command is not resent (a resend would restart the
item): silence asks for the confirmation instead, ``COMMAND_LONG(MAV_CMD_REQUEST_MESSAGE,
MISSION_CURRENT)`` (ArduPilot answers with a MISSION_CURRENT at once, besides its ~1 Hz
stream), on the same timer. Defaults 1.0 s x 5: a 6 s window sees ~6 streamed
MISSION_CURRENTs and 5 asked-for ones, so at 20 % loss (each way) all of them are lost
with probability 0.2^6 x 0.36^5 (~4e-7).

**Moved on, shown by the stream.** After the ACK, MISSION_CURRENT past ``seq`` confirms
too when the vehicle was seen on ``seq`` during the exchange (a MISSION_CURRENT ``seq``
since the command was first sent, even the ambiguous one before the ACK), or when
``past_frames`` (2) such MISSION_CURRENTs, with none at or before ``seq`` between them,
span at least ``past_span_s`` (0.8 s). One beyond the mission's ``total`` (when the
vehicle reports it: ArduPilot's excludes home, so the last item is ``seq == total``) is
an overwritten item still flown, never this evidence. Either way the vehicle started
``seq`` (the ACK) and its stream now says it moved on. One late frame cannot do that (it
is one frame; the next one of the stream, at or before ``seq`` while the vehicle is still
on it, starts the count again).

**Passed at once.** After the ACK, ``MISSION_ITEM_REACHED`` with ``seq`` confirms too: the
vehicle started item ``seq`` and has already completed it (ArduPlane sends it once when an
item completes, ``verify_command_callback``: ``if (cmd_complete)
send_mission_item_reached_message(cmd.index)``). ArduPlane does this with a waypoint:
``DO_SET_MISSION_CURRENT`` starts the item while it still cross-tracks from the previous
waypoint (``next_wp_crosstrack`` is cleared only after the item started), so a re-uploaded
waypoint that lies behind that line is "Passed" at once: ArduPlane's ACK and the
MISSION_CURRENT it queues (``send_message(MSG_CURRENT_WAYPOINT)``, sent after the ACK) may be
the only frames showing ``seq``, and a busy link may send the queued one only after the pass
(showing ``seq + 1``). Without this rule such a set-current waited out its whole window (6
s) and was reported as 5 retries.

A single ``MISSION_CURRENT`` on a later item is *not* taken as that evidence: links do not
all keep the vehicle's order (UDP, a router or MAVProxy merging two masters such as radio
and LTE can deliver an older frame late) and ``MISSION_CURRENT`` carries no time, so a
vehicle that held item 2 of its previous mission could confirm a set-current 1 of the new
one with a delayed ``MISSION_CURRENT 2`` (the sustained rule above needs the stream). A
stale ``MISSION_ITEM_REACHED seq`` after the ACK would need a frame sent when an earlier
item ``seq`` ended to be overtaken by the whole exchange; that is the residual risk of this
rule, as is a COMMAND_ACK of an earlier exchange delivered seconds late (then the stream
of the previous mission past ``seq`` would confirm). Before the ACK it is ignored like
``MISSION_CURRENT``.

Any other command (:class:`CommandLong`) and PARAM_SET (:class:`ParamSet`) are in
:mod:`groundstation.mavlink.vehicle_commands`.
"""

from __future__ import annotations

import enum

from domain.errors import LocalProtocolError
from groundstation.mavlink.codec import MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_transfer import (
    COMMAND_TIMEOUT_S,
    DEFAULT_RETRIES,
    Action,
    Send,
    TransferBase,
    TransferCode,
    int_field,
)

__all__ = [
    "ClearState",
    "MissionClear",
    "MissionSetCurrent",
    "SetCurrentState",
    "command_result_code",
    "command_result_name",
]

SET_CURRENT_TIMEOUT_S = 1.0
_UINT8_MAX = 255
_UINT16_MAX = 65535

_COMMAND_RESULT_CODES: dict[int, TransferCode] = {
    mavlink2.MAV_RESULT_TEMPORARILY_REJECTED: TransferCode.COMMAND_FAILED,
    mavlink2.MAV_RESULT_DENIED: TransferCode.DENIED,
    mavlink2.MAV_RESULT_UNSUPPORTED: TransferCode.UNSUPPORTED,
    mavlink2.MAV_RESULT_FAILED: TransferCode.COMMAND_FAILED,
    6: TransferCode.REMOTE_CANCELLED,  # MAV_RESULT_CANCELLED (not in every dialect)
}


def command_result_name(result: int) -> str:
    """``MAV_RESULT_*`` name of a COMMAND_ACK result (``"MAV_RESULT_<n>"`` if unknown)."""
    entry = mavlink2.enums["MAV_RESULT"].get(result)
    if entry is None or entry.name.endswith("ENUM_END"):
        return f"MAV_RESULT_{result}"
    return str(entry.name)


def command_result_code(result: int) -> TransferCode:
    """The result code for a COMMAND_ACK result (ACCEPTED: SUCCESS; unknown: REMOTE_ERROR)."""
    if result == mavlink2.MAV_RESULT_ACCEPTED:
        return TransferCode.SUCCESS
    return _COMMAND_RESULT_CODES.get(result, TransferCode.REMOTE_ERROR)


class ClearState(enum.Enum):
    """Where a clear is."""

    IDLE = "idle"
    WAITING_ACK = "waiting_ack"  # MISSION_CLEAR_ALL sent (silence resends it)
    DONE = "done"


class MissionClear(TransferBase[ClearState]):
    """Delete the vehicle's mission of ``mission_type``."""

    default_timeout_s = COMMAND_TIMEOUT_S
    _IDLE = ClearState.IDLE
    _DONE = ClearState.DONE
    _HANDLED = frozenset({"MISSION_ACK"})
    _WHAT = "clear"

    def start(self, now_s: float) -> list[Action]:
        """Begin: send MISSION_CLEAR_ALL."""
        self._begin(now_s, ClearState.WAITING_ACK)
        return [Send(self._clear())]

    def _on_silence(self, now_s: float, *, give_up: bool) -> list[Action]:
        """Resend MISSION_CLEAR_ALL on silence, or give up (TIMEOUT)."""
        if give_up:
            return self._finish(
                TransferCode.TIMEOUT,
                f"no MISSION_ACK after {self.retries + 1} MISSION_CLEAR_ALL",
            )
        return [Send(self._clear())]

    def _on_message(self, kind: str, msg: MAVLinkMessage, now_s: float) -> list[Action]:
        ack_type = int_field(msg, "type", 0, _UINT8_MAX)
        if ack_type is None:
            return []
        mismatch = self._mission_type_mismatch(kind, msg)
        if mismatch is not None:
            return mismatch
        if ack_type == mavlink2.MAV_MISSION_ACCEPTED:
            return self._finish(
                TransferCode.SUCCESS, "mission cleared", remote_code="MAV_MISSION_ACCEPTED"
            )
        return self._finish_for_ack(ack_type, "to MISSION_CLEAR_ALL")

    def _clear(self) -> MAVLinkMessage:
        return mavlink2.MAVLink_mission_clear_all_message(
            self.target_system, self.target_component, self.mission_type
        )


class SetCurrentState(enum.Enum):
    """Where a set-current is."""

    IDLE = "idle"
    SENDING_COMMAND = "sending_command"  # no COMMAND_ACK ACCEPTED yet (silence resends)
    CONFIRMING = "confirming"  # ACK ACCEPTED: waiting for MISSION_CURRENT (no resends)
    DONE = "done"


class MissionSetCurrent(TransferBase[SetCurrentState]):
    """Make item ``seq`` the vehicle's current mission item, and confirm it."""

    _IDLE = SetCurrentState.IDLE
    _DONE = SetCurrentState.DONE
    _HANDLED = frozenset({"COMMAND_ACK", "MISSION_CURRENT", "MISSION_ITEM_REACHED"})
    _WHAT = "set-current"

    def __init__(
        self,
        target_system: int,
        target_component: int,
        seq: int,
        *,
        known_current_seq: int | None = None,
        use_command: bool = True,
        timeout_s: float = SET_CURRENT_TIMEOUT_S,
        retries: int = DEFAULT_RETRIES,
        own_system: int | None = None,
        own_component: int | None = None,
        past_frames: int = 2,
        past_span_s: float = 0.8,
        command_retries: int | None = None,
    ) -> None:
        super().__init__(
            target_system,
            target_component,
            mission_type=mavlink2.MAV_MISSION_TYPE_MISSION,
            timeout_s=timeout_s,
            retries=retries,
            own_system=own_system,
            own_component=own_component,
        )
        if not 0 <= seq <= _UINT16_MAX:
            raise LocalProtocolError(f"seq must be in 0..65535, got {seq}")
        self.seq = seq
        self.use_command = use_command
        self.command_retries = 2 * retries if command_retries is None else command_retries
        self.past_frames = past_frames
        self.past_span_s = past_span_s
        self._confirmation = 0
        self._seen_other_seq = known_current_seq is not None and known_current_seq != seq
        self._seen_seq = False
        """A MISSION_CURRENT ``seq`` arrived since the command was first sent."""
        self._past: list[float] = []
        """Arrival times of the MISSION_CURRENTs past ``seq`` since the ACK (a run)."""
        self.asked = 0
        """REQUEST_MESSAGE(MISSION_CURRENT) sent after the ACK."""

    def start(self, now_s: float) -> list[Action]:
        """Begin: send the set-current command."""
        self._begin(now_s, SetCurrentState.SENDING_COMMAND)
        self._retries_left = self.command_retries  # until the ACK (see the module docstring)
        return [Send(self._command())]

    def _on_silence(self, now_s: float, *, give_up: bool) -> list[Action]:
        """Resend the command while unacknowledged; give up after the retries (TIMEOUT)."""
        acked = self._state is SetCurrentState.CONFIRMING
        if give_up:
            if acked:
                message = f"COMMAND_ACK ACCEPTED but MISSION_CURRENT never showed {self.seq}"
                return self._finish(
                    TransferCode.TIMEOUT, message, remote_code="MAV_RESULT_ACCEPTED"
                )
            message = f"no confirmation of current item {self.seq}"
            return self._finish(TransferCode.TIMEOUT, message)
        if acked:
            self.asked += 1
            return [Send(self._ask_current())]
        self._confirmation = min(self._confirmation + 1, _UINT8_MAX)
        return [Send(self._command())]

    def _on_message(self, kind: str, msg: MAVLinkMessage, now_s: float) -> list[Action]:
        if kind == "MISSION_CURRENT":
            return self._on_mission_current(msg, now_s)
        if kind == "MISSION_ITEM_REACHED":
            return self._on_item_reached(msg)
        if int_field(msg, "command") != mavlink2.MAV_CMD_DO_SET_MISSION_CURRENT:
            return []
        result = int_field(msg, "result", 0, _UINT8_MAX)
        if result is None or result == mavlink2.MAV_RESULT_IN_PROGRESS:
            return []
        if result == mavlink2.MAV_RESULT_ACCEPTED:
            if self._state is SetCurrentState.SENDING_COMMAND:
                self._state = SetCurrentState.CONFIRMING
                self._arm(now_s)
            return []
        name = command_result_name(result)
        return self._finish(
            command_result_code(result),
            f"vehicle answered {name} to DO_SET_MISSION_CURRENT {self.seq}",
            remote_code=name,
        )

    def _on_mission_current(self, msg: MAVLinkMessage, now_s: float) -> list[Action]:
        current = int_field(msg, "seq", 0, _UINT16_MAX)
        if current is None:
            return []
        acked = self._state is SetCurrentState.CONFIRMING
        total = int_field(msg, "total", 0, _UINT16_MAX)
        beyond = total is not None and 0 < total < current  # an overwritten item still flown
        if current > self.seq and acked and not beyond:
            return self._on_past(current, now_s)
        self._past.clear()  # at or before seq: the vehicle may still be on it
        if current != self.seq:
            self._seen_other_seq = True
            return []
        self._seen_seq = True
        if acked:
            how = "COMMAND_ACK and MISSION_CURRENT"
        elif self._seen_other_seq:
            how = "MISSION_CURRENT moved to it; no ACK seen"
        else:
            return []  # possibly stale: the vehicle may have been on seq already
        return self._finish(TransferCode.SUCCESS, f"current item {self.seq} ({how})")

    def _on_past(self, current: int, now_s: float) -> list[Action]:
        """After the ACK, MISSION_CURRENT ``current`` > ``seq``: moved on (see module)."""
        self._past.append(now_s)
        if self._seen_seq:
            how = f"COMMAND_ACK, MISSION_CURRENT {self.seq} then {current}: started and moved on"
        elif (
            len(self._past) >= self.past_frames
            and self._past[-1] - self._past[0] >= self.past_span_s - 1e-9
        ):
            how = (f"COMMAND_ACK, then {len(self._past)} MISSION_CURRENT past it over "
                   f"{self._past[-1] - self._past[0]:.1f} s: started and moved on")
        else:
            return []
        return self._finish(TransferCode.SUCCESS, f"current item {self.seq} ({how})",
                            remote_code="MAV_RESULT_ACCEPTED")

    def _on_item_reached(self, msg: MAVLinkMessage) -> list[Action]:
        """After the ACK, ``MISSION_ITEM_REACHED seq``: started and completed (see module)."""
        reached = int_field(msg, "seq", 0, _UINT16_MAX)
        if reached != self.seq or self._state is not SetCurrentState.CONFIRMING:
            return []
        return self._finish(
            TransferCode.SUCCESS,
            f"current item {self.seq} (COMMAND_ACK, then MISSION_ITEM_REACHED {self.seq}: "
            "the vehicle started it and moved on)",
            remote_code="MAV_RESULT_ACCEPTED",
        )

    def _ask_current(self) -> MAVLinkMessage:
        """COMMAND_LONG MAV_CMD_REQUEST_MESSAGE(MISSION_CURRENT): the confirmation, asked
        for without restarting the item."""
        return mavlink2.MAVLink_command_long_message(
            self.target_system,
            self.target_component,
            mavlink2.MAV_CMD_REQUEST_MESSAGE,
            0,
            float(mavlink2.MAVLINK_MSG_ID_MISSION_CURRENT),
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
        )  # fmt: skip

    def _command(self) -> MAVLinkMessage:
        if not self.use_command:
            return mavlink2.MAVLink_mission_set_current_message(
                self.target_system, self.target_component, self.seq
            )
        return mavlink2.MAVLink_command_long_message(
            self.target_system,
            self.target_component,
            mavlink2.MAV_CMD_DO_SET_MISSION_CURRENT,
            self._confirmation,
            float(self.seq),
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
        )
