"""One root for every error floe raises on purpose, and the classes beneath it.

::

    FloeError
    ├── UsageError        a mistake in what the user asked (flags, a request to the API);
    │   └── ConfigError   ... in a setting or an input file (config, scenario, targets, URL)
    ├── DataError         a recorded file that cannot be read (journal, tlog, detection line)
    ├── PlanningError     a planning problem that is malformed or cannot be solved
    ├── LinkError         a link that cannot be opened or has failed (expected in the field)
    └── ProtocolError
        ├── RemoteProtocolError  the peer broke the protocol (expected: the peer is not ours)
        └── LocalProtocolError   floe misused a protocol machine (a bug)

The classes that name user mistakes also derive from :class:`ValueError`, so a caller that
validates input can catch either. Supervision uses the tree: a task restarts only on the
errors it can expect from the outside world (:data:`EXPECTED_TASK_ERRORS`); anything else is
a bug and stops the daemon cleanly.
"""

from __future__ import annotations

__all__ = [
    "EXPECTED_TASK_ERRORS",
    "ConfigError",
    "DataError",
    "FloeError",
    "LinkError",
    "LocalProtocolError",
    "PlanningError",
    "ProtocolError",
    "RemoteProtocolError",
    "UsageError",
]


class FloeError(Exception):
    """The root of every error floe raises on purpose."""


class UsageError(FloeError, ValueError):
    """A mistake in what the user asked; the message names the option or field."""


class ConfigError(UsageError):
    """A bad setting or input file; the message names the field."""


class DataError(FloeError, ValueError):
    """A recorded file (journal, tlog, detection line) that cannot be read."""


class PlanningError(FloeError, ValueError):
    """A planning problem that is malformed or cannot be solved."""


class LinkError(FloeError, RuntimeError):
    """A link that cannot be opened, or that failed."""


class ProtocolError(FloeError):
    """A protocol exchange went wrong."""


class RemoteProtocolError(ProtocolError):
    """The peer broke the protocol or refused (never a reason to stop: the peer is not
    ours); ``result`` is the transfer result that says how, when there is one. The sans-IO
    machines never raise it: they finish with a result that says so, as data
    (``TransferResult.raise_for_status`` turns a failed one into this at the edge)."""

    def __init__(self, message: str, result: object = None) -> None:
        super().__init__(message)
        self.result = result


class LocalProtocolError(ProtocolError, ValueError):
    """floe misused a protocol machine (``receive`` before ``start``, an invalid mission
    item, target or parameter): a bug, or bad input handed in; raised at once. Input after a
    machine's end is not misuse: it returns no actions."""


EXPECTED_TASK_ERRORS: tuple[type[BaseException], ...] = (
    LinkError,
    RemoteProtocolError,
    OSError,
    TimeoutError,
)
"""What the outside world can make a task fail with (sockets, serial ports, peers); a
supervised task restarts on these, within its limit, and on nothing else."""
