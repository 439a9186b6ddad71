"""The daemon's mission clock (design.md, "mission clock").

Mission time ``t = (monotonic() - t0) * K`` with the speed-up ``K`` (1 for real vehicles).
With the built-in simulator in the same process the clock follows the simulator's own
simulated time instead (``source``), so an overloaded host that slows the simulator slows the
mission clock with it: every daemon timeout, retry, loiter, Kalman step, ``--duration`` and
journal ``t`` stays on the vehicles' clock. ``wall_s(mission_s)`` converts a mission
duration into the wall seconds to sleep.
"""

from __future__ import annotations

import time
from collections.abc import Callable

__all__ = ["MissionClock"]


class MissionClock:
    """Mission seconds since start; ``speedup`` mission seconds per wall second."""

    def __init__(self, speedup: float = 1.0, source: Callable[[], float] | None = None) -> None:
        if not speedup > 0:
            raise ValueError(f"speed-up must be > 0, got {speedup}")
        self.speedup = float(speedup)
        self._source = source
        self._t0 = time.monotonic()
        self._offset_s = source() if source is not None else 0.0

    def now_s(self) -> float:
        """Mission seconds since the clock started."""
        if self._source is not None:
            return self._source() - self._offset_s
        return (time.monotonic() - self._t0) * self.speedup

    def wall_s(self, mission_s: float) -> float:
        """Wall seconds that ``mission_s`` mission seconds take (>= 0)."""
        return max(0.0, mission_s / self.speedup)

    @staticmethod
    def unix_s() -> float:
        """Wall-clock Unix time (for journal lines and the tlog)."""
        return time.time()

    def measured_speedup(self) -> float:
        """Mission seconds per wall second since start (checks a simulator's real rate)."""
        wall = time.monotonic() - self._t0
        return self.now_s() / wall if wall > 0 else 0.0
