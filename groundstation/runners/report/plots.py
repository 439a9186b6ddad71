"""The figures of a flight report, as PNG bytes (matplotlib object API, Agg canvas).

Each function returns a :class:`FigurePng`: the PNG and, for the map, the extent that was
plotted (``xlim``, ``ylim``) and the vehicles' track bounding box, so a test (or a reader)
can check that every track is inside the picture.
"""

from __future__ import annotations

import math
from typing import Any

from matplotlib.figure import Figure
from matplotlib.patches import Circle

from domain.wind_triangle import wind_from_vector
from groundstation.runners.html_page import FigurePng, plain_log_axis, render_png
from groundstation.runners.report.data import RunData, fallback_wind_of

__all__ = [
    "COLOURS",
    "FigurePng",
    "plot_map",
    "plot_solves",
    "plot_timeline",
    "plot_uncertainty",
    "plot_wind",
]

COLOURS = [
    "tab:blue",
    "tab:orange",
    "tab:green",
    "tab:red",
    "tab:purple",
    "tab:brown",
    "tab:pink",
    "tab:olive",
    "tab:cyan",
    "tab:gray",
]
_MODE_COLOURS = ["#9ecae1", "#a1d99b", "#fdae6b", "#bcbddc", "#bdbdbd", "#fdd0a2"]


def _colour(k: int) -> str:
    return COLOURS[k % len(COLOURS)]


def _finite(rows: list[tuple[float, ...]]) -> list[tuple[float, ...]]:
    return [r for r in rows if all(math.isfinite(v) for v in r[1:3])]


def plot_map(data: RunData) -> FigurePng:
    """Vehicle tracks, targets' true (grey) and estimated (dashed) tracks, loiters, boat."""
    fig = Figure(figsize=(9, 7.5), layout="constrained")
    ax = fig.subplots()
    for rows in data.target_truth.values():
        pts = _finite(rows)
        if pts:
            ax.plot([p[1] for p in pts], [p[2] for p in pts], color="0.65", lw=1.0)
            ax.plot(pts[-1][1], pts[-1][2], "o", color="tab:cyan", mec="k", mew=0.4, ms=5)
    for target, rows in sorted(data.target_estimates.items()):
        pts = _finite(rows)
        if pts:
            ax.plot([p[1] for p in pts], [p[2] for p in pts], color="k", lw=0.8, ls="--")
            ax.plot(pts[-1][1], pts[-1][2], "kx", ms=6)
            ax.annotate(
                target,
                (pts[-1][1], pts[-1][2]),
                textcoords="offset points",
                xytext=(4, 4),
                fontsize=7,
            )
    xs: list[float] = []
    ys: list[float] = []
    names = data.vehicles()
    for k, vehicle in enumerate(names):
        pts = _finite(data.vehicle_tracks.get(vehicle, []))
        if not pts:
            continue
        colour = _colour(k)
        px, py = [p[1] for p in pts], [p[2] for p in pts]
        xs += px
        ys += py
        ax.plot(px, py, color=colour, lw=1.3, label=f"vehicle {vehicle}")
        ax.plot(px[0], py[0], "o", color=colour, mec="k", ms=6)
        ax.plot(px[-1], py[-1], "^", color=colour, mec="k", ms=8)
    loiters = 0
    for f in data.fly:
        if f["loiter_s"] > 0 and math.isfinite(f["x_m"]) and math.isfinite(f["loiter_radius_m"]):
            k = names.index(f["vehicle"]) if f["vehicle"] in names else 0
            ax.add_patch(
                Circle(
                    (f["x_m"], f["y_m"]),
                    f["loiter_radius_m"],
                    fill=False,
                    color=_colour(k),
                    lw=0.6,
                    alpha=0.6,
                )
            )
            loiters += 1
    boat = _finite(data.boat)
    if boat:
        ax.plot(
            [p[1] for p in boat], [p[2] for p in boat], color="navy", lw=2, alpha=0.6, label="boat"
        )
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.grid(True, alpha=0.3)
    if names:  # outside the axes: never over a track
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_title(
        "tracks (o start, ^ end); icebergs: grey truth, dashed estimate, x last; circles: loiters",
        fontsize=9,
    )
    png = render_png(fig)  # draws: the limits below are the final ones
    info: dict[str, Any] = {
        "xlim": list(ax.get_xlim()),
        "ylim": list(ax.get_ylim()),
        "loiters": loiters,
    }
    if xs:
        info["track_bbox"] = [min(xs), max(xs), min(ys), max(ys)]
        # axes pixel box (origin bottom-left, as matplotlib reports it)
        bbox = ax.get_window_extent()
        info["axes_px"] = [bbox.x0, bbox.y0, bbox.x1, bbox.y1]
        info["figure_px"] = [fig.bbox.width, fig.bbox.height]
    return FigurePng("map", "Map of the flight", png, info)


