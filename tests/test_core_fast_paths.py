"""The decision core's fast paths (issue 30) give what the plain path gives: a tick before the
first wind report against a core driven through the plain path, input by input; the
written-out ``__init__``s against the ones a frozen dataclass generates; a Telemetry's
empty answer and a detection's verdicts."""

from __future__ import annotations

import inspect
import math
from dataclasses import FrozenInstanceError, asdict, fields, make_dataclass, replace

import pytest
from core_run import solve_all

from groundstation.core.commands import Command, Decisions, FlyToTarget, Note, PlanAdopted
from groundstation.core.config import CoreConfig, ReplanPolicy
from groundstation.core.decision import DecisionCore
from groundstation.core.events import (
    Detection,
    Event,
    TargetAdded,
    Telemetry,
    Tick,
    VehicleJoined,
    WindReport,
)
from groundstation.core.views import TrackView
from observer import ObserverConfig


def _windy_core() -> DecisionCore:
    """Wind-aware, the wind replan rule on, no commitment, a plan every 5 s."""
    return DecisionCore(CoreConfig(
        observer=ObserverConfig(model="kalman"), time_limit_s=1.0, wind_xy_m_s=(0.0, 0.0),
        policy=ReplanPolicy(on_events=True, period_s=5.0, commit=False)))


def _comparable(commands: list[Command]) -> list[Command]:
    """The commands, an adopted plan without its measured solve time."""
    return [replace(c, result=replace(c.result, solve_time_s=0.0))
            if isinstance(c, PlanAdopted) else c for c in commands]


def _drive(cores: list[DecisionCore], reports_from_s: float, end_s: float) -> list[Command]:
    """Feed every core the same inputs (two vehicles flying 22 m/s towards the aim point
    each was last sent to, three drifting targets, a tick every 0.1 s, and from
    ``reports_from_s`` vehicle 1's wind reports once a second: 12 m/s east, then 6 m/s
    north after 40 s); assert that they answer alike, input by input; return the answers."""
    pose = {"1": [0.0, 0.0, 0.0], "2": [0.0, 500.0, 0.0]}
    aims: dict[str, tuple[float, float]] = {}
    answers: list[Command] = []

    def feed(event: Event) -> None:
        outs = [_comparable(solve_all(core, core.handle(event))) for core in cores]
        assert all(out == outs[0] for out in outs[1:]), event
        answers.extend(outs[0])
        for command in outs[0]:
            if isinstance(command, FlyToTarget):
                aims[command.vehicle] = (command.x_m, command.y_m)

    for vehicle, (x, y, heading) in pose.items():
        feed(VehicleJoined(0.0, vehicle, x, y, heading, 22.0))
    for name, x, y in (("A", 3000.0, 0.0), ("B", -2000.0, 1500.0), ("C", 500.0, -2500.0)):
        feed(TargetAdded(0.0, name, x, y, vx_m_s=0.3, vy_m_s=-0.2, sigma0=50.0))
    for k in range(1, round(end_s / 0.1) + 1):
        t_s = k * 0.1
        for vehicle, p in pose.items():
            aim = aims.get(vehicle)
            if aim is not None and math.dist(p[:2], aim) > 30.0:
                p[2] = math.atan2(aim[1] - p[1], aim[0] - p[0])
                p[0] += 2.2 * math.cos(p[2])
                p[1] += 2.2 * math.sin(p[2])
            feed(Telemetry(t_s, vehicle, p[0], p[1], p[2], 22.0))
        if t_s >= reports_from_s and k % 10 == 0:
            wind = (12.0, 0.0) if t_s < 40.0 else (0.0, 6.0)
            feed(WindReport(t_s, "1", *wind))
        feed(Tick(t_s))
    return answers


