"""The figures of a campaign report (matplotlib object API, PNG bytes).

Each ``plot_*`` returns a :class:`Panel`: a figure, or no figure and the sentence that says
why (the page prints it in the figure's place), plus a caption. ``info`` of each figure
says what was drawn (curves, runs, plans), for checks.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyarrow.compute as pc
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from groundstation.runners.campaign.data import CampaignData, float_column
from groundstation.runners.campaign.stats import (
    Cells,
    CellSummary,
    SeriesBands,
    plan_cells,
    show_value,
)
from groundstation.runners.html_page import FigurePng, render_png
from groundstation.runners.report.plots import COLOURS

__all__ = [
    "Panel",
    "plot_mean_vs_fleet",
    "plot_mu_ratio",
    "plot_series",
    "plot_solve_times",
]

FLEET_KEY = "uavs"
MAX_PANELS = 12
"""Most sub-plots of the series figure (one per combination of the other varying keys)."""
MAX_BOXES = 60
"""Most boxes of the solve-time figure."""
LOG_RATIO = 20.0
"""A value axis is logarithmic when its largest positive value is this many times its
smallest."""


@dataclass
class Panel:
    """A figure, or none and why; ``caption`` goes under it."""

    name: str
    title: str
    figure: FigurePng | None
    caption: str = ""
    reason: str = ""


def _colour(k: int) -> str:
    return COLOURS[k % len(COLOURS)]


def _maybe_log(ax: Axes, values: Sequence[float] | np.ndarray, axis: str = "y") -> None:
    arr = np.asarray(values, dtype=np.float64)
    positive = arr[np.isfinite(arr) & (arr > 0)]
    if positive.size and positive.max() / positive.min() > LOG_RATIO:
        (ax.set_yscale if axis == "y" else ax.set_xscale)("log")


def _groups(cells: Cells, without: Sequence[str]) -> dict[tuple[str, ...], list[int]]:
    """Cells grouped by their values of the varying keys not in ``without`` (in cell
    order); the key is the tuple of ``key=value`` texts."""
    keys = [k for k in cells.varying if k not in without]
    out: dict[tuple[str, ...], list[int]] = {}
    for c, values in enumerate(cells.values):
        out.setdefault(tuple(f"{k}={show_value(values[k])}" for k in keys), []).append(c)
    return out


def _fleet_varies(cells: Cells) -> bool:
    return FLEET_KEY in cells.varying


def plot_mean_vs_fleet(summaries: Sequence[CellSummary], cells: Cells) -> Panel:
    """Mean over seeds of the run-average uncertainty against fleet size, one line per
    combination of the other varying grid keys, 95 % t band (error bars per cell when the
    fleet size does not vary)."""
    name, title = "fleet", "Mean uncertainty against fleet size"
    fig = Figure(figsize=(9, 5.5), layout="constrained")
    ax = fig.subplots()
    lines = 0
    every: list[float] = []
    if _fleet_varies(cells):
        for k, (group, members) in enumerate(_groups(cells, [FLEET_KEY]).items()):
            xs = [float(cells.values[c][FLEET_KEY]) for c in members]
            ys = [summaries[c].mean_uncertainty_m2 for c in members]
            lo = [summaries[c].ci_low_m2 for c in members]
            hi = [summaries[c].ci_high_m2 for c in members]
            y = np.array([math.nan if v is None else v for v in ys])
            colour = _colour(k)
            ax.plot(xs, y, "o-", color=colour, label=", ".join(group) or "all runs")
            low = np.array([math.nan if v is None else v for v in lo])
            high = np.array([math.nan if v is None else v for v in hi])
            ax.fill_between(xs, low, high, color=colour, alpha=0.2, lw=0)
            every += [*y.tolist(), *low.tolist(), *high.tolist()]
            lines += 1
        ax.set_xlabel("UAVs")
        ax.set_xticks(sorted({float(v[FLEET_KEY]) for v in cells.values}))
    else:
        for c, s in enumerate(summaries):
            if s.mean_uncertainty_m2 is None:
                continue
            err = (
                [[s.mean_uncertainty_m2 - s.ci_low_m2], [s.ci_high_m2 - s.mean_uncertainty_m2]]
                if s.ci_low_m2 is not None and s.ci_high_m2 is not None
                else None
            )
            ax.errorbar(
                [c], [s.mean_uncertainty_m2], yerr=err, fmt="o", color=_colour(c), capsize=4
            )
            every += [s.mean_uncertainty_m2, s.ci_low_m2 or math.nan, s.ci_high_m2 or math.nan]
            lines += 1
        ax.set_xticks(range(len(summaries)), [cells.label(c) for c in range(len(summaries))])
        ax.tick_params(axis="x", labelrotation=30, labelsize=7)
    _maybe_log(ax, every)
    ax.set_ylabel("mean uncertainty, mean over seeds (m²)")
    ax.grid(True, which="both", alpha=0.3)
    if lines > 1 and _fleet_varies(cells):
        ax.legend(fontsize=7)
    ax.set_title("run-average uncertainty, mean over seeds; band: 95 % t interval", fontsize=9)
    png = render_png(fig)
    return Panel(
        name,
        title,
        FigurePng(name, title, png, {"lines": lines}),
        "Each point is the mean over a cell's seeds of the runs' mean_uncertainty; the band "
        "or bar is the 95 % Student t interval of that mean.",
    )


def plot_series(bands: SeriesBands | None, cells: Cells) -> Panel:
    """The paper's Figure 4: mean uncertainty against mission time, mean over seeds with a
    95 % t band, one curve per fleet size; one sub-plot per combination of the other
    varying grid keys (at most :data:`MAX_PANELS`)."""
    name, title = "series", "Mean uncertainty over mission time (the paper's Figure 4)"
    if bands is None:
        return Panel(
            name,
            title,
            None,
            reason="not shown: the runs have no series_t_s and series_mean_sigma lists.",
        )
    groups = _groups(cells, [FLEET_KEY] if _fleet_varies(cells) else cells.varying)
    shown = list(groups.items())[:MAX_PANELS]
    cols = 1 if len(shown) == 1 else 2 if len(shown) <= 4 else 3
    rows = math.ceil(len(shown) / cols)
    fig = Figure(
        figsize=(9 if cols == 1 else 4.2 * cols, 5.5 if rows == 1 else 3.3 * rows),
        layout="constrained",
    )
    axes = np.asarray(fig.subplots(rows, cols, squeeze=False, sharex=True, sharey=True)).ravel()
    curve_keys = [FLEET_KEY] if _fleet_varies(cells) else cells.varying
    curves = 0
    with np.errstate(invalid="ignore"):  # a cell without points: NaN, left out
        levels = np.nanmean(np.where(bands.count > 0, bands.mean, np.nan), axis=1)
    for ax, (group, members) in zip(axes, shown, strict=False):
        for k, c in enumerate(members):
            has = bands.count[c] > 0
            if not has.any():
                continue
            t = bands.t_s[has]
            colour = _colour(k)
            n_runs = int(bands.count[c].max())
            ax.plot(
                t,
                bands.mean[c][has],
                color=colour,
                lw=1.5,
                label=f"{cells.label(c, curve_keys)} (n={n_runs})",
            )
            ax.fill_between(t, bands.low[c][has], bands.high[c][has], color=colour, alpha=0.2, lw=0)
            curves += 1
        ax.set_title(", ".join(group) or "mean over seeds, 95 % t band", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    for ax in axes[len(shown) :]:
        ax.set_visible(False)
    _maybe_log(axes[0], levels)  # by the curves' levels: every curve starts near 0
    positive = levels[np.isfinite(levels) & (levels > 0)]
    if axes[0].get_yscale() == "log" and positive.size:  # not decades of the first seconds
        axes[0].set_ylim(bottom=float(positive.min()) / 10)
    for ax in axes[-cols:]:
        ax.set_xlabel("mission time (s)")
    for ax in axes[::cols]:
        ax.set_ylabel("mean sigma (m²)")
    caption = (
        "Mean over a cell's seeds of the runs' average uncertainty at each mission "
        f"{'second' if bands.step_s == 1 else f'{bands.step_s} s'}; band: 95 % t interval."
    )
    if len(groups) > len(shown):
        caption += f" {len(groups) - len(shown)} more panel(s) not drawn."
    if bands.dropped_runs:
        caption += f" {bands.dropped_runs} run(s) with unequal t/sigma lists left out."
    info: dict[str, Any] = {"curves": curves, "panels": len(shown), "step_s": bands.step_s}
    return Panel(name, title, FigurePng(name, title, render_png(fig), info), caption)


def _boxes(fig_title: str, labels: list[str], data: list[np.ndarray], ylabel: str) -> bytes:
    fig = Figure(figsize=(min(18.0, 3.5 + 0.32 * len(data)), 5.0), layout="constrained")
    ax = fig.subplots()
    ax.boxplot(data, whis=(5, 95), showfliers=False, widths=0.6)
    ax.set_xticks(range(1, len(labels) + 1), labels, rotation=45, ha="right", fontsize=7)
    _maybe_log(ax, np.concatenate(data) if data else [])
    ax.set_ylabel(ylabel)
    ax.grid(True, axis="y", which="both", alpha=0.3)
    ax.set_title(fig_title, fontsize=9)
    return render_png(fig)


def _split(values: np.ndarray, index: np.ndarray, groups: int) -> list[np.ndarray]:
    order = np.argsort(index, kind="stable")
    counts = np.bincount(index, minlength=groups)
    return np.split(values[order], np.cumsum(counts)[:-1])


def plot_solve_times(data: CampaignData, cells: Cells) -> Panel:
    """Box plots (box: quartiles, whiskers: 5th-95th percentile) of every adopted plan's
    solve time per grid cell; without plans, of the runs' median and maximum."""
    name, title = "solve", "Solve times per grid cell"
    labels = [cells.label(c) for c in range(cells.count)]
    plans = data.plans
    if plans is not None and plans.num_rows and "solve_time_s" in plans.column_names:
        where = plan_cells(data.runs, cells, plans)
        values = float_column(plans, "solve_time_s")
        ok = (where >= 0) & np.isfinite(values)
        per_cell = _split(values[ok], where[ok], cells.count)
        keep = [c for c in range(cells.count) if per_cell[c].size][:MAX_BOXES]
        if keep:
            png = _boxes(
                f"{int(ok.sum())} adopted plans",
                [labels[c] for c in keep],
                [per_cell[c] for c in keep],
                "solve time (s)",
            )
            info = {"boxes": len(keep), "plans": int(ok.sum())}
            return Panel(
                name,
                title,
                FigurePng(name, title, png, info),
                "Every adopted plan's solve_time_s (plans.parquet); box: quartiles, "
                "line: median, whiskers: 5th to 95th percentile.",
            )
    if not {"solve_time_median_s", "solve_time_max_s"} & set(data.runs.column_names):
        return Panel(name, title, None, reason="no plans.parquet and no solve-time columns.")
    boxes: list[np.ndarray] = []
    names: list[str] = []
    for column, word in (("solve_time_median_s", "median"), ("solve_time_max_s", "max")):
        values = float_column(data.runs, column)
        ok = np.isfinite(values)
        for c, arr in enumerate(_split(values[ok], cells.index[ok], cells.count)):
            if arr.size and len(boxes) < MAX_BOXES:
                boxes.append(arr)
                names.append(f"{labels[c]} ({word})")
    if not boxes:
        return Panel(name, title, None, reason="no run has a solve time.")
    png = _boxes("per run: median and maximum solve time", names, boxes, "solve time (s)")
    return Panel(
        name,
        title,
        FigurePng(name, title, png, {"boxes": len(boxes), "plans": 0}),
        "No plans.parquet (per_plan: false): each box is over the runs' median or "
        "maximum solve time (runs.parquet solve_time_median_s, solve_time_max_s).",
    )


