"""Journal records of the decision core's inputs and decisions, and back.

Replay is exact only if every input the core saw can be fed to it again. Frontends journal
each input with :func:`event_to_record` (``{"event": "input", "kind": "Telemetry", ...}``)
and each decision with :func:`command_to_record`; :func:`record_to_event` turns an input line
back into the event. Floats are written with full precision (JSON ``repr``), so a replayed
run sees bit-identical inputs.

State lines are written from the core's read model (``core/views.py``), one function each,
for every frontend: :func:`track_records` (every track, with its status), :func:`truth_records`
(the simulated icebergs' true positions) and :func:`search_record` (the search cells, at most
every :data:`SEARCH_RECORD_S`: :class:`SearchSchedule`). Full precision here too; journals of
``gcs run`` written before these functions existed rounded positions to 0.1 m and sigmas to
0.001 m^2 and left ``lost`` out when false, and are read alike (``gcs replay`` compares track
samples within that rounding, ``gcs report`` reads the fields it draws).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, get_args

from domain.errors import DataError
from domain.wind_triangle import wind_from_vector
from groundstation.core.commands import (
    CancelSolve,
    Command,
    FlyToTarget,
    LaunchVehicle,
    Note,
    PlanAdopted,
    ReleaseVehicle,
    SendHome,
    SetHome,
    SolveRequest,
    WindEstimate,
)
from groundstation.core.events import (
    Event,
)
from groundstation.core.views import CoreView
from planner import PlanResult, PlanStatus, problem_from_dict, problem_to_dict, result_to_dict

__all__ = [
    "SEARCH_RECORD_S",
    "RecordError",
    "SearchSchedule",
    "command_to_record",
    "event_to_record",
    "record_to_event",
    "result_from_record",
    "result_to_record",
    "search_record",
    "track_records",
    "truth_records",
]

SEARCH_RECORD_S = 10.0
"""Mission seconds between two ``search`` journal lines."""

_OPTIONAL_TELEMETRY = frozenset({"fix_age_s", "sigma_m"})
"""Telemetry fields written only when set (a predicted pose)."""

_EVENT_TYPES: dict[str, type] = {cls.__name__: cls for cls in get_args(Event)}


class RecordError(DataError):
    """A journal line cannot be turned back into an event."""


def result_to_record(result: PlanResult) -> dict[str, Any]:
    """The ``gcs plan`` output object plus ``hit_time_limit``."""
    return {**result_to_dict(result), "hit_time_limit": result.hit_time_limit}


def _optional_float(value: Any) -> float | None:
    return None if value is None else float(value)


def result_from_record(data: Mapping[str, Any]) -> PlanResult:
    """Inverse of :func:`result_to_record`; records written before ``bound`` and ``gap``
    existed read as None (no bound known)."""
    try:
        return PlanResult(
            status=PlanStatus(str(data["status"])),
            solver=str(data["solver"]),
            objective=float(data["objective"]),
            f1=float(data["f1"]),
            f2=float(data["f2"]),
            mu=float(data["mu"]),
            routes={str(k): [str(t) for t in v] for k, v in data["routes"].items()},
            idle={str(k): str(v) for k, v in data.get("idle", {}).items()},
            excluded=[str(t) for t in data.get("excluded", [])],
            solve_time_s=float(data["solve_time_s"]),
            hit_time_limit=bool(data.get("hit_time_limit", False)),
            bound=_optional_float(data.get("bound")),
            gap=_optional_float(data.get("gap")),
        )
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise RecordError(f"bad plan result record: {exc}") from exc


_RECORD_FIELDS: dict[type, tuple[str, ...]] = {}
"""Each input class's fields but ``t_s``, in declaration order (what
``dataclasses.fields`` gives; kept per class, as every tick and telemetry is journalled)."""


def event_to_record(event: Event) -> dict[str, Any]:
    """``{"event": "input", "kind": <class name>, "t": t_s, ...fields}``."""
    cls = type(event)
    record: dict[str, Any] = {"event": "input", "kind": cls.__name__, "t": event.t_s}
    names = _RECORD_FIELDS.get(cls)
    if names is None:
        names = _RECORD_FIELDS[cls] = tuple(
            f.name for f in dataclasses.fields(event) if f.name != "t_s")
    for name in names:
        value = getattr(event, name)
        if name == "prior" and value is False:
            continue  # TargetAdded lines read as before priors existed
        if name in _OPTIONAL_TELEMETRY and value is None:
            continue  # a fix's Telemetry line reads as before predictions existed
        record[name] = result_to_record(value) if isinstance(value, PlanResult) else value
    return record


def record_to_event(record: Mapping[str, Any]) -> Event:
    """Inverse of :func:`event_to_record`; raises RecordError on a malformed line."""
    kind = record.get("kind")
    cls = _EVENT_TYPES.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise RecordError(f"unknown input kind {kind!r}")
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        key = "t" if f.name == "t_s" else f.name
        if key not in record:
            if f.default is dataclasses.MISSING:
                raise RecordError(f"{kind}: missing field {key!r}")
            continue
        value = record[key]
        if f.name == "result":
            value = result_from_record(value)
        kwargs[f.name] = value
    try:
        event: Event = cls(**kwargs)
    except TypeError as exc:
        raise RecordError(f"{kind}: {exc}") from exc
    return event


def command_to_record(command: Command) -> dict[str, Any]:
    """A decision as a journal line (names other tools rely on: ``plan``, ``fly`` ...)."""
    if isinstance(command, PlanAdopted):
        return {
            "event": "plan", "t": command.t_s, "request_id": command.request_id,
            "routes": command.result.routes, "assignments": dict(command.assignments),
            "solve_time_s": command.result.solve_time_s, "status": command.result.status,
            "objective": command.result.objective,
            "reason": command.reason,
            "problem": problem_to_dict(command.problem),
            "hint": {k: list(v) for k, v in command.hint.items()},
            "result": result_to_record(command.result),
        }
    if isinstance(command, SolveRequest):
        return {
            "event": "solve_request", "t": command.t_s, "request_id": command.request_id,
            "reason": command.reason, "problem": problem_to_dict(command.problem),
            "hint": {k: list(v) for k, v in command.hint.items()},
        }
    if isinstance(command, CancelSolve):
        return {"event": "solve_cancelled", "t": command.t_s, "request_id": command.request_id}
    if isinstance(command, FlyToTarget):
        return {
            "event": "fly", "t": command.t_s, "vehicle": command.vehicle,
            "target": command.target, "x_m": command.x_m, "y_m": command.y_m,
            "loiter_s": command.loiter_s, "loiter_radius_m": command.loiter_radius_m,
            "route": list(command.route), "eta_s": command.eta_s,
            **({"through": [[c.target, c.x_m, c.y_m] for c in command.through]}
               if command.through else {}),
        }
    if isinstance(command, ReleaseVehicle):
        return {"event": "release", "t": command.t_s, "vehicle": command.vehicle,
                "reason": command.reason}
    if isinstance(command, SendHome):
        return {"event": "send_home", "t": command.t_s, "vehicle": command.vehicle,
                "reason": command.reason}
    if isinstance(command, SetHome):
        return {"event": "set_home", "t": command.t_s, "vehicle": command.vehicle,
                "x_m": command.x_m, "y_m": command.y_m}
    if isinstance(command, LaunchVehicle):
        return {"event": "launch_order", "t": command.t_s, "vehicle": command.vehicle,
                "reason": command.reason, "relieves": command.relieves}
    if isinstance(command, WindEstimate):
        speed, from_deg = wind_from_vector(command.wx_m_s, command.wy_m_s)
        return {"event": "wind", "t": command.t_s, "speed_m_s": speed, "from_deg": from_deg,
                "wx_m_s": command.wx_m_s, "wy_m_s": command.wy_m_s, "source": command.source,
                "vehicles": list(command.vehicles)}
    if isinstance(command, Note):
        return {"event": command.kind, "t": command.t_s, "vehicle": command.vehicle,
                "target": command.target, "detail": command.detail}
    raise TypeError(f"not a command: {command!r}")


def problem_of_record(record: Mapping[str, Any]) -> Any:
    """The planning problem recorded in a ``plan`` or ``solve_request`` line."""
    return problem_from_dict(record["problem"])


def track_records(t_s: float, view: CoreView) -> list[dict[str, Any]]:
    """One ``track`` line per track of ``view`` (``status``: tentative, confirmed or prior)."""
    return [
        {"event": "track", "t": t_s, "target": tr.id, "x_m": tr.x_m, "y_m": tr.y_m,
         "vx_m_s": tr.vx_m_s, "vy_m_s": tr.vy_m_s, "sigma": tr.sigma_m2, "lost": tr.lost,
         "status": tr.status}
        for tr in view.tracks
    ]


def truth_records(t_s: float, truth: Mapping[str, tuple[float, float]]
                  ) -> list[dict[str, Any]]:
    """One ``truth`` line per simulated iceberg (its true position), in ``truth``'s order."""
    return [{"event": "truth", "t": t_s, "target": target, "x_m": x, "y_m": y}
            for target, (x, y) in truth.items()]


def search_record(t_s: float, view: CoreView) -> dict[str, Any]:
    """The ``search`` line: ``cells`` as ``[id, x_m, y_m, size_m, value_m2]`` each."""
    cells = [[c.id, c.x_m, c.y_m, c.size_m, c.value_m2] for c in view.search_cells]
    return {"event": "search", "t": t_s, "cells": cells}


class SearchSchedule:
    """When a ``search`` line is due: at the first sample, then every
    :data:`SEARCH_RECORD_S` mission seconds (never for a core that does not search)."""

    def __init__(self, period_s: float = SEARCH_RECORD_S) -> None:
        self._period_s = period_s
        self._next_s = 0.0

    def due(self, t_s: float, view: CoreView) -> bool:
        if not view.searching or t_s < self._next_s - 1e-9:
            return False
        while self._next_s <= t_s + 1e-9:
            self._next_s += self._period_s
        return True
