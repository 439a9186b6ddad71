"""Metrics of a simulated (or replayed) run, in the ``metrics.json`` format of design.md.

* ``uncertainty_series``: ``[t_s, mean sigma]`` every second of mission time, the mean over
  the targets present (lost ones included);
* ``visits``: a visit is the first accepted measurement of a target after >= 5 s unseen
  (a never-seen target counts as unseen since forever);
* *trend* (the paper's Figure 4 claim, "the average uncertainty stays bounded"): the
  second half of the run is cut into windows of ``TREND_WINDOW_S``; with ``m_k`` the mean of
  the average uncertainty in window k (centre ``c_k``), the Theil-Sen slope
  ``s = median_{k < l} (m_l - m_k) / (c_l - c_k)`` is robust to a few peaks, and

      trend = s * (second half's duration) / (mean of the second half)

  is the growth over the second half that the slope predicts, relative to the level (0 for
  a level run, 0.67 for sigma growing linearly from 0, about 1.7 for the t^3 growth of a
  track never seen again). ``bounded_trend`` is the threshold ``trend <= TREND_BOUND`` =
  0.5 (the key keeps its old name; it is a threshold on a rate, not a test of
  boundedness: sqrt(t) passes it). Measured on paper-boat (docs/planner.md, "Figure 4 at
  the ensemble level"):
  with icebergs that do not drift (a field 3-6 UAVs can hold), 4 of 120 runs of 200 s and
  600 s exceed 0.5 (0.4: 8, 0.25: 18); runs that must grow (one UAV over 200 s; 1, 3 and 5
  UAVs over 600 s of drift) all exceed it (0.6 lets 2 of 80 pass).
* *growth over the second half* of an ensemble (:func:`ensemble_growth`; the campaign
  report per grid cell, ``gcs simulate --uavs 1,3 --seeds K`` per fleet size): with
  ``M_r`` and ``L_r`` run r's mean sigma over the middle third and the last third of its
  mission time,

      G = sum_r L_r / sum_r M_r

  the ratio of the ensemble's mean curve over its last third to its middle third (runs of
  equal length), with a 95 % percentile bootstrap interval over the runs (seeds). G = 1 is
  level, G = 2 doubled over the second half. It judges the mean curve, not each run: a
  single run's trend swings by +-0.65 between seeds (docs/planner.md).
* the first definition (``bounded``, ``boundedness_ratio``: the second half's maximum at
  most 1.5 times the first half's) stays for comparison: it passes growing runs and fails
  level ones whose first half was unusually good.
* ``arrival_error_s`` {median, p90}, ``arrival_bias_s`` and ``arrivals``: the core's
  predicted arrival at each aim point against the flown one (:mod:`.arrivals`), and the
  same split into each vehicle's first leg and the later ones (``arrival_error_first_s``,
  ``arrival_error_later_s`` {median, p90, max, counted}, ``arrival_bias_first_s``,
  ``arrival_bias_later_s``); frontends
  feed it with :meth:`MetricsRecorder.fly`, :meth:`~MetricsRecorder.position` and
  :meth:`~MetricsRecorder.abandoned`.
* ``mu_ratio`` {mean, sd, n}: eq. 18's mu over the realised F1/F2' of each adopted plan
  (F2' the plan's distance sum without mu), i.e. ``f2 / f1`` as floe's ``f2`` includes mu;
  1 means the plan's two terms weigh as mu assumed (the paper's Section 4.5 table). Plans
  with F1 = 0, and plans without a distance term (mu = 0: every ``latency`` plan), are left
  out; mean and sd are null when n = 0 (sd too when n = 1; sd with n - 1).
* ``uploads``: per vehicle, the FlyToTarget commands it was given (each one mission upload;
  ``core/uploads.py`` decides when one is worth it), and ``uploads_per_hour`` the same per
  hour of the run: ``3600 n / T``, ``T`` the mission time of the last sample (s).
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from groundstation.core.arrivals import ArrivalTracker
from groundstation.core.views import TrackView
from observer import TrackSnapshot

__all__ = [
    "BOUNDED_RATIO",
    "TREND_BOUND",
    "TREND_WINDOW_S",
    "EnsembleGrowth",
    "MetricsRecorder",
    "boundedness_ratio",
    "ensemble_growth",
    "theil_sen_slope",
    "third_means",
    "trend_growth",
]

BOUNDED_RATIO = 1.5
TREND_BOUND = 0.5
TREND_WINDOW_S = 10.0
VISIT_GAP_S = 5.0


def theil_sen_slope(xs: Sequence[float], ys: Sequence[float]) -> float:
    """Median of the slopes (y_l - y_k) / (x_l - x_k) over all pairs with x_k < x_l; 0 if none."""
    slopes = [
        (ys[b] - ys[a]) / (xs[b] - xs[a])
        for a in range(len(xs))
        for b in range(a + 1, len(xs))
        if xs[b] != xs[a]
    ]
    return statistics.median(slopes) if slopes else 0.0


def trend_growth(
    series: Sequence[Sequence[float]], window_s: float = TREND_WINDOW_S
) -> float | None:
    """Relative growth of the second half predicted by its robust trend (module docstring).

    Windows are (t_mid + k w, t_mid + (k + 1) w], k = 0, 1, ... up to the end, by sample
    time (uneven sampling is windowed by time, not by count): a window without samples is
    skipped, the last one counts if the run reaches at least half way into it. None when
    the second half has fewer than 3 windows (too short to tell); 0 when its mean is 0 and
    inf if it is 0 but growing.
    """
    if len(series) < 2:
        return None
    t0, t_end = series[0][0], series[-1][0]
    t_mid = (t0 + t_end) / 2.0
    second = [(t, s) for t, s in series if t > t_mid]
    if not second:
        return None
    windows: dict[int, list[tuple[float, float]]] = {}
    for t, s in second:
        windows.setdefault(math.ceil((t - t_mid) / window_s) - 1, []).append((t, s))
    centres: list[float] = []
    means: list[float] = []
    for k in sorted(windows):
        if t_end < t_mid + (k + 0.5) * window_s:
            continue  # the last window, less than half covered
        chunk = windows[k]
        centres.append(statistics.fmean(t for t, _ in chunk))
        means.append(statistics.fmean(s for _, s in chunk))
    if len(means) < 3:
        return None
    slope = theil_sen_slope(centres, means)
    level = statistics.fmean(s for _, s in second)
    span = t_end - t_mid
    if level <= 0.0:
        return 0.0 if slope <= 0.0 else math.inf
    return slope * span / level


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


def third_means(
    times_s: Sequence[float], values: Sequence[float]
) -> tuple[float, float] | None:
    """(mean over the middle third, mean over the last third) of a series by time: t0 + T/3 <
    t <= t0 + 2T/3 and t > t0 + 2T/3, T = t_end - t0. None when a third has no sample."""
    if len(times_s) < 3 or len(times_s) != len(values):
        return None
    t0, t_end = times_s[0], times_s[-1]
    one, two = t0 + (t_end - t0) / 3.0, t0 + 2.0 * (t_end - t0) / 3.0
    middle = [v for t, v in zip(times_s, values, strict=True) if one < t <= two]
    last = [v for t, v in zip(times_s, values, strict=True) if t > two]
    if not middle or not last:
        return None
    return statistics.fmean(middle), statistics.fmean(last)


@dataclass(frozen=True)
class EnsembleGrowth:
    """Growth over the second half of an ensemble's mean curve (module docstring): ``value``
    = last third / middle third, ``low``/``high`` its 95 % bootstrap interval over ``runs``
    (None with fewer than 2 runs); value None when the middle third's mean is 0."""

    value: float | None
    low: float | None
    high: float | None
    runs: int

    def text(self) -> str:
        """``1.08 [0.92, 1.26]`` (``-`` without a value; no interval with one run)."""
        if self.value is None:
            return "-"
        if self.low is None or self.high is None:
            return f"{self.value:.2f} (1 run: no interval)"
        return f"{self.value:.2f} [{self.low:.2f}, {self.high:.2f}]"


