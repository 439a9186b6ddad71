"""Half-aware decision cores for the wind benchmark: which half of wind-awareness costs what.

A wind-aware core uses the wind in two places (docs/wind.md, groundstation/core/decision.py):

* the **costs**: the planning problem carries ``wind_m_s``, so the planner's matrix is
  ``d_ij = V T_ij`` with travel times in the wind (planner/wind.py);
* the **intercept**: the aim point is ``p_hat + v_hat T`` with ``T`` the first-leg time in
  the wind to the drifting target (``planner.wind.time_in_wind_s``), not the still-air
  fixed point ``T = D(pose, p) / V``.

``costs``: the wind in the costs only (the still-air intercept); ``intercept``: the wind in
the intercept only (still-air costs). ``all`` is the shipped core. These are measurement
probes, not product options: ``wind_study.py --aware-part`` swaps the core class the
offline runner builds, as it swaps the metrics recorder.
"""

from __future__ import annotations

from groundstation.core.commands import Command
from groundstation.core.config import CoreConfig
from groundstation.core.decision import DecisionCore, VehicleRecord

__all__ = ["AWARE_PARTS", "CostsOnlyCore", "InterceptOnlyCore", "core_class"]


class CostsOnlyCore(DecisionCore):
    """Wind-aware costs, still-air intercept."""

    def __init__(self, config: CoreConfig) -> None:
        super().__init__(config)
        self._still_air = False

    def planning_wind_m_s(self) -> tuple[float, float]:
        if self._still_air:
            return 0.0, 0.0
        return super().planning_wind_m_s()

    def intercept(self, record: VehicleRecord, target: str) -> tuple[float, float, float]:
        self._still_air = True
        try:
            return super().intercept(record, target)
        finally:
            self._still_air = False


class InterceptOnlyCore(DecisionCore):
    """Wind-aware intercept, still-air costs (every problem planned as in still air)."""

    def _problem_wind(self, t_s: float, out: list[Command]) -> tuple[float, float] | None:
        return None


AWARE_PARTS: dict[str, type[DecisionCore]] = {
    "all": DecisionCore,
    "costs": CostsOnlyCore,
    "intercept": InterceptOnlyCore,
}


def core_class(part: str) -> type[DecisionCore]:
    """The core class of an ``--aware-part`` value (KeyError for an unknown one)."""
    return AWARE_PARTS[part]
