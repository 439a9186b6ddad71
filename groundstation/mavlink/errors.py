"""Errors of the sans-IO MAVLink protocol layer (the h11 split).

* :class:`LocalProtocolError`: *we* misused a state machine (``receive`` after it finished,
  ``start`` twice, an invalid mission item). This is a programming or input error on the
  ground-station side and is raised at once. It is a :class:`ValueError`, so a command-line
  edge can report it as bad input.
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
