"""The decision core's configuration as a scenario describes it (one mapping for every
frontend: ``gcs simulate``, ``gcs run --scenario`` and replay).

The tracker's settings: the camera's ``pd`` and ``clutter_per_frame`` are the tracker's
``pd`` and ``clutter_per_frame`` (the tracker models the camera it is fed by), and the
scenario's ``tracker:`` mapping overrides any key (``TrackerConfig`` validates them). Search:
the scenario's ``search:`` over its ``area:``.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from groundstation.core.config import CoreConfig, ReplanPolicy, WatchConfig
from observer import ObserverConfig, TrackerConfig
from planner import MuRule, Objective
from planner.search_cells import SearchConfig
from world.scenario import Scenario

__all__ = ["core_config_for", "tracker_config_for", "watch_config_for"]


def tracker_config_for(scenario: Scenario) -> TrackerConfig:
    """The camera's pd and clutter, then the scenario's ``tracker:`` overrides."""
    values: dict[str, object] = {
        "pd": scenario.camera.pd,
        "clutter_per_frame": scenario.camera.clutter_per_frame,
    }
    values.update(scenario.tracker)
    try:
        return TrackerConfig(**values)  # type: ignore[arg-type]
    except TypeError as exc:
        raise ValueError(f"tracker: {exc}") from exc


def core_config_for(scenario: Scenario, objective: str | None = None) -> CoreConfig:
    """The decision core's configuration as a scenario describes it."""
    obs = scenario.observer
    config = _core_config(scenario, obs, objective)
    policy = scenario.policy  # core/uploads.py; None: the core's default
    if policy.upload_min_interval_s is not None:
        config = dataclasses.replace(config, upload_min_interval_s=policy.upload_min_interval_s)
    if policy.upload_budget_per_h is not None:
        config = dataclasses.replace(config, upload_budget_per_h=policy.upload_budget_per_h)
    return config


def _core_config(scenario: Scenario, obs: Any, objective: str | None) -> CoreConfig:
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
        mu=_mu(scenario.planner.mu),
        priority_gain=obs.priority_gain,
        priority_near_m=obs.priority_near_m,
        priority_far_m=obs.priority_far_m,
        wind_xy_m_s=_plain(scenario.wind.mean_xy_m_s),
        wind_aware=scenario.planner.wind_aware,
        tentative_weight=scenario.planner.tentative_weight,
        tracker=tracker_config_for(scenario),
        search=_search(scenario),
        area_m=None if scenario.area is None else (
            scenario.area.x_min_m, scenario.area.x_max_m,
            scenario.area.y_min_m, scenario.area.y_max_m,
        ),
        watch=watch_config_for(scenario),
    )


def _mu(value: float | str) -> float | MuRule:
    """The scenario's ``planner.mu`` (a rule name, checked by world.scenario, or a number)."""
    return MuRule(value) if isinstance(value, str) else value


def watch_config_for(scenario: Scenario) -> WatchConfig | None:
    """The core's side of the scenario's ``watch:`` (None without one)."""
    spec = scenario.watch
    if spec is None:
        return None
    return WatchConfig(on_station=spec.on_station, endurance_s=spec.endurance_s,
                       reserve_pct=spec.reserve_pct, home_update_m=spec.home_update_m,
                       recovery_radius_m=spec.recovery_radius_m, launch_s=spec.launch_s)


def _search(scenario: Scenario) -> SearchConfig | None:
    spec = scenario.search
    if spec is None:
        return None
    return SearchConfig(cell_m=spec.cell_m, growth_m2_per_s=spec.growth_m2_per_s,
                        max_cells=spec.max_cells, prior_weight=spec.prior_weight)


def _plain(wind_xy_m_s: tuple[float, float]) -> tuple[float, float]:
    """The wind without negative zeros (still air journals as [0.0, 0.0])."""
    return wind_xy_m_s[0] + 0.0, wind_xy_m_s[1] + 0.0

