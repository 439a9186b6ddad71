"""Which journal lines an operator sees, how important each is, and how it reads.

**Operator events.** One predicate, :func:`is_operator_event`, decides for every operator
view: the console's log lines (``--status log``), the status table's recent pane, the live
page's EVENTS pane (the control server pushes only these) and ``GET /api/events?notable=1``.
A line is an operator event when its ``event`` is in :data:`OPERATOR_EVENTS`, or when it is a
``statustext`` of severity WARNING or worse (MAV_SEVERITY <= 4), a ``clock_check`` that
failed, or an ``arm``/``param_set`` that failed. Everything else (``track``, ``truth``,
``detection``, ``input``, ``mode``, ``armed``, ``fly``, ``solve_request`` ...)
is a state update: its effect is in the tables and the map, every line of it in the journal.

**Level.** :func:`line_level`: WARNING for a problem (:data:`PROBLEM_EVENTS`, ``ok: false``,
an upload that needed retries), INFO otherwise; warnings reach the console in every
``--status`` mode.

**Reading.** :func:`describe_line`: ``t=25.1 plan 1 -> T5, T8 | 2 -> T7 (optimal, 3 ms,
period)``, ``t=61.0 wind 12.0 m/s from 270 deg (vehicles 1, 2)``; other events as
``key=value`` with floats to 4 significant digits, without the bulky planner records
(``problem``, ``result``, ``hint``) or nested mappings (the journal keeps every value at
full precision).

A ``wind`` line (the core's estimate changed meaningfully) is an operator event, and so are
a ``wind_outlier``, a ``wind_fallback`` and an ``airspeed_failed`` (problems) and an
``airspeed_recovered``; the vehicles' periodic ``WindReport`` inputs are not.

The tracker's notes: ``track_confirmed`` is an operator event, and so is a
``track_deleted`` of a track that was confirmed or a prior entry (its line says
``confirmed: true``, or does not say); ``track_born`` and the deletion of a never-confirmed
tentative track (``confirmed: false``) are state updates, as clutter makes them frequent
(``daemon/track_views.py``).

The ship watch's (``core/watch.py``, docs/ship.md): a ``watch_alarm`` (no vehicle in the
plan, fewer on station than planned, a vehicle that may not reach the ship), a
``vehicle_down`` or ``vehicle_fell``, a ``home_set_failed`` and a silent ship feed are
problems; ``watch_clear``, ``vehicle_recovered``, ``vehicle_spare``, ``launch_order`` and
the feed's ``ship_feed_restored`` are operator events; the homes' ``set_home`` (every
vehicle, each time the ship moved ``home_update_m``) and the battery inputs are state.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

__all__ = [
    "OPERATOR_EVENTS",
    "PROBLEM_EVENTS",
    "describe_line",
    "format_routes",
    "is_operator_event",
    "line_level",
    "override_detail",
    "plan_detail",
    "short_value",
    "wind_detail",
]

PROBLEM_EVENTS = frozenset(
    {
        "link_lost",
        "link_silent",
        "link_drops",
        "link_rebound",
        "peer_rebound",
        "override",
        "battery_low",
        "reboot",
        "task_error",
        "task_gave_up",
        "core_error",
        "plan_failed",
        "signing_rejected",
        "no_progress",
        "landed",
        "resume_refused",
        "command_refused",
        "launch_timeout",
        "launch_held",
        "ship_beacon_conflict",
        "landed_unplaced",
        "stop_wait_timeout",
        "target_refused",
        "detections_dropped",
        "duplicate_target",
        "unknown_target",
        "wind_outlier",
        "wind_refused",
        "wind_fallback",
        "airspeed_failed",
        "cruise_speed_refused",
        "watch_alarm",
        "vehicle_down",
        "vehicle_fell",
        "home_set_failed",
        "ship_feed_silent",
        "unknown_systems",
        "file_write_failed",
    }
)
"""Operator events that report something wrong: logged at WARNING."""

OPERATOR_EVENTS = PROBLEM_EVENTS | frozenset(
    {
        "plan",
        "upload",
        "loiter_end",
        "link_restored",
        "resume",
        "resume_deferred",
        "target_fixed",
        "vehicle_seen",
        "vehicle_joined",
        "cruise_speed",
        "wind_replan",
        "origin",
        "launch",
        "launch_request",
        "launch_wanted",
        "waiting",
        "on_ground",
        "target_added",
        "target_removed",
        "target_discovered",
        "clipped",
        "rtl",
        "release",
        "released",
        "send_home",
        "autopilot_mode",
        "wind",
        "airspeed_recovered",
        "start",
        "stop",
        "track_confirmed",
        "watch_clear",
        "power_up",
        "vehicle_recovered",
        "vehicle_spare",
        "launch_order",
        "ship_feed_restored",
        "ship_feed_link",
        "fence",
    }
)
"""The events every operator view shows (plus the conditional ones of the module doc)."""

MAV_SEVERITY_WARNING = 4


def is_operator_event(line: Mapping[str, Any]) -> bool:
    """True if an operator view shows ``line`` (see the module docstring)."""
    event = line.get("event")
    if event in OPERATOR_EVENTS:
        return True
    if event == "statustext":
        severity = line.get("severity")
        return isinstance(severity, int) and severity <= MAV_SEVERITY_WARNING
    if event in ("clock_check", "arm", "param_set"):
        return line.get("ok") is False
    if event == "track_deleted":
        return line.get("confirmed") is not False
    return False


def line_level(line: Mapping[str, Any]) -> int:
    """``logging.WARNING`` for a problem, ``logging.INFO`` for other operator events,
    ``logging.DEBUG`` for state updates: above DEBUG exactly when :func:`is_operator_event`
    (one call serves a view that needs both)."""
    if not is_operator_event(line):
        return logging.DEBUG
    event = line.get("event")
    if event in PROBLEM_EVENTS or event == "statustext" or line.get("ok") is False:
        return logging.WARNING
    retries = line.get("retries")
    if event == "upload" and isinstance(retries, int) and retries > 0:
        return logging.WARNING
    return logging.INFO


def format_routes(routes: Mapping[str, Any]) -> str:
    """``{"1": ["T5", "T6"], "2": []}`` -> ``1 -> T5, T6 | 2 -> -``."""
    parts = []
    for vehicle, route in routes.items():
        names = ", ".join(str(t) for t in route) if isinstance(route, list) and route else "-"
        parts.append(f"{vehicle} -> {names}")
    return " | ".join(parts) or "no vehicle"


_SKIP = frozenset({"t", "unix_s", "event", "problem", "result", "hint", "request_id"})


def describe_line(line: Mapping[str, Any]) -> str:
    """One readable line for a person (see the module docstring)."""
    t = line.get("t")
    head = f"t={t:.1f}" if isinstance(t, int | float) else "t=?"
    event = str(line.get("event"))
    if event == "plan" and isinstance(line.get("routes"), Mapping):
        return f"{head} plan {format_routes(line['routes'])} ({plan_detail(line)})"
    if event == "wind" and isinstance(line.get("speed_m_s"), int | float):
        return f"{head} wind {wind_detail(line)}"
    if event == "override" and line.get("vehicle") is not None:
        return f"{head} {override_detail(line)}"
    parts = [head, event]
    for key, value in line.items():
        if key in _SKIP or isinstance(value, Mapping):
            continue
        if event == "upload" and key == "retries" and value == 0:
            continue
        parts.append(f"{key}={short_value(value)}")
    return " ".join(parts)


def plan_detail(line: Mapping[str, Any]) -> str:
    """``optimal, 3 ms, period``: a plan's status, solve time and reason (if any)."""
    detail = [str(line.get("status", "?"))]
    solve_s = line.get("solve_time_s")
    if isinstance(solve_s, int | float):
        detail.append(f"{solve_s * 1000:.0f} ms")
    if line.get("reason"):
        detail.append(str(line["reason"]))
    return ", ".join(detail)


