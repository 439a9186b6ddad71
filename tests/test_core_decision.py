"""The decision core: policies, commitment, fleet events, stale plans, aim points."""

from __future__ import annotations

import math

import pytest
from core_run import solve_all

from groundstation.core.commands import (
    CancelSolve,
    Command,
    FlyToTarget,
    Note,
    PlanAdopted,
    ReleaseVehicle,
    SendHome,
    SolveRequest,
)
from groundstation.core.config import CoreConfig, ReplanPolicy
from groundstation.core.decision import DecisionCore
from groundstation.core.events import (
    BatteryLow,
    Detection,
    LoiterEnded,
    OperatorOverride,
    OperatorResume,
    PlanSolved,
    TargetAdded,
    TargetRemoved,
    Telemetry,
    Tick,
    VehicleJoined,
    VehicleLost,
    VehicleReturned,
)
from observer import ObserverConfig
from planner import solve_plan


def make_core(*, commit: bool = True, period_s: float | None = None, on_events: bool = True,
              loiter_s: float = 30.0) -> DecisionCore:
    return DecisionCore(CoreConfig(
        policy=ReplanPolicy(on_events=on_events, period_s=period_s, commit=commit),
        observer=ObserverConfig(model="linear"),
        loiter_s=loiter_s,
        time_limit_s=1.0,
    ))


def of_type(commands: list[Command], kind: type) -> list:
    return [c for c in commands if isinstance(c, kind)]




def join(core: DecisionCore, vehicle: str, x_m: float = 0.0, y_m: float = 0.0) -> None:
    core.handle(VehicleJoined(0.0, vehicle, x_m, y_m, 0.0, 22.0))


def add(core: DecisionCore, target: str, x_m: float, y_m: float, sigma0: float = 10.0,
        t_s: float = 0.0) -> None:
    core.handle(TargetAdded(t_s, target, x_m, y_m, sigma0=sigma0))


def test_events_are_batched_into_one_plan_on_the_next_tick() -> None:
    core = make_core()
    join(core, "1")
    add(core, "A", 1000, 0)
    add(core, "B", 0, 1000)
    add(core, "C", -1000, 0)
    requests = of_type(core.handle(Tick(0.1)), SolveRequest)
    assert len(requests) == 1
    assert {t.id for t in requests[0].problem.targets} == {"A", "B", "C"}
    assert of_type(core.handle(Tick(0.2)), SolveRequest) == []


def test_period_policy_plans_at_start_and_every_period_only() -> None:
    core = make_core(commit=False, period_s=5.0, on_events=False)
    join(core, "1")
    add(core, "A", 500, 0)
    times = []
    for k in range(0, 121):
        t = k * 0.1
        if of_type(solve_all(core, core.handle(Tick(t))), SolveRequest):
            times.append(round(t, 1))
    assert times == [0.0, 5.0, 10.0]


def test_commit_keeps_busy_vehicles_and_covers_their_targets() -> None:
    core = make_core(commit=True)
    join(core, "1", 0, 0)
    join(core, "2", 0, 100)
    add(core, "A", 1000, 0, sigma0=50)
    add(core, "B", 0, 1000, sigma0=40)
    add(core, "C", -1000, 0, sigma0=30)
    first = solve_all(core, core.handle(Tick(0.1)))
    flights = {c.vehicle: c.target for c in of_type(first, FlyToTarget)}
    assert set(flights) == {"1", "2"}
    # vehicle 1 ends its loiter: only it is replanned, and 2's target is covered
    core.handle(LoiterEnded(40.0, "1"))
    request = of_type(core.handle(Tick(40.1)), SolveRequest)[0]
    assert [u.id for u in request.problem.uavs] == ["1"]
    assert flights["2"] not in {t.id for t in request.problem.targets}


def test_without_commit_every_vehicle_is_replanned() -> None:
    core = make_core(commit=False, period_s=5.0)
    join(core, "1", 0, 0)
    join(core, "2", 0, 100)
    add(core, "A", 1000, 0)
    add(core, "B", 0, 1000)
    solve_all(core, core.handle(Tick(0.1)))
    request = of_type(core.handle(Tick(5.0)), SolveRequest)[0]
    assert [u.id for u in request.problem.uavs] == ["1", "2"]
    assert {t.id for t in request.problem.targets} == {"A", "B"}


