"""The decision core's configuration as a scenario describes it (one mapping for every
frontend: ``gcs simulate``, ``gcs run --scenario`` and replay)."""

from __future__ import annotations

from groundstation.core.config import CoreConfig, ReplanPolicy
from observer import ObserverConfig
from planner import Objective
from world.scenario import Scenario

__all__ = ["core_config_for"]


def core_config_for(scenario: Scenario, objective: str | None = None) -> CoreConfig:
    """The decision core's configuration as a scenario describes it."""
    obs = scenario.observer
    return CoreConfig(
        policy=ReplanPolicy.from_names(
            scenario.policy.replan, scenario.policy.period_s, scenario.policy.commit
        ),
        observer=ObserverConfig(
            model=obs.model,
            q_per_s=obs.q_per_s,
            r_m2=obs.r_m2,
            max_step_s=obs.step_s,
            fov_radius_m=scenario.fleet.fov_radius_m,
            linear_growth_per_s=obs.linear_growth_per_s,
        ),
        turn_radius_m=scenario.fleet.turn_radius_m,
        speed_m_s=scenario.fleet.speed_m_s,
        loiter_s=scenario.fleet.loiter_s,
        loiter_radius_m=scenario.fleet.loiter_radius_m,
        tau=scenario.planner.tau,
        objective=Objective(objective or scenario.planner.objective),
        time_limit_s=scenario.planner.time_limit_s,
        min_sigma_fraction=scenario.planner.min_sigma_fraction,
        priority_gain=obs.priority_gain,
        priority_near_m=obs.priority_near_m,
        priority_far_m=obs.priority_far_m,
        wind_xy_m_s=_plain(scenario.wind.mean_xy_m_s),
        wind_aware=scenario.planner.wind_aware,
    )


def _plain(wind_xy_m_s: tuple[float, float]) -> tuple[float, float]:
    """The wind without negative zeros (still air journals as [0.0, 0.0])."""
    return wind_xy_m_s[0] + 0.0, wind_xy_m_s[1] + 0.0