def test_a_calm_tick_skips_the_wind_update_until_the_first_report_and_answers_alike() -> None:
    """Before the first kept report the estimate is the fallback every leg was predicted
    in: the core skips the update and the wind replan (``WindEstimator.heard``). Checked
    against a core that takes the plain path on every tick (``heard`` set from the
    start), through the first report and two wind changes that replan legs."""
    fast, plain = _windy_core(), _windy_core()
    plain.wind.heard = True  # the plain path: update and wind replan on every tick
    answers = _drive([fast, plain], reports_from_s=20.0, end_s=19.9)
    assert not fast.wind.heard and answers
    fast.handle(WindReport(19.95, "1", math.nan, 0.0))  # rejected: not kept, still unheard
    plain.handle(WindReport(19.95, "1", math.nan, 0.0))
    assert not fast.wind.heard
    answers = _drive([fast, plain], reports_from_s=20.0, end_s=60.0)
    assert fast.wind.heard  # the first kept report ends the fast path
    replans = [c for c in answers if isinstance(c, Note) and c.kind == "wind_replan"]
    assert replans, "the reports must move legs, or this test checks nothing"


def test_telemetry_is_answered_with_empty_decisions_and_detections_with_verdicts() -> None:
    """A Telemetry input only moves its vehicle (the first branch of ``handle``); the
    verdicts of a detection come back on its decisions, and none on the next input's."""
    core = _windy_core()
    core.handle(VehicleJoined(0.0, "1", 0.0, 0.0, 0.0, 22.0))
    core.handle(TargetAdded(0.0, "A", 100.0, 0.0, sigma0=50.0))
    out = core.handle(Telemetry(0.1, "1", 10.0, 5.0, 0.5, 21.0))
    assert isinstance(out, Decisions) and out == [] and out.verdicts == ()
    record = core.vehicles["1"]
    assert (record.x_m, record.y_m, record.heading_rad, record.speed_m_s, record.pose_t_s) == (
        10.0, 5.0, 0.5, 21.0, 0.1)
    seen = core.handle(Detection(0.1, "1", "A", 101.0, 1.0, 4.0))
    assert [(v.target, v.accepted) for v in seen.verdicts] == [("A", True)]
    assert core.handle(Telemetry(0.2, "1", 12.0, 5.0, 0.5, 21.0)).verdicts == ()
    assert core.handle(Tick(0.2)).verdicts == ()


_SAMPLES: dict[type, list[tuple[tuple[object, ...], dict[str, object]]]] = {
    Telemetry: [((1.5, "2", 3.0, -4.0, 0.25, 21.5), {}),
                ((1.5, "2", 3.0, -4.0, 0.25, 21.5, 2.0, 7.5), {}),
                ((), {"t_s": 0.1, "vehicle": "1", "x_m": 1.0, "y_m": 2.0, "heading_rad": 3.0,
                      "speed_m_s": 4.0, "sigma_m": 5.0})],
    TrackView: [(("A", "confirmed", 1.0, 2.0, 3.0, 1.0, 4.0), {}),
                (("T7", "tentative", 1.0, 2.0, 3.0, 0.4, 4.0, 0.1, -0.2, (2.0, 0.5, 1.0),
                  True, 3.5), {}),
                (("B", "prior", 1.0, 2.0, 3.0, 0.5, 4.0),
                 {"lost": True, "cov_xy": (1.0, 0.0, 2.0)})],
}


@pytest.mark.parametrize("cls", list(_SAMPLES), ids=lambda c: c.__name__)
def test_written_out_init_is_the_generated_one(cls: type) -> None:
    """``Telemetry`` and ``TrackView`` write their ``__init__`` out (fast); the value must
    be the one the frozen dataclass would generate: the same parameters and defaults,
    fields in order, equality, hash, repr, ``replace``, and still frozen."""
    generated = make_dataclass(cls.__name__, [(f.name, f.type, f) for f in fields(cls)],
                               frozen=True)
    fast_params = list(inspect.signature(cls).parameters.values())
    plain_params = list(inspect.signature(generated).parameters.values())
    assert [(p.name, p.default, p.kind) for p in fast_params] == [
        (p.name, p.default, p.kind) for p in plain_params]
    for args, kwargs in _SAMPLES[cls]:
        fast, plain = cls(*args, **kwargs), generated(*args, **kwargs)
        assert asdict(fast) == asdict(plain) and vars(fast) == vars(plain)
        assert list(vars(fast)) == [f.name for f in fields(cls)]
        assert fast == cls(*args, **kwargs) and hash(fast) == hash(plain)
        assert repr(fast) == repr(plain)
        name = fields(cls)[2].name
        assert replace(fast, **{name: 9.0}) == cls(**{**vars(fast), name: 9.0})
        with pytest.raises(FrozenInstanceError):
            setattr(fast, name, 0.0)
