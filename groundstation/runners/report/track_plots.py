"""The report's figure of the multi-target tracker (from
:mod:`~groundstation.runners.report.track_data`): a map and a timeline.

Map: the newest search cells as squares shaded by their value (m^2, colour bar), the true
icebergs' last positions (grey), and every track's path styled by its status at each
sample: confirmed solid green, tentative dashed orange, prior dotted purple; its last
position filled (confirmed), hollow (tentative) or a hollow diamond (prior), and a grey
``x`` when it was deleted. Timeline: how many tracks of each status every journalled sample
had, and the cumulative births, confirmations and deletions (steps).

``info`` holds what was drawn (tracks per final status, deleted tracks, cells and the
largest value, the lifecycle counts) so tests check data, not pixels.
"""

from __future__ import annotations

import math
from collections import defaultdict
from typing import Any

from matplotlib import colormaps
from matplotlib.cm import ScalarMappable
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from groundstation.runners.html_page import FigurePng, render_png
from groundstation.runners.report.data import RunData
from groundstation.runners.report.track_data import STATUSES, TrackingData, TrackSample

__all__ = ["STYLE", "plot_tracking"]

STYLE: dict[str, dict[str, Any]] = {
    "confirmed": {"color": "tab:green", "ls": "-", "lw": 1.3, "marker": "o", "filled": True},
    "tentative": {"color": "tab:orange", "ls": "--", "lw": 0.8, "marker": "o", "filled": False},
    "prior": {"color": "tab:purple", "ls": ":", "lw": 1.2, "marker": "D", "filled": False},
}
"""How each status is drawn (the live map uses the same idea: hollow dashed tentative,
filled confirmed, a distinct prior)."""


def _runs(rows: list[TrackSample]) -> list[tuple[str, list[TrackSample]]]:
    """Consecutive samples of one status; each run starts at the previous run's last
    point so the path has no gap."""
    out: list[tuple[str, list[TrackSample]]] = []
    for s in rows:
        if out and out[-1][0] == s.status:
            out[-1][1].append(s)
        else:
            start = [out[-1][1][-1]] if out else []
            out.append((s.status, [*start, s]))
    return out


def _draw_map(ax: Any, fig: Figure, data: RunData, tracking: TrackingData) -> dict[str, Any]:
    cells = tracking.last_search()
    top = max((c.value_m2 for c in cells), default=0.0)
    if cells:
        norm = Normalize(vmin=0.0, vmax=top if top > 0 else 1.0)
        cmap = colormaps["Blues"]
        for c in cells:
            ax.add_patch(Rectangle((c.x_m - c.size_m / 2, c.y_m - c.size_m / 2), c.size_m,
                                   c.size_m, facecolor=cmap(norm(max(c.value_m2, 0.0))),
                                   edgecolor="0.6", lw=0.4, alpha=0.6, zorder=0))
            ax.update_datalim([(c.x_m - c.size_m / 2, c.y_m - c.size_m / 2),
                               (c.x_m + c.size_m / 2, c.y_m + c.size_m / 2)])
        fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, shrink=0.7,
                     label=f"search value (m²) at t={tracking.search[-1][0]:.0f} s")
    for truth in data.target_truth.values():
        pts = [r for r in truth if math.isfinite(r[1]) and math.isfinite(r[2])]
        if pts:
            ax.plot(pts[-1][1], pts[-1][2], "s", color="0.55", ms=5, zorder=2)
    gone = tracking.deleted()
    final = tracking.final_status()
    paths: dict[str, list[list[tuple[float, float]]]] = {s: [] for s in STATUSES}
    ends: dict[str, list[tuple[float, float]]] = {s: [] for s in (*STATUSES, "deleted")}
    for tid, samples in sorted(tracking.tracks.items()):
        for status, run in _runs(samples):
            paths[status].append([(s.x_m, s.y_m) for s in run])
        last = samples[-1]
        kind = "deleted" if tid in gone else final[tid]
        ends[kind].append((last.x_m, last.y_m))
        if kind in ("confirmed", "prior"):
            ax.annotate(tid, (last.x_m, last.y_m), textcoords="offset points", xytext=(4, 4),
                        fontsize=7)
    for status in STATUSES:  # one collection per style: a long run has thousands of tracks
        style = STYLE[status]
        if paths[status]:
            ax.add_collection(LineCollection(paths[status], colors=style["color"],
                                             linestyles=style["ls"], linewidths=style["lw"],
                                             zorder=3))
        if ends[status]:
            xs, ys = zip(*ends[status], strict=True)
            ax.plot(xs, ys, style["marker"], ls="none", ms=7, mec=style["color"], mew=1.5,
                    mfc=style["color"] if style["filled"] else "none", zorder=4)
    if ends["deleted"]:
        xs, ys = zip(*ends["deleted"], strict=True)
        ax.plot(xs, ys, "x", ls="none", color="0.45", ms=5, zorder=4)
    for status in STATUSES:  # legend entries
        style = STYLE[status]
        ax.plot([], [], color=style["color"], ls=style["ls"], marker=style["marker"],
                mfc=style["color"] if style["filled"] else "none", label=status)
    ax.plot([], [], "x", color="0.45", label="deleted")
    if data.target_truth:
        ax.plot([], [], "s", color="0.55", label="true iceberg")
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="best", framealpha=0.8)
    ax.set_title("tracks by status, search cells shaded by value", fontsize=9)
    by_final: dict[str, list[str]] = {s: [] for s in STATUSES}
    for tid, status in sorted(final.items()):
        if tid not in gone:
            by_final[status].append(tid)
    return {"tracks": by_final, "deleted": sorted(gone), "search_cells": len(cells),
            "search_value_max_m2": top}


def _draw_timeline(ax: Any, data: RunData, tracking: TrackingData) -> None:
    per_t: dict[float, dict[str, int]] = defaultdict(lambda: dict.fromkeys(STATUSES, 0))
    for rows in tracking.tracks.values():
        for s in rows:
            per_t[round(s.t_s, 3)][s.status] += 1
    times = sorted(per_t)
    for status in STATUSES:
        if any(per_t[t][status] for t in times):
            ax.plot(times, [per_t[t][status] for t in times], color=STYLE[status]["color"],
                    lw=1.5, label=f"{status} tracks")
    for kind, colour in (("born", "tab:orange"), ("confirmed", "tab:green"),
                         ("deleted", "0.4")):
        ts = sorted(e.t_s for e in tracking.lifecycle if e.kind == kind)
        if ts:
            ax.step([0.0, *ts, max(data.end_t_s, ts[-1])], [0, *range(1, len(ts) + 1), len(ts)],
                    where="post", color=colour, ls="-.", lw=1, label=f"{kind} (cumulative)")
    ax.set_xlabel("mission time (s)")
    ax.set_ylabel("tracks")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, ncol=3, loc="upper left")
    ax.set_title("tracks per status, and births, confirmations, deletions so far", fontsize=9)


def plot_tracking(data: RunData) -> FigurePng | None:
    """The tracker's figure, or None when the journal has nothing of it (see the module
    docstring)."""
    tracking = data.tracking
    if not tracking.present():
        return None
    fig = Figure(figsize=(9, 10), layout="constrained")
    top, bottom = fig.subplots(2, 1, height_ratios=[3, 1.3])
    info = _draw_map(top, fig, data, tracking)
    _draw_timeline(bottom, data, tracking)
    info["counts"] = tracking.counts()
    info["skipped"] = tracking.skipped
    return FigurePng("tracking", "Tracks and search", render_png(fig), info)
