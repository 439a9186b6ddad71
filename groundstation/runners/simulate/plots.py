"""PNG plots of simulated runs: uncertainty against time, map snapshots, fleet comparison.

Uses matplotlib's object API with the Agg canvas (no pyplot, no global backend switch), so it
works headless and never touches a display.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle

from groundstation.runners.html_page import plain_log_axis
from groundstation.runners.simulate.simulator import MapSnapshot, SimulationRun
from groundstation.storage import atomic_write_with

__all__ = ["plot_comparison", "plot_map", "plot_uncertainty", "write_plots"]

_COLOURS = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown",
            "tab:pink", "tab:olive", "tab:cyan", "tab:gray"]


def _save(fig: Figure, path: Path) -> Path:
    """Write the PNG atomically (a temporary file then a rename): a full disk raises
    :class:`groundstation.storage.StorageError` and leaves no half image."""
    FigureCanvasAgg(fig)
    atomic_write_with(path, lambda fh: fig.savefig(fh, format="png", dpi=110))
    return path


def growth_text(series: Sequence[Sequence[float]]) -> str:
    """``last/middle third 1.08`` of one run's curve (groundstation/core/metrics.py,
    third_means); ``-`` when a third has no sample. One run has no interval: the ensemble's
    is in ``gcs simulate --seeds K`` and the campaign report."""
    from groundstation.core.metrics import third_means

    pair = third_means([t for t, _ in series], [v for _, v in series])
    if pair is None or pair[0] <= 0.0:
        return "last/middle third -"
    return f"last/middle third {pair[1] / pair[0]:.2f}"


def uncertainty_title(run: SimulationRun) -> str:
    """uncertainty.png's title: the run and its growth over the second half (never a
    threshold verdict: docs/planner.md, "Figure 4 at the ensemble level")."""
    return (f"{run.scenario.name}: {run.metrics['uavs']} UAV(s), seed {run.options.seed} - "
            f"growth over the 2nd half: {growth_text(run.metrics['uncertainty_series'])}")


def plot_uncertainty(run: SimulationRun, path: Path) -> Path:
    """Mean uncertainty (top) and each target's (bottom, log scale) against time."""
    fig = Figure(figsize=(9, 7), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True)
    series = run.metrics["uncertainty_series"]
    top.plot([t for t, _ in series], [s for _, s in series], color="black", lw=2)
    top.set_ylabel("mean uncertainty sigma (m²)")
    top.set_title(uncertainty_title(run))
    top.grid(True, alpha=0.3)
    fov = run.scenario.fleet.fov_radius_m
    for k, (target, rows) in enumerate(sorted(run.target_estimates.items())):
        values = [max(r[3], 1e-3) for r in rows]
        bottom.plot([r[0] for r in rows], values, lw=1, color=_COLOURS[k % len(_COLOURS)],
                    label=target)
    bottom.axhline(fov**2, color="red", ls="--", lw=1, label="lost (sqrt sigma = FOV)")
    bottom.set_yscale("log")
    plain_log_axis(bottom.yaxis)
    bottom.set_xlabel("mission time (s)")
    bottom.set_ylabel("sigma per target (m²)")
    bottom.legend(fontsize=7, ncol=6, loc="upper left")
    bottom.grid(True, alpha=0.3)
    return _save(fig, path)