def plot_uncertainty(data: RunData) -> FigurePng | None:
    """Mean uncertainty (top) and each target's (bottom, log scale) against time."""
    mean = data.mean_uncertainty()
    if not mean and not data.target_estimates:
        return None
    fig = Figure(figsize=(9, 6.5), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True)
    top.plot([t for t, _ in mean], [s for _, s in mean], color="black", lw=2)
    top.set_ylabel("mean sigma (m²)")
    top.set_title("uncertainty: average over the targets (top), per target (bottom)")
    top.grid(True, alpha=0.3)
    for k, (target, rows) in enumerate(sorted(data.target_estimates.items())):
        pts = [r for r in rows if math.isfinite(r[3])]
        bottom.plot(
            [r[0] for r in pts],
            [max(r[3], 1e-3) for r in pts],
            lw=1,
            color=_colour(k),
            label=target,
        )
    bottom.axhline(150.0**2, color="red", ls="--", lw=1, label="lost (sqrt sigma = 150 m)")
    bottom.set_yscale("log")
    plain_log_axis(bottom.yaxis)
    bottom.set_xlabel("mission time (s)")
    bottom.set_ylabel("sigma (m²)")
    bottom.legend(fontsize=7, ncol=6, loc="upper left")
    bottom.grid(True, alpha=0.3)
    return FigurePng(
        "uncertainty",
        "Uncertainty against time",
        render_png(fig),
        {"series": len(data.target_estimates)},
    )


def _spans(events: list[tuple[float, str]], end_s: float) -> list[tuple[float, float, str]]:
    out = []
    for k, (t, label) in enumerate(events):
        t_next = events[k + 1][0] if k + 1 < len(events) else end_s
        out.append((t, max(t_next, t), label))
    return out


def plot_timeline(data: RunData) -> FigurePng | None:
    """Per vehicle: the target it was sent to and when (bars), modes (thin band), loiter
    ends, link losses (red), overrides and releases (markers)."""
    names = data.vehicles()
    if not names:
        return None
    end_s = max(data.end_t_s, 1.0)
    fig = Figure(figsize=(10, 1.0 + 0.9 * len(names)), layout="constrained")
    ax = fig.subplots()
    targets = sorted({str(f["target"]) for f in data.fly})
    colour_of = {t: _colour(k) for k, t in enumerate(targets)}
    mode_colours: dict[str, str] = {}
    for row, vehicle in enumerate(names):
        y = len(names) - 1 - row
        flights = [(f["t"], str(f["target"])) for f in data.fly if f["vehicle"] == vehicle]
        stops = [
            o["t"]
            for o in data.overrides
            if o["vehicle"] == vehicle and o["event"] in ("release", "send_home", "override")
        ]
        for t0, t1, target in _spans(flights, end_s):
            t1 = min([t1, *[s for s in stops if s > t0]])
            ax.broken_barh([(t0, t1 - t0)], (y - 0.3, 0.45), color=colour_of[target], alpha=0.8)
            if t1 - t0 > end_s / 40:
                ax.text(t0 + (t1 - t0) / 2, y - 0.08, target, ha="center", va="center", fontsize=7)
        for t0, t1, mode in _spans(data.modes.get(vehicle, []), end_s):
            c = mode_colours.setdefault(mode, _MODE_COLOURS[len(mode_colours) % len(_MODE_COLOURS)])
            ax.broken_barh([(t0, t1 - t0)], (y + 0.2, 0.12), color=c, alpha=0.5)
            if t1 - t0 > end_s / 30:
                ax.text(t0, y + 0.38, mode, fontsize=6, va="bottom")
        ends = [e["t"] for e in data.loiter_ends if e["vehicle"] == vehicle]
        ax.plot(ends, [y - 0.35] * len(ends), "|", color="k", ms=8)
        lost_at: float | None = None
        for e in sorted(
            (e for e in data.link_events if e["vehicle"] == vehicle), key=lambda e: e["t"]
        ):
            if e["event"] == "link_lost":
                lost_at = e["t"] if lost_at is None else lost_at
            elif lost_at is not None:
                ax.broken_barh(
                    [(lost_at, e["t"] - lost_at)], (y - 0.45, 0.9), color="red", alpha=0.2
                )
                lost_at = None
        if lost_at is not None:
            ax.broken_barh([(lost_at, end_s - lost_at)], (y - 0.45, 0.9), color="red", alpha=0.2)
        labels: dict[float, list[str]] = {}
        for o in data.overrides:
            if o["vehicle"] == vehicle:
                labels.setdefault(round(o["t"], 1), []).append(str(o["event"]))
        for t, words in labels.items():
            ax.plot(t, y + 0.05, "v", color="red", ms=7)
            ax.annotate(
                " / ".join(dict.fromkeys(words)),
                (t, y + 0.05),
                textcoords="offset points",
                xytext=(3, 3),
                fontsize=6,
                color="red",
            )
    ax.set_yticks(range(len(names)), [f"vehicle {v}" for v in reversed(names)])
    ax.set_ylim(-0.6, len(names) - 0.4)
    ax.set_xlim(0, end_s)
    ax.set_xlabel("mission time (s)")
    ax.set_title(
        "plan timeline: target per vehicle (bars), modes (thin bands), loiter ends "
        "(|), link lost (red), overrides/releases (v)",
        fontsize=9,
    )
    ax.grid(True, axis="x", alpha=0.3)
    return FigurePng(
        "timeline",
        "Plan timeline per vehicle",
        render_png(fig),
        {"vehicles": names, "fly": len(data.fly)},
    )


