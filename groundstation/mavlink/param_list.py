"""Sans-IO download of every parameter (the ``.parm`` snapshot), as MAVProxy's ``param
fetch`` does it.

Sequence::

    GCS  PARAM_REQUEST_LIST          ->
         <- PARAM_VALUE(name, value, param_count, param_index)   x param_count
    GCS  PARAM_REQUEST_READ(index)   ->   for the ones that did not come, on silence
         <- PARAM_VALUE(...)

Rules:

* The vehicle's ``param_count`` (the first PARAM_VALUE with an index below it says it) is
  the number expected; each index 0..count-1 is kept once, by its name (a later value of a
  kept index replaces it: the vehicle's newest word).
* A PARAM_VALUE with index 65535 (the answer to a read by name, or the broadcast after a
  PARAM_SET) updates a name already kept and counts for nothing else.
* Every new index resets the silence timer and the retry budget. Silence for ``timeout_s``
  resends PARAM_REQUEST_LIST while no count is known, else PARAM_REQUEST_READ by index for
  up to :data:`REREAD_BATCH` missing indexes; ``retries`` silences in a row end it with
  TIMEOUT (the values so far stay in :attr:`ParamList.values`).
* SUCCESS once every index came: :attr:`ParamList.values` holds name -> value.
"""

from __future__ import annotations

import enum

from groundstation.mavlink.codec import MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_transfer import (
    Action,
    Send,
    TransferBase,
    TransferCode,
    float_field,
    int_field,
)

__all__ = ["REREAD_BATCH", "ParamList", "ParamListState"]

REREAD_BATCH = 20
"""Missing parameters asked for by index per silence (a burst the vehicle answers at once)."""
_UINT16_MAX = 65535


class ParamListState(enum.Enum):
    IDLE = "idle"
    RECEIVING = "receiving"  # PARAM_REQUEST_LIST sent; values arrive (silence re-asks)
    DONE = "done"


class ParamList(TransferBase[ParamListState]):
    """Read every parameter (module docstring); :attr:`values` on success."""

    _IDLE = ParamListState.IDLE
    _DONE = ParamListState.DONE
    _HANDLED = frozenset({"PARAM_VALUE"})
    _WHAT = "parameter download"
    default_timeout_s = 1.0

    def __init__(self, target_system: int, target_component: int, **options: object) -> None:
        super().__init__(target_system, target_component, **options)  # type: ignore[arg-type]
        self.count: int | None = None
        self._by_index: dict[int, tuple[str, float]] = {}

    @property
    def values(self) -> dict[str, float]:
        """Name -> value of every parameter received so far."""
        return dict(self._by_index.values())

    def start(self, now_s: float) -> list[Action]:
        self._begin(now_s, ParamListState.RECEIVING)
        return [Send(self._request_list())]

    def _request_list(self) -> MAVLinkMessage:
        return mavlink2.MAVLink_param_request_list_message(self.target_system,
                                                           self.target_component)

    def _on_message(self, kind: str, msg: MAVLinkMessage, now_s: float) -> list[Action]:
        raw = getattr(msg, "param_id", None)
        if isinstance(raw, bytes):
            raw = raw.decode("ascii", "replace")
        name = raw.rstrip("\x00") if isinstance(raw, str) else ""
        value = float_field(msg, "param_value")
        index = int_field(msg, "param_index", 0, _UINT16_MAX)
        count = int_field(msg, "param_count", 0, _UINT16_MAX)
        if not name or value is None or index is None:
            self._notes.append(f"unreadable PARAM_VALUE ignored at t={now_s:.3f}s")
            return []
        if index == _UINT16_MAX:  # a read by name or a set's broadcast: update only
            for i, (kept, _) in self._by_index.items():
                if kept == name:
                    self._by_index[i] = (name, value)
            return []
        if self.count is None and count is not None and index < count:
            self.count = count
        if self.count is None or index >= self.count:
            return []
        new = index not in self._by_index
        self._by_index[index] = (name, value)
        if new:
            if len(self._by_index) == 1:
                self._answered(now_s)
            self._arm(now_s)
        if len(self._by_index) == self.count:
            return self._finish(TransferCode.SUCCESS, f"{self.count} parameters")
        return []

    def _on_silence(self, now_s: float, *, give_up: bool) -> list[Action]:
        if give_up:
            got = len(self._by_index)
            return self._finish(
                TransferCode.TIMEOUT,
                f"{got} of {self.count if self.count is not None else '?'} parameters after "
                f"{self.retries + 1} silences of {self.timeout_s:g} s",
            )
        if self.count is None:
            return [Send(self._request_list())]
        missing = [i for i in range(self.count) if i not in self._by_index][:REREAD_BATCH]
        return [
            Send(mavlink2.MAVLink_param_request_read_message(
                self.target_system, self.target_component, b"", i))
            for i in missing
        ]
