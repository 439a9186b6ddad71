"""Target-visitation planner: Dubins distances, the paper's model, exact and heuristic solvers."""

from planner.dubins import dubins_distance_to_point
from planner.problem import (
    MU_RULES,
    MuRule,
    Objective,
    PlanningProblem,
    PlanResult,
    PlanStatus,
    ProblemError,
    TargetEstimate,
    UavPose,
    parse_mu,
    problem_from_dict,
    problem_to_dict,
    result_to_dict,
)
from planner.solve import PlanSolver, solve_plan

__all__ = [
    "MU_RULES",
    "MuRule",
    "Objective",
    "PlanResult",
    "PlanSolver",
    "PlanStatus",
    "PlanningProblem",
    "ProblemError",
    "TargetEstimate",
    "UavPose",
    "dubins_distance_to_point",
    "parse_mu",
    "problem_from_dict",
    "problem_to_dict",
    "result_to_dict",
    "solve_plan",
]
