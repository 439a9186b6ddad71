"""The planning problem the decision core hands to the planner: which vehicles, which
targets, and the settings of :class:`~groundstation.core.config.CoreConfig`.

Targets (each an id, a position and a value ``sigma`` in m^2; the planner needs nothing
else):

* **confirmed and prior tracks**: their uncertainty ``sigma = trace(P_xy)``, as in the
  paper (every track is confirmed while there is no tracker, so labelled runs plan exactly
  as before);
* **tentative tracks**: a confirmation visit, worth (``tentative_weight`` is 0 by
  default, measured: see ``CoreConfig.tentative_weight``; then they are not planned)
  ``sigma_plan = tentative_weight * r * max(sigma, mean sigma of the confirmed and prior
  tracks)``, ``r`` the tracker's existence probability (the visit finds an iceberg with
  probability ``r``: a single false alarm's track has ``r = lambda_b / (lambda_b +
  lambda_c)``, 0.09 with the defaults, two hits make it ~1) (their own sigma right after
  birth is the camera's noise, a few m^2, which the
  planner's 10 % rule would drop: a tentative track is as urgent as an average track, since
  unconfirmed it can neither be planned as an iceberg nor deleted as clutter without a
  look); with no confirmed or prior track, its own sigma;
* **search cells** (``planner/search_cells.py``): the most valuable cells, at their centre,
  worth their value ``w g (t - t_last)`` m^2.

Tracks and cells a committed vehicle already flies to are left out (covered).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

from groundstation.core.config import CoreConfig
from observer import TrackSnapshot
from planner import MuRule, PlanningProblem, TargetEstimate, UavPose
from planner.search_cells import SearchCell

__all__ = ["build_problem", "search_targets", "track_targets"]

TENTATIVE = "tentative"


def track_targets(
    tracks: Sequence[TrackSnapshot],
    status_of: Callable[[str], str],
    covered: set[str],
    tentative_weight: float,
    existence_of: Callable[[str], float] = lambda _track: 1.0,
) -> list[TargetEstimate]:
    """Tracks as planning targets (module docstring), in the order given."""
    statuses = [status_of(tr.id) for tr in tracks]
    if TENTATIVE not in statuses:
        return [TargetEstimate(tr.id, tr.x_m, tr.y_m, tr.sigma)
                for tr in tracks if tr.id not in covered]
    firm = [tr.sigma for tr, s in zip(tracks, statuses, strict=True) if s != TENTATIVE]
    mean = sum(firm) / len(firm) if firm else 0.0
    out = []
    for tr, status in zip(tracks, statuses, strict=True):
        if tr.id in covered:
            continue
        sigma = tr.sigma if status != TENTATIVE else (
            tentative_weight * existence_of(tr.id) * max(tr.sigma, mean))
        out.append(TargetEstimate(tr.id, tr.x_m, tr.y_m, sigma))
    return out


def search_targets(cells: Iterable[SearchCell]) -> list[TargetEstimate]:
    """Search cells as planning targets at their centres, worth their value."""
    return [TargetEstimate(c.id, c.x_m, c.y_m, c.value_m2) for c in cells]


def build_problem(
    config: CoreConfig,
    uavs: Sequence[UavPose],
    targets: Sequence[TargetEstimate],
    wind_m_s: tuple[float, float] | None,
) -> PlanningProblem:
    """The planner's input: ``uavs`` (sorted by the caller), ``targets`` and the wind
    (None in still air: the problem then reads as before wind existed)."""
    mu_rule = config.mu if isinstance(config.mu, MuRule) else MuRule.FLOE
    return PlanningProblem(
        uavs=tuple(uavs),
        targets=tuple(targets),
        turn_radius_m=config.turn_radius_m,
        tau=config.tau,
        mu=None if isinstance(config.mu, MuRule) else config.mu,
        mu_rule=mu_rule,
        min_sigma_fraction=config.min_sigma_fraction,
        time_limit_s=config.time_limit_s,
        objective=config.objective,
        speed_m_s=config.speed_m_s,
        wind_m_s=wind_m_s,
    )
