"""Statistics of a campaign per grid cell: the numbers behind its report and its
end-of-run summary table.

A *cell* is one combination of the grid's values except the seed; its runs are
repetitions. Everything here is vectorised over runs (``numpy.bincount`` on a cell index),
so 10 000 runs of 600 mission seconds summarise in well under a second.

* Mean of a cell: the mean over its runs of their ``mean_uncertainty``, with the 95 %
  Student t interval ``mean +- t(0.975, n - 1) s / sqrt(n)`` (s the sample standard
  deviation; no interval for n < 2).
* Bounded rate: runs whose ``bounded_trend`` is true among those where it is not null
  (``bounded``, the first test, when there is no ``bounded_trend``), with the 95 % Wilson
  score interval.
* Median solve time: over every adopted plan of the cell's runs (``plans.parquet``
  ``solve_time_s``), else the median of the runs' ``solve_time_median_s``.
* Growth over the second half (``growth``): the ensemble statistic of
  :func:`groundstation.core.metrics.ensemble_growth`, the cell's mean curve over its last
  third divided by its middle third, with a 95 % bootstrap interval over the cell's runs
  (seeds). It replaces counting runs under a trend threshold as the verdict on the paper's
  Figure 4: a threshold on one run's growth rate is a coin flip near it, and passes curves
  that grow without bound.
* mu / (F1/F2) (``mu_ratio``, eq. 18; the paper's Section 4.5 table): over the cell's
  adopted plans with f1 and mu not 0 (``plans.parquet``), ``f2 / f1``; its mean and
  standard deviation over the plans, and a 95 % Student t interval over the runs' own means
  (plans of one run are not independent; runs are).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
from scipy.special import stdtrit

from groundstation.core.metrics import EnsembleGrowth, ensemble_growth, third_means
from groundstation.runners.campaign.data import (
    SEED_KEY,
    column_codes,
    dedupe,
    float_column,
    grid_keys_of,
    recorded_grid_keys,
)

__all__ = [
    "TREND_BOUNDS",
    "CellSummary",
    "Cells",
    "MuRatio",
    "SeriesBands",
    "TrendCounts",
    "group_cells",
    "grouped_mean_ci",
    "grouped_median",
    "plan_cells",
    "series_bands",
    "show_value",
    "summaries_of",
    "summarise_cells",
    "t_quantile_975",
    "trend_counts",
    "wilson_interval",
]

Z_975 = 1.959963984540054
"""The standard normal 97.5 % quantile (two-sided 95 %)."""

MAX_SERIES_POINTS = 2000
"""Most time points per curve of :func:`series_bands` (longer runs: every k-th second)."""


@dataclass
class Cells:
    """Runs grouped by grid cell: ``index[r]`` is run r's cell, ``values[c]`` cell c's
    value of each of ``keys`` (the grid keys but the seed), cells in the order of
    :func:`group_cells`."""

    keys: list[str]
    index: np.ndarray
    values: list[dict[str, Any]]

    @property
    def count(self) -> int:
        return len(self.values)

    @property
    def varying(self) -> list[str]:
        """The keys with more than one value over the cells."""
        return [k for k in self.keys if len({repr(v[k]) for v in self.values}) > 1]

    def label(self, cell: int, keys: Sequence[str] | None = None) -> str:
        """``uavs=3, objective=sequence`` (the varying keys, or ``keys``); ``all runs``
        when there is nothing to name."""
        names = self.varying if keys is None else list(keys)
        text = ", ".join(f"{k}={show_value(self.values[cell][k])}" for k in names)
        return text or "all runs"


def show_value(value: Any) -> str:
    """A grid value as a campaign file spells it: ``200`` (not ``200.0``), ``1, 3, 5``
    for a list, ``0 to 19`` for a seed range, ``-`` for none."""
    if isinstance(value, float) and value.is_integer() and abs(value) < 1e15:
        return f"{value:g}"
    if isinstance(value, list | tuple):
        return ", ".join(show_value(v) for v in value)
    if isinstance(value, Mapping) and set(value) == {"from", "to"}:
        return f"{show_value(value['from'])} to {show_value(value['to'])}"
    if isinstance(value, Mapping):
        return ", ".join(f"{k}: {show_value(v)}" for k, v in value.items())
    return "-" if value is None else str(value)


def _in_order(distinct: list[Any], listed: Sequence[Any]) -> np.ndarray:
    """A permutation of ``distinct`` that puts the values in ``listed``'s order (values not
    listed after them, in their sorted order)."""

    def rank(j: int) -> tuple[int, int]:
        for i, value in enumerate(listed):
            if distinct[j] == value:
                return (0, i)
        return (1, j)

    return np.asarray(sorted(range(len(distinct)), key=rank), dtype=np.int64)


def group_cells(
    runs: pa.Table, keys: Sequence[str], order: Mapping[str, Any] | None = None
) -> Cells:
    """The cells of ``runs`` over grid ``keys`` (the seed left out if among them), sorted
    by value, or for a key whose ``order`` entry is a list (the campaign file's grid) in
    that list's order."""
    cell_keys = [k for k in keys if k != SEED_KEY and k in runs.column_names]
    combined = np.zeros(runs.num_rows, dtype=np.int64)
    distinct_of: list[list[Any]] = []
    for key in cell_keys:
        codes, distinct = column_codes(runs.column(key))
        listed = (order or {}).get(key)
        if isinstance(listed, list | tuple):
            perm = _in_order(distinct, listed)
            position = np.empty(len(perm), dtype=np.int64)
            position[perm] = np.arange(len(perm))
            codes, distinct = position[codes], [distinct[j] for j in perm]
        combined = combined * len(distinct) + codes
        distinct_of.append(distinct)
    unique, index = np.unique(combined, return_inverse=True)
    values: list[dict[str, Any]] = []
    for code in unique.tolist():
        cell: dict[str, Any] = {}
        for key, distinct in zip(reversed(cell_keys), reversed(distinct_of), strict=True):
            code, k = divmod(code, len(distinct))
            cell[key] = distinct[k]
        values.append({k: cell[k] for k in cell_keys})
    return Cells(cell_keys, np.asarray(index, dtype=np.int64).reshape(-1), values)


def t_quantile_975(df: np.ndarray | float) -> np.ndarray:
    """Student's t 97.5 % quantile for ``df`` degrees of freedom (NaN where df < 1)."""
    df = np.asarray(df, dtype=np.float64)
    safe = np.where(df >= 1, df, 1.0)
    return np.where(df >= 1, stdtrit(safe, 0.975), math.nan)


def wilson_interval(k: int, n: int, z: float = Z_975) -> tuple[float, float] | None:
    """95 % Wilson score interval of the proportion k / n (None when n = 0)."""
    if n <= 0:
        return None
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    low = 0.0 if k <= 0 else max(0.0, centre - half)  # exact at the ends, no 1e-17
    high = 1.0 if k >= n else min(1.0, centre + half)
    return low, high


def grouped_mean_ci(
    values: np.ndarray, index: np.ndarray, groups: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per group: count of finite values, their mean and the half-width of the 95 % t
    interval (NaN for fewer than two values). Two passes (mean, then squared deviations),
    so large values keep their precision."""
    ok = np.isfinite(values)
    idx, x = index[ok], values[ok]
    n = np.bincount(idx, minlength=groups).astype(np.float64)
    total = np.bincount(idx, weights=x, minlength=groups)
    mean = np.divide(total, n, out=np.full(groups, math.nan), where=n > 0)
    dev = x - mean[idx]
    squares = np.bincount(idx, weights=dev * dev, minlength=groups)
    var = np.divide(squares, n - 1, out=np.full(groups, math.nan), where=n > 1)
    half = t_quantile_975(n - 1) * np.sqrt(var) / np.sqrt(np.maximum(n, 1))
    return n, mean, half


def grouped_median(values: np.ndarray, index: np.ndarray, groups: int) -> np.ndarray:
    """Per group: the median of its finite values (NaN for none). One sort, no loop."""
    ok = np.isfinite(values)
    idx, x = index[ok], values[ok]
    order = np.lexsort((x, idx))
    xs = x[order]
    n = np.bincount(idx, minlength=groups)
    start = np.cumsum(n) - n
    lo = start + np.maximum(n - 1, 0) // 2
    hi = start + n // 2
    out = np.full(groups, math.nan)
    has = n > 0
    out[has] = 0.5 * (xs[lo[has]] + xs[hi[has]])
    return out


def plan_cells(runs: pa.Table, cells: Cells, plans: pa.Table) -> np.ndarray:
    """The cell of each plan row (through its ``run_id``); -1 for a plan of no run."""
    where = pc.index_in(plans.column("run_id"), value_set=runs.column("run_id").combine_chunks())
    rows = np.asarray(pc.fill_null(where, -1).to_numpy(zero_copy_only=False), dtype=np.int64)
    return np.where(rows >= 0, cells.index[np.maximum(rows, 0)], -1)


@dataclass(frozen=True)
class MuRatio:
    """mu / (F1/F2) over a cell's plans: ``mean``, ``sd`` over ``plans`` plans, the 95 % t
    interval ``low``-``high`` over the means of its ``runs`` runs, and the mean mu."""

    mean: float
    sd: float | None
    plans: int
    low: float | None
    high: float | None
    runs: int
    mu_mean: float


@dataclass(frozen=True)
class CellSummary:
    """One grid cell of a campaign (see the module docstring for the statistics)."""

    values: dict[str, Any]
    """The cell's value of each grid key but the seed."""
    runs: int
    """Distinct runs (duplicates of a run_id dropped)."""
    measured: int
    """Runs with a finite ``mean_uncertainty``."""
    mean_uncertainty_m2: float | None
    ci_low_m2: float | None
    ci_high_m2: float | None
    bounded: int
    """Runs judged bounded (``bounded_column`` true)."""
    bounded_of: int
    """Runs with a verdict (``bounded_column`` not null)."""
    bounded_low: float | None
    bounded_high: float | None
    bounded_column: str
    solve_time_median_s: float | None
    solve_time_source: str
    """``plans`` (every adopted plan's ``solve_time_s``), ``runs`` (median of the runs'
    ``solve_time_median_s``) or ``none``."""
    ratio_bounded: int = 0
    """Runs the first, unsound test (``bounded``: boundedness_ratio <= 1.5) calls bounded,
    when ``bounded_column`` is ``bounded_trend`` (else 0)."""
    ratio_bounded_of: int = 0
    growth: EnsembleGrowth | None = None
    """Growth over the second half of the cell's mean curve (module docstring); None
    without series."""
    mu_ratio: MuRatio | None = None
    """mu / (F1/F2) over the cell's plans (module docstring); None without plans."""

    def label(self, keys: Sequence[str] | None = None) -> str:
        """``uavs=3, objective=sequence`` over ``keys`` (default: all of the cell's)."""
        names = list(self.values) if keys is None else list(keys)
        return ", ".join(f"{k}={show_value(self.values[k])}" for k in names) or "all runs"


def _optional(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def summarise_cells(
    runs: pa.Table,
    plans: pa.Table | None = None,
    grid_keys: Sequence[str] | None = None,
    grid: Mapping[str, Any] | None = None,
) -> list[CellSummary]:
    """One :class:`CellSummary` per grid cell of ``runs`` (a ``runs.parquet`` table; rows
    repeating a ``run_id`` are dropped here), in :func:`group_cells`' order. ``grid_keys``:
    the campaign file's grid keys (default: those ``gcs campaign`` records in the Parquet
    metadata, else :func:`grid_keys_of` the columns); ``plans``:
    the ``plans.parquet`` table, for the median solve time over every plan; ``grid``: the
    campaign file's ``grid`` mapping, whose lists order the cells (default: by value)."""
    runs, _ = dedupe(runs, ["run_id"])
    declared = grid_keys or (list(grid) if grid else None) or recorded_grid_keys(runs)
    keys = grid_keys_of(runs.column_names, declared)
    cells = group_cells(runs, keys, grid)
    return summaries_of(runs, cells, plans)


def summaries_of(runs: pa.Table, cells: Cells, plans: pa.Table | None) -> list[CellSummary]:
    """:func:`summarise_cells` for runs already deduplicated and grouped."""
    g = cells.count
    counts = np.bincount(cells.index, minlength=g)
    n, mean, half = grouped_mean_ci(float_column(runs, "mean_uncertainty"), cells.index, g)
    bounded_column = "bounded_trend" if "bounded_trend" in runs.column_names else "bounded"
    verdict = float_column(runs, bounded_column)
    judged = np.isfinite(verdict)
    bounded_of = np.bincount(cells.index[judged], minlength=g)
    bounded = np.bincount(cells.index[judged], weights=verdict[judged] > 0.5, minlength=g)
    ratio_bounded: np.ndarray = np.zeros(g)
    ratio_of: np.ndarray = np.zeros(g)
    if bounded_column == "bounded_trend" and "bounded" in runs.column_names:
        first = float_column(runs, "bounded")
        has = np.isfinite(first)
        ratio_of = np.bincount(cells.index[has], minlength=g)
        ratio_bounded = np.bincount(cells.index[has], weights=first[has] > 0.5, minlength=g)
    growth = cell_growth(runs, cells)
    ratios = mu_ratios(runs, cells, plans)
    source = "none"
    solve = np.full(g, math.nan)
    if plans is not None and plans.num_rows and "solve_time_s" in plans.column_names:
        where = plan_cells(runs, cells, plans)
        keep = where >= 0
        solve = grouped_median(float_column(plans, "solve_time_s")[keep], where[keep], g)
        source = "plans"
    elif "solve_time_median_s" in runs.column_names:
        solve = grouped_median(float_column(runs, "solve_time_median_s"), cells.index, g)
        source = "runs"
    out: list[CellSummary] = []
    for c in range(g):
        interval = wilson_interval(int(bounded[c]), int(bounded_of[c]))
        has_ci = n[c] >= 2
        out.append(
            CellSummary(
                values=dict(cells.values[c]),
                runs=int(counts[c]),
                measured=int(n[c]),
                mean_uncertainty_m2=_optional(mean[c]),
                ci_low_m2=_optional(mean[c] - half[c]) if has_ci else None,
                ci_high_m2=_optional(mean[c] + half[c]) if has_ci else None,
                bounded=int(bounded[c]),
                bounded_of=int(bounded_of[c]),
                bounded_low=interval[0] if interval else None,
                bounded_high=interval[1] if interval else None,
                bounded_column=bounded_column,
                solve_time_median_s=_optional(solve[c]),
                solve_time_source=source if math.isfinite(solve[c]) else "none",
                ratio_bounded=int(ratio_bounded[c]),
                ratio_bounded_of=int(ratio_of[c]),
                growth=None if growth is None else growth[c],
                mu_ratio=None if ratios is None else ratios[c],
            )
        )
    return out


def cell_growth(runs: pa.Table, cells: Cells) -> list[EnsembleGrowth] | None:
    """Per cell, the growth over the second half of its runs' mean curve with its bootstrap
    interval (module docstring); None without the series columns."""
    if not {"series_t_s", "series_mean_sigma"} <= set(runs.column_names):
        return None
    times = runs.column("series_t_s").to_pylist()
    values = runs.column("series_mean_sigma").to_pylist()
    thirds: list[list[tuple[float, float]]] = [[] for _ in range(cells.count)]
    for r, (t, v) in enumerate(zip(times, values, strict=True)):
        if not t or not v:
            continue
        pair = third_means(t, v)
        if pair is not None:
            thirds[int(cells.index[r])].append(pair)
    return [ensemble_growth(pairs) for pairs in thirds]


def mu_ratios(runs: pa.Table, cells: Cells, plans: pa.Table | None) -> list[MuRatio | None] | None:
    """Per cell, :class:`MuRatio` over its plans with f1 and mu not 0 (module docstring);
    None without plans or without their mu, f1, f2 columns; a cell without such a plan
    gets None."""
    if plans is None or not plans.num_rows or not {"mu", "f1", "f2"} <= set(plans.column_names):
        return None
    mu, f1, f2 = (float_column(plans, k) for k in ("mu", "f1", "f2"))
    ok = np.isfinite(mu) & np.isfinite(f1) & np.isfinite(f2) & (mu != 0) & (f1 != 0)
    where = plan_cells(runs, cells, plans)
    run_of = pc.index_in(plans.column("run_id"), value_set=runs.column("run_id").combine_chunks())
    run_index = np.asarray(pc.fill_null(run_of, -1).to_numpy(zero_copy_only=False), np.int64)
    ok &= (where >= 0) & (run_index >= 0)
    ratio = np.divide(f2, f1, out=np.full(len(f1), math.nan), where=ok)
    g = cells.count
    n, mean, _ = grouped_mean_ci(ratio[ok], where[ok], g)
    sd = np.sqrt(np.maximum(grouped_mean_ci_var(ratio[ok], where[ok], g), 0.0))
    _, mu_mean, _ = grouped_mean_ci(mu[ok], where[ok], g)
    _, run_mean, _ = grouped_mean_ci(ratio[ok], run_index[ok], runs.num_rows)
    has_run = np.isfinite(run_mean)
    rn, rmean, rhalf = grouped_mean_ci(run_mean[has_run], cells.index[has_run], g)
    out: list[MuRatio | None] = []
    for c in range(g):
        if n[c] == 0:
            out.append(None)
            continue
        interval = rn[c] >= 2 and math.isfinite(rhalf[c])
        out.append(MuRatio(
            mean=float(mean[c]), sd=_optional(sd[c]) if n[c] > 1 else None, plans=int(n[c]),
            low=float(rmean[c] - rhalf[c]) if interval else None,
            high=float(rmean[c] + rhalf[c]) if interval else None,
            runs=int(rn[c]), mu_mean=float(mu_mean[c]),
        ))
    return out


def grouped_mean_ci_var(values: np.ndarray, index: np.ndarray, groups: int) -> np.ndarray:
    """Per group: the sample variance (n - 1) of its finite values (NaN for fewer than 2)."""
    n, _, half = grouped_mean_ci(values, index, groups)
    t = t_quantile_975(n - 1)
    return np.asarray(np.square(half * np.sqrt(np.maximum(n, 1)) / t), dtype=np.float64)


TREND_BOUNDS = (0.25, 0.4, 0.5, 0.6)
"""Bounds of the trend test counted by :func:`trend_counts` (0.5 is ``bounded_trend``'s)."""


@dataclass
class TrendCounts:
    """Per cell: the median ``trend`` and how many runs have a trend at most each bound
    (docs/planner.md "Figure 4 at the ensemble level": the table that chose the bound 0.5)."""

    bounds: tuple[float, ...]
    median: np.ndarray
    """(cells,), NaN for a cell without a trend."""
    passing: np.ndarray
    """(cells, bounds): runs with ``trend <= bound``."""
    of: np.ndarray
    """(cells,): runs with a trend (not null: long enough)."""


def trend_counts(
    runs: pa.Table, cells: Cells, bounds: Sequence[float] = TREND_BOUNDS
) -> TrendCounts | None:
    """:class:`TrendCounts` from the runs' ``trend`` column; None without one."""
    if "trend" not in runs.column_names:
        return None
    trend = float_column(runs, "trend")
    ok = np.isfinite(trend)
    if not ok.any():
        return None
    idx, x = cells.index[ok], trend[ok]
    passing = np.stack(
        [np.bincount(idx, weights=x <= b, minlength=cells.count) for b in bounds], axis=1
    )
    return TrendCounts(
        tuple(bounds),
        grouped_median(x, idx, cells.count),
        passing.astype(np.int64),
        np.bincount(idx, minlength=cells.count),
    )


@dataclass
class SeriesBands:
    """Per cell and mission time: how many runs have a point, their mean and the 95 % t
    interval of that mean (NaN where fewer than two runs)."""

    t_s: np.ndarray
    """Mission times (s), shape (T,)."""
    count: np.ndarray
    """(cells, T)."""
    mean: np.ndarray
    low: np.ndarray
    high: np.ndarray
    step_s: int
    """Seconds between two points (1, or more for runs longer than MAX_SERIES_POINTS s)."""
    dropped_runs: int
    """Runs whose time and value lists differ in length (left out)."""


def _flat(column: pa.ChunkedArray) -> tuple[np.ndarray, np.ndarray]:
    lengths = pc.fill_null(pc.list_value_length(column), 0)
    flat = pc.cast(pc.list_flatten(column), pa.float64())
    return (
        np.asarray(lengths.to_numpy(zero_copy_only=False), dtype=np.int64),
        np.asarray(flat.to_numpy(zero_copy_only=False), dtype=np.float64),
    )


def series_bands(
    runs: pa.Table, cells: Cells, max_points: int = MAX_SERIES_POINTS
) -> SeriesBands | None:
    """The mean-uncertainty series of every cell, mean over its runs at each mission
    second (``series_t_s`` rounded to whole seconds) with the 95 % t band. None without
    the series columns (or with columns that are not lists of numbers) or points.
    Vectorised: one ``bincount`` over every point of every run, no loop over runs or
    points."""
    if not {"series_t_s", "series_mean_sigma"} <= set(runs.column_names):
        return None
    try:
        len_t, t = _flat(runs.column("series_t_s"))
        len_v, v = _flat(runs.column("series_mean_sigma"))
    except (pa.ArrowException, TypeError):  # not lists of numbers: no series to draw
        return None
    same = len_t == len_v
    dropped = int(np.count_nonzero(~same & ((len_t > 0) | (len_v > 0))))
    if not same.all():  # keep the points of runs whose lists agree
        t = t[np.repeat(same, len_t)]
        v = v[np.repeat(same, len_v)]
        len_t = np.where(same, len_t, 0)
    cell = np.repeat(cells.index, len_t)
    second = np.rint(t)
    ok = np.isfinite(second) & (second >= 0) & np.isfinite(v)
    if not ok.any():
        return None
    second = second[ok].astype(np.int64)
    cell, v = cell[ok], v[ok]
    step_s = max(1, math.ceil((int(second.max()) + 1) / max_points))
    if step_s > 1:  # every step_s-th second, so each run still has one point per time
        keep = second % step_s == 0
        second, cell, v = second[keep] // step_s, cell[keep], v[keep]
    width = int(second.max()) + 1
    n, mean, half = grouped_mean_ci(v, cell * width + second, cells.count * width)
    shape = (cells.count, width)
    n, mean, half = n.reshape(shape), mean.reshape(shape), half.reshape(shape)
    return SeriesBands(
        t_s=np.arange(width, dtype=np.float64) * step_s,
        count=n.astype(np.int64),
        mean=mean,
        low=mean - half,
        high=mean + half,
        step_s=step_s,
        dropped_runs=dropped,
    )