def plot_solves(data: RunData) -> FigurePng | None:
    """Solve time of every plan (hit-the-limit and fallback marked); upload retries."""
    if not data.plans and not data.uploads:
        return None
    panels = 2 if data.uploads else 1
    fig = Figure(figsize=(9, 2.8 * panels + 0.5), layout="constrained")
    axes = fig.subplots(panels, 1, squeeze=False)[:, 0]
    ax = axes[0]
    normal = [p for p in data.plans if not p["hit_time_limit"] and p["status"] != "fallback"]
    limited = [p for p in data.plans if p["hit_time_limit"] or p["status"] == "fallback"]
    ax.plot(
        [p["t"] for p in normal],
        [p["solve_time_s"] for p in normal],
        "o",
        ms=4,
        color="tab:blue",
        label="solved",
    )
    if limited:
        ax.plot(
            [p["t"] for p in limited],
            [p["solve_time_s"] for p in limited],
            "s",
            ms=6,
            color="tab:red",
            label="hit the time limit / fallback",
        )
    ax.set_ylabel("solve time (s)")
    ax.set_title(f"{len(data.plans)} plan(s): solve times", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    if data.uploads:
        up = axes[1]
        ok = [u for u in data.uploads if u["ok"]]
        bad = [u for u in data.uploads if not u["ok"]]
        up.plot(
            [u["t"] for u in ok],
            [u["retries"] for u in ok],
            "o",
            ms=4,
            color="tab:green",
            label="upload verified",
        )
        up.plot(
            [u["t"] for u in bad],
            [u["retries"] for u in bad],
            "x",
            ms=7,
            color="tab:red",
            label="upload failed",
        )
        up.set_ylabel("retries")
        up.set_title(f"{len(data.uploads)} upload(s): retries", fontsize=9)
        up.grid(True, alpha=0.3)
        up.legend(fontsize=7)
    axes[-1].set_xlabel("mission time (s)")
    return FigurePng(
        "solves",
        "Solve times and upload retries",
        render_png(fig),
        {"plans": len(data.plans), "uploads": len(data.uploads)},
    )


def plot_wind(data: RunData) -> FigurePng | None:
    """The core's wind estimate (a step at each ``wind`` line, from the fallback at t = 0)
    and each vehicle's own reports (dots): speed (top) and the compass direction it blows
    from (bottom). None when the journal has neither."""
    if not data.wind and not data.wind_reports:
        return None
    fig = Figure(figsize=(9, 5.5), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True)
    fallback = wind_from_vector(*fallback_wind_of(data))
    steps = [(0.0, *fallback)] + [(w["t"], w["speed_m_s"], w["from_deg"]) for w in data.wind]
    end_s = max(data.end_t_s, steps[-1][0])
    xs = [t for t, _s, _d in steps] + [end_s]
    for ax, k in ((top, 1), (bottom, 2)):
        ys = [row[k] for row in steps]
        ax.step(xs, [*ys, ys[-1]], where="post", color="black", lw=2, label="estimate")
        ax.grid(True, alpha=0.3)
    for n, (vehicle, rows) in enumerate(sorted(data.wind_reports.items())):
        pts = [(t, *wind_from_vector(x, y)) for t, x, y in rows
               if math.isfinite(x) and math.isfinite(y)]
        top.plot([p[0] for p in pts], [p[1] for p in pts], ".", ms=3, color=_colour(n),
                 label=f"vehicle {vehicle}")
        bottom.plot([p[0] for p in pts], [p[2] for p in pts], ".", ms=3, color=_colour(n))
    top.set_ylabel("wind speed (m/s)")
    top.set_title("wind: the core's estimate as journalled (line), each vehicle's reports (dots)")
    top.legend(fontsize=7, ncol=6, loc="upper left")
    bottom.set_ylabel("from (compass deg)")
    bottom.set_ylim(0, 360)
    bottom.set_yticks(range(0, 361, 90))
    bottom.set_xlabel("mission time (s)")
    return FigurePng("wind", "Wind estimate against time", render_png(fig),
                     {"changes": len(data.wind), "vehicles": len(data.wind_reports)})