def test_an_overtaken_plan_is_cancelled_and_its_answer_dropped() -> None:
    core = make_core(commit=False)
    join(core, "1")
    add(core, "A", 1000, 0)
    old = of_type(core.handle(Tick(0.1)), SolveRequest)[0]
    add(core, "B", 0, 1000, t_s=0.2)
    newer = core.handle(Tick(0.3))
    assert of_type(newer, CancelSolve)[0].request_id == old.request_id
    new = of_type(newer, SolveRequest)[0]
    assert not core.wants_answer(old.request_id) and core.wants_answer(new.request_id)
    stale = core.handle(PlanSolved(0.4, old.request_id, solve_plan(old.problem)))
    assert stale == []
    assert core.counters["stale_plans_dropped"] == 1
    fresh = core.handle(PlanSolved(0.5, new.request_id, solve_plan(new.problem)))
    assert of_type(fresh, PlanAdopted) and of_type(fresh, FlyToTarget)
    assert not core.wants_answer(new.request_id)  # answered: a second answer is stale


@pytest.mark.parametrize("leaves", ["lost", "override"])
def test_a_plan_asked_with_a_vehicle_that_leaves_before_its_answer_is_dropped(
    leaves: str,
) -> None:
    """A loaded daemon: a plan asked with vehicles 1 and 2, then vehicle 2's link is lost
    (or its pilot takes it) before the answer comes. The request is cancelled at once, its
    late answer is dropped, and the next tick plans without vehicle 2: no adopted plan
    names it (test_daemon_faults.py saw one 0.3 mission s after the loss)."""
    core = make_core(commit=False)
    join(core, "1", 0, 0)
    join(core, "2", 0, 100)
    add(core, "A", 1000, 0)
    add(core, "B", 0, 1000)
    asked = of_type(core.handle(Tick(0.1)), SolveRequest)[0]
    assert [u.id for u in asked.problem.uavs] == ["1", "2"]
    event = VehicleLost(0.2, "2") if leaves == "lost" else OperatorOverride(0.2, "2")
    out = core.handle(event)
    assert [c.request_id for c in of_type(out, CancelSolve)] == [asked.request_id]
    assert not core.wants_answer(asked.request_id)
    late = core.handle(PlanSolved(0.3, asked.request_id, solve_plan(asked.problem)))
    assert late == [] and core.counters["stale_plans_dropped"] == 1
    again = of_type(core.handle(Tick(0.4)), SolveRequest)
    assert [u.id for u in again[0].problem.uavs] == ["1"]
    answer = solve_all(core, again)
    adopted = of_type(answer, PlanAdopted)
    assert adopted and "2" not in adopted[0].result.routes
    assert {c.vehicle for c in of_type(answer, FlyToTarget)} == {"1"}


def test_override_releases_and_resume_takes_back() -> None:
    core = make_core()
    join(core, "1", 0, 0)
    join(core, "2", 0, 100)
    add(core, "A", 1000, 0)
    add(core, "B", 0, 1000)
    solve_all(core, core.handle(Tick(0.1)))
    released = core.handle(OperatorOverride(10.0, "2"))
    assert of_type(released, ReleaseVehicle)[0].vehicle == "2"
    core.handle(LoiterEnded(50.0, "1"))
    request = of_type(core.handle(Tick(50.1)), SolveRequest)[0]
    assert [u.id for u in request.problem.uavs] == ["1"]
    solve_all(core, [request])
    core.handle(OperatorResume(60.0, "2"))
    request = of_type(core.handle(Tick(60.1)), SolveRequest)[0]
    assert [u.id for u in request.problem.uavs] == ["2"]


def test_battery_low_sends_home_and_leaves_the_plan() -> None:
    core = make_core(commit=False, period_s=5.0)
    join(core, "1", 0, 0)
    join(core, "2", 0, 100)
    add(core, "A", 1000, 0)
    solve_all(core, core.handle(Tick(0.0)))
    out = core.handle(BatteryLow(2.0, "1"))
    assert of_type(out, SendHome)[0].vehicle == "1"
    request = of_type(core.handle(Tick(5.0)), SolveRequest)[0]
    assert [u.id for u in request.problem.uavs] == ["2"]


