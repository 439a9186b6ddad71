"""The live status table of ``gcs run`` (built with ``rich``).

Header: mission time, speed-up, advisory, the run folder, the **live map URL and where the
token is** (``RUN/control.json``), the newest plan as readable routes
(``1 -> T5, T6 | 2 -> T2``), the wind the core plans with (``wind 12.0 m/s from 270°
(vehicles 1,2,3)``, or its fallback's source: ``config``, ``scenario``, ``none``), links
that heard no vehicle, dropped detections and signing refusals. Then one row per vehicle
(id, system id, status, mode, armed, altitude, target, battery, link (``lag N s`` while its
telemetry lags: docs/links.md), uploads ok/failed, upload retries, its own wind estimate
as ``speed/from``), the tracker's counts
(``tracks: 9 confirmed, 3 tentative, 1 prior; 100 search cells``), one row per confirmed or
prior target (id, position, sigma, lost, last seen, status; tentative tracks are only
counted: clutter makes many), one line per link (frames received, dropped unread, bad, foreign)
and the newest operator events (``log_lines.is_operator_event``; problems in colour).
Redrawn once a wall second in place (``rich.live.Live``); the console's own lines
(warnings, the start lines) stay above it. Colours come from ``rich``: none on a dumb
terminal or a file.
"""

from __future__ import annotations

import asyncio
import logging
from collections import deque
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

from rich import box
from rich.console import Console, Group, RenderableType
from rich.table import Table
from rich.text import Text

from domain.wind_triangle import wind_from_vector
from groundstation.daemon.log_lines import (
    describe_line,
    format_routes,
    is_operator_event,
    line_level,
    plan_detail,
)
from groundstation.daemon.track_views import count_line, track_counts, track_dicts
from groundstation.daemon.watch_lines import ship_text, watch_rows
from groundstation.daemon.wind_view import wind_label, wind_text
from groundstation.mavlink.telemetry_events import VehicleSnapshot
from groundstation.vehicle.state import LinkState

if TYPE_CHECKING:
    from groundstation.daemon.alerts import OperatorAlerts
    from groundstation.daemon.daemon import Daemon

__all__ = ["RECENT_LINES", "EventTally", "link_lines", "render_status", "status_loop"]

RECENT_LINES = 8
REDRAW_S = 1.0
_LINK_STYLE = {LinkState.OK: "green", LinkState.LOST: "bold red"}  # degraded: yellow


class EventTally:
    """The newest ``RECENT_LINES`` operator events of the journal (the recent pane). The
    table's counts come from the controllers, never from this lossy subscription."""

    def __init__(self) -> None:
        self.recent: deque[dict[str, Any]] = deque(maxlen=RECENT_LINES)

    @classmethod
    def from_lines(cls, lines: Iterable[dict[str, Any]]) -> EventTally:
        """A tally seeded with journal lines (the journal's recent ones, at the start)."""
        tally = cls()
        for line in lines:
            tally.add(line)
        return tally

    def add(self, line: dict[str, Any]) -> None:
        if is_operator_event(line):
            self.recent.append(line)


def _fmt(value: Any, spec: str = "") -> str:
    if value is None:
        return "-"
    return format(value, spec) if spec else str(value)


def link_lines(stats: dict[str, dict[str, int]], only_trouble: bool = False) -> list[str]:
    """One line per link from ``Router.link_stats()``: received, dropped (unread, inbox
    full), bad (checksum or garbage), foreign (a vehicle bound elsewhere), overflow.
    ``only_trouble``: just the links where something was lost or refused."""
    lines = []
    for link_id, c in stats.items():
        trouble = c.get("dropped", 0) + c.get("bad", 0) + c.get("foreign", 0)
        if only_trouble and not trouble + c.get("overflow", 0):
            continue
        lines.append(
            f"link {link_id}: received {c.get('received', 0)}, dropped {c.get('dropped', 0)}, "
            f"bad {c.get('bad', 0)}, foreign {c.get('foreign', 0)}"
            + (f", overflow {c['overflow']}" if c.get("overflow") else "")
        )
    return lines


