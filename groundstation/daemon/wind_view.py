"""The wind as ``gcs run`` resolves and shows it: the fallback's source, the status
table's header line, the live map's ``wind`` object.

The decision core knows two sources (``core/wind_estimate.py``): ``vehicles`` (their own
WIND estimates, combined) and ``fallback`` (``CoreConfig.wind_xy_m_s``). The daemon knows
where the fallback came from, and names it for the operator: ``config`` (``--wind`` or the
config file's ``wind``), ``scenario`` (the scenario's ``wind`` section) or ``none`` (still
air: nothing configured).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from domain.wind_triangle import wind_from_vector
from groundstation.core.wind_estimate import VEHICLES, WindState
from groundstation.daemon.config import DaemonConfig
from world.wind import WindSpec

if TYPE_CHECKING:
    from world.scenario import Scenario

__all__ = ["fallback_wind", "vehicle_wind", "wind_label", "wind_summary", "wind_text"]


def fallback_wind(config: DaemonConfig, scenario: Scenario | None) -> tuple[WindSpec, str]:
    """The wind the core falls back on and the simulator flies in, and its source:
    the config's, else the scenario's (unless calm), else still air (``none``)."""
    if config.wind is not None:
        return config.wind, "config"
    if scenario is not None and not scenario.wind.calm:
        return scenario.wind, "scenario"
    return WindSpec(), "none"


def wind_label(state: WindState, fallback_source: str) -> str:
    """``vehicles 1,2,3``, or the fallback's source (``config``, ``scenario``, ``none``)."""
    if state.source == VEHICLES:
        return "vehicles " + ",".join(state.vehicles)
    return fallback_source


def wind_text(wx_m_s: float, wy_m_s: float) -> str:
    """``12.0 m/s from 270°`` (``calm`` below 0.05 m/s)."""
    speed, from_deg = wind_from_vector(wx_m_s, wy_m_s)
    if speed < 0.05:
        return "calm"
    return f"{speed:.1f} m/s from {from_deg:.0f}°"


def wind_summary(state: WindState, fallback_source: str, wind_aware: bool) -> dict[str, Any]:
    """The live map's and the control API's ``wind``: the estimate (ENU vector the air
    moves towards, speed, compass direction it blows from), its source and label, and
    whether the planner uses it."""
    speed, from_deg = wind_from_vector(state.wx_m_s, state.wy_m_s)
    return {
        "wx_m_s": state.wx_m_s,
        "wy_m_s": state.wy_m_s,
        "speed_m_s": speed,
        "from_deg": from_deg,
        "source": state.source if state.source == VEHICLES else fallback_source,
        "vehicles": list(state.vehicles),
        "label": f"{wind_text(state.wx_m_s, state.wy_m_s)} ({wind_label(state, fallback_source)})",
        "planning": wind_aware,
    }


def vehicle_wind(xy_m_s: tuple[float, float] | None) -> dict[str, float] | None:
    """One vehicle's own accepted estimate for the live map (None: none yet)."""
    if xy_m_s is None:
        return None
    speed, from_deg = wind_from_vector(*xy_m_s)
    return {"wx_m_s": xy_m_s[0], "wy_m_s": xy_m_s[1], "speed_m_s": speed, "from_deg": from_deg}