BOOTSTRAP_RESAMPLES = 2000


def ensemble_growth(
    thirds: Sequence[tuple[float, float]], resamples: int = BOOTSTRAP_RESAMPLES, seed: int = 0
) -> EnsembleGrowth:
    """G = sum L_r / sum M_r over the runs' (M_r, L_r) (:func:`third_means`), with the 2.5 and
    97.5 percentiles of G over ``resamples`` resamplings of the runs with replacement (a
    fixed ``seed``: the same runs give the same interval)."""
    import numpy as np

    pairs = np.asarray(thirds, dtype=np.float64).reshape(-1, 2)
    pairs = pairs[np.isfinite(pairs).all(axis=1)]
    n = len(pairs)
    middle, last = pairs[:, 0], pairs[:, 1]
    if n == 0 or middle.sum() <= 0.0:
        return EnsembleGrowth(None, None, None, n)
    value = float(last.sum() / middle.sum())
    if n < 2:
        return EnsembleGrowth(value, None, None, n)
    rng = np.random.default_rng(seed)
    pick = rng.integers(0, n, size=(resamples, n))
    sums_m = middle[pick].sum(axis=1)
    ok = sums_m > 0.0
    ratios = last[pick].sum(axis=1)[ok] / sums_m[ok]
    low, high = np.percentile(ratios, [2.5, 97.5])
    return EnsembleGrowth(value, float(low), float(high), n)


