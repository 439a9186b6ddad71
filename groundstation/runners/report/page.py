"""``gcs report``: one self-contained HTML page about a flight.

:func:`build_report` gathers the run's data (:mod:`~groundstation.runners.report.data`),
draws the figures (:mod:`~groundstation.runners.report.plots`) and writes
``OUT/report.html`` with every PNG embedded as a ``data:image/png;base64`` URI, so the
page can be mailed or archived alone. The map's ``<img>`` carries the plotted extent
(``data-xlim``, ``data-ylim``, metres) and the vehicles' track bounding box
(``data-track-bbox``) for checks. The PNGs are also written next to the page. A ``gcs run``
folder's per-vehicle files (the missions as QGC WPL 110, the ``.parm`` snapshots) are
linked in the table ``vehicle-files``, relative to the page.
"""

from __future__ import annotations

import html
import json
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from groundstation.runners.html_page import FigurePng, figure_html, page_start
from groundstation.runners.report.data import RunData, load_run_data, summary_rows
from groundstation.runners.report.plots import (
    plot_map,
    plot_solves,
    plot_timeline,
    plot_uncertainty,
    plot_wind,
)
from groundstation.runners.report.track_plots import plot_tracking
from groundstation.storage import (
    StorageError,
    atomic_write_bytes,
    atomic_write_text,
    describe_os_error,
)

__all__ = ["ReportResult", "build_report", "render_html"]

_EVENT_ROWS = 200


@dataclass
class ReportResult:
    """What :func:`build_report` wrote."""

    html_path: Path
    figures: list[FigurePng] = field(default_factory=list)
    data: RunData | None = None


def _events(data: RunData) -> list[tuple[float, str, str, str]]:
    rows: list[tuple[float, str, str, str]] = []
    for u in data.uploads:
        if not u["ok"] or u["retries"]:
            detail = f"retries {u['retries']}" + (f", {u['error']}" if u.get("error") else "")
            rows.append(
                (u["t"], str(u["vehicle"]), "upload " + ("ok" if u["ok"] else "FAILED"), detail)
            )
    for e in data.link_events:
        rows.append((e["t"], str(e["vehicle"]), e["event"], ""))
    for o in data.overrides:
        rows.append((o["t"], str(o["vehicle"]), o["event"], str(o.get("reason") or "")))
    for w in data.wind_outliers:
        rows.append((w["t"], str(w["vehicle"]), "wind_outlier", str(w.get("detail") or "")))
    for p in data.plans:
        if p["hit_time_limit"] or p["status"] == "fallback":
            rows.append(
                (
                    p["t"],
                    "",
                    "plan " + str(p["status"]),
                    f"request {p['request']}, {p['solve_time_s']:.3f} s, hit the limit",
                )
            )
    return sorted(rows, key=lambda r: r[0])


def _lifecycle_html(data: RunData) -> list[str]:
    """The tracker's births, confirmations and deletions as a table (``id="tracks"``);
    nothing for a journal without them."""
    lifecycle = data.tracking.lifecycle
    if not lifecycle:
        return []
    esc = html.escape
    out = ['<h2>Track births, confirmations and deletions</h2><table id="tracks"><tr>'
           "<th>t (s)</th><th>track</th><th>event</th><th>detail</th></tr>"]
    for e in lifecycle[:_EVENT_ROWS]:
        out.append(f"<tr><td>{e.t_s:.1f}</td><td>{esc(e.track)}</td><td>{esc(e.kind)}</td>"
                   f"<td>{esc(e.detail)}</td></tr>")
    out.append("</table>")
    if len(lifecycle) > _EVENT_ROWS:
        out.append(f"<p>... {len(lifecycle) - _EVENT_ROWS} more</p>")
    return out


def _files_html(data: RunData, out_dir: Path | None) -> list[str]:
    """Links to each vehicle's mission files (QGC WPL 110: MAVProxy ``wp load``,
    QGroundControl) and parameter snapshot (``.parm``: MAVProxy ``param load``), relative
    to the page when it has a folder."""
    if not data.vehicle_files:
        return []
    esc = html.escape
    out = ['<h2>Vehicle files</h2><table id="vehicle-files"><tr><th>vehicle</th>'
           "<th>file</th><th>opens with</th></tr>"]
    for vehicle, kind, path in data.vehicle_files:
        href = (os.path.relpath(path, out_dir) if out_dir is not None
                else path.resolve().as_uri())
        opens = ("MAVProxy wp load, QGroundControl" if kind == "mission"
                 else "MAVProxy param load")
        out.append(f'<tr><td>{esc(vehicle)}</td><td><a href="{esc(href)}">'
                   f"{esc(kind)}: {esc(path.name)}</a></td><td>{opens}</td></tr>")
    out.append("</table>")
    return out


