"""The per-cell summary of a campaign as a text table: for the report's page and for a
terminal (the end-of-run table of ``gcs campaign``). No matplotlib here.

    summaries = summarise_cells(runs, plans, grid_keys)    # stats
    header, rows = cell_table(summaries, ["uavs", "objective"])
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from groundstation.runners.campaign.stats import CellSummary, show_value

__all__ = ["cell_table", "format_number"]


def format_number(value: float | None) -> str:
    """``6,008`` for a large value, three significant digits for a small one; ``-`` for
    none."""
    if value is None or not math.isfinite(value):
        return "-"
    return f"{value:,.0f}" if abs(value) >= 100 else f"{value:.3g}"


def cell_table(
    summaries: Sequence[CellSummary], keys: Sequence[str]
) -> tuple[list[str], list[list[str]]]:
    """The summary table as text: a header and one row per cell (``keys`` first), for the
    page and for a terminal (the campaign engine's end-of-run table)."""
    column = summaries[0].bounded_column if summaries else "bounded_trend"
    solve_from = {s.solve_time_source for s in summaries} - {"none"}
    solve_word = {frozenset(): "", frozenset({"plans"}): " (plans)"}.get(
        frozenset(solve_from), " (runs' medians)"
    )
    first_test = any(s.ratio_bounded_of for s in summaries)
    header = [
        *keys,
        "runs",
        "mean sigma (m^2)",
        "95 % CI",
        f"bounded ({column})",
        "95 % Wilson",
        f"median solve s{solve_word}",
        *(["first test (ratio)"] if first_test else []),
    ]
    rows: list[list[str]] = []
    for s in summaries:
        ci = (
            f"{format_number(s.ci_low_m2)} - {format_number(s.ci_high_m2)}"
            if s.ci_low_m2 is not None
            else "-"
        )
        wilson = (
            f"{100 * s.bounded_low:.0f}-{100 * s.bounded_high:.0f} %"
            if s.bounded_low is not None and s.bounded_high is not None
            else "-"
        )
        runs = str(s.runs) if s.measured == s.runs else f"{s.runs} ({s.runs - s.measured} no value)"
        rows.append(
            [
                *(show_value(s.values.get(k)) for k in keys),
                runs,
                format_number(s.mean_uncertainty_m2),
                ci,
                f"{s.bounded}/{s.bounded_of}",
                wilson,
                format_number(s.solve_time_median_s),
                *([f"{s.ratio_bounded}/{s.ratio_bounded_of}"] if first_test else []),
            ]
        )
    return header, rows
