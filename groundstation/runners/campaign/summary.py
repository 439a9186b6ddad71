"""The end-of-campaign summary: per grid cell, means with 95 % confidence intervals.

A *cell* is one combination of the grid keys other than ``seed`` that take more than one
value (the seeds are the repetitions). For a figure x over the n runs of a cell the
interval is Student's t: mean +- t(0.975, n - 1) s / sqrt(n) (none for n < 2). Booleans
(``bounded_trend``: trend <= 0.5) are counted, k of the n runs that have a value. The
verdict on the paper's Figure 4 is ``growth``: the cell's mean curve over the last third of
the mission divided by its middle third, with a 95 % bootstrap interval over the seeds
(:func:`groundstation.core.metrics.ensemble_growth`).
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from groundstation.core.metrics import EnsembleGrowth, ensemble_growth, third_means

__all__ = ["SUMMARY_FIGURES", "CellMeans", "summarise", "t_half_width"]

SUMMARY_FIGURES = ("mean_uncertainty", "final_uncertainty", "visits", "lost_targets")


@dataclass(frozen=True)
class CellMeans:
    """One cell: its coordinates, its run count, (mean, half width) per figure, how many
    runs had trend <= 0.5 out of those with a trend, and the growth over the second half
    of the cell's mean curve (module docstring)."""

    cell: dict[str, Any]
    runs: int
    figures: dict[str, tuple[float, float | None]]
    bounded: int
    bounded_of: int
    growth: EnsembleGrowth | None = None


def t_half_width(values: Sequence[float]) -> float | None:
    """Half width of the 95 % Student-t interval of the mean; None below 2 values."""
    n = len(values)
    if n < 2:
        return None
    from groundstation.runners.campaign.stats import t_quantile_975  # the report's quantile

    return float(t_quantile_975(n - 1)) * statistics.stdev(values) / math.sqrt(n)


def summarise(
    rows: Sequence[Mapping[str, Any]], grid: Mapping[str, Sequence[Any]]
) -> tuple[list[str], list[CellMeans]]:
    """The varying keys (cell columns) and one summary per cell, in grid order."""
    keys = [k for k, values in grid.items() if k != "seed" and len(values) > 1]
    order = {k: {_marker(v): i for i, v in enumerate(grid[k])} for k in keys}
    cells: dict[tuple[Any, ...], list[Mapping[str, Any]]] = {}
    for row in rows:
        cells.setdefault(tuple(_marker(row.get(k)) for k in keys), []).append(row)

    def position(item: tuple[tuple[Any, ...], list[Mapping[str, Any]]]) -> tuple[int, ...]:
        return tuple(order[k].get(m, len(order[k])) for k, m in zip(keys, item[0], strict=True))

    out: list[CellMeans] = []
    for _, members in sorted(cells.items(), key=position):
        figures: dict[str, tuple[float, float | None]] = {}
        for name in SUMMARY_FIGURES:
            values = [float(r[name]) for r in members if r.get(name) is not None]
            if values:
                figures[name] = (statistics.fmean(values), t_half_width(values))
        verdicts = [r["bounded_trend"] for r in members if r.get("bounded_trend") is not None]
        thirds = [
            pair for r in members
            if (pair := third_means(r.get("series_t_s") or [], r.get("series_mean_sigma") or []))
            is not None
        ]
        out.append(CellMeans(
            cell={k: members[0].get(k) for k in keys}, runs=len(members), figures=figures,
            bounded=sum(bool(v) for v in verdicts), bounded_of=len(verdicts),
            growth=ensemble_growth(thirds) if thirds else None,
        ))
    return keys, out


def _marker(value: Any) -> Any:
    """A hashable stand-in that makes 5 and 5.0 one cell."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return value if isinstance(value, str | bool | type(None)) else repr(value)
    return float(value)