@dataclass
class MetricsRecorder:
    """Accumulates what metrics.json reports while a run goes on."""

    series: list[list[float]] = field(default_factory=list)
    max_error_m: dict[str, float] = field(default_factory=dict)
    lost: set[str] = field(default_factory=set)
    visits: list[dict[str, Any]] = field(default_factory=list)
    solve_times_s: list[float] = field(default_factory=list)
    mu_ratios: list[float] = field(default_factory=list)
    plans: int = 0
    arrivals: ArrivalTracker = field(default_factory=ArrivalTracker)
    uploads: dict[str, int] = field(default_factory=dict)
    _last_seen_s: dict[str, float] = field(default_factory=dict)

    def sample(self, t_s: float, sigmas: Iterable[float]) -> None:
        values = list(sigmas)
        mean = sum(values) / len(values) if values else 0.0
        self.series.append([round(t_s, 6), mean])

    def sample_tracks(
        self,
        t_s: float,
        tracks: Sequence[TrackSnapshot | TrackView],
        truth: Mapping[str, tuple[float, float]],
    ) -> None:
        """The once-a-mission-second sample of a run: mean sigma over ``tracks``, lost
        tracks, and each track's distance to its true position where ``truth`` knows it."""
        self.sample(t_s, (tr.sigma for tr in tracks))
        for tr in tracks:
            if tr.lost:
                self.mark_lost(tr.id)
            if tr.id in truth:
                tx, ty = truth[tr.id]
                self.error(tr.id, math.hypot(tr.x_m - tx, tr.y_m - ty))

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

    def fly(self, t_s: float, vehicle: str, target: str, x_m: float, y_m: float,
            eta_s: float | None, fov_radius_m: float) -> None:
        """A FlyToTarget the vehicle was actually given (arrival error, uploads)."""
        self.uploads[vehicle] = self.uploads.get(vehicle, 0) + 1
        self.arrivals.commanded(t_s, vehicle, target, x_m, y_m, eta_s, fov_radius_m)

    def position(self, t_s: float, vehicle: str, x_m: float, y_m: float) -> None:
        """Where ``vehicle`` is (true position offline, telemetry in the daemon)."""
        self.arrivals.position(t_s, vehicle, x_m, y_m)

    def abandoned(self, vehicle: str) -> None:
        """``vehicle`` was released or sent home: its last FlyToTarget will not be flown."""
        self.arrivals.abandoned(vehicle)

    def plan(self, solve_time_s: float, mu: float = 0.0, f1: float = 0.0,
             f2: float = 0.0) -> None:
        """An adopted plan: its solve time, and mu / (F1 / F2') = f2 / f1 (module docstring)
        unless F1 or mu is 0."""
        self.plans += 1
        self.solve_times_s.append(solve_time_s)
        if f1 != 0.0 and mu != 0.0 and math.isfinite(f1) and math.isfinite(f2):
            self.mu_ratios.append(f2 / f1)

    def mu_ratio(self) -> dict[str, float | int | None]:
        """``{mean, sd, n}`` of the plans' mu / (F1 / F2') (module docstring)."""
        values = self.mu_ratios
        return {
            "mean": statistics.fmean(values) if values else None,
            "sd": statistics.stdev(values) if len(values) > 1 else None,
            "n": len(values),
        }

    def to_dict(self, wall_time_s: float) -> dict[str, Any]:
        values = [s for _, s in self.series]
        ratio = boundedness_ratio(self.series)
        trend = trend_growth(self.series)
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
            "mu_ratio": self.mu_ratio(),
            "bounded": ratio <= BOUNDED_RATIO,
            "boundedness_ratio": ratio if math.isfinite(ratio) else None,
            "trend": trend if trend is not None and math.isfinite(trend) else None,
            "bounded_trend": None if trend is None else trend <= TREND_BOUND,
            **self.arrivals.to_dict(),
            "uploads": dict(sorted(self.uploads.items())),
            "uploads_per_hour": self.uploads_per_hour(),
        }

    def uploads_per_hour(self) -> dict[str, float]:
        """Each vehicle's FlyToTargets per hour of the run (module docstring); empty before
        the first sample."""
        t_end_s = self.series[-1][0] if self.series else 0.0
        if t_end_s <= 0.0:
            return {}
        return {v: n * 3600.0 / t_end_s for v, n in sorted(self.uploads.items())}
