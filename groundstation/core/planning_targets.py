"""The planning problem the decision core hands to the planner: which vehicles, which
targets, and the settings of :class:`~groundstation.core.config.CoreConfig`."""

from __future__ import annotations

from collections.abc import Sequence

from groundstation.core.config import CoreConfig
from planner import PlanningProblem, TargetEstimate, UavPose

__all__ = ["build_problem"]


def build_problem(
    config: CoreConfig,
    uavs: Sequence[UavPose],
    targets: Sequence[TargetEstimate],
    wind_m_s: tuple[float, float] | None,
) -> PlanningProblem:
    """The planner's input: ``uavs`` (sorted by the caller), ``targets`` and the wind
    (None in still air: the problem then reads as before wind existed)."""
    return PlanningProblem(
        uavs=tuple(uavs),
        targets=tuple(targets),
        turn_radius_m=config.turn_radius_m,
        tau=config.tau,
        min_sigma_fraction=config.min_sigma_fraction,
        time_limit_s=config.time_limit_s,
        objective=config.objective,
        speed_m_s=config.speed_m_s,
        wind_m_s=wind_m_s,
    )
