"""The live status table of ``gcs run`` (built with ``rich``).

Header: mission time, speed-up, advisory, the run folder, the **live map URL and where the
token is** (``RUN/control.json``), the newest plan as readable routes
(``1 -> T5, T6 | 2 -> T2``), the wind the core plans with (``wind 12.0 m/s from 270°
(vehicles 1,2,3)``, or its fallback's source: ``config``, ``scenario``, ``none``), links
that heard no vehicle, dropped detections and signing refusals. Then one row per vehicle
(id, status, mode, link (``lag N s`` while its telemetry lags: docs/links.md), target,
altitude, battery, armed, its route in the plan line's plan, system id, uploads
ok/failed, its own wind estimate as ``speed/from``, upload retries: the columns that fit
the terminal's width, :func:`fit_table`), the tracker's counts
(``tracks: 9 confirmed, 3 tentative, 1 prior; 100 search cells``), one row per confirmed or
prior target (id, ``sqrt(sigma)`` in metres, state: tracked, LOST or never seen, last seen,
status, position; as many as the terminal's height leaves, the rest counted; tentative
tracks are only counted: clutter makes many), one line per link (frames received, dropped
unread, bad, foreign) and the newest operator events (``log_lines.is_operator_event``;
problems in colour).
Redrawn once a wall second in place (``rich.live.Live``); the console's own lines
(warnings, the start lines) stay above it. Colours come from ``rich``: none on a dumb
terminal or a file.
"""

from __future__ import annotations

import asyncio
import logging
import math
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from rich import box
from rich.console import Console, ConsoleOptions, Group, RenderableType, RenderResult
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


Cell = str | Text


@dataclass(frozen=True)
class Column:
    """One column of a fitted table: ``rank`` 0 is always shown; higher ranks are left out
    first when the terminal is too narrow (see :func:`fit_table`)."""

    header: str
    rank: int
    right: bool = False


def _cell_width(cell: Cell) -> int:
    return Text(cell).cell_len if isinstance(cell, str) else cell.cell_len


def fit_table(columns: list[Column], rows: list[list[Cell]], width: int) -> Table:
    """The columns that fit ``width`` terminal cells, whole: each column is as wide as its
    header or its widest cell (never cut to ``vehi…``), three cells apart; while the sum is
    wider than ``width``, the column of the highest rank (the rightmost of equal rank) is
    left out. Rank-0 columns always stay."""
    widths = [max([_cell_width(c.header)] + [_cell_width(r[i]) for r in rows])
              for i, c in enumerate(columns)]
    keep = list(range(len(columns)))

    def total() -> int:
        return sum(widths[i] for i in keep) + 3 * max(0, len(keep) - 1)

    while total() > width:
        droppable = [i for i in keep if columns[i].rank > 0]
        if not droppable:
            break
        worst = max(droppable, key=lambda i: (columns[i].rank, i))
        keep.remove(worst)
    table = Table(box=box.SIMPLE_HEAD, pad_edge=False, show_edge=False)
    for i in keep:
        table.add_column(columns[i].header, justify="right" if columns[i].right else "left",
                         no_wrap=True, min_width=widths[i])
    for row in rows:
        table.add_row(*(row[i] for i in keep))
    return table


def _link_cell(link: LinkState, lagging: bool, age_s: float | None) -> Text:
    """The link's state, or ``lag N s`` while the vehicle's telemetry lags (its frames
    arrive, its newest position is old: planned from a prediction)."""
    if lagging and age_s is not None:
        return Text(f"lag {age_s:.0f} s", style="bold yellow")
    return Text(link, style=_LINK_STYLE.get(link, "yellow"))


VEHICLE_COLUMNS = [
    Column("vehicle", 0), Column("status", 0), Column("mode", 0), Column("link", 0),
    Column("target", 0), Column("alt m", 1, right=True), Column("batt %", 1, right=True),
    Column("armed", 2), Column("route", 3), Column("sysid", 4, right=True),
    Column("uploads", 5, right=True), Column("wind", 6, right=True),
    Column("retries", 6, right=True),
]


def planned_route(daemon: Daemon, vehicle: str) -> list[str] | None:
    """The vehicle's route in the newest plan (the plan line's own routes), None when the
    plan gave it none or there is no plan yet."""
    plan = daemon.last_plan
    route = plan["routes"].get(vehicle) if plan is not None else None
    return [str(t) for t in route] if isinstance(route, list) else None


def _route_cell(route: list[str] | None) -> str:
    """``T10, T8 +3``: the plan's first two targets and how many more."""
    if not route:
        return "-"
    more = f" +{len(route) - 2}" if len(route) > 2 else ""
    return ", ".join(route[:2]) + more


def _vehicles(daemon: Daemon, width: int) -> Table:
    """One row per vehicle, every vehicle; the columns that fit ``width``. ``target`` is
    what the vehicle flies to; ``route`` the plan line's route for it (the same source)."""
    rows: list[list[Cell]] = []
    for s in sorted(daemon.sessions.values(), key=lambda s: s.system_id):
        snap = s.snapshot
        retries = s.upload_retries
        rows.append([
            s.id, s.status, _fmt(snap.mode_name), _link_cell(s.link, s.lagging, s.telemetry_age_s),
            _fmt(s.shown_fly.target if s.shown_fly else None), _fmt(snap.alt_m, ".0f"),
            _fmt(snap.battery_remaining_pct, ".0f"), "yes" if snap.armed else (
                "-" if snap.armed is None else "no"),
            _route_cell(planned_route(daemon, s.id)), str(s.system_id),
            Text(f"{s.uploads_ok}/{s.uploads_failed}",
                 style="red" if s.uploads_failed else ""),
            _own_wind(snap), Text(str(retries), style="yellow" if retries else ""),
        ])  # fmt: skip
    if not daemon.sessions:
        rows.append(["(none yet)", *[""] * (len(VEHICLE_COLUMNS) - 1)])
    return fit_table(VEHICLE_COLUMNS, rows, width)


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


