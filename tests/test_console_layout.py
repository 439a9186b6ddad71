"""The live table laid out for a real terminal (groundstation/daemon/status.py): at 80x24
and at 160x50 every vehicle is shown with whole, readable headers, no line is wider than
the terminal, the picture fits its height, ``sqrt(sigma)`` is in metres, lost and
never-seen targets are told apart, and the plan line and the vehicle rows agree.

A fake daemon carries what ``render_status`` reads (the real ``TrackView``,
``VehicleSnapshot`` and ``WindState``); ``rich`` renders it at a fixed size, as on a
terminal of that size (checked by hand with tmux: the report of issue 29).
"""

from __future__ import annotations

import io
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
from rich.console import Console

from groundstation.core.views import TrackView
from groundstation.core.wind_estimate import WindState
from groundstation.daemon.status import EventTally, render_status
from groundstation.mavlink.telemetry_events import VehicleSnapshot
from groundstation.vehicle.state import LinkState

T_S = 600.0


def _vehicle(k: int) -> Any:
    snap = VehicleSnapshot(system_id=k, alt_m=100.0 + 15 * k, mode_name="AUTO", armed=True,
                           battery_remaining_pct=75.0, wind_xy_m_s=(3.0, 1.0))
    return SimpleNamespace(
        id=str(k), system_id=k, status="active", snapshot=snap, link=LinkState.OK,
        lagging=False, telemetry_age_s=0.4, uploads_ok=30 + k, uploads_failed=0,
        upload_retries=0, fly=SimpleNamespace(target=f"T{k}"),
        shown_fly=SimpleNamespace(target=f"T{k}"),
    )


def _tracks(n: int) -> tuple[TrackView, ...]:
    out = []
    for k in range(1, n + 1):
        seen = None if k == 2 else T_S - 10.0 * k  # T2: never seen
        out.append(TrackView(id=f"T{k}", status="prior" if k == 2 else "confirmed",
                             x_m=100.0 * k, y_m=-50.0 * k, sigma_m2=900.0 * k,
                             existence=1.0, t_s=T_S, lost=k in (2, 3), last_seen_s=seen))
    return tuple(out)


def _daemon(vehicles: int, targets: int) -> Any:
    view = SimpleNamespace(
        t_s=T_S, tracks=_tracks(targets), search_cells=(), wind=WindState(3.0, 1.0, "config"),
        wind_outliers=frozenset(), firm_tracks=lambda: _tracks(targets),
    )
    sessions = {str(k): _vehicle(k) for k in range(1, vehicles + 1)}
    routes = {str(k): [f"T{k}", f"T{k + 3}", f"T{k + 6}", f"T{k + 9}"]
              for k in range(1, vehicles + 1)}
    return SimpleNamespace(
        clock=SimpleNamespace(now_s=lambda: T_S, speedup=50.0),
        config=SimpleNamespace(advisory=False),
        run_dir=Path("runs/20261123T091046Z"), control_url="http://127.0.0.1:38349",
        last_plan={"t": 595.7, "routes": routes, "status": "optimal", "solve_time_s": 0.001},
        core=SimpleNamespace(view=lambda: view, watch_view=lambda: None),
        core_config=SimpleNamespace(wind_aware=True), wind_fallback_source="config",
        signing=None, sessions=sessions,
        router=SimpleNamespace(link_stats=lambda: {"sim": {"received": 37}}),
    )


def _screen(daemon: Any, width: int, height: int, recent: int = 8) -> list[str]:
    tally = EventTally.from_lines(
        {"t": 500.0 + k, "event": "vehicle_joined", "vehicle": str(k)} for k in range(recent))
    out = io.StringIO()
    console = Console(file=out, width=width, height=height, force_terminal=False,
                      color_system=None)
    console.print(render_status(daemon, tally))
    return out.getvalue().rstrip("\n").split("\n")


@pytest.mark.parametrize(("width", "height", "vehicles"), [(80, 24, 3), (160, 50, 3),
                                                           (80, 24, 6), (160, 50, 10)])
def test_every_vehicle_with_whole_headers_within_the_screen(
    width: int, height: int, vehicles: int
) -> None:
    lines = _screen(_daemon(vehicles, 14), width, height)
    assert len(lines) <= height, "\n".join(lines)
    assert all(len(line) <= width for line in lines), "\n".join(lines)
    text = "\n".join(lines)
    assert "…" not in text, text
    header = next(line for line in lines if line.startswith("vehicle"))
    for name in ("vehicle", "status", "mode", "link", "target", "alt m", "batt %"):
        assert name in header.split("  ") or f" {name} " in f" {header} ", (name, header)
    rows = [line.split()[0] for line in lines[lines.index(header) + 2:]
            if line[:1].isdigit()]
    assert rows[:vehicles] == [str(k) for k in range(1, vehicles + 1)], text
    target_header = next(line for line in lines if line.startswith("target"))
    assert "√σ m" in target_header and "state" in target_header


def test_wide_terminal_shows_every_column_and_target() -> None:
    lines = _screen(_daemon(3, 14), 160, 50)
    header = next(line for line in lines if line.startswith("vehicle"))
    for name in ("sysid", "armed", "route", "uploads", "retries", "wind"):
        assert name in header, header
    targets = [line for line in lines if (line.startswith("T") and "s ago" in line) or
               line.startswith("T2 ")]
    assert len(targets) == 14, "\n".join(lines)


def test_sqrt_sigma_in_metres_and_lost_told_from_never_seen() -> None:
    lines = _screen(_daemon(3, 4), 120, 40)
    row = {line.split()[0]: line for line in lines if line[:2] in ("T1", "T2", "T3", "T4")}
    assert row["T3"].split()[1] == "52"  # sqrt(2700 m^2)
    assert "LOST" in row["T3"] and "never" not in row["T3"]
    assert "never seen" in row["T2"] and "LOST" not in row["T2"]
    assert "tracked" in row["T1"] and "10 s ago" in row["T1"]
    assert "33941" not in "\n".join(lines)


def test_short_terminal_counts_the_targets_left_out() -> None:
    lines = _screen(_daemon(3, 30), 80, 24)
    assert len(lines) <= 24
    more = [line for line in lines if "more targets" in line]
    assert more, "\n".join(lines)
    shown = [line for line in lines if line[:1] == "T" and line[1:2].isdigit()]
    assert len(shown) + int(more[0].split()[1]) == 30
    assert shown[0].startswith("T3 "), shown  # the lost (once seen) one first


def test_plan_line_and_vehicle_rows_agree() -> None:
    lines = _screen(_daemon(3, 14), 160, 50)
    plan = next(line for line in lines if line.startswith("plan "))
    assert "1 -> T1, T4, T7, T10" in plan
    row = next(line for line in lines if line.startswith("1 "))
    assert "T1, T4 +2" in row, row


def test_a_released_vehicle_shows_no_target() -> None:
    """Released (or taken over, or sent home), the vehicle keeps its last mission in the
    controller, but the console shows no target for it, as the API and the page do."""
    daemon = _daemon(3, 4)
    released = daemon.sessions["2"]
    released.status, released.shown_fly = "released", None
    lines = _screen(daemon, 160, 50)
    row = next(line for line in lines if line.startswith("2 "))
    assert "released" in row and "T2" not in row.split("released", 1)[1].split()[:4], row
    assert "T1" in next(line for line in lines if line.startswith("1 "))