def _header(daemon: Daemon, alerts: OperatorAlerts | None) -> list[RenderableType]:
    t = daemon.clock.now_s()
    head = Text.assemble(
        ("floe gcs run", "bold"), f"  t={t:8.1f} s  speed-up {daemon.clock.speedup:g}x",
        ("  ADVISORY" if daemon.config.advisory else "", "bold yellow"),
        f"  run {daemon.run_dir}",
    )
    out: list[RenderableType] = [head]
    if daemon.control_url:
        out.append(Text.assemble(
            "live map ", (f"{daemon.control_url}/", "bold cyan"),
            f"   token: {daemon.run_dir}/control.json (and on the start line)",
        ))  # fmt: skip
    plan = daemon.last_plan
    if plan is not None:
        out.append(Text(f"plan t={plan['t']:.1f}: {format_routes(plan['routes'])} "
                        f"({plan_detail(plan)})"))
    else:
        out.append(Text("plan: none yet"))
    out.append(_wind_line(daemon))
    if alerts is not None:
        for link in alerts.silent_links():
            out.append(Text(f"link {link.link_id} ({link.spec.url}): no vehicle heard "
                            f"({alerts.link_state(link)})", style="bold red"))
        drops = {k: v for k, v in alerts.drops().items() if v}
        if drops:
            text = ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in drops.items())
            out.append(Text(f"detections dropped: {text}", style="yellow"))
    if daemon.signing is not None:
        refused = daemon.signing.summary()["rejected"]
        text = ", ".join(f"{k} {sum(v.values())}" for k, v in refused.items()) or "none"
        out.append(Text(f"signing on; refused frames: {text}",
                        style="yellow" if refused else ""))
    return out


def _wind_line(daemon: Daemon) -> Text:
    view = daemon.core.view()
    state = view.wind
    text = f"wind {wind_text(*state.xy_m_s)} ({wind_label(state, daemon.wind_fallback_source)})"
    if not daemon.core_config.wind_aware:
        text += ", not used by the planner (wind_aware false)"
    flagged = sorted(view.wind_outliers)
    if flagged:
        return Text.assemble(text, (f"  outlier: {', '.join(flagged)}", "yellow"))
    return Text(text)


def _own_wind(snap: VehicleSnapshot) -> str:
    """A vehicle's own estimate as ``12/270``: m/s and the compass direction it is from
    (``calm`` below 0.5 m/s, whose direction means nothing)."""
    if snap.wind_xy_m_s is None:
        return "-"
    speed, from_deg = wind_from_vector(*snap.wind_xy_m_s)
    return "calm" if speed < 0.5 else f"{speed:.0f}/{from_deg:03.0f}"


def _table(*columns: str) -> Table:
    """A borderless table; a column named with a trailing ``>`` is right-aligned."""
    table = Table(box=box.SIMPLE_HEAD, pad_edge=False, show_edge=False)
    for column in columns:
        name = column.removesuffix(">")
        table.add_column(name, justify="right" if name != column else "left")
    return table


def _link_cell(link: LinkState, lagging: bool, age_s: float | None) -> Text:
    """The link's state, or ``lag N s`` while the vehicle's telemetry lags (its frames
    arrive, its newest position is old: planned from a prediction)."""
    if lagging and age_s is not None:
        return Text(f"lag {age_s:.0f} s", style="bold yellow")
    return Text(link, style=_LINK_STYLE.get(link, "yellow"))


def _vehicles(daemon: Daemon) -> Table:
    table = _table("vehicle", "sysid>", "status", "mode", "armed", "alt m>", "target",
                   "batt %>", "link", "uploads>", "retries>", "wind>")
    for s in sorted(daemon.sessions.values(), key=lambda s: s.system_id):
        snap = s.snapshot
        retries = s.upload_retries
        table.add_row(
            s.id, str(s.system_id), s.status, _fmt(snap.mode_name), _fmt(snap.armed),
            _fmt(snap.alt_m, ".0f"), _fmt(s.fly.target if s.fly else None),
            _fmt(snap.battery_remaining_pct, ".0f"),
            _link_cell(s.link, s.lagging, s.telemetry_age_s),
            Text(f"{s.uploads_ok}/{s.uploads_failed}",
                 style="red" if s.uploads_failed else ""),
            Text(str(retries), style="yellow" if retries else ""), _own_wind(snap),
        )  # fmt: skip
    if not daemon.sessions:
        table.add_row("(none yet)", *[""] * 11)
    return table


