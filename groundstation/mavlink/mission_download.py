"""Sans-IO mission download (vehicle -> ground station), ground-station driven.

Sequence::

    GCS  MISSION_REQUEST_LIST        ->
         <- MISSION_COUNT(n)
    GCS  MISSION_REQUEST_INT(0)      ->
         <- MISSION_ITEM_INT(0)
         ...
    GCS  MISSION_ACK(ACCEPTED)       ->   after the last item (our side ends the transfer)

Silence for ``timeout_s`` resends the pending request (REQUEST_LIST or REQUEST_INT(k)), at
most ``retries`` times in a row; each received item resets the budget. Items with another
seq than the one asked for (late duplicates) are ignored; a second MISSION_COUNT with the
same n (an answer to a resent REQUEST_LIST) is ignored, with another n it is a
PROTOCOL_ERROR (the mission changed under us). ``MISSION_ITEM`` (float) answers are accepted
too. An error MISSION_ACK from the vehicle ends the download with its code. A count of 0
ends at once (we still send the final ACK).

``window`` > 1 (a slow link: docs/protocol.md, "Over a telemetry radio") keeps that many
item requests outstanding instead of one: after MISSION_COUNT, REQUEST_INT(0..window-1)
go together, each item received asks for the next one not yet asked for, and silence
resends every outstanding request. ArduPlane (and the built-in simulator) answer every
MISSION_REQUEST_INT on its own, so a 3-item mission reads back in two round trips instead
of four; what is read back, and checked, is the same whole mission. With ``expect_count``
(the count just uploaded) the first requests go with MISSION_REQUEST_LIST itself: one
round trip. Items that arrive before the count are kept; a count below what was asked
drops the excess (the vehicle answers their requests with an error ACK, which ends the
download: the verification fails, as it must for a mission of another length).
"""

from __future__ import annotations

import enum

from domain.errors import LocalProtocolError
from groundstation.mavlink.codec import MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_items import MissionItem
from groundstation.mavlink.mission_transfer import (
    DEFAULT_RETRIES,
    Action,
    Send,
    TransferBase,
    TransferCode,
    int_field,
)

__all__ = ["DownloadState", "MissionDownload"]

_UINT16_MAX = 65535
_UINT8_MAX = 255


_ITEM_ERRORS = frozenset({mavlink2.MAV_MISSION_ERROR, mavlink2.MAV_MISSION_INVALID_SEQUENCE})
"""MISSION_ACK results that answer an item (its sequence, a duplicate), never a list
request."""


class DownloadState(enum.Enum):
    """Where a download is."""

    IDLE = "idle"  # not started
    REQUESTING_LIST = "requesting_list"  # MISSION_REQUEST_LIST sent, no MISSION_COUNT yet
    REQUESTING_ITEMS = "requesting_items"  # MISSION_REQUEST_INT(k) sent for the next item
    DONE = "done"


