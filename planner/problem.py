"""Planning problem and result types, and the `gcs plan` JSON format.

Problem JSON (all planar metres, headings in radians counter-clockwise from +x)::

    {"uavs": [{"id": "u1", "x": 0, "y": 0, "heading": 0.0}, ...],
     "targets": [{"id": "t1", "x": 10, "y": 5, "sigma": 3.0}, ...],
     "turn_radius": 105.0, "tau": 0.5,
     "mu": null | float | "floe" | "paper" | "unconstrained",
     "min_sigma_fraction": 0.1, "time_limit_s": 5.0,
     "objective": "sequence" | "arrival" | "latency", "speed_m_s": 22.0,
     "wind_m_s": null | [wx, wy]}

`uavs`, `targets` and `turn_radius` are required; any other key is an error. `mu` is a
number (eq. 18's weight given), or the rule that computes it (:class:`MuRule`; null is
``floe``). `wind_m_s` is
the ENU vector (m/s) the air moves towards; absent or null is still air. A wind at or above
the airspeed `speed_m_s` is refused (upwind legs could not be flown).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from domain.errors import PlanningError
from domain.limits import MAX_FLEET, MAX_TARGETS


class Objective(StrEnum):
    """The objective (equations in planner.instance and docs/planner.md): the paper's
    ``sequence`` (uncertainty weighted by position in the sequence), ``arrival`` (the same
    with the position replaced by the arrival time in mean hops, plus the distance term) or
    ``latency`` (sum of sigma times arrival time in seconds: no distance term, no tau/mu)."""

    SEQUENCE = "sequence"
    ARRIVAL = "arrival"
    LATENCY = "latency"


class PlanStatus(StrEnum):
    """``optimal``: the DP ran or CP-SAT proved optimality; ``feasible``: CP-SAT found a
    plan; ``fallback``: CP-SAT found none (time limit or stop), the heuristic plan is used."""

    OPTIMAL = "optimal"
    FEASIBLE = "feasible"
    FALLBACK = "fallback"


class MuRule(StrEnum):
    """How eq. 18's mu = F1max / F2avg is computed when no number is given (planner.instance,
    docs/planner.md "mu"). F2avg = d_avg (N - nUAV) for every rule, d_avg the mean of all
    N (N - 1) off-diagonal entries of d (as eq. 18 defines it); they differ in F1max:

    * ``floe``: the largest F1 a feasible plan reaches, the k-th largest sigma at
      t = 2 + k // nUAV (round robin over the UAVs; the design notes' reading);
    * ``paper``: the paper's "optimizing without constraints" read literally, every iceberg
      right after a UAV: t = 2, F1max = (N - 2) sum sigma;
    * ``unconstrained``: constraints (14)-(15) dropped too, t = 1: F1max = (N - 1) sum sigma.
    """

    FLOE = "floe"
    PAPER = "paper"
    UNCONSTRAINED = "unconstrained"


MU_RULES = tuple(r.value for r in MuRule)

OBJECTIVES = tuple(o.value for o in Objective)
STATUSES = tuple(s.value for s in PlanStatus)


class ProblemError(PlanningError):
    """Malformed planning problem: `field` names the offending key (e.g. ``targets[2].sigma``)."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


@dataclass(frozen=True)
class UavPose:
    """A UAV at (x_m, y_m) flying heading_rad (counter-clockwise from +x)."""

    id: str
    x_m: float
    y_m: float
    heading_rad: float


@dataclass(frozen=True)
class TargetEstimate:
    """A target position estimate with uncertainty sigma = trace(P[:2, :2]) (m^2)."""

    id: str
    x_m: float
    y_m: float
    sigma: float


@dataclass(frozen=True)
class PlanningProblem:
    """One planning instance; see docs/planner.md for the model."""

    uavs: tuple[UavPose, ...]
    targets: tuple[TargetEstimate, ...]
    turn_radius_m: float
    tau: float = 0.5
    mu: float | None = None  # given: used as is; None: computed by mu_rule
    min_sigma_fraction: float = 0.1
    time_limit_s: float = 5.0
    objective: Objective = Objective.SEQUENCE
    speed_m_s: float = 22.0
    wind_m_s: tuple[float, float] | None = None  # ENU, towards; None: still air
    mu_rule: MuRule = MuRule.FLOE  # eq. 18's F1max when mu is None (MuRule)

    @property
    def planning_wind_m_s(self) -> tuple[float, float] | None:
        """The wind the costs are computed in: None in still air (no wind, or (0, 0)),
        where the costs are exactly the still-air distances."""
        w = self.wind_m_s
        if w is None or (w[0] == 0.0 and w[1] == 0.0):
            return None
        return w