TARGET_COLUMNS = [
    Column("target", 0), Column("√σ m", 0, right=True), Column("state", 0),
    Column("seen", 1, right=True), Column("status", 2), Column("x m", 3, right=True),
    Column("y m", 3, right=True),
]


def target_state(lost: bool, last_seen_s: float | None) -> Text:
    """``never seen`` (no measurement yet: a listed or reported position only), ``LOST``
    (seen once, then ``sqrt(sigma)`` outgrew the camera's footprint) or ``tracked``."""
    if last_seen_s is None:
        return Text("never seen", style="yellow")
    if lost:
        return Text("LOST", style="bold red")
    return Text("tracked")


def _seen_cell(t_s: float, last_seen_s: float | None) -> str:
    """``12 s ago``; ``never``."""
    return "never" if last_seen_s is None else f"{max(0.0, t_s - last_seen_s):.0f} s ago"


def _targets(daemon: Daemon, width: int, max_rows: int | None = None) -> list[RenderableType]:
    """The tracker's counts, then the confirmed and prior targets (tentative: counted),
    ``sqrt(sigma)`` in metres, the lost ones first, then the least certain. At most
    ``max_rows`` rows (the terminal's height); a last line counts the ones left out."""
    t = daemon.clock.now_s()
    view = daemon.core.view()
    tracks = track_dicts(view.tracks)
    firm = sorted(view.firm_tracks(),
                  key=lambda tr: (not (tr.lost and tr.last_seen_s is not None), -tr.sigma))
    shown = firm if max_rows is None or len(firm) <= max_rows else firm[:max(0, max_rows - 1)]
    rows: list[list[Cell]] = []
    for tr in shown:
        kind = tr.status
        rows.append([tr.id, f"{math.sqrt(max(0.0, tr.sigma)):.0f}",
                     target_state(tr.lost, tr.last_seen_s), _seen_cell(t, tr.last_seen_s),
                     Text(kind, style="magenta" if kind == "prior" else ""),
                     f"{tr.x_m:.0f}", f"{tr.y_m:.0f}"])
    counts = track_counts(tracks)
    out: list[RenderableType] = [Text(count_line(counts, len(view.search_cells)))]
    if rows:
        out.append(fit_table(TARGET_COLUMNS, rows, width))
    if len(shown) < len(firm):
        out.append(Text(f"... {len(firm) - len(shown)} more targets (the least uncertain; "
                        f"all on the live map)", style="dim"))
    return out


def _recent(lines: Iterable[dict[str, Any]]) -> list[RenderableType]:
    out: list[RenderableType] = [Text("recent:", style="bold")]
    for line in lines:
        level = line_level(line)
        style = "yellow" if level >= logging.WARNING else ""
        out.append(Text("  " + describe_line(line)[:200], style=style, no_wrap=True,
                        overflow="ellipsis"))
    return out


class StatusView:
    """The status picture, laid out for the terminal it is drawn on (``rich`` hands it the
    width and height at each redraw): the columns that fit the width (:func:`fit_table`),
    every vehicle, then as many targets as the height leaves (at least 3, the rest counted),
    then the newest events in what is left."""

    def __init__(self, daemon: Daemon, tally: EventTally,
                 alerts: OperatorAlerts | None) -> None:
        self.daemon, self.tally, self.alerts = daemon, tally, alerts

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        daemon, width = self.daemon, options.max_width
        # one line short of the terminal: a picture as tall as the screen scrolls it as
        # rich.live redraws, and a warning printed above would land on the table's last line
        height = (options.height or console.height) - 1
        stats = daemon.router.link_stats()
        trouble = set(link_lines(stats, only_trouble=True))
        links = [Text(text, style="yellow" if text in trouble else "", no_wrap=True,
                      overflow="ellipsis") for text in link_lines(stats)]
        top = Group(*_header(daemon, self.alerts), _vehicles(daemon, width), *_watch(daemon))

        def lines(renderable: RenderableType) -> int:
            return len(console.render_lines(renderable, options.update(height=None),
                                            pad=False))

        used = lines(top) + len(links) + 1  # the blank line before the recent pane
        # the targets' count line, the table's header and rule, each target; the recent
        # pane gets what is left (at least its title)
        spare = height - used - 3 - 1
        max_rows = max(3, spare - min(len(self.tally.recent), 3))
        targets = _targets(daemon, width, max_rows)
        left = height - used - lines(Group(*targets)) - 1
        recent = list(self.tally.recent)[-left:] if left > 0 else []
        yield Group(top, *targets, *links, Text(""), *_recent(recent))


def render_status(
    daemon: Daemon, tally: EventTally, alerts: OperatorAlerts | None = None
) -> RenderableType:
    """The table as a ``rich`` renderable (:class:`StatusView`); the recent pane from
    ``tally``."""
    return StatusView(daemon, tally, alerts)


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