def test_lost_vehicle_leaves_and_returns() -> None:
    core = make_core(commit=False, period_s=5.0)
    join(core, "1", 0, 0)
    join(core, "2", 0, 100)
    add(core, "A", 1000, 0)
    solve_all(core, core.handle(Tick(0.0)))
    core.handle(VehicleLost(1.0, "2"))
    assert [u.id for u in of_type(core.handle(Tick(5.0)), SolveRequest)[0].problem.uavs] == ["1"]
    core.handle(VehicleReturned(6.0, "2"))
    request = of_type(core.handle(Tick(10.0)), SolveRequest)[0]
    assert [u.id for u in request.problem.uavs] == ["1", "2"]


def test_target_removed_frees_its_vehicle() -> None:
    core = make_core()
    join(core, "1")
    add(core, "A", 1000, 0)
    add(core, "B", 0, 1000, sigma0=1.0)
    flights = of_type(solve_all(core, core.handle(Tick(0.1))), FlyToTarget)
    target = flights[0].target
    core.handle(TargetRemoved(5.0, target))
    request = of_type(core.handle(Tick(5.1)), SolveRequest)[0]
    assert target not in {t.id for t in request.problem.targets}
    assert [u.id for u in request.problem.uavs] == ["1"]


def test_aim_point_leads_a_moving_target() -> None:
    core = DecisionCore(CoreConfig(observer=ObserverConfig(model="kalman")))
    join(core, "1", 0, 0)
    core.handle(TargetAdded(0.0, "A", 2000, 0, vx_m_s=0.0, vy_m_s=3.0))
    fly = of_type(solve_all(core, core.handle(Tick(0.1))), FlyToTarget)[0]
    # about 2000 m at 22 m/s: ~91 s of drift at 3 m/s north
    assert fly.x_m == pytest.approx(2000, abs=1)
    assert 250 < fly.y_m < 300


def test_detection_of_an_unknown_target_adds_it() -> None:
    core = make_core()
    out = core.handle(Detection(1.0, "1", "Z", 100.0, 200.0, 5.0))
    assert of_type(out, Note)[0].kind == "target_discovered"
    assert "Z" in core.observer.target_ids


def test_nan_telemetry_is_ignored_and_counted() -> None:
    core = make_core()
    join(core, "1", 10, 20)
    core.handle(Telemetry(1.0, "1", math.nan, 0.0, 0.0, 22.0))
    assert core.vehicles["1"].x_m == 10
    assert core.counters["invalid_telemetry"] == 1


def test_policy_validation() -> None:
    with pytest.raises(ValueError):
        ReplanPolicy(on_events=False, period_s=None)
    with pytest.raises(ValueError):
        ReplanPolicy(period_s=0.0)
    assert ReplanPolicy.from_names("period", 5.0, False).on_events is False


def test_input_records_round_trip_exactly() -> None:
    from groundstation.core.records import RecordError, event_to_record, record_to_event

    core = make_core()
    join(core, "1")
    add(core, "A", 1000.123456789, 0.1)
    request = of_type(core.handle(Tick(0.1)), SolveRequest)[0]
    result = solve_plan(request.problem)
    events = [
        Tick(0.30000000000000004),
        Telemetry(1.0, "1", 1.0 / 3.0, -2.5e-7, 3.14159, 22.0),
        Detection(2.0, None, None, 1.5, 2.5),
        TargetAdded(3.0, "B", 1.0, 2.0, 0.1, -0.2, 5.0, None),
        BatteryLow(4.0, "1"),
        PlanSolved(5.0, 7, result),
    ]
    for event in events:
        record = event_to_record(event)
        assert record["event"] == "input"
        import json

        assert record_to_event(json.loads(json.dumps(record))) == event
    with pytest.raises(RecordError):
        record_to_event({"event": "input", "kind": "Explode", "t": 1})
    with pytest.raises(RecordError):
        record_to_event({"event": "input", "kind": "Telemetry", "t": 1})


def test_core_config_round_trips_and_rejects_unknown_keys() -> None:
    from groundstation.core.config import config_from_dict, config_to_dict

    config = CoreConfig(policy=ReplanPolicy(on_events=False, period_s=5.0, commit=False),
                        observer=ObserverConfig(model="linear", q_per_s=0.2), loiter_s=12.0)
    assert config_from_dict(config_to_dict(config)) == config
    with pytest.raises(ValueError, match="unknown key 'colour'"):
        config_from_dict({**config_to_dict(config), "colour": 1})
