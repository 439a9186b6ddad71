"""Sans-IO mission upload (ground station -> vehicle), vehicle-driven as MAVLink specifies.

Sequence::

    GCS  MISSION_COUNT(n)            ->
         <- MISSION_REQUEST[_INT](0)      (ArduPlane uses MISSION_REQUEST, not _INT)
    GCS  MISSION_ITEM_INT(0)         ->
         ...                              (one item per request, in the vehicle's order)
         <- MISSION_ACK(ACCEPTED)         upload complete

Rules (MAVSDK's MissionTransferClient semantics, adapted to ArduPlane):

* Before the first request, silence for ``timeout_s`` resends MISSION_COUNT, at most
  ``retries`` times. After it, the vehicle drives: silence only consumes retries (ArduPlane
  re-requests by itself about every second); nothing is resent, so no resend storm.
* Every request is answered by exactly one MISSION_ITEM_INT, duplicates included (a
  duplicated request means our answer or its request was lost, or the link duplicated it).
  Progress (a request) resets the retry budget.
* A request for a seq outside 0..n-1 ends the upload (PROTOCOL_ERROR) and tells the vehicle
  with MISSION_ACK OPERATION_CANCELLED.
* MISSION_ACK ACCEPTED completes the upload only once every item was requested; earlier it
  is a PROTOCOL_ERROR (a stale ACK, or a vehicle that dropped items). An error ACK ends it
  with the matching code, except INVALID_SEQUENCE: ArduPlane sends that when an item
  arrives out of order and then asks again, so it is only noted.
* A request or ACK for another mission type (addressed to us) ends it with
  MISSION_TYPE_MISMATCH, as MAVSDK does.
* ``cancel`` sends MISSION_ACK OPERATION_CANCELLED and ends with CANCELLED.
* ``resend_items`` (a constrained link; off by default, as MAVSDK): silence after the
  vehicle asked for item k resends item k, once per timeout, from the retry budget,
  instead of waiting for ArduPlane's own re-request (every ``1 s + stream slowdown``,
  ``MissionItemProtocol::update``; on a SiK link that is ~1.2 s a loss, the time of
  four round trips). Either item k was lost, and the vehicle takes the copy and asks for
  k + 1; or its request for k + 1 was, and it answers the copy with MISSION_ACK
  INVALID_SEQUENCE (``handle_mission_item``: ``seq != request_i``; not fatal). That
  answer, while k is still the newest item asked for, says the vehicle holds k and waits
  for k + 1 (it advances only on the item it asked for, and the radio keeps order: a
  request for k + 1 sent before it would have come first), so item k + 1 is sent at once,
  as if asked for. The item's own request, when it comes late, is answered as a
  duplicate (INVALID_SEQUENCE again, noted).

  Once every item was asked for, the last one is never resent blindly: ArduPlane, done
  with the upload, takes no stray item (some versions raise an internal error on one).
  Silence there asks instead, with MISSION_REQUEST_LIST, which ArduPlane answers with
  MISSION_ACK DENIED while it still receives (``handle_mission_request_list``: the last
  item, or its re-request, was lost: the item is sent again) and with MISSION_COUNT once
  it is done (the final ACK was lost: the upload ends as TIMEOUT with ``maybe_stored``,
  for the verifying download to read). Either costs one timeout, not ``ack_retries`` of
  them; the probe's answer is no round-trip sample (Karn).
* ``ack_retries`` (default: ``retries``) bounds the silent timeouts once every item was
  requested: ArduPlane sends its final ACK once, so when it is lost nothing more comes. A
  slow link passes 1: after two timeouts (longer than ArduPlane's 1 s re-request of a lost
  last item) the upload ends as TIMEOUT with ``maybe_stored``, and the verifying download
  reads what the vehicle holds, instead of waiting ``retries`` timeouts for nothing.

* ``window`` > 1 (a constrained link, as the download's window): the items go *ahead of
  the vehicle's requests*, ``window`` of them past the newest item it asked for. ArduPlane
  takes any item whose seq is the one it expects next, asked for or not
  (``MissionItemProtocol::handle_mission_item`` checks only ``seq == request_i``; its
  requests for items already on their way are then just read), so an n-item upload over a
  TDM radio costs two round trips instead of n + 1: item 0 goes with MISSION_COUNT (one
  small radio packet, lost or carried together), the rest once the vehicle's first request
  shows the upload open. Items are never sent ahead of a count the vehicle has not
  acknowledged: an item with no upload open is a stray (ArduPlane answers MISSION_ACK
  ERROR; some versions raised an internal error), and at most item 0 can be one. Losses:
  an item that arrives out of order (an earlier one was lost) is answered INVALID_SEQUENCE
  while the vehicle still waits for the newest item it asked for, so that answer resends
  the items from there (once per newest request: the rest of the batch answers alike); a
  request seen twice (ArduPlane's own re-request) does the same. Silence before any request
  sends MISSION_COUNT and item 0 again; silence once every item went at least once
  probes with MISSION_REQUEST_LIST as above (DENIED: the items from the newest request go
  again; MISSION_COUNT: done, verify by download), so no item is ever sent to a vehicle that
  may have finished; silence before that sends the items from the newest request again.
  MISSION_ACK ERROR (an item with no upload in progress: the count was lost, or the items
  of a resend came after the end) is only noted; the silence rules settle it. ACCEPTED
  completes once every item was sent. One round-trip sample per upload: the first request.

Remember (design.md): ArduPlane truncates its stored mission as soon as MISSION_COUNT
arrives, so a failed upload leaves a partial mission; retry until verified by download.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence

from domain.errors import LocalProtocolError
from groundstation.mavlink.codec import MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_items import MissionItem, validate_items
from groundstation.mavlink.mission_transfer import (
    DEFAULT_RETRIES,
    DEFAULT_TIMEOUT_S,
    Action,
    Send,
    TransferBase,
    TransferCode,
    int_field,
    mission_result_name,
)

__all__ = ["MissionUpload", "UploadState"]

_UINT16_MAX = 65535
_UINT8_MAX = 255


class UploadState(enum.Enum):
    """Where an upload is."""

    IDLE = "idle"  # not started
    SENDING_COUNT = "sending_count"  # MISSION_COUNT sent, no request yet (silence resends it)
    SENDING_ITEMS = "sending_items"  # the vehicle is requesting items
    WAITING_ACK = "waiting_ack"  # every item was requested: only the final ACK is missing
    DONE = "done"


class MissionUpload(TransferBase[UploadState]):
    """Upload ``items`` (already numbered 0..n-1; item 0 is home for ArduPilot)."""

    _IDLE = UploadState.IDLE
    _DONE = UploadState.DONE
    _HANDLED = frozenset({"MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK",
                          "MISSION_COUNT"})
    _WHAT = "upload"

    def __init__(
        self,
        target_system: int,
        target_component: int,
        items: Sequence[MissionItem],
        *,
        mission_type: int = mavlink2.MAV_MISSION_TYPE_MISSION,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        retries: int = DEFAULT_RETRIES,
        own_system: int | None = None,
        own_component: int | None = None,
        ack_retries: int | None = None,
        resend_items: bool = False,
        window: int = 1,
    ) -> None:
        super().__init__(
            target_system,
            target_component,
            mission_type=mission_type,
            timeout_s=timeout_s,
            retries=retries,
            own_system=own_system,
            own_component=own_component,
        )
        validate_items(items, mission_type)
        if not 1 <= window <= _UINT16_MAX:
            raise LocalProtocolError(f"window must be 1..{_UINT16_MAX}, got {window}")
        self.window = window
        self._pushed = 0  # pipelined: items 0.._pushed-1 went at least once
        self._tail_for: int | None = None  # pipelined: the newest request a resend answered
        self.items: tuple[MissionItem, ...] = tuple(items)
        self._requested: set[int] = set()
        self.items_sent = 0  # MISSION_ITEM_INT answers sent, duplicates included
        self.ack_retries = retries if ack_retries is None else min(ack_retries, retries)
        self.resend_items = resend_items
        self._newest: int | None = None  # the newest item the vehicle asked for
        self._resent_seq: int | None = None  # _newest, resent on silence
        self._probes_out = 0  # MISSION_REQUEST_LISTs asking whether the upload is over
        self._probing = False  # one went after the last item we sent
        self.items_pushed = 0
        """Items sent unasked after an INVALID_SEQUENCE answered a resent one (module
        docstring, ``resend_items``)."""

    @property
    def requested_seqs(self) -> frozenset[int]:
        """The item numbers the vehicle has asked for so far."""
        return frozenset(self._requested)

    @property
    def pipelined(self) -> bool:
        """Items go ahead of the requests (``window`` > 1: module docstring)."""
        return self.window > 1

    def start(self, now_s: float) -> list[Action]:
        """Begin: send MISSION_COUNT (pipelined: and item 0 with it)."""
        self._begin(now_s, UploadState.SENDING_COUNT)
        return [Send(self._count_message()), *self._send_from(0, again=False, most=1)]

    def _send_from(self, first: int, *, again: bool, most: int | None = None) -> list[Action]:
        """Pipelined: items ``first`` .. ``first + window - 1`` (at most ``most`` of them;
        ``again`` False: only those not sent yet). Nothing when not pipelined."""
        if not self.pipelined:
            return []
        span = self.window if most is None else min(most, self.window)
        end = min(first + span, len(self.items))
        start = first if again else max(first, self._pushed)
        self._pushed = max(self._pushed, end)
        self.items_sent += max(0, end - start)
        return [Send(self._item_message(seq)) for seq in range(start, end)]

    @property
    def _expected(self) -> int:
        """The item the vehicle waits for, as far as we know: its newest request (0 before
        any)."""
        return 0 if self._newest is None else self._newest

    def _resend_tail(self, now_s: float) -> list[Action]:
        """Pipelined: the items from :attr:`_expected` go again; the timer restarts without
        refilling the retry budget."""
        first = self._tail_for = self._expected
        self._probing = False
        self._arm(now_s, reset_retries=False)
        return self._send_from(first, again=True)

    # -- internals ------------------------------------------------------------------------

    def _on_silence(self, now_s: float, *, give_up: bool) -> list[Action]:
        """Resend MISSION_COUNT before the first request; after it just wait (or give up)."""
        if give_up:
            return self._finish(
                TransferCode.TIMEOUT,
                self._silence_message(),
                maybe_stored=self._state is UploadState.WAITING_ACK,
            )
        if self._state is UploadState.SENDING_COUNT:
            return [Send(self._count_message()), *self._send_from(0, again=True, most=1)]
        if self.pipelined and self._pushed < len(self.items):  # it cannot have finished
            return self._resend_tail(now_s)
        if not (self.resend_items or self.pipelined) or self._newest is None:
            return []
        if self._state is UploadState.WAITING_ACK or self.pipelined:
            self._probing = True
            self._probes_out += 1
            return [Send(mavlink2.MAVLink_mission_request_list_message(
                self.target_system, self.target_component, self.mission_type))]
        self._resent_seq = self._newest
        self.items_sent += 1
        return [Send(self._item_message(self._newest))]

    def _item_message(self, seq: int) -> MAVLinkMessage:
        return self.items[seq].to_message(self.target_system, self.target_component)

    def _on_message(self, kind: str, msg: MAVLinkMessage, now_s: float) -> list[Action]:
        mismatch = self._mission_type_mismatch(kind, msg)
        if mismatch is not None:
            return mismatch
        if kind == "MISSION_ACK":
            return self._on_ack(msg, now_s)
        if kind == "MISSION_COUNT":
            return self._on_count(msg, now_s)
        return self._on_request(msg, kind, now_s)

    def _on_count(self, msg: MAVLinkMessage, now_s: float) -> list[Action]:
        """The answer to a probe (module docstring): the vehicle is done with the upload
        and its final ACK was lost."""
        if not self._probes_out:
            self._notes.append(f"MISSION_COUNT ignored at t={now_s:.3f}s (no probe)")
            return []
        count = int_field(msg, "count", 0, _UINT16_MAX)
        return self._finish(
            TransferCode.TIMEOUT,
            f"the final MISSION_ACK was lost: the vehicle holds {count} items "
            "(verify by download)",
            maybe_stored=True,
        )

    def _cancel_actions(self, now_s: float) -> list[Action]:
        """Abandon the upload, telling the vehicle (MISSION_ACK OPERATION_CANCELLED)."""
        return self._finish(
            TransferCode.CANCELLED,
            "upload cancelled by the ground station",
            send=self._mission_ack(mavlink2.MAV_MISSION_OPERATION_CANCELLED),
        )

    def _count_message(self) -> MAVLinkMessage:
        return mavlink2.MAVLink_mission_count_message(
            self.target_system, self.target_component, len(self.items), self.mission_type
        )

    def _on_request(self, msg: MAVLinkMessage, kind: str, now_s: float) -> list[Action]:
        if int_field(msg, "seq") is None:
            self._notes.append(f"unreadable {kind} ignored at t={now_s:.3f}s")
            return []
        seq = int_field(msg, "seq", 0, len(self.items) - 1)
        if seq is None:
            return self._finish(
                TransferCode.PROTOCOL_ERROR,
                f"vehicle requested item {getattr(msg, 'seq', None)} of a "
                f"{len(self.items)}-item mission",
                send=self._mission_ack(mavlink2.MAV_MISSION_OPERATION_CANCELLED),
            )
        if self.pipelined:
            return self._on_request_pipelined(seq, kind, now_s)
        if seq in self._requested:
            self._notes.append(f"duplicate {kind} for item {seq} at t={now_s:.3f}s")
        else:  # a new request answers our count or our last item
            self._answered(now_s)
        return self._send_item(seq, now_s)

    def _on_request_pipelined(self, seq: int, kind: str, now_s: float) -> list[Action]:
        """Item ``seq`` asked for while items go ahead (module docstring, ``window``)."""
        if not self._requested:
            self._answered(now_s)  # the one round-trip sample: count and batch -> request
        again = seq in self._requested
        if again:
            self._notes.append(f"duplicate {kind} for item {seq} at t={now_s:.3f}s")
        self._requested.add(seq)
        self._probing = False
        if self._newest is None or seq > self._newest:
            self._newest = seq
        self._state = (UploadState.WAITING_ACK if self._newest == len(self.items) - 1
                       else UploadState.SENDING_ITEMS)
        if again and seq == self._newest:  # the vehicle still waits for it: it was lost
            out = self._resend_tail(now_s)
        else:
            self._arm(now_s)
            out = self._send_from(seq, again=seq >= self._pushed)
        if self._state is UploadState.WAITING_ACK:
            self._retries_left = self.ack_retries
        return out

    def _send_item(self, seq: int, now_s: float) -> list[Action]:
        """Item ``seq``, asked for (or known to be awaited): the state follows."""
        self._requested.add(seq)
        self._probing = False
        if self._newest is None or seq > self._newest:
            self._newest, self._resent_seq = seq, None
        self._state = (
            UploadState.WAITING_ACK
            if len(self._requested) == len(self.items)
            else UploadState.SENDING_ITEMS
        )
        self._arm(now_s)
        if self._state is UploadState.WAITING_ACK:
            self._retries_left = self.ack_retries
        self.items_sent += 1
        return [Send(self._item_message(seq))]

    def _on_ack(self, msg: MAVLinkMessage, now_s: float) -> list[Action]:
        ack_type = int_field(msg, "type", 0, _UINT8_MAX)
        if ack_type is None:
            self._notes.append(f"unreadable MISSION_ACK ignored at t={now_s:.3f}s")
            return []
        if ack_type == mavlink2.MAV_MISSION_ACCEPTED:
            missing = len(self.items) - (self._pushed if self.pipelined
                                         else len(self._requested))
            if missing:
                return self._finish(
                    TransferCode.PROTOCOL_ERROR,
                    f"MISSION_ACK ACCEPTED before {missing} of {len(self.items)} items were "
                    "requested: the vehicle may hold a partial mission",
                    remote_code=mission_result_name(ack_type),
                )
            if not self.pipelined:
                self._answered(now_s)
            return self._finish(
                TransferCode.SUCCESS,
                f"{len(self.items)} items accepted",
                remote_code=mission_result_name(ack_type),
            )
        if ack_type == mavlink2.MAV_MISSION_DENIED and self._probes_out:
            # still receiving: the last item (or its re-request) was lost, unless an item
            # went since the probe (the vehicle asked again meanwhile)
            self._probes_out -= 1
            if self._probing and self._newest is not None:
                self._notes.append(f"probe answered DENIED at t={now_s:.3f}s: item resent")
                if self.pipelined:
                    return self._resend_tail(now_s)
                return self._send_item(self._newest, now_s)
            self._notes.append(f"probe answered DENIED at t={now_s:.3f}s (item sent since)")
            return []
        if self.pipelined and ack_type == mavlink2.MAV_MISSION_ERROR:
            # an item with no upload in progress (module docstring, ``window``)
            self._notes.append(f"MAV_MISSION_ERROR at t={now_s:.3f}s (an item after the "
                               "upload's end, or before its count): noted")
            return []
        if ack_type == mavlink2.MAV_MISSION_INVALID_SEQUENCE:
            # ArduPlane: an item arrived out of order; it will ask again. Not fatal.
            self._notes.append(f"MAV_MISSION_INVALID_SEQUENCE at t={now_s:.3f}s (not fatal)")
            if self.pipelined:  # once per newest request: the rest of the batch alike
                return [] if self._tail_for == self._expected else self._resend_tail(now_s)
            resent = self._resent_seq
            if resent is not None and resent == self._newest and resent + 1 < len(self.items):
                # it holds the item we resent and waits for the next (module docstring)
                self._resent_seq = None
                self._answered(now_s)
                self.items_pushed += 1
                return self._send_item(resent + 1, now_s)
            self._arm(now_s, reset_retries=False)
            return []
        return self._finish_for_ack(ack_type, "to the upload")

    def _silence_message(self) -> str:
        tries = self.retries + 1
        if self._state is UploadState.SENDING_COUNT:
            return f"no MISSION_REQUEST after {tries} MISSION_COUNT ({self.timeout_s:g} s each)"
        if self._state is UploadState.WAITING_ACK:
            return (
                "no MISSION_ACK after every item was sent; the vehicle may have stored the "
                "mission (verify by download)"
            )
        return (
            f"vehicle silent for {tries} x {self.timeout_s:g} s after requesting "
            f"{len(self._requested)} of {len(self.items)} items"
        )
