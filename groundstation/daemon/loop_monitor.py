"""How long the daemon's event loop was kept from its tasks: the loop-lag monitor.

Every vehicle link, the clock's ticks, the journal and the control API share one asyncio
loop, so anything that holds it (a burst of HTTP clients, a long garbage collection, a
synchronous call) delays them all. The monitor measures it from inside: a task sleeps
``interval_s`` (20 ms) again and again; how much later than asked it wakes is the loop's
stall at that moment (wall milliseconds, ``time.perf_counter``).

``metrics.json`` carries the worst stall of the run (``loop_stall_max_ms``) and how many
stalls exceeded ``threshold_ms`` (100 ms: ``loop_stalls_over_100ms``). The figure includes
what the operating system did to the process (another program holding the cores), so it is
a fact about the run, not a decision input: the journal does not carry it and replay does
not compare it.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable

__all__ = ["LoopMonitor"]


class LoopMonitor:
    """The worst lateness of a task sleeping ``interval_s`` in the loop (module docstring)."""

    def __init__(self, interval_s: float = 0.02, threshold_ms: float = 100.0,
                 clock: Callable[[], float] = time.perf_counter) -> None:
        self.interval_s = interval_s
        self.threshold_ms = threshold_ms
        self._clock = clock
        self.max_ms = 0.0
        self.over_threshold = 0
        self.samples = 0

    def note(self, late_ms: float) -> None:
        """One wake-up ``late_ms`` later than asked."""
        self.samples += 1
        self.max_ms = max(self.max_ms, late_ms)
        if late_ms > self.threshold_ms:
            self.over_threshold += 1

    async def run(self) -> None:
        """Sleep and measure until cancelled."""
        while True:
            start_s = self._clock()
            await asyncio.sleep(self.interval_s)
            self.note(max(0.0, (self._clock() - start_s - self.interval_s) * 1000.0))

    def to_dict(self) -> dict[str, float | int]:
        """``loop_stall_max_ms`` and ``loop_stalls_over_<threshold>ms`` for metrics.json."""
        return {"loop_stall_max_ms": round(self.max_ms, 1),
                f"loop_stalls_over_{self.threshold_ms:g}ms": self.over_threshold}