def wind_problem(wind_m_s: tuple[float, float], speed_m_s: float) -> str | None:
    """Why a wind cannot be planned in (not finite, or not below the airspeed), or None."""
    wx, wy = wind_m_s
    if not (math.isfinite(wx) and math.isfinite(wy)):
        return "must be finite"
    speed = math.hypot(wx, wy)
    if not speed < speed_m_s:
        return (
            f"a wind of {speed:g} m/s is not below the airspeed speed_m_s = {speed_m_s:g} m/s: "
            "legs into it cannot be flown"
        )
    return None


@dataclass(frozen=True)
class PlanResult:
    """Outcome of a solve. `routes` is the model optimum; `idle` the idle-UAV rule."""

    status: PlanStatus
    solver: str
    objective: float
    f1: float
    f2: float
    mu: float
    routes: dict[str, list[str]]
    idle: dict[str, str]
    excluded: list[str]
    solve_time_s: float
    hit_time_limit: bool
    bound: float | None = None  # proven lower bound on `objective` (= it when optimal)
    gap: float | None = None  # plan_gap(objective, bound)


def plan_gap(objective: float, bound: float | None) -> float | None:
    """(objective - bound) / |objective|, at least 0: how far above the optimum the plan can
    be. 0 when bound == objective (also at objective 0); None without a bound, or when the
    objective is 0 and the bound below it (no relative figure exists)."""
    if bound is None or not math.isfinite(bound) or not math.isfinite(objective):
        return None
    if bound >= objective:
        return 0.0
    if objective == 0.0:
        return None
    return (objective - bound) / abs(objective)


_TOP_KEYS = {
    "uavs",
    "targets",
    "turn_radius",
    "tau",
    "mu",
    "min_sigma_fraction",
    "time_limit_s",
    "objective",
    "speed_m_s",
    "wind_m_s",
}
_UAV_KEYS = ("id", "x", "y", "heading")
_TARGET_KEYS = ("id", "x", "y", "sigma")


