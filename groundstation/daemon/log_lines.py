"""How journal lines reach the console and ``gcs.log``: which events are logged at INFO and
how a line is shortened for a person (the journal keeps every value at full precision)."""

from __future__ import annotations

from typing import Any

__all__ = ["LOGGED_EVENTS", "describe_line", "short_value"]

LOGGED_EVENTS = frozenset(
    {
        "plan",
        "upload",
        "loiter_end",
        "link_lost",
        "link_restored",
        "override",
        "resume",
        "battery_low",
        "vehicle_joined",
        "reboot",
        "launch",
        "target_added",
        "target_removed",
        "task_error",
        "rtl",
        "release",
        "released",
        "send_home",
        "stop",
        "autopilot_mode",
        "on_ground",
        "waiting",
        "plan_failed",
        "signing_rejected",
        "no_progress",
        "landed",
        "resume_refused",
        "command_refused",
        "link_drops",
        "link_rebound",
        "peer_rebound",
    }
)


def describe_line(line: dict[str, Any]) -> str:
    skip = {"t", "unix_s", "event", "problem", "result", "hint", "request_id"}
    parts = [f"t={line['t']:.1f}", line["event"]]
    for key, value in line.items():
        if key not in skip:
            parts.append(f"{key}={short_value(value)}")
    return " ".join(parts)


def short_value(value: Any) -> Any:
    """Floats to 4 significant digits for the log (the journal keeps full precision)."""
    if isinstance(value, float):
        return f"{value:.4g}" if abs(value) < 1e5 else f"{value:.0f}"
    if isinstance(value, list) and len(value) > 6 and all(isinstance(v, float) for v in value):
        return f"[{len(value)} values, median {sorted(value)[len(value) // 2]:.3g}]"
    if isinstance(value, list):
        return [short_value(v) for v in value]
    return value
