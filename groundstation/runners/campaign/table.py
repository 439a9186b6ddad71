"""The per-cell summary of a campaign as a text table: for the report's page and for a
terminal (the end-of-run table of ``gcs campaign``). No matplotlib here.

    summaries = summarise_cells(runs, plans, grid_keys)    # stats
    header, rows = cell_table(summaries, ["uavs", "objective"])
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from groundstation.runners.campaign.stats import CellSummary, show_value

__all__ = ["cell_table", "format_number", "text_table"]


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
    page and for a terminal (the campaign engine's end-of-run table). The Figure 4 verdict
    is the ensemble's growth over the second half with its bootstrap interval; the count
    of runs under the trend threshold (``bounded_trend``: trend <= 0.5) is named for what
    it counts, not "bounded"."""
    column = summaries[0].bounded_column if summaries else "bounded_trend"
    threshold = "runs trend <= 0.5" if column == "bounded_trend" else "runs ratio <= 1.5"
    solve_from = {s.solve_time_source for s in summaries} - {"none"}
    solve_word = {frozenset(): "", frozenset({"plans"}): " (plans)"}.get(
        frozenset(solve_from), " (runs' medians)"
    )
    first_test = any(s.ratio_bounded_of for s in summaries)
    with_growth = any(s.growth is not None for s in summaries)
    with_mu = any(s.mu_ratio is not None for s in summaries)
    header = [
        *keys,
        "runs",
        "mean sigma (m^2)",
        "95 % CI",
        *(["growth 2nd half (last/middle third) [95 % CI]"] if with_growth else []),
        threshold,
        "95 % Wilson",
        f"median solve s{solve_word}",
        *(["runs ratio <= 1.5"] if first_test else []),
        *(["mu/(F1/F2) mean +- sd (plans)", "95 % CI (runs)"] if with_mu else []),
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
        mu = s.mu_ratio
        mu_cells = ["-", "-"]
        if mu is not None:
            sd = "" if mu.sd is None else f" +- {mu.sd:.2f}"
            mu_cells = [f"{mu.mean:.2f}{sd} ({mu.plans})",
                        "-" if mu.low is None or mu.high is None
                        else f"{mu.low:.2f} - {mu.high:.2f}"]
        rows.append(
            [
                *(show_value(s.values.get(k)) for k in keys),
                runs,
                format_number(s.mean_uncertainty_m2),
                ci,
                *([s.growth.text() if s.growth is not None else "-"] if with_growth else []),
                f"{s.bounded}/{s.bounded_of}",
                wilson,
                format_number(s.solve_time_median_s),
                *([f"{s.ratio_bounded}/{s.ratio_bounded_of}"] if first_test else []),
                *(mu_cells if with_mu else []),
            ]
        )
    return header, rows


def text_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """Rows as lines of columns padded to their widest cell, two spaces apart."""
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    return ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
            for r in [header, *rows]]
