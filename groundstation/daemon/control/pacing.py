"""Keeping the control surface from stalling the daemon's event loop.

The daemon's vehicles, clock and journal share one asyncio loop with the control server, so
a burst of clients must never hold the loop for long. Two rules, measured in
``benchmarks/control_load.py`` (docs/control.md, Load):

* **The state document is built once for every reader.** :class:`StateDocument` builds the
  daemon's state (``DaemonControl.state()``) and serialises it to JSON at most once per
  ``max_age_s`` (0.1 s), whatever the number of readers: ``GET /api/state`` and the other
  reads, every live page's first state and the periodic push all share that one text. A
  write through the API makes it stale at once (the next read rebuilds it), so a client
  reads its own write.
* **A loop turn does a bounded amount of work.** :class:`TurnBudget` lets at most
  ``per_turn`` (8) units of work run in one turn of the loop: every request (answered or
  refused) and every message sent to a live page takes one unit first; the rest wait, in
  arrival order, for the following turns. So 200 clients arriving at once are handled 8 per
  turn, with the daemon's own tasks running between.
"""

from __future__ import annotations

import asyncio
import collections
import json
import time
from collections.abc import Callable
from typing import Any

from groundstation.daemon.control.bodies import jsonable
from groundstation.daemon.control.contract import DaemonControl

__all__ = ["REQUESTS_PER_TURN", "STATE_MAX_AGE_S", "StateDocument", "TurnBudget"]

#: Units of work (requests, page messages) one loop turn may run.
REQUESTS_PER_TURN = 8
#: Oldest state document a read may be answered with (wall seconds).
STATE_MAX_AGE_S = 0.1


class TurnBudget:
    """At most ``per_turn`` takers resume in one turn of the event loop.

    Rule: :meth:`take` queues the caller (first come, first served); one release callback,
    scheduled with ``call_soon``, wakes at most ``per_turn`` waiters and, while others wait,
    schedules itself again. A waiter woken in turn T resumes in turn T+1, and the release
    callback runs again in T+1 too, so its waiters resume in T+2: no turn resumes more than
    ``per_turn`` takers. A waiter that was cancelled meanwhile (its client went away) costs
    nothing. Every taker waits at least one turn, even when the loop is idle."""

    def __init__(self, per_turn: int = REQUESTS_PER_TURN) -> None:
        if per_turn < 1:
            raise ValueError(f"per_turn must be >= 1, got {per_turn}")
        self.per_turn = per_turn
        self._waiting: collections.deque[asyncio.Future[None]] = collections.deque()
        self._scheduled = False
        self.taken = 0
        self.max_waiting = 0
        """The longest queue seen (how large a burst was)."""

    @property
    def waiting(self) -> int:
        return len(self._waiting)

    async def take(self) -> None:
        """Wait for this caller's turn (at least the next turn of the loop)."""
        loop = asyncio.get_running_loop()
        future: asyncio.Future[None] = loop.create_future()
        self._waiting.append(future)
        self.max_waiting = max(self.max_waiting, len(self._waiting))
        if not self._scheduled:
            self._scheduled = True
            loop.call_soon(self._release)
        await future
        self.taken += 1

    def _release(self) -> None:
        released = 0
        while self._waiting and released < self.per_turn:
            future = self._waiting.popleft()
            if not future.done():
                future.set_result(None)
                released += 1
        if self._waiting:
            asyncio.get_running_loop().call_soon(self._release)
        else:
            self._scheduled = False


class StateDocument:
    """The daemon's state as a JSON-safe dict and its JSON text, shared by every reader.

    Rebuilt when older than ``max_age_s`` (``clock``: monotonic seconds) or made stale by
    :meth:`invalidate` (a write); :attr:`builds` counts the builds. A ``state()`` that does
    not return a dict is an empty document."""

    def __init__(self, control: DaemonControl, max_age_s: float = STATE_MAX_AGE_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.control = control
        self.max_age_s = max_age_s
        self._clock = clock
        self._built_s: float | None = None
        self._doc: dict[str, Any] = {}
        self._text = "{}"
        self.builds = 0

    def invalidate(self) -> None:
        """The next read rebuilds the document (a write has just changed the state)."""
        self._built_s = None

    def _current(self) -> None:
        now_s = self._clock()
        if self._built_s is not None and now_s - self._built_s <= self.max_age_s:
            return
        state = self.control.state()  # raises: the caller's error path (500, or a push skipped)
        doc = jsonable(state) if isinstance(state, dict) else {}
        self._doc, self._text = doc, json.dumps(doc)
        self._built_s = now_s
        self.builds += 1

    def doc(self) -> dict[str, Any]:
        """The document (shared: do not change it)."""
        self._current()
        return self._doc

    def text(self) -> str:
        """The document as JSON text."""
        self._current()
        return self._text
