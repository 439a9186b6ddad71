"""Random planning problems shared by the planner tests: seeded instances and a
hypothesis strategy (UAVs and targets uniform in [0, 1500]^2 m)."""

from __future__ import annotations

import math
import random
from collections.abc import Sequence
from typing import Any, ClassVar

from hypothesis import strategies as st

from planner import PlanningProblem, TargetEstimate, UavPose
from planner.cpsat_model import CpSatOutcome
from planner.instance import Instance

SIDE_M = 1500.0


def random_problem(seed: int, m: int, n: int, **kw: object) -> PlanningProblem:
    """m UAVs and n targets (sigma uniform in [1, 100]) drawn from ``random.Random(seed)``,
    turn radius 105 m; ``kw`` sets any other PlanningProblem field."""
    rng = random.Random(seed)
    return PlanningProblem(
        uavs=tuple(
            UavPose(f"u{k}", rng.uniform(0, SIDE_M), rng.uniform(0, SIDE_M), rng.uniform(-3, 3))
            for k in range(m)
        ),
        targets=tuple(
            TargetEstimate(
                f"t{k}", rng.uniform(0, SIDE_M), rng.uniform(0, SIDE_M), rng.uniform(1, 100)
            )
            for k in range(n)
        ),
        turn_radius_m=105.0,
        **kw,  # type: ignore[arg-type]
    )


@st.composite
def problems(
    draw: st.DrawFn,
    max_targets: int = 6,
    objectives: Sequence[str] = ("sequence", "arrival"),
    sigma_max: float = 100.0,
    taus: Sequence[float] = (0.0, 0.25, 0.5, 0.9, 1.0),
    speeds_m_s: Sequence[float] = (22.0,),
) -> PlanningProblem:
    """1-3 UAVs, 0..max_targets targets (sigma in [0, sigma_max], with exact 0 and 10
    drawn often), turn radius 1, 105 or 300 m, mu automatic or in [0.001, 10]."""
    m = draw(st.integers(1, 3))
    n = draw(st.integers(0, max_targets))
    xy = st.floats(0, SIDE_M, allow_nan=False)
    uavs = tuple(
        UavPose(f"u{k}", draw(xy), draw(xy), draw(st.floats(-math.pi, math.pi))) for k in range(m)
    )
    sigma = st.one_of(st.floats(0, sigma_max, allow_nan=False), st.just(0.0), st.just(10.0))
    targets = tuple(TargetEstimate(f"t{k}", draw(xy), draw(xy), draw(sigma)) for k in range(n))
    return PlanningProblem(
        uavs=uavs,
        targets=targets,
        turn_radius_m=draw(st.sampled_from([1.0, 105.0, 300.0])),
        tau=draw(st.sampled_from(list(taus))),
        mu=draw(st.one_of(st.none(), st.floats(0.001, 10))),
        objective=draw(st.sampled_from(list(objectives))),  # type: ignore[arg-type]
        speed_m_s=draw(st.sampled_from(list(speeds_m_s))),
    )


class FakeCpSatRun:
    """Stands in for ``planner.cpsat_model.CpSatRun`` (monkeypatched): records each model it
    is built for (``built``) and each budget its solve is given (``budgets``), and finds
    no plan. Reset both lists in each test."""

    built: ClassVar[list[str]] = []
    budgets: ClassVar[list[float]] = []

    def __init__(self, inst: Instance, model: str, keep: Any = None) -> None:
        FakeCpSatRun.built.append(model)
        self.kind = model

    def add_hint(self, routes: list[list[int]]) -> None:
        pass

    def stop(self) -> None:
        pass

    def solve(self, time_limit_s: float, **options: Any) -> CpSatOutcome:
        FakeCpSatRun.budgets.append(time_limit_s)
        return CpSatOutcome("none", None, 0.0, False, self.kind)
