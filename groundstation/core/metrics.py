"""Metrics of a simulated (or replayed) run, in the ``metrics.json`` format of design.md.

* ``uncertainty_series``: ``[t_s, mean sigma]`` every second of mission time, the mean over
  the targets present (lost ones included);
* ``visits``: a visit is the first accepted measurement of a target after >= 5 s unseen
  (a never-seen target counts as unseen since forever);
* *bounded* (the paper's Figure 4 claim): the maximum of the average uncertainty over the
  second half of the run is at most 1.5 times its maximum over the first half.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

__all__ = ["BOUNDED_RATIO", "MetricsRecorder", "boundedness_ratio"]

BOUNDED_RATIO = 1.5
VISIT_GAP_S = 5.0


def boundedness_ratio(series: Sequence[Sequence[float]]) -> float:
    """max(mean sigma, second half) / max(mean sigma, first half); inf if the first is 0."""
    if len(series) < 2:
        return 0.0
    t_end = series[-1][0]
    half = (series[0][0] + t_end) / 2.0
    first = [s for t, s in series if t <= half]
    second = [s for t, s in series if t > half]
    if not second:
        return 0.0
    first_max = max(first) if first else 0.0
    second_max = max(second)
    if first_max <= 0.0:
        return 0.0 if second_max <= 0.0 else math.inf
    return second_max / first_max


@dataclass
class MetricsRecorder:
    """Accumulates what metrics.json reports while a run goes on."""

    series: list[list[float]] = field(default_factory=list)
    max_error_m: dict[str, float] = field(default_factory=dict)
    lost: set[str] = field(default_factory=set)
    visits: list[dict[str, Any]] = field(default_factory=list)
    solve_times_s: list[float] = field(default_factory=list)
    plans: int = 0
    _last_seen_s: dict[str, float] = field(default_factory=dict)

    def sample(self, t_s: float, sigmas: Iterable[float]) -> None:
        values = list(sigmas)
        mean = sum(values) / len(values) if values else 0.0
        self.series.append([round(t_s, 6), mean])

    def error(self, target: str, error_m: float) -> None:
        if math.isfinite(error_m):
            self.max_error_m[target] = max(self.max_error_m.get(target, 0.0), error_m)

    def seen(self, t_s: float, vehicle: str | None, target: str) -> None:
        last = self._last_seen_s.get(target)
        if last is None or t_s - last >= VISIT_GAP_S:
            self.visits.append({"t_s": round(t_s, 3), "vehicle": vehicle, "target": target})
        self._last_seen_s[target] = t_s

    def mark_lost(self, target: str) -> None:
        self.lost.add(target)

    def plan(self, solve_time_s: float) -> None:
        self.plans += 1
        self.solve_times_s.append(solve_time_s)

    def to_dict(self, wall_time_s: float) -> dict[str, Any]:
        values = [s for _, s in self.series]
        ratio = boundedness_ratio(self.series)
        return {
            "uncertainty_series": self.series,
            "mean_uncertainty": statistics.fmean(values) if values else 0.0,
            "max_uncertainty": max(values) if values else 0.0,
            "final_uncertainty": values[-1] if values else 0.0,
            "max_estimation_error_m": dict(sorted(self.max_error_m.items())),
            "lost_targets": sorted(self.lost),
            "visits": self.visits,
            "plans": self.plans,
            "solve_time_s": {
                "median": statistics.median(self.solve_times_s) if self.solve_times_s else 0.0,
                "max": max(self.solve_times_s) if self.solve_times_s else 0.0,
            },
            "wall_time_s": wall_time_s,
            "bounded": ratio <= BOUNDED_RATIO,
            "boundedness_ratio": ratio if math.isfinite(ratio) else None,
        }