def render_html(data: RunData, figures: list[FigurePng], out_dir: Path | None = None) -> str:
    """The page (see the module docstring); ``out_dir``: where it is written (its links to
    the run folder's files are relative to it)."""
    esc = html.escape
    out = page_start(f"floe report: {data.title}", f"floe flight report: {data.title}")
    out.append('<h2>Summary</h2><table id="summary">')
    for name, value in summary_rows(data):
        out.append(f"<tr><th>{esc(name)}</th><td>{esc(value)}</td></tr>")
    out.append("</table>")
    if data.warnings:
        out.append('<h2>Warnings</h2><ul class="warn">')
        out += [f"<li>{esc(w)}</li>" for w in data.warnings[:50]]
        if len(data.warnings) > 50:
            out.append(f"<li>... {len(data.warnings) - 50} more</li>")
        out.append("</ul>")
    for fig in figures:
        attrs = ""
        if fig.name == "map":
            for key in ("xlim", "ylim", "track_bbox"):
                if key in fig.info:
                    attrs += (
                        f' data-{key.replace("_", "-")}="'
                        + esc(",".join(f"{v:.3f}" for v in fig.info[key]))
                        + '"'
                    )
        out.append(figure_html(fig, attrs))
    if data.wind:
        out.append('<h2>Wind estimate changes</h2><table id="wind"><tr><th>t (s)</th>'
                   "<th>speed (m/s)</th><th>from (deg)</th><th>source</th></tr>")
        for w in data.wind[:_EVENT_ROWS]:
            who = w["source"] + (" " + ", ".join(w["vehicles"]) if w["vehicles"] else "")
            out.append(f"<tr><td>{w['t']:.1f}</td><td>{w['speed_m_s']:.1f}</td>"
                       f"<td>{w['from_deg']:.0f}</td><td>{esc(who)}</td></tr>")
        out.append("</table>")
        if len(data.wind) > _EVENT_ROWS:
            out.append(f"<p>... {len(data.wind) - _EVENT_ROWS} more</p>")
    out += _lifecycle_html(data)
    events = _events(data)
    out.append("<h2>Upload retries, link losses, overrides</h2>")
    if events:
        out.append(
            '<table id="events"><tr><th>t (s)</th><th>vehicle</th><th>event</th>'
            "<th>detail</th></tr>"
        )
        for t, vehicle, event, detail in events[:_EVENT_ROWS]:
            out.append(
                f"<tr><td>{t:.1f}</td><td>{esc(vehicle)}</td><td>{esc(event)}</td>"
                f"<td>{esc(detail)}</td></tr>"
            )
        out.append("</table>")
        if len(events) > _EVENT_ROWS:
            out.append(f"<p>... {len(events) - _EVENT_ROWS} more</p>")
    else:
        out.append("<p>none recorded</p>")
    out += _files_html(data, out_dir)
    if data.tlog is not None and data.tlog.vehicles:
        out.append(
            '<h2>Vehicles in the tlog</h2><table id="tlog"><tr><th>system id</th>'
            "<th>frames</th><th>positions</th><th>modes</th><th>top messages</th></tr>"
        )
        for sysid, v in data.tlog.vehicles.items():
            modes = " &rarr; ".join(esc(m) for _t, m in v.modes[:12])
            top = ", ".join(f"{esc(k)} {n}" for k, n in v.messages.most_common(6))
            out.append(
                f"<tr><td>{sysid}</td><td>{v.frames}</td><td>{len(v.positions)}</td>"
                f"<td>{modes}</td><td>{top}</td></tr>"
            )
        out.append("</table>")
    out.append("</body></html>")
    return "\n".join(out) + "\n"


def build_report(
    path: Path, out_dir: Path, say: Callable[[str], None] | None = None
) -> ReportResult:
    """Write ``out_dir/report.html`` (and the PNGs) for the run at ``path``.

    Raises :class:`~groundstation.runners.report.data.ReportError` when there is nothing
    to report, :class:`~groundstation.storage.StorageError` when ``out_dir`` cannot be
    written. Every file is written atomically (temporary file, fsync, rename), the page
    last, so a failure never leaves a half page.
    """
    note = say or (lambda text: None)
    data = load_run_data(path, note)
    figures: list[FigurePng] = []
    for name, draw in (
        ("map", plot_map),
        ("uncertainty", plot_uncertainty),
        ("timeline", plot_timeline),
        ("solves", plot_solves),
        ("wind", plot_wind),
        ("tracking", plot_tracking),
    ):
        note(f"drawing {name}")
        fig = draw(data)
        if fig is not None:
            figures.append(fig)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise StorageError(f"cannot create {out_dir}: {describe_os_error(exc)}") from None
    for fig in figures:
        atomic_write_bytes(out_dir / f"{fig.name}.png", fig.png)
    atomic_write_text(
        out_dir / "figures.json", json.dumps({f.name: f.info for f in figures}, indent=1) + "\n"
    )
    html_path = out_dir / "report.html"
    atomic_write_text(html_path, render_html(data, figures, out_dir))
    return ReportResult(html_path, figures, data)
