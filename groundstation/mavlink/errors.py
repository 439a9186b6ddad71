"""Errors of the sans-IO MAVLink protocol layer (the h11 split).

* :class:`LocalProtocolError`: *we* misused a state machine (``receive`` before ``start``,
  ``start`` twice, an invalid mission item, target, timeout, command or parameter). This is
  a programming or input error on the ground-station side and is raised at once. It is a
  :class:`ValueError`, so a command-line edge can report it as bad input. Input after a
  machine's end is *not* misuse: it returns no actions (h11's "a state, not an exception"),
  so a message that was already queued when a transfer ended is harmless.
* :class:`RemoteProtocolError`: the *vehicle* misbehaved or refused (timeout, error ACK,
  out-of-range request...). The state machines never raise it: they finish with a
  ``TransferResult`` that says so, as data. The asyncio session that drives them turns a
  failed result into this exception at the edge, if it wants an exception.
"""

from __future__ import annotations

from typing import Any

from domain import errors

__all__ = ["LocalProtocolError", "RemoteProtocolError"]


class LocalProtocolError(errors.LocalProtocolError):
    """The local side broke the protocol or handed in invalid data."""


class RemoteProtocolError(errors.RemoteProtocolError):
    """The peer broke the protocol or refused; carries the transfer result that says how."""

    def __init__(self, message: str, result: Any = None) -> None:
        super().__init__(message)
        self.result = result