def _number(value: Any, field: str) -> float:
    """A finite real number (bool is rejected)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ProblemError(field, f"expected a number, got {type(value).__name__}")
    try:
        out = float(value)
    except OverflowError:
        raise ProblemError(field, "must be finite") from None
    if not math.isfinite(out):
        raise ProblemError(field, "must be finite")
    return out


def _items(d: Mapping[str, Any], key: str, keys: tuple[str, ...]) -> list[dict[str, Any]]:
    raw = d[key]
    if not isinstance(raw, list):
        raise ProblemError(key, f"expected a list, got {type(raw).__name__}")
    seen: set[str] = set()
    out: list[dict[str, Any]] = []
    for k, item in enumerate(raw):
        where = f"{key}[{k}]"
        if not isinstance(item, Mapping):
            raise ProblemError(where, f"expected an object, got {type(item).__name__}")
        for name in item:
            if name not in keys:
                raise ProblemError(f"{where}.{name}", "unknown key")
        for name in keys:
            if name not in item:
                raise ProblemError(f"{where}.{name}", "missing")
        ident = item["id"]
        if not isinstance(ident, str) or not ident:
            raise ProblemError(f"{where}.id", "expected a non-empty string")
        if ident in seen:
            raise ProblemError(f"{where}.id", f"duplicate id {ident!r}")
        seen.add(ident)
        out.append({name: item[name] for name in keys})
    return out


def problem_from_dict(d: Mapping[str, Any]) -> PlanningProblem:
    """Parse and validate the `gcs plan` problem format; raise ProblemError on any defect."""
    if not isinstance(d, Mapping):
        raise ProblemError("problem", f"expected a JSON object, got {type(d).__name__}")
    for key in d:
        if key not in _TOP_KEYS:
            raise ProblemError(str(key), "unknown key")
    for key in ("uavs", "targets", "turn_radius"):
        if key not in d:
            raise ProblemError(key, "missing")
    for key, most in (("uavs", MAX_FLEET), ("targets", MAX_TARGETS)):
        if isinstance(d[key], list) and len(d[key]) > most:
            raise ProblemError(key, f"{len(d[key])} entries; floe's limit is {most}")
    uavs = []
    for k, u in enumerate(_items(d, "uavs", _UAV_KEYS)):
        where = f"uavs[{k}]"
        uavs.append(
            UavPose(
                u["id"],
                _number(u["x"], f"{where}.x"),
                _number(u["y"], f"{where}.y"),
                _number(u["heading"], f"{where}.heading"),
            )
        )
    if not uavs:
        raise ProblemError("uavs", "at least one UAV is needed")
    targets = []
    for k, t in enumerate(_items(d, "targets", _TARGET_KEYS)):
        where = f"targets[{k}]"
        sigma = _number(t["sigma"], f"{where}.sigma")
        if sigma < 0:
            raise ProblemError(f"{where}.sigma", "must be >= 0")
        targets.append(
            TargetEstimate(
                t["id"], _number(t["x"], f"{where}.x"), _number(t["y"], f"{where}.y"), sigma
            )
        )
    uav_ids = {u.id for u in uavs}
    for k, tgt in enumerate(targets):
        if tgt.id in uav_ids:
            raise ProblemError(f"targets[{k}].id", f"{tgt.id!r} is also a UAV id")
    turn_radius = _number(d["turn_radius"], "turn_radius")
    if turn_radius <= 0:
        raise ProblemError("turn_radius", "must be > 0")
    tau = _number(d.get("tau", 0.5), "tau")
    if not 0.0 <= tau <= 1.0:
        raise ProblemError("tau", "must be in [0, 1]")
    mu, mu_rule = parse_mu(d.get("mu"))
    frac = _number(d.get("min_sigma_fraction", 0.1), "min_sigma_fraction")
    if not 0.0 <= frac <= 1.0:
        raise ProblemError("min_sigma_fraction", "must be in [0, 1]")
    limit = _number(d.get("time_limit_s", 5.0), "time_limit_s")
    if limit <= 0:
        raise ProblemError("time_limit_s", "must be > 0")
    objective = d.get("objective", "sequence")
    if objective not in OBJECTIVES:
        raise ProblemError("objective", f"must be one of {', '.join(OBJECTIVES)}")
    speed = _number(d.get("speed_m_s", 22.0), "speed_m_s")
    if speed <= 0:
        raise ProblemError("speed_m_s", "must be > 0")
    wind = _wind(d.get("wind_m_s"), speed)
    return PlanningProblem(
        uavs=tuple(uavs),
        targets=tuple(targets),
        turn_radius_m=turn_radius,
        tau=tau,
        mu=mu,
        min_sigma_fraction=frac,
        time_limit_s=limit,
        objective=Objective(objective),
        speed_m_s=speed,
        wind_m_s=wind,
        mu_rule=mu_rule,
    )


def parse_mu(raw: Any, field: str = "mu") -> tuple[float | None, MuRule]:
    """A `mu` setting: null (the ``floe`` rule), a rule name (:class:`MuRule`) or a number
    >= 0 (used as is). Returns (mu, rule); raises ProblemError naming ``field``."""
    if raw is None:
        return None, MuRule.FLOE
    if isinstance(raw, str):
        if raw not in MU_RULES:
            raise ProblemError(field, f"must be a number >= 0 or one of {', '.join(MU_RULES)}, "
                               f"got {raw!r}")
        return None, MuRule(raw)
    if isinstance(raw, bool) or not isinstance(raw, int | float):
        raise ProblemError(field, f"must be a number >= 0 or one of {', '.join(MU_RULES)}, "
                           f"got {type(raw).__name__}")
    mu = _number(raw, field)
    if mu < 0:
        raise ProblemError(field, "must be >= 0")
    return mu, MuRule.FLOE


def _wind(raw: Any, speed_m_s: float) -> tuple[float, float] | None:
    """`wind_m_s`: null or [wx, wy], finite, slower than the airspeed."""
    if raw is None:
        return None
    if not isinstance(raw, list) or len(raw) != 2:
        raise ProblemError("wind_m_s", "expected [wx, wy] (m/s, ENU, the way the air moves)")
    wind = (_number(raw[0], "wind_m_s[0]"), _number(raw[1], "wind_m_s[1]"))
    problem = wind_problem(wind, speed_m_s)
    if problem is not None:
        raise ProblemError("wind_m_s", problem)
    return wind


def problem_to_dict(p: PlanningProblem) -> dict[str, Any]:
    """Inverse of problem_from_dict (`mu` and `wind_m_s` only when set, so a still-air
    problem under the ``floe`` rule reads as it did before wind and mu rules existed;
    `mu` is the number, else the rule's name when it is not ``floe``)."""
    out: dict[str, Any] = {
        "uavs": [{"id": u.id, "x": u.x_m, "y": u.y_m, "heading": u.heading_rad} for u in p.uavs],
        "targets": [{"id": t.id, "x": t.x_m, "y": t.y_m, "sigma": t.sigma} for t in p.targets],
        "turn_radius": p.turn_radius_m,
        "tau": p.tau,
        "min_sigma_fraction": p.min_sigma_fraction,
        "time_limit_s": p.time_limit_s,
        "objective": str(p.objective),
        "speed_m_s": p.speed_m_s,
    }
    if p.mu is not None:
        out["mu"] = p.mu
    elif p.mu_rule != MuRule.FLOE:
        out["mu"] = str(p.mu_rule)
    if p.wind_m_s is not None:
        out["wind_m_s"] = [p.wind_m_s[0], p.wind_m_s[1]]
    return out


def result_to_dict(r: PlanResult) -> dict[str, Any]:
    """The `gcs plan` output object."""
    return {
        "status": str(r.status),
        "solver": r.solver,
        "objective": r.objective,
        "f1": r.f1,
        "f2": r.f2,
        "mu": r.mu,
        "routes": {k: list(v) for k, v in r.routes.items()},
        "idle": dict(r.idle),
        "excluded": list(r.excluded),
        "solve_time_s": r.solve_time_s,
        "bound": r.bound if r.bound is not None and math.isfinite(r.bound) else None,
        "gap": r.gap,
    }