def plot_mu_ratio(data: CampaignData, cells: Cells) -> Panel:
    """Distribution over adopted plans of mu / (F1 / F2'), F2' the plan's distance term
    without mu (the paper's eq. 18 sets mu = F1max / F2avg to balance F1 and F2). floe's
    ``f2`` already includes mu (F2 = mu F2'), so the ratio is ``f2 / f1``; plans with
    f1, f2 or mu zero or not finite (every ``latency`` plan) or a negative ratio are left
    out and counted."""
    name, title = "mu", "mu / (F1 / F2) over adopted plans (the paper's eq. 18)"
    plans = data.plans
    if plans is None:
        return Panel(
            name,
            title,
            None,
            reason="not shown: this campaign kept no plans "
            "(per_plan: false), and mu, F1 and F2 are only in plans.parquet.",
        )
    if not {"mu", "f1", "f2"} <= set(plans.column_names) or plans.num_rows == 0:
        return Panel(
            name, title, None, reason="not shown: plans.parquet has no plan with mu, f1 and f2."
        )
    mu, f1, f2 = (float_column(plans, k) for k in ("mu", "f1", "f2"))
    usable = np.isfinite(mu) & np.isfinite(f1) & np.isfinite(f2) & (mu != 0) & (f1 != 0) & (f2 != 0)
    ratio = np.full(plans.num_rows, math.nan)
    ratio[usable] = f2[usable] / f1[usable]
    positive = usable & (ratio > 0)
    left_out = plans.num_rows - int(positive.sum())
    if not positive.any():
        return Panel(
            name,
            title,
            None,
            reason=f"not shown: none of the {plans.num_rows} plans "
            "has f1, f2 and mu all non-zero (the latency objective has no F2 and no "
            "mu).",
        )
    where = plan_cells(data.runs, cells, plans)
    objective = (
        np.asarray(pc.cast(plans.column("objective"), "string").to_numpy(zero_copy_only=False))
        if "objective" in plans.column_names
        else np.full(plans.num_rows, "", dtype=object)
    )
    fig = Figure(figsize=(9, 5.0), layout="constrained")
    ax = fig.subplots()
    r = ratio[positive]
    lo, hi = np.log10(r.min()), np.log10(r.max())
    bins = (
        np.logspace(lo - 0.05, hi + 0.05, 60)
        if hi > lo
        else np.array([r.min() * 0.9, r.max() * 1.1])
    )
    drawn = set(np.unique(where[positive & (where >= 0)]).tolist())
    groups: dict[tuple[str, ...], list[int]] = {}
    for without in ([], [k for k in cells.varying if k != FLEET_KEY], cells.varying):
        groups = {g: [c for c in m if c in drawn] for g, m in _groups(cells, without).items()}
        groups = {g: m for g, m in groups.items() if m}
        if len(groups) <= len(COLOURS):  # else coarser: by fleet size, then all in one
            break
    for k, (group, members) in enumerate(groups.items()):
        sel = positive & np.isin(where, members)
        label = ", ".join(group) or "all plans"
        ax.hist(
            ratio[sel],
            bins=bins.tolist(),
            histtype="step",
            lw=1.4,
            color=_colour(k),
            label=f"{label} ({int(sel.sum())})",
        )
    curves = len(groups)
    ax.axvline(1.0, color="k", ls="--", lw=1)
    ax.set_xscale("log")
    ax.set_xlabel("mu / (F1 / F2') = f2 / f1  (1: the plan's terms balanced as mu assumes)")
    ax.set_ylabel("plans")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    objectives = sorted({str(o) for o in objective[positive]})
    caption = (
        f"{int(positive.sum())} plans ({', '.join(objectives) or 'objective not recorded'}); "
        f"median {np.median(r):.3g}, 5th-95th percentile {np.percentile(r, 5):.3g}-"
        f"{np.percentile(r, 95):.3g}. mu = F1max / F2avg (eq. 18); F2' is the plan's "
        "distance sum without mu, so mu / (F1 / F2') = f2 / f1 with floe's f2 = mu F2'."
    )
    if left_out:
        caption += (
            f" {left_out} plan(s) left out: f1, f2 or mu zero or not finite (latency "
            "plans), or a negative ratio."
        )
    info = {"plans": int(positive.sum()), "left_out": left_out, "curves": curves}
    return Panel(name, title, FigurePng(name, title, render_png(fig), info), caption)
