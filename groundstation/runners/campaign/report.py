"""``gcs campaign report DIR``: one self-contained HTML page about a campaign.

:func:`write_campaign_report` reads the campaign folder
(:mod:`~groundstation.runners.campaign.data`), summarises each grid cell
(:mod:`~groundstation.runners.campaign.stats`), draws the figures
(:mod:`~groundstation.runners.campaign.plots`) and writes ``DIR/report.html`` (or
``out``) with every figure inline as a PNG ``data:`` URI
(:mod:`~groundstation.runners.html_page`, shared with ``gcs report``): the page has no
external asset. Each figure is also written next to the page as
``<page stem>-<figure>.png`` (``report-series.png``...), for papers and docs.

The page: the campaign (name, grid, fixed overrides, runs, floe versions, when written);
a table per grid cell (runs, mean of ``mean_uncertainty`` with its 95 % t interval, the
growth over the second half of the cell's mean curve with its bootstrap interval, runs with
trend <= 0.5 with its 95 % Wilson interval, median solve time, mu / (F1/F2) over the plans;
every number also in the cell's ``data-value`` attribute at full precision); mean
uncertainty against fleet size; the paper's Figure 4 (mean uncertainty over mission time,
mean over seeds with a 95 % band);
solve-time distributions; the distribution of mu / (F1 / F2) over adopted plans (eq. 18).
"""

from __future__ import annotations

import datetime as dt
import html
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from groundstation.runners.campaign.data import (
    SEED_KEY,
    CampaignData,
    CampaignReportError,
    column_codes,
    float_column,
    load_campaign,
)
from groundstation.runners.campaign.paired import PairedRow, paired_with_base
from groundstation.runners.campaign.stats import (
    Cells,
    CellSummary,
    TrendCounts,
    group_cells,
    series_bands,
    show_value,
    summaries_of,
    summarise_cells,
    trend_counts,
)
from groundstation.runners.campaign.table import cell_table, text_table
from groundstation.runners.html_page import figure_html, page_start
from groundstation.storage import StorageError, atomic_write_bytes, atomic_write_text

if TYPE_CHECKING:
    from groundstation.runners.campaign.plots import Panel

__all__ = [
    "CampaignReportError",
    "CellSummary",
    "summarise_cells",
    "write_campaign_report",
]


def _data_values(s: CellSummary, summaries: Sequence[CellSummary]) -> list[str]:
    """The full-precision numbers behind a row's numeric cells (``data-value``), one per
    column of :func:`cell_table` (the optional columns when any cell has them)."""

    def full(*values: float | None) -> str:
        return ",".join("" if v is None else repr(float(v)) for v in values)

    growth = s.growth
    mu = s.mu_ratio
    out = [str(s.runs), full(s.mean_uncertainty_m2), full(s.ci_low_m2, s.ci_high_m2)]
    if any(c.growth is not None for c in summaries):
        out.append("" if growth is None else full(growth.value, growth.low, growth.high))
    out += [
        f"{s.bounded},{s.bounded_of}",
        full(s.bounded_low, s.bounded_high),
        full(s.solve_time_median_s),
    ]
    if any(c.ratio_bounded_of for c in summaries):
        out.append(f"{s.ratio_bounded},{s.ratio_bounded_of}")
    if any(c.mu_ratio is not None for c in summaries):
        out += (["", ""] if mu is None
                else [full(mu.mean, mu.sd) + f",{mu.plans}", full(mu.low, mu.high)])
    return out


def _distinct_text(data: CampaignData, column: str) -> str:
    if column not in data.runs.column_names:
        return "-"
    return ", ".join(str(v) for v in column_codes(data.runs.column(column))[1]) or "-"


def _header_rows(
    data: CampaignData, cells: Cells, written_at: dt.datetime
) -> list[tuple[str, str]]:
    runs = data.runs
    rows = [("campaign", data.name), ("folder", str(data.folder))]
    for key, value in data.grid.items():
        rows.append((f"grid: {key}", show_value(value)))
    for key, value in data.fixed.items():
        rows.append((f"set: {key}", show_value(value)))
    extra = (
        f" ({data.duplicate_runs} duplicate row(s) of a run_id dropped)"
        if data.duplicate_runs
        else ""
    )
    rows.append(("runs", f"{runs.num_rows}{extra}"))
    seeds = ""
    if SEED_KEY in runs.column_names:
        seeds = f", {len(column_codes(runs.column(SEED_KEY))[1])} seed(s)"
    rows.append(("grid cells", f"{cells.count} (seed aside){seeds}"))
    if data.plans is None:
        rows.append(("plans", "not kept (per_plan: false)"))
    else:
        dup = f" ({data.duplicate_plans} duplicate row(s) dropped)" if data.duplicate_plans else ""
        rows.append(("plans", f"{data.plans.num_rows}{dup}"))
    rows.append(("floe version(s)", _distinct_text(data, "floe_version")))
    for column, word in (("wall_s", "wall time of the runs"), ("cpu_s", "CPU time of the runs")):
        total = float(np.nansum(float_column(runs, column)))
        if column in runs.column_names:
            rows.append(
                (word, f"{total:,.0f} s" + (f" ({total / 3600:.1f} h)" if total >= 3600 else ""))
            )
    if "worker" in runs.column_names:
        rows.append(("workers", str(len(column_codes(runs.column("worker"))[1]))))
    rows.append(("report written", written_at.strftime("%Y-%m-%d %H:%M:%S %Z").strip()))
    return rows