def _draw_snapshot(ax: Any, run: SimulationRun, snap: MapSnapshot) -> None:
    fov = run.scenario.fleet.fov_radius_m
    for _target, rows in sorted(run.target_truth.items()):
        pts = [(x, y) for t, x, y in rows if t <= snap.t_s]
        if pts:
            ax.plot([p[0] for p in pts], [p[1] for p in pts], color="0.6", lw=0.8)
    for target, (x, y, sigma) in sorted(snap.estimates.items()):
        ax.plot(x, y, "kx", ms=6)
        ax.add_patch(Circle((x, y), math.sqrt(max(sigma, 0.0)), fill=False, color="0.3",
                            lw=0.6, ls=":"))
        ax.annotate(target, (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
    for _target, (x, y) in sorted(snap.truth.items()):
        ax.plot(x, y, "o", color="tab:cyan", ms=4, mec="k", mew=0.4)
    for k, (vehicle, rows) in enumerate(sorted(run.uav_tracks.items())):
        colour = _COLOURS[k % len(_COLOURS)]
        pts = [(x, y) for t, x, y in rows if t <= snap.t_s]
        ax.plot([p[0] for p in pts], [p[1] for p in pts], color=colour, lw=1.2,
                label=f"UAV {vehicle}")
        ux, uy = snap.uav_xy_m[vehicle]
        ax.plot(ux, uy, "^", color=colour, ms=8, mec="k")
        ax.add_patch(Circle((ux, uy), fov, fill=False, color=colour, lw=0.8))
        route = snap.routes.get(vehicle, [])
        seq = [(ux, uy)] + [snap.estimates[t][:2] for t in route if t in snap.estimates]
        if len(seq) > 1:
            ax.plot([p[0] for p in seq], [p[1] for p in seq], ls=":", color=colour, lw=1.2)
    boat = [(x, y) for t, x, y in run.boat_track if t <= snap.t_s]
    if boat:
        ax.plot([p[0] for p in boat], [p[1] for p in boat], color="navy", lw=2, alpha=0.6)
        ax.plot(boat[-1][0], boat[-1][1], "s", color="navy", ms=9, label="boat")
    _draw_wind(ax, run)
    ax.set_title(f"t = {snap.t_s:.0f} s")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.grid(True, alpha=0.3)


def _draw_wind(ax: Any, run: SimulationRun) -> None:
    """The mean wind as an arrow (pointing where the air goes) in the top-right corner."""
    wind = run.scenario.wind
    if wind.speed_m_s <= 0.0:
        return
    wx, wy = wind.mean_xy_m_s
    length_pt = 28.0
    ux, uy = wx / wind.speed_m_s, wy / wind.speed_m_s
    ax.annotate("", xy=(0.9, 0.85), xycoords="axes fraction",
                xytext=(-ux * length_pt, -uy * length_pt), textcoords="offset points",
                arrowprops={"arrowstyle": "-|>", "color": "tab:red", "lw": 2})
    ax.annotate(f"wind {wind.describe()}", xy=(0.98, 0.98), xycoords="axes fraction",
                ha="right", va="top", fontsize=7, color="tab:red")


def plot_map(run: SimulationRun, path: Path) -> Path:
    """Map snapshots like the paper's Figure 3: tracks, planned sequences (dotted), FOVs."""
    snaps = run.snapshots or []
    n = max(len(snaps), 1)
    fig = Figure(figsize=(5.2 * n, 5.4), layout="constrained")
    axes = fig.subplots(1, n, squeeze=False)[0]
    for ax, snap in zip(axes, snaps, strict=False):
        _draw_snapshot(ax, run, snap)
    if snaps:
        axes[0].legend(fontsize=7, loc="best")
    fig.suptitle(f"{run.scenario.name}: {run.metrics['uavs']} UAV(s), seed {run.options.seed}"
                 " - tracks, planned sequences (dotted), FOV circles, icebergs (x estimate,"
                 " o truth)", fontsize=9)
    return _save(fig, path)


def plot_comparison(
    curves: Mapping[int, Sequence[Sequence[float]]], title: str, path: Path
) -> Path:
    """Mean uncertainty against time for several fleet sizes (the paper's Figure 4)."""
    fig = Figure(figsize=(8, 4.5), layout="constrained")
    ax = fig.subplots()
    for k, (uavs, series) in enumerate(sorted(curves.items())):
        ax.plot([t for t, _ in series], [s for _, s in series], lw=2,
                color=_COLOURS[k % len(_COLOURS)],
                label=f"{uavs} UAV(s), growth over the 2nd half: {growth_text(series)}")
    ax.set_xlabel("mission time (s)")
    ax.set_ylabel("mean uncertainty sigma (m²)")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend()
    return _save(fig, path)


def write_plots(run: SimulationRun, out_dir: Path) -> list[Path]:
    """uncertainty.png and map.png for one run."""
    return [plot_uncertainty(run, out_dir / "uncertainty.png"), plot_map(run, out_dir / "map.png")]
