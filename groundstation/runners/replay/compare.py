"""Comparing what a replayed decision core decides with what the journal recorded.

Decisions are normalised into :class:`Decision` values, from journal records (either
frontend's spelling) and from the replayed core's commands (through the same
``command_to_record``), so both sides go through one function:

======================  ===========================================================
journal record          decision (kind, key)
======================  ===========================================================
``solve_request``       ("solve", request id): the planner's input
``plan``                ("plan", request id): adopted, with its assignments
``solve_cancelled``,    ("cancel", request id)
``plan_cancelled``
``fly``                 ("fly", vehicle): target and aim point
``release``             ("release", vehicle), or ("send_home", vehicle) if ``home``
``send_home``           ("send_home", vehicle)
``wind``                ("wind", "estimate"): source and vector (1e-9)
notes of the core       ("note:<kind>", vehicle/target)
======================  ===========================================================

Planning problems are compared number by number at 1e-9 relative (absolute 1e-9 near 0):
same vehicles and poses, same targets, positions and sigmas, same settings.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "AIM_TOLERANCE_M",
    "NOTE_KINDS",
    "Decision",
    "compare_decisions",
    "compare_problems",
    "decision_of_record",
    "describe",
]

NOTE_KINDS = frozenset(
    {"target_discovered", "duplicate_target", "unknown_target", "wind_outlier",
     "wind_refused", "wind_fallback", "track_born", "track_confirmed", "track_deleted"}
)
"""Notes the decision core emits (journalled as their own event by ``gcs simulate``)."""

AIM_TOLERANCE_M = 0.1
"""Aim points closer than this are the same (``gcs run`` journals them to 0.1 m)."""

_REL = 1e-9


@dataclass(frozen=True)
class Decision:
    """One decision, normalised for comparison."""

    t_s: float
    kind: str
    key: str
    fields: Mapping[str, Any] = field(default_factory=dict)


def _request_id(record: Mapping[str, Any]) -> str:
    value = record.get("request_id", record.get("request"))
    return str(value) if value is not None else "?"


def decision_of_record(record: Mapping[str, Any]) -> Decision | None:
    """The decision a journal record holds, or None if it is not a decision."""
    event = record.get("event")
    t_s = float(record.get("t", 0.0) or 0.0)
    if event == "solve_request":
        return Decision(t_s, "solve", _request_id(record), {"problem": record.get("problem")})
    if event == "plan":
        return Decision(
            t_s,
            "plan",
            _request_id(record),
            {
                "assignments": dict(record.get("assignments") or {}),
            },
        )
    if event in ("solve_cancelled", "plan_cancelled"):
        return Decision(t_s, "cancel", _request_id(record))
    vehicle = str(record.get("vehicle"))
    if event == "fly":
        return Decision(
            t_s,
            "fly",
            vehicle,
            {
                "target": record.get("target"),
                "x_m": record.get("x_m"),
                "y_m": record.get("y_m"),
            },
        )
    if event == "release":
        kind = "send_home" if record.get("home") else "release"
        return Decision(t_s, kind, vehicle)
    if event == "send_home":
        return Decision(t_s, "send_home", vehicle)
    if event == "wind":
        return Decision(
            t_s,
            "wind",
            "estimate",
            {k: record.get(k) for k in ("source", "wx_m_s", "wy_m_s")},
        )
    note = record.get("kind") if event == "note" else event
    if note in NOTE_KINDS:
        return Decision(t_s, f"note:{note}", f"{record.get('vehicle')}/{record.get('target')}")
    return None


def describe(decision: Decision | None) -> str:
    """Short human text of a decision (``fly T3 (1203.4, 88.1)``)."""
    if decision is None:
        return "none"
    f = decision.fields
    if decision.kind == "fly":
        x, y = f.get("x_m"), f.get("y_m")
        where = (
            f" ({x:.1f}, {y:.1f})"
            if isinstance(x, int | float) and isinstance(y, int | float)
            else ""
        )
        return f"fly {f.get('target')}{where}"
    if decision.kind == "plan":
        pairs = ", ".join(f"{k}->{v}" for k, v in sorted(f.get("assignments", {}).items()))
        return f"plan #{decision.key} [{pairs}]"
    if decision.kind == "solve":
        return f"solve request #{decision.key}"
    if decision.kind == "cancel":
        return f"cancel request #{decision.key}"
    if decision.kind == "wind":
        x, y = f.get("wx_m_s"), f.get("wy_m_s")
        if isinstance(x, int | float) and isinstance(y, int | float):
            return f"wind ({x:.3f}, {y:.3f}) m/s from {f.get('source')}"
    return f"{decision.kind} {decision.key}"


def _close(a: Any, b: Any) -> bool:
    if isinstance(a, int | float) and isinstance(b, int | float):
        return math.isclose(float(a), float(b), rel_tol=_REL, abs_tol=_REL)
    return bool(a == b)


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.10g}"
    return repr(value)


def compare_problems(
    recorded: Mapping[str, Any], now: Mapping[str, Any], limit: int = 6
) -> list[tuple[str, str, str]]:
    """What differs between two problems (``gcs plan`` format), as (what, recorded, now)
    triples, at most ``limit`` of them plus a count of the rest; empty if the same."""
    out: list[tuple[str, str, str]] = []
    for key in sorted(set(recorded) | set(now)):
        if key in ("uavs", "targets"):
            continue
        if not _close(recorded.get(key), now.get(key)):
            out.append((key, _fmt(recorded.get(key)), _fmt(now.get(key))))
    for group, names in (("uavs", ("x", "y", "heading")), ("targets", ("x", "y", "sigma"))):
        rec = {str(item.get("id")): item for item in recorded.get(group) or []}
        cur = {str(item.get("id")): item for item in now.get(group) or []}
        if set(rec) != set(cur):
            out.append((group, ",".join(sorted(rec)), ",".join(sorted(cur))))
        for ident in sorted(set(rec) & set(cur)):
            for name in names:
                a, b = rec[ident].get(name), cur[ident].get(name)
                if not _close(a, b):
                    out.append((f"{group[:-1]} {ident} {name}", _fmt(a), _fmt(b)))
    if len(out) > limit:
        out = [*out[:limit], (f"{len(out) - limit} more values", "...", "...")]
    return out


def _same(recorded: Decision, now: Decision) -> bool:
    if recorded.kind == "fly":
        a, b = recorded.fields, now.fields
        if a.get("target") != b.get("target"):
            return False
        try:
            return (
                math.dist((float(a["x_m"]), float(a["y_m"])), (float(b["x_m"]), float(b["y_m"])))
                <= AIM_TOLERANCE_M
            )
        except (KeyError, TypeError, ValueError):
            return True  # no aim point recorded: the target decides
    if recorded.kind == "plan":
        return dict(recorded.fields.get("assignments", {})) == dict(
            now.fields.get("assignments", {})
        )
    if recorded.kind == "wind":
        a, b = recorded.fields, now.fields
        return a.get("source") == b.get("source") and all(
            _close(a.get(k), b.get(k)) for k in ("wx_m_s", "wy_m_s")
        )
    return True


def _unique(decisions: Iterable[Decision]) -> dict[tuple[str, str], Decision]:
    """One decision per (kind, key): ``gcs simulate`` journals a release twice."""
    out: dict[tuple[str, str], Decision] = {}
    for d in decisions:
        out.setdefault((d.kind, d.key), d)
    return out


def compare_decisions(
    recorded: Iterable[Decision], now: Iterable[Decision], *, skip_kinds: frozenset[str]
) -> list[tuple[str, Decision | None, Decision | None]]:
    """Pairs (kind, recorded, now) that differ, for the decisions of one input.

    ``skip_kinds`` are not compared here (``solve``: compared through the problem).
    """
    rec = _unique(d for d in recorded if d.kind not in skip_kinds)
    cur = _unique(d for d in now if d.kind not in skip_kinds)
    out: list[tuple[str, Decision | None, Decision | None]] = []
    for key in sorted(set(rec) | set(cur)):
        a, b = rec.get(key), cur.get(key)
        if a is None or b is None or not _same(a, b):
            out.append((key[0], a, b))
    return out