def _trend_html(trends: TrendCounts | None, cells: Cells, keys: Sequence[str]) -> list[str]:
    """Runs under each trend bound per cell (docs/planner.md "Figure 4 at the ensemble level")."""
    if trends is None:
        return []
    esc = html.escape
    out = [
        "<h2>Trend test at other bounds</h2>",
        '<table id="trend"><tr>'
        + "".join(f"<th>{esc(k)}</th>" for k in keys)
        + "<th>median trend</th>"
        + "".join(f"<th>trend &lt;= {b:g}</th>" for b in trends.bounds)
        + "</tr>",
    ]
    for c, values in enumerate(cells.values):
        med = float(trends.median[c])
        med_text = "-" if math.isnan(med) else f"{med:.2f}"
        out.append(
            "<tr>"
            + "".join(f"<td>{esc(show_value(values[k]))}</td>" for k in keys)
            + f'<td class="num" data-value="{med!r}">{med_text}</td>'
            + "".join(
                f'<td class="num">{int(k)}/{int(trends.of[c])}</td>' for k in trends.passing[c]
            )
            + "</tr>"
        )
    out.append(
        "</table><p>trend: the growth over the second half of a run that a robust (Theil-Sen) "
        "slope of its 10 s means predicts, relative to its level (metrics.json "
        "bounded_trend is trend &lt;= 0.5: a threshold on a rate, not a test of "
        "boundedness).</p>"
    )
    return out


def _pct(value: float | None) -> str:
    return "-" if value is None else f"{value:+.1f}"


def _paired_html(paired: Sequence[PairedRow] | None) -> list[str]:
    """The paired table (``paired``), or nothing when no variant key varies."""
    if not paired:
        return []
    esc = html.escape
    first = paired[0]
    base = ", ".join(f"{k}={show_value(v)}" for k, v in first.base.items())
    keys = [*first.block, *first.variant]
    out = [
        f"<h2>Paired against {esc(base)} (same seed)</h2>",
        '<table id="paired"><tr>'
        + "".join(f"<th>{esc(k)}</th>" for k in keys)
        + f"<th>pairs</th><th>vs {esc(base)}, % (95 % CI)</th><th>wins/losses</th></tr>",
    ]
    for row in paired:
        values = {**row.block, **row.variant}
        ci = (
            f" [{_pct(row.ci_low_pct)}, {_pct(row.ci_high_pct)}]"
            if row.ci_low_pct is not None
            else ""
        )
        full = ",".join(
            "" if v is None else repr(v) for v in (row.mean_pct, row.ci_low_pct, row.ci_high_pct)
        )
        out.append(
            "<tr>"
            + "".join(f"<td>{esc(show_value(values[k]))}</td>" for k in keys)
            + f'<td class="num">{row.pairs}</td>'
            + f'<td class="num" data-value="{esc(full)}">{esc(_pct(row.mean_pct))} %{esc(ci)}</td>'
            + f'<td class="num" data-value="{row.wins},{row.losses}">{row.wins}/{row.losses}</td>'
            + "</tr>"
        )
    out.append("</table>")
    out.append(
        "<p>Each seed's run against the base variant's run of the same seed and block: mean "
        "of 100 (mean_uncertainty / base's - 1), 95 % Student t interval; wins/losses: seeds "
        "where the variant is lower/higher.</p>"
    )
    return out