def _watch(daemon: Daemon) -> list[RenderableType]:
    """The ship watch (docs/ship.md): the ship, each vehicle's endurance and turn-home
    time, the spares and the next relief; the alarms in red."""
    view = daemon.core.watch_view()
    if view is None:
        return []
    t = daemon.clock.now_s()
    out: list[RenderableType] = [Text(ship_text(view))]
    spares = ", ".join(view.spares) or "none"
    relief = ("" if view.next_relief is None else
              f"; next return: {view.next_relief[0]} at t={view.next_relief[1]:.0f}")
    out.append(Text(f"on station {view.on_station} of {view.planned_on_station}; "
                    f"spares on deck: {spares}; reliefs {view.reliefs}{relief}"))
    for alarm in view.alarms:
        out.append(Text(f"WATCH: {alarm}", style="bold red"))
    table = _table("vehicle", "charge %>", "drain %/min>", "min left>", "turn home",
                   "reach ship")
    for row in watch_rows(view, t):
        table.add_row(*row[:5], Text(row[5], style="bold red" if row[5] == "NO" else ""))
    if table.row_count:
        out.append(table)
    return out


def _targets(daemon: Daemon) -> list[RenderableType]:
    """The tracker's counts, then the confirmed and prior targets (tentative: counted)."""
    t = daemon.clock.now_s()
    view = daemon.core.view()
    tracks = track_dicts(view.tracks)
    table = _table("target", "x m>", "y m>", "sigma>", "lost", "seen s>", "status")
    for tr in view.firm_tracks():
        seen = None if tr.last_seen_s is None else t - tr.last_seen_s
        kind = tr.status
        table.add_row(tr.id, f"{tr.x_m:.0f}", f"{tr.y_m:.0f}", f"{tr.sigma:.2f}",
                      Text("LOST", style="bold red") if tr.lost else "", _fmt(seen, ".0f"),
                      Text(kind, style="magenta" if kind == "prior" else ""))
    counts = track_counts(tracks)
    return [Text(count_line(counts, len(view.search_cells))), table]


def _recent(lines: Iterable[dict[str, Any]]) -> list[RenderableType]:
    out: list[RenderableType] = [Text("recent:", style="bold")]
    for line in lines:
        level = line_level(line)
        style = "yellow" if level >= logging.WARNING else ""
        out.append(Text("  " + describe_line(line)[:200], style=style, no_wrap=True,
                        overflow="ellipsis"))
    return out


def render_status(
    daemon: Daemon, tally: EventTally, alerts: OperatorAlerts | None = None
) -> RenderableType:
    """The table as a ``rich`` renderable; the recent pane from ``tally``."""
    stats = daemon.router.link_stats()
    trouble = set(link_lines(stats, only_trouble=True))
    links = [Text(text, style="yellow" if text in trouble else "", no_wrap=True,
                  overflow="ellipsis") for text in link_lines(stats)]
    return Group(*_header(daemon, alerts), _vehicles(daemon), *_watch(daemon),
                 *_targets(daemon), *links,
                 Text(""), *_recent(tally.recent))


async def status_loop(
    daemon: Daemon, console: Console, alerts: OperatorAlerts | None = None, *, live: bool = True
) -> None:
    """Redraw the table once a wall second in place until cancelled (``live``); otherwise
    print it once when cancelled (a forced table on a file or dumb terminal). The journal is
    followed in a child task of this one (the daemon's task tree)."""
    tally = EventTally.from_lines(daemon.journal_file.recent)

    async def follow() -> None:
        async for line in daemon.journal_file.subscribe():
            tally.add(line)

    async with asyncio.TaskGroup() as group:
        group.create_task(follow(), name="status-journal")
        try:
            if live:
                await _redraw(daemon, console, tally, alerts)
            else:
                await asyncio.Event().wait()
        finally:
            if not live:
                console.print(render_status(daemon, tally, alerts))


async def _redraw(daemon: Daemon, console: Console, tally: EventTally,
                  alerts: OperatorAlerts | None) -> None:
    from rich.live import Live

    with Live(render_status(daemon, tally, alerts), console=console, auto_refresh=False,
              redirect_stdout=True, redirect_stderr=True) as display:
        try:
            while True:
                await asyncio.sleep(REDRAW_S)
                display.update(render_status(daemon, tally, alerts), refresh=True)
        finally:  # the last picture, as the run ends (Live draws it as it stops)
            display.update(render_status(daemon, tally, alerts))