class MissionDownload(TransferBase[DownloadState]):
    """Read the vehicle's mission; ``result.items`` holds it on success."""

    _IDLE = DownloadState.IDLE
    _DONE = DownloadState.DONE
    _HANDLED = frozenset({"MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_ACK"})
    _WHAT = "download"
    _count: int | None = None  # the vehicle's item count, once it has said it

    @property
    def count(self) -> int | None:
        """The vehicle's item count once known."""
        return self._count

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
        window: int = 1,
        expect_count: int | None = None,
    ) -> None:
        super().__init__(target_system, target_component, mission_type=mission_type,
                         timeout_s=timeout_s, retries=retries, own_system=own_system,
                         own_component=own_component)
        if not 1 <= window <= _UINT16_MAX:
            raise LocalProtocolError(f"window must be 1..{_UINT16_MAX}, got {window}")
        if expect_count is not None and not 0 <= expect_count <= _UINT16_MAX:
            raise LocalProtocolError(f"expect_count must be 0..{_UINT16_MAX}")
        self.window = window
        self.expect_count = expect_count
        self._got: dict[int, MissionItem] = {}
        self._asked = 0  # items 0..asked-1 have been requested

    def start(self, now_s: float) -> list[Action]:
        """Begin: send MISSION_REQUEST_LIST (and, pipelined with an expected count, the
        first ``window`` item requests with it)."""
        self._begin(now_s, DownloadState.REQUESTING_LIST)
        out: list[Action] = [Send(self._request_list())]
        if self.window > 1 and self.expect_count:
            self._asked = min(self.window, self.expect_count)
            out += [Send(self._request_item(seq)) for seq in range(self._asked)]
        return out

    def _outstanding(self) -> list[int]:
        """Items asked for and not received, in order."""
        return [seq for seq in range(self._asked) if seq not in self._got]

    def _ask_more(self) -> list[Action]:
        """Fill the window with requests for the next items not yet asked for."""
        assert self._count is not None
        out: list[Action] = []
        while self._asked < self._count and len(self._outstanding()) < self.window:
            out.append(Send(self._request_item(self._asked)))
            self._asked += 1
        return out

    # -- internals ------------------------------------------------------------------------

    def _on_silence(self, now_s: float, *, give_up: bool) -> list[Action]:
        """Resend the pending request, or give up (TIMEOUT, telling the vehicle)."""
        if give_up:
            if self._state is DownloadState.REQUESTING_LIST:
                what = f"no MISSION_COUNT after {self.retries + 1} MISSION_REQUEST_LIST"
            else:
                missing = self._outstanding()
                what = f"no MISSION_ITEM_INT {missing[0] if missing else 0} of {self._count}"
            return self._finish(
                TransferCode.TIMEOUT,
                f"{what} ({self.timeout_s:g} s each)",
                send=self._mission_ack(mavlink2.MAV_MISSION_OPERATION_CANCELLED),
            )
        out: list[Action] = []
        if self._state is DownloadState.REQUESTING_LIST:
            out.append(Send(self._request_list()))
        return out + [Send(self._request_item(seq)) for seq in self._outstanding()]

    def _on_message(self, kind: str, msg: MAVLinkMessage, now_s: float) -> list[Action]:
        mismatch = self._mission_type_mismatch(kind, msg)
        if mismatch is not None:
            return mismatch
        if kind == "MISSION_COUNT":
            return self._on_count(msg, now_s)
        if kind == "MISSION_ACK":
            ack_type = int_field(msg, "type", 0, _UINT8_MAX)
            if ack_type is None or ack_type == mavlink2.MAV_MISSION_ACCEPTED:
                return []
            if self._state is DownloadState.REQUESTING_LIST and ack_type in _ITEM_ERRORS:
                # an item error before the count answers an earlier exchange (the upload
                # this download verifies: the vehicle's answer to a duplicate item), not the
                # MISSION_REQUEST_LIST: the count it waits for may come in the same instant
                self._notes.append(f"stale MISSION_ACK {ack_type} ignored at t={now_s:.3f}s")
                return []
            return self._finish_for_ack(ack_type, "to the download")
        return self._on_item(msg, now_s)

    def _cancel_actions(self, now_s: float) -> list[Action]:
        """Abandon the download, telling the vehicle (MISSION_ACK OPERATION_CANCELLED)."""
        return self._finish(
            TransferCode.CANCELLED,
            "download cancelled by the ground station",
            send=self._mission_ack(mavlink2.MAV_MISSION_OPERATION_CANCELLED),
        )

    def _request_list(self) -> MAVLinkMessage:
        return mavlink2.MAVLink_mission_request_list_message(
            self.target_system, self.target_component, self.mission_type
        )

    def _request_item(self, seq: int) -> MAVLinkMessage:
        return mavlink2.MAVLink_mission_request_int_message(
            self.target_system, self.target_component, seq, self.mission_type
        )

    def _on_count(self, msg: MAVLinkMessage, now_s: float) -> list[Action]:
        count = int_field(msg, "count", 0, _UINT16_MAX)
        if count is None:
            self._notes.append(f"unreadable MISSION_COUNT ignored at t={now_s:.3f}s")
            return []
        if self._count is not None:
            if count == self._count:
                self._notes.append(f"duplicate MISSION_COUNT at t={now_s:.3f}s")
                return []
            return self._finish(
                TransferCode.PROTOCOL_ERROR,
                f"MISSION_COUNT changed from {self._count} to {count} during the download",
                send=self._mission_ack(mavlink2.MAV_MISSION_OPERATION_CANCELLED),
            )
        self._count = count
        self._answered(now_s)
        self._asked = min(self._asked, count)  # asked ahead for more than it holds
        for seq in [seq for seq in self._got if seq >= count]:
            del self._got[seq]
        if count and len(self._got) == count:
            return self._complete()
        if count == 0:
            return self._finish(
                TransferCode.SUCCESS,
                "vehicle holds no mission items",
                items=(),
                send=self._mission_ack(mavlink2.MAV_MISSION_ACCEPTED),
            )
        self._state = DownloadState.REQUESTING_ITEMS
        self._arm(now_s)
        return self._ask_more()

    def _on_item(self, msg: MAVLinkMessage, now_s: float) -> list[Action]:
        if self._count is None and not self._asked:
            return []  # nothing asked for yet
        seq = int_field(msg, "seq")
        if seq is None or seq >= self._asked or seq in self._got:
            return []  # late duplicate or stray; silence resends the pending requests
        item = MissionItem.from_message(msg)
        if self.window == 1 or not self._got:  # pipelined: only the first is a round trip
            self._answered(now_s)
        if item is None:
            return self._finish(
                TransferCode.PROTOCOL_ERROR,
                f"item {seq} is unreadable",
                send=self._mission_ack(mavlink2.MAV_MISSION_OPERATION_CANCELLED),
            )
        self._got[seq] = item
        if self._count is None:  # asked ahead: the count is still to come
            self._arm(now_s)
            return []
        if len(self._got) == self._count:
            return self._complete()
        self._arm(now_s)
        return self._ask_more()

    def _complete(self) -> list[Action]:
        assert self._count is not None
        return self._finish(
            TransferCode.SUCCESS,
            f"{self._count} items downloaded",
            items=tuple(self._got[i] for i in range(self._count)),
            send=self._mission_ack(mavlink2.MAV_MISSION_ACCEPTED),
        )
