"""A solve's time budget: a wall-clock deadline, and the CPU time the solve actually obtains.

On a loaded machine a second of wall time is not a second of computing: beside two busy
loops on two cores a solver thread gets 0.5-0.7 CPU-s per wall second, less with more
load. Phases whose cost is known in CPU (the LP, CP-SAT's build) are therefore sized by

    cpu_left = rate * wall_left,   rate = CPU obtained / wall elapsed since the start,

(rate clamped to [MIN_RATE, 1]; 1 until MIN_SAMPLE_S of wall time have passed, and always 1
when no CPU clock is given, as in tests that drive the budget with a fake wall clock). The
deadline itself is always wall time: every phase polls it or is given it as its own limit.
"""

from __future__ import annotations

from collections.abc import Callable

Clock = Callable[[], float]

MIN_RATE = 0.01
MIN_SAMPLE_S = 0.02  # below this the CPU clock's granularity makes the rate meaningless


class Budget:
    """Deadline `end` (wall clock `wall`) and the CPU rate of one solve."""

    def __init__(self, wall: Clock, cpu: Clock | None, start: float, end: float) -> None:
        self.wall = wall
        self._cpu = cpu
        self.start = start
        self.end = end
        self.cpu_start = cpu() if cpu is not None else start

    def cpu(self) -> float:
        """CPU time obtained (s; the wall clock when no CPU clock is given)."""
        return self._cpu() if self._cpu is not None else self.wall()

    def wall_left_s(self) -> float:
        return self.end - self.wall()

    def rate(self) -> float:
        """CPU obtained per wall second since the start, in [MIN_RATE, 1]."""
        if self._cpu is None:
            return 1.0
        elapsed = self.wall() - self.start
        if elapsed < MIN_SAMPLE_S:
            return 1.0
        return min(1.0, max(MIN_RATE, (self._cpu() - self.cpu_start) / elapsed))

    def cpu_left_s(self) -> float:
        """The CPU time the rest of the wall budget will give at the rate obtained so far."""
        left = self.wall_left_s()
        return self.rate() * left if left > 0.0 else 0.0


class Poll:
    """The search's deadline check: true once the *next* poll would come after `end`.

    The gap between two polls is a few microseconds of CPU, but on a loaded machine the
    thread can lose the processor between them for tens of milliseconds. The check keeps the
    largest wall gap seen between consecutive polls of the current phase (`restart()` at
    each phase: a gap across another phase is no poll gap) and stops when now + that gap
    passes `end`, so the solve stops early rather than late."""

    def __init__(self, clock: Clock, end: float) -> None:
        self.clock = clock
        self.end = end
        self.last: float | None = None
        self.max_gap_s = 0.0

    def restart(self, end: float) -> None:
        self.end = end
        self.last = None

    def __call__(self) -> bool:
        now = self.clock()
        if self.last is not None:
            self.max_gap_s = max(self.max_gap_s, now - self.last)
        self.last = now
        return now + self.max_gap_s > self.end