def override_detail(line: Mapping[str, Any]) -> str:
    """``operator took vehicle 1 (RTL): floe stops commanding it ...`` of an ``override``
    line: who took it (the operator, another ground station, a failsafe floe cannot tell
    from a pilot's switch) and how it is given back."""
    vehicle, reason = line.get("vehicle"), str(line.get("reason", ""))
    mode = line.get("mode")
    if reason.startswith("mode "):
        who = f"operator took vehicle {vehicle} ({mode or reason[5:]})"
    elif reason == "failsafe":
        who = f"failsafe took vehicle {vehicle} ({mode or '?'}), or its operator did"
    elif reason.startswith("api"):
        who = f"operator released vehicle {vehicle} ({reason})"
    else:
        who = f"vehicle {vehicle} taken over: {reason}"
    return (
        f"{who}; floe stops commanding it until it is given back "
        f"(AUTO, or 'gcs vehicle resume {vehicle}')"
    )


def wind_detail(line: Mapping[str, Any]) -> str:
    """``12.0 m/s from 270 deg (vehicles 1, 2, 3)`` of a ``wind`` line."""
    speed, from_deg = line.get("speed_m_s"), line.get("from_deg")
    if not (isinstance(speed, int | float) and isinstance(from_deg, int | float)):
        text = "?"
    else:
        text = "calm" if speed < 0.05 else f"{speed:.1f} m/s from {from_deg:.0f} deg"
    source = str(line.get("source", "?"))
    vehicles = line.get("vehicles")
    if source == "vehicles" and isinstance(vehicles, list) and vehicles:
        source += " " + ", ".join(str(v) for v in vehicles)
    return f"{text} ({source})"


def short_value(value: Any) -> Any:
    """Floats to 4 significant digits for the log (the journal keeps full precision)."""
    if isinstance(value, float):
        return f"{value:.4g}" if abs(value) < 1e5 else f"{value:.0f}"
    if isinstance(value, list) and len(value) > 6 and all(isinstance(v, float) for v in value):
        return f"[{len(value)} values, median {sorted(value)[len(value) // 2]:.3g}]"
    if isinstance(value, list):
        return [short_value(v) for v in value]
    return value
