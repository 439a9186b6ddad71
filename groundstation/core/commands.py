"""Outputs of the decision core: what the frontend must do (and journal)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from planner import PlanningProblem, PlanResult

__all__ = [
    "CancelSolve",
    "Command",
    "Decisions",
    "FlyToTarget",
    "LaunchVehicle",
    "Note",
    "PlanAdopted",
    "ReleaseVehicle",
    "SendHome",
    "SetHome",
    "SolveRequest",
    "ThroughPoint",
    "Verdict",
    "WindEstimate",
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
class ThroughPoint:
    """A search cell a mission flies through after its head: its id and centre (m)."""

    target: str
    x_m: float
    y_m: float


@dataclass(frozen=True)
class FlyToTarget:
    """Fly to the aim point (the target predicted at arrival), loiter, then hold there.

    ``through`` are the search cells of the planned route that follow ``target``, flown
    through in the same mission as plain waypoints (``core/route.py``: a vehicle moving on
    to the next cell of its route needs no new mission); empty: the mission ends at
    ``target`` (journals written before routes, and every loitering visit).
    ``route`` is the rest of the vehicle's planned sequence, for display only. ``eta_s`` is
    the mission time the core predicts the vehicle reaches the aim point (the intercept's
    arrival time; None where unknown, e.g. a command built outside the core); the run's
    ``arrival_error_s`` metric compares it with the flown arrival.
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
    through: tuple[ThroughPoint, ...] = field(default=())


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
class SetHome:
    """Move ``vehicle``'s home (where an RTL goes, whoever starts it: floe, ArduPlane's
    battery or link-loss failsafe) to (x_m, y_m): the ship's predicted position when the
    vehicle would reach it (``core/ship.py``). The frontend sends ``MAV_CMD_DO_SET_HOME``
    and verifies it by the ``HOME_POSITION`` that follows, like a mission."""

    t_s: float
    vehicle: str
    x_m: float
    y_m: float


@dataclass(frozen=True)
class LaunchVehicle:
    """Launch the spare ``vehicle`` from the ship (``reason``: ``on station``, or
    ``relief`` of the vehicle ``relieves``). With ``--launch`` the frontend launches it
    itself; otherwise it asks the operator for a catapult launch (console, API, map)."""

    t_s: float
    vehicle: str
    reason: str
    relieves: str | None = None


@dataclass(frozen=True)
class Note:
    """Something worth journalling that needs no action (e.g. a target discovered)."""

    t_s: float
    kind: str
    vehicle: str | None = None
    target: str | None = None
    detail: str = ""


@dataclass(frozen=True)
class WindEstimate:
    """The core's wind estimate changed meaningfully (journalled as a ``wind`` line).

    ``wx_m_s, wy_m_s``: the ENU vector the air moves towards; ``source``: ``"vehicles"``
    (combined from the reports of ``vehicles``) or ``"fallback"`` (the configured or the
    scenario's wind, ``CoreConfig.wind_xy_m_s``: no vehicle reports one)."""

    t_s: float
    wx_m_s: float
    wy_m_s: float
    source: str
    vehicles: tuple[str, ...] = field(default=())


Command = (
    SolveRequest | CancelSolve | PlanAdopted | FlyToTarget | ReleaseVehicle | SendHome | Note
    | WindEstimate | SetHome | LaunchVehicle
)


@dataclass(frozen=True)
class Verdict:
    """The observer's verdict on a camera detection, for the frontends' visit counts (not a
    command and not journalled: replay recomputes it from the same inputs).

    ``accepted`` is True when the detection was fused into track ``target``: a labelled
    detection the observer accepted, or, at the tick that scanned its frame, an unlabelled
    one the tracker assigned to ``target`` (``reason`` ``assigned``; ``t_s`` and
    ``vehicle`` are then the frame's). False when it was not fused: ``reason`` is the
    observer's (``gated``, ``late``, ``non_finite``...), ``discovered`` (it started the
    unknown target ``target``) or ``invalid``. None while an unlabelled detection waits in
    its frame for the next tick's scan (``buffered``, ``invalid``)."""

    t_s: float
    vehicle: str | None
    target: str | None
    accepted: bool | None
    reason: str


class Decisions(list[Command]):
    """What :meth:`DecisionCore.handle` returns: the commands, in order, and the verdicts
    on the detections this input decided (empty but for a ``Detection`` or a ``Tick``).

    Built like a list (``Decisions(commands)``, list's own constructor: one is returned
    for every input, 8 600 a paper-boat run, most of them empty); ``verdicts`` is the
    class's empty tuple unless the core set the input's."""

    verdicts: tuple[Verdict, ...] = ()
