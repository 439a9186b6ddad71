"""Keep the heap that exists before the daemon starts out of its garbage collections.

CPython's cyclic collector runs on whichever thread allocates: here the event loop's. A
full (generation-2) collection traverses every tracked object of the process, so its pause
grows with the heap, ~0.2 s per million objects on this class of host. The daemon's own
heap is small, but what the process held before it started is not always: an embedding
process (a test run, a notebook) may hold millions of objects, and one full collection in
the middle of a flood then stalls every vehicle's telemetry for ~0.4 s.

:func:`frozen_heap` moves every object alive when the daemon has started into the
collector's permanent generation (``gc.freeze``), so collections during the run traverse
only what the daemon allocated since; on leaving, the outermost user returns them
(``gc.unfreeze``: they join the oldest generation and are collected as usual again).
Objects that die meanwhile are still freed by reference counting; only cycles among them
wait for the unfreeze. Nested or concurrent users share one freeze: the first freezes, the
last unfreezes; a freeze made by the embedding process itself is left as it was.
"""

from __future__ import annotations

import gc
import threading
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["frozen_heap"]

_lock = threading.Lock()
_users = 0
_owner = False  # whether our first user froze (the process had not frozen anything itself)


@contextmanager
def frozen_heap() -> Iterator[None]:
    """Freeze the current heap for the body's duration (module docstring)."""
    global _users, _owner
    with _lock:
        if _users == 0:
            _owner = gc.get_freeze_count() == 0
            if _owner:  # a freeze the process made itself is left as it was
                gc.freeze()
        _users += 1
    try:
        yield
    finally:
        with _lock:
            _users -= 1
            if _users == 0 and _owner:
                gc.unfreeze()
