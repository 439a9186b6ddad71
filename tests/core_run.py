"""Driving a DecisionCore in tests as the offline runner does: every solve request solved
inline, its result handed back."""

from __future__ import annotations

from groundstation.core.commands import Command, SolveRequest
from groundstation.core.decision import DecisionCore
from groundstation.core.events import PlanSolved
from planner import solve_plan


def solve_all(core: DecisionCore, commands: list[Command]) -> list[Command]:
    """Solve every request inline, like the offline runner; return all resulting commands."""
    out: list[Command] = []
    queue = list(commands)
    while queue:
        command = queue.pop(0)
        out.append(command)
        if isinstance(command, SolveRequest):
            result = solve_plan(command.problem, command.hint)
            queue.extend(core.handle(PlanSolved(command.t_s, command.request_id, result)))
    return out
