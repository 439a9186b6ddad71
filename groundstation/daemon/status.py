"""The live status table (stdout is a TTY) or plain log lines (otherwise).

Table: one row per vehicle (id, system id, status, mode, armed, altitude, target, battery,
link, uploads), one per target (id, position, sigma, lost, last seen), one per link
(frames received, dropped unread, bad, foreign), then the newest journal lines. Redrawn
once a wall second.
"""

from __future__ import annotations

import asyncio
import sys
from typing import TYPE_CHECKING, Any, TextIO

if TYPE_CHECKING:
    from groundstation.daemon.daemon import Daemon

__all__ = ["link_lines", "render_table", "status_loop"]

_CLEAR = "\x1b[H\x1b[2J"


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


def render_table(daemon: Daemon) -> str:
    """The status table as text."""
    t = daemon.clock.now_s()
    lines = [
        f"floe gcs run  t={t:8.1f} s  speed-up {daemon.clock.speedup:g}x"
        f"{'  ADVISORY' if daemon.config.advisory else ''}  run {daemon.run_dir}",
        "",
        *_signing_line(daemon),
        f"{'vehicle':<10}{'sysid':>6} {'status':<11}{'mode':<13}{'armed':<6}{'alt m':>7}"
        f"  {'target':<8}{'batt %':>7}  {'link':<9}{'uploads':>8}",
    ]
    for s in sorted(daemon.sessions.values(), key=lambda s: s.system_id):
        snap = s.snapshot
        lines.append(
            f"{s.id:<10}{s.system_id:>6} {s.status:<11}{_fmt(snap.mode_name):<13}"
            f"{_fmt(snap.armed):<6}{_fmt(snap.alt_m, '7.0f'):>7}  "
            f"{_fmt(s.fly.target if s.fly else None):<8}"
            f"{_fmt(snap.battery_remaining_pct, '7.0f'):>7}  {s.link:<9}{s.uploads_ok:>8}"
        )
    lines += ["", f"{'target':<10}{'x m':>9}{'y m':>9}{'sigma':>11}  {'lost':<6}{'seen s':>8}"]
    for tr in daemon.core.observer.tracks():
        seen = None if tr.last_seen_s is None else t - tr.last_seen_s
        lines.append(
            f"{tr.id:<10}{tr.x_m:9.0f}{tr.y_m:9.0f}{tr.sigma:11.2f}  "
            f"{'LOST' if tr.lost else '':<6}{_fmt(seen, '8.0f'):>8}"
        )
    lines += ["", *link_lines(daemon.router.link_stats())]
    lines += ["", "recent:"]
    recent = [
        line
        for line in daemon.journal_file.recent
        if line["event"] not in ("track", "detection", "statustext", "mode")
    ]
    for line in recent[-8:]:
        extra = " ".join(
            f"{k}={v}"
            for k, v in line.items()
            if k not in ("t", "unix_s", "event", "problem", "result", "hint")
        )
        lines.append(f"  {line['t']:8.1f} {line['event']} {extra}"[:160])
    return "\n".join(lines)


def _signing_line(daemon: Daemon) -> list[str]:
    """``signing: refused ...`` per vehicle@link (nothing when signing is off)."""
    if daemon.signing is None:
        return []
    refused = daemon.signing.summary()["rejected"]
    text = ", ".join(f"{k} {sum(v.values())}" for k, v in refused.items()) or "none"
    return [f"signing on; refused frames: {text}", ""]


async def status_loop(daemon: Daemon, stream: TextIO | None = None) -> None:
    """Redraw the table once a wall second until cancelled."""
    out = stream or sys.stdout
    while True:
        out.write(_CLEAR + render_table(daemon) + "\n")
        out.flush()
        await asyncio.sleep(1.0)
