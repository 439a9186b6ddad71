"""Outputs of the decision core: what the frontend must do (and journal)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from planner import PlanningProblem, PlanResult

__all__ = [
    "CancelSolve",
    "Command",
    "FlyToTarget",
    "Note",
    "PlanAdopted",
    "ReleaseVehicle",
    "SendHome",
    "SolveRequest",
]


@dataclass(frozen=True)
class SolveRequest:
    """Solve ``problem`` (warm-started from ``hint``) and answer with PlanSolved(request_id)."""

    t_s: float
    request_id: int
    problem: PlanningProblem
    hint: Mapping[str, Sequence[str]]
    reason: str


@dataclass(frozen=True)
class CancelSolve:
    """A newer request overtook ``request_id``: stop it; its answer will be ignored."""

    t_s: float
    request_id: int


@dataclass(frozen=True)
class PlanAdopted:
    """A plan was accepted: ``routes`` is the solver's, ``assignments`` what vehicles fly.

    ``hint`` and ``reason`` are the request's, so the journalled plan holds the planner's
    exact input (problem + hint) next to its result."""

    t_s: float
    request_id: int
    problem: PlanningProblem
    result: PlanResult
    assignments: Mapping[str, str]
    hint: Mapping[str, Sequence[str]] = field(default_factory=dict)
    reason: str = ""


@dataclass(frozen=True)
class FlyToTarget:
    """Fly to the aim point (the target predicted at arrival), loiter, then hold there.

    ``route`` is the rest of the vehicle's planned sequence, for display only. ``eta_s``
    is the mission time the core predicts the vehicle reaches the aim point.
    """

    t_s: float
    vehicle: str
    target: str
    x_m: float
    y_m: float
    loiter_s: float
    loiter_radius_m: float
    route: tuple[str, ...] = field(default=())
    eta_s: float | None = None


@dataclass(frozen=True)
class ReleaseVehicle:
    """Stop commanding ``vehicle`` (operator override, lost link)."""

    t_s: float
    vehicle: str
    reason: str


@dataclass(frozen=True)
class SendHome:
    """Command ``vehicle`` home (RTL), e.g. on low battery."""

    t_s: float
    vehicle: str
    reason: str


@dataclass(frozen=True)
class Note:
    """Something worth journalling that needs no action (e.g. a target discovered)."""

    t_s: float
    kind: str
    vehicle: str | None = None
    target: str | None = None
    detail: str = ""


Command = SolveRequest | CancelSolve | PlanAdopted | FlyToTarget | ReleaseVehicle | SendHome | Note