def render_campaign_html(
    data: CampaignData,
    cells: Cells,
    summaries: Sequence[CellSummary],
    panels: Sequence[Panel],
    written_at: dt.datetime,
    paired: Sequence[PairedRow] | None = None,
    trends: TrendCounts | None = None,
) -> str:
    """The page (see the module docstring)."""
    esc = html.escape
    out = page_start(f"floe campaign: {data.name}", f"floe campaign report: {data.name}")
    out.append('<table id="campaign">')
    for name, value in _header_rows(data, cells, written_at):
        out.append(f"<tr><th>{esc(name)}</th><td>{esc(value)}</td></tr>")
    out.append("</table>")
    if data.warnings:
        out.append('<ul class="warn">' + "".join(f"<li>{esc(w)}</li>" for w in data.warnings))
        out.append("</ul>")
    keys = cells.varying or cells.keys
    header, rows = cell_table(summaries, keys)
    out.append("<h2>Per grid cell</h2>")
    out.append('<table id="cells"><tr>' + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr>")
    for s, row in zip(summaries, rows, strict=True):
        cells_html = [f"<td>{esc(v)}</td>" for v in row[: len(keys)]]
        cells_html += [
            f'<td class="num" data-value="{esc(full)}">{esc(text)}</td>'
            for text, full in zip(row[len(keys) :], _data_values(s, summaries), strict=True)
        ]
        out.append("<tr>" + "".join(cells_html) + "</tr>")
    out.append("</table>")
    out.append(
        "<p>mean sigma: mean over the cell's runs of their mean_uncertainty (the average "
        "uncertainty over the targets and the mission), 95 % Student t interval. Growth over "
        "the second half: the cell's mean curve (over its seeds) averaged over the last "
        "third of the mission divided by its average over the middle third (1: level; 2: "
        "doubled), with the 95 % percentile bootstrap interval over the seeds "
        "(groundstation/core/metrics.py, ensemble_growth); the verdict on the paper's "
        "Figure 4. runs trend &lt;= 0.5: runs whose own growth rate (trend) is at most 0.5, "
        "95 % Wilson interval; a threshold on a rate, not a test of boundedness (sqrt(t) "
        "passes it). mu/(F1/F2): eq. 18's mu over the realised F1/F2' of each adopted plan "
        "(f2 / f1; plans with f1 or mu 0 left out), mean and sd over the plans, 95 % t "
        "interval over the runs' means.</p>"
    )
    out += _trend_html(trends, cells, keys)
    out += _paired_html(paired)
    for panel in panels:
        if panel.figure is not None:
            out.append(figure_html(panel.figure, caption=panel.caption))
        else:
            out.append(
                f'<h2>{esc(panel.title)}</h2><p class="note" id="note-{esc(panel.name)}">'
                f"{esc(panel.reason)}</p>"
            )
    out.append("</body></html>")
    return "\n".join(out) + "\n"


def write_campaign_report(
    campaign_dir: Path,
    out: Path | None = None,
    *,
    written_at: dt.datetime | None = None,
    say: Callable[[str], None] | None = None,
) -> Path:
    """Write the report of ``campaign_dir`` to ``out`` (default
    ``campaign_dir/report.html``) and its figures as PNGs beside it; return the page's
    path. Raises :class:`CampaignReportError` (one line) when the folder is missing, empty
    or unreadable, or the page cannot be written. ``written_at`` (default: now, UTC) is
    printed in the header."""
    note = say or (lambda text: None)
    campaign_dir = Path(campaign_dir)
    data = load_campaign(campaign_dir)
    note(f"{data.runs.num_rows} runs read")
    cells = group_cells(data.runs, data.grid_keys, data.grid)
    summaries = summaries_of(data.runs, cells, data.plans)
    for line in text_table(*cell_table(summaries, cells.varying or cells.keys)):
        note(line)
    # matplotlib (0.6-1 CPU-s to import) only once the table is out and the plots are due
    from groundstation.runners.campaign.plots import (
        plot_mean_vs_fleet,
        plot_mu_ratio,
        plot_series,
        plot_solve_times,
    )

    panels = [
        plot_mean_vs_fleet(summaries, cells),
        plot_series(series_bands(data.runs, cells), cells),
        plot_solve_times(data, cells),
        plot_mu_ratio(data, cells),
    ]
    when = written_at or dt.datetime.now(dt.UTC)
    page = Path(out) if out is not None else campaign_dir / "report.html"
    try:
        page.parent.mkdir(parents=True, exist_ok=True)
        for panel in panels:
            if panel.figure is not None:
                atomic_write_bytes(
                    page.with_name(f"{page.stem}-{panel.figure.name}.png"), panel.figure.png
                )
        paired = paired_with_base(data.runs, cells)
        trends = trend_counts(data.runs, cells)
        html_text = render_campaign_html(data, cells, summaries, panels, when, paired, trends)
        atomic_write_text(page, html_text)
    except StorageError as exc:
        raise CampaignReportError(str(exc)) from None
    except OSError as exc:
        raise CampaignReportError(f"cannot write {page}: {exc.strerror or exc}") from None
    return page
