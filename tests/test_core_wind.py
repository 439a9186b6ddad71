"""The decision core in wind: the planning wind, the intercept's time in wind checked by
flying it with world.dynamics, the refusal of a wind at the airspeed, the scenario and
journal plumbing, and replay of windy and of pre-wind journals."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
import yaml
from simulate_run import simulate_text
from test_core_decision import join, of_type, solve_all

from groundstation.cli import main
from groundstation.core.commands import FlyToTarget, Note, PlanAdopted, SolveRequest
from groundstation.core.config import CoreConfig, ReplanPolicy, config_from_dict, config_to_dict
from groundstation.core.decision import DecisionCore
from groundstation.core.events import TargetAdded, Tick, WindReport
from groundstation.core.fleet import VehicleRecord
from groundstation.core.records import command_to_record, problem_of_record
from groundstation.core.scenario_config import core_config_for
from groundstation.core.wind_replan import WindReplan
from groundstation.daemon.log_lines import PROBLEM_EVENTS, is_operator_event
from groundstation.runners.replay.compare import decision_of_record
from observer import ObserverConfig
from planner import dubins_distance_to_point
from world.dynamics import UavState, max_turn_rate_rad_s, step_kinematics
from world.scenario import parse_scenario

WIND = (8.0, -6.0)  # 10 m/s, towards the south-east


def core_in(wind: tuple[float, float], *, aware: bool = True) -> DecisionCore:
    return DecisionCore(CoreConfig(observer=ObserverConfig(model="kalman"), time_limit_s=1.0,
                                   wind_xy_m_s=wind, wind_aware=aware))


def first_flight(core: DecisionCore, x_m: float, y_m: float, vx_m_s: float = 0.0,
                 vy_m_s: float = 0.0) -> tuple[FlyToTarget, list]:
    join(core, "1", 0, 0)
    core.handle(TargetAdded(0.0, "A", x_m, y_m, vx_m_s=vx_m_s, vy_m_s=vy_m_s))
    out = solve_all(core, core.handle(Tick(0.1)))
    return of_type(out, FlyToTarget)[0], out


def fly_to(aim: tuple[float, float], wind: tuple[float, float], t0_s: float) -> tuple[float, float]:
    """(arrival mission time, miss distance) of the faster of the two turn-then-straight
    flights from (0, 0) heading east at 22 m/s, flown with world.dynamics (air-relative
    arcs) plus the wind's drift: turn at the maximum rate until the ground velocity points
    at the aim, then hold the heading until the aim is closest. 2 ms steps."""
    best = (math.inf, math.inf)
    dt = 0.002
    u_max = max_turn_rate_rad_s(22.0, 105.0)
    for side in (1.0, -1.0):
        air = UavState(0.0, 0.0, 0.0, 22.0)
        t, turning, closest, last_cross = 0.0, True, (math.inf, math.inf), math.nan
        while t < 300.0:
            gx, gy = air.x_m + wind[0] * t, air.y_m + wind[1] * t  # ground = air + wind
            vx = 22.0 * math.cos(air.heading_rad) + wind[0]
            vy = 22.0 * math.sin(air.heading_rad) + wind[1]
            ax, ay = aim[0] - gx, aim[1] - gy
            cross = vx * ay - vy * ax
            if turning and cross * last_cross <= 0.0 and vx * ax + vy * ay > 0.0:
                turning = False
            last_cross = cross
            if not turning:
                miss = math.hypot(ax, ay)
                if miss > closest[1]:
                    break
                closest = (t, miss)
            air = step_kinematics(air, side * u_max if turning else 0.0, dt)
            t += dt
        best = min(best, closest)
    return t0_s + best[0], best[1]


def test_planning_wind_and_the_problem() -> None:
    assert core_in(WIND).planning_wind_m_s() == WIND
    assert core_in(WIND, aware=False).planning_wind_m_s() == (0.0, 0.0)
    for wind, expected in ((WIND, WIND), ((0.0, 0.0), None)):
        core = core_in(wind)
        join(core, "1")
        core.handle(TargetAdded(0.0, "A", 900.0, 0.0))
        request = of_type(core.handle(Tick(0.1)), SolveRequest)[0]
        assert request.problem.wind_m_s == expected
    blind = core_in(WIND, aware=False)
    join(blind, "1")
    blind.handle(TargetAdded(0.0, "A", 900.0, 0.0))
    assert of_type(blind.handle(Tick(0.1)), SolveRequest)[0].problem.wind_m_s is None


def test_intercept_in_wind_lands_the_vehicle_on_the_moving_target() -> None:
    fly, _ = first_flight(core_in(WIND), -900.0, 700.0, vx_m_s=-1.5, vy_m_s=2.5)
    assert fly.eta_s is not None
    # the aim point is where the target (upwind, at (-900, 700) at t = 0) will be at eta
    assert (fly.x_m, fly.y_m) == pytest.approx((-900.0 - 1.5 * fly.eta_s,
                                                700.0 + 2.5 * fly.eta_s))
    arrival_s, miss_m = fly_to((fly.x_m, fly.y_m), WIND, 0.1)
    assert miss_m < 1.0  # turn-end resolution: omega dt x range ~ 0.5 m
    assert arrival_s == pytest.approx(fly.eta_s, abs=0.03)
    # a wind-blind core predicts a time the vehicle cannot keep in this wind
    blind, _ = first_flight(core_in(WIND, aware=False), -900.0, 700.0, vx_m_s=-1.5,
                            vy_m_s=2.5)
    assert blind.eta_s is not None
    blind_arrival_s, _ = fly_to((blind.x_m, blind.y_m), WIND, 0.1)
    assert abs(blind_arrival_s - blind.eta_s) > 5.0


def test_still_air_eta_is_the_dubins_time() -> None:
    fly, _ = first_flight(core_in((0.0, 0.0)), 2000.0, 0.0, vy_m_s=3.0)
    assert fly.eta_s is not None
    d = dubins_distance_to_point(0.0, 0.0, 0.0, fly.x_m, fly.y_m, 105.0)
    # the aim is the second fixed-point iterate; eta is the time of its own iteration
    assert fly.eta_s - 0.1 == pytest.approx(d / 22.0, rel=1e-3)
    assert fly.y_m == pytest.approx(3.0 * fly.eta_s, abs=0.5)  # the last iterate's time


def test_a_wind_at_the_airspeed_is_refused_once_and_planned_as_still_air() -> None:
    core = core_in((0.0, 22.0))
    fly, out = first_flight(core, 900.0, 0.0)
    notes = [n for n in of_type(out, Note) if n.kind == "wind_refused"]
    assert len(notes) == 1 and "22 m/s" in notes[0].detail and "airspeed" in notes[0].detail
    record = command_to_record(notes[0])  # a warning for the operator, compared by replay
    assert is_operator_event(record) and record["event"] in PROBLEM_EVENTS
    assert decision_of_record(record) is not None
    assert of_type(out, SolveRequest)[0].problem.wind_m_s is None
    assert fly.eta_s is not None and fly.eta_s > 0.1
    core.handle(TargetAdded(1.0, "B", 0.0, 900.0))
    again = core.handle(Tick(1.1))
    assert not [n for n in of_type(again, Note) if n.kind == "wind_refused"]


def test_plan_record_round_trips_the_wind_exactly() -> None:
    wind = (0.1 + 0.2, -7.000000000000001)
    _, out = first_flight(core_in(wind), 900.0, 300.0)
    adopted = of_type(out, PlanAdopted)[0]
    record = json.loads(json.dumps(command_to_record(adopted)))
    assert record["problem"]["wind_m_s"] == [0.1 + 0.2, -7.000000000000001]
    assert problem_of_record(record) == adopted.problem
    del record["problem"]["wind_m_s"]  # a journal written before wind existed
    assert problem_of_record(record).wind_m_s is None


def test_config_keys_and_scenario_mapping() -> None:
    config = CoreConfig(wind_xy_m_s=(3.0, -4.0), wind_aware=False)
    assert config_from_dict(json.loads(json.dumps(config_to_dict(config)))) == config
    assert config_from_dict({}).wind_xy_m_s == (0.0, 0.0)
    with pytest.raises(ValueError, match="wind_xy_m_s"):
        CoreConfig(wind_xy_m_s=(math.nan, 0.0))
    with pytest.raises(ValueError, match="wind_xy_m_s"):
        config_from_dict({"wind_xy_m_s": "west"})
    text = SCENARIO.replace("planner: {}", "planner: {wind_aware: false}")
    blind = core_config_for(parse_scenario(yaml.safe_load(text)))
    assert blind.wind_aware is False
    aware = core_config_for(parse_scenario(yaml.safe_load(SCENARIO)))
    assert aware.wind_aware is True
    assert aware.wind_xy_m_s == pytest.approx((11.276311449430901, 4.104241719908025))
    calm = core_config_for(parse_scenario(yaml.safe_load(CALM)))
    assert calm.wind_xy_m_s == (0.0, 0.0)
    assert json.dumps(list(calm.wind_xy_m_s)) == "[0.0, 0.0]"  # no negative zeros


SCENARIO = """\
name: wind-replay
description: two UAVs in 12 m/s of wind from the west-south-west
duration_s: 80
origin: {lat_deg: 78.93, lon_deg: 11.92}
fleet: {count: 2, loiter_s: 10, launch: {x_m: 0.0, y_m: 0.0}}
targets:
  list:
    - {id: A, x_m: 800, y_m: 300, vx_m_s: 0.3, vy_m_s: -0.2}
    - {id: B, x_m: -600, y_m: 900, vx_m_s: -0.2, vy_m_s: 0.1}
    - {id: C, x_m: 1200, y_m: -700, vx_m_s: 0.1, vy_m_s: 0.3}
planner: {}
wind: {speed_m_s: 12, from_deg: 250}
"""
CALM = SCENARIO.split("wind: {")[0]


def _replay(run: Path, capsys: pytest.CaptureFixture[str]) -> dict:
    capsys.readouterr()
    assert main(["replay", str(run), "--json"]) == 0
    return dict(json.loads(capsys.readouterr().out))


def test_windy_run_and_a_pre_wind_journal_replay_identical(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "windy").mkdir()
    windy = simulate_text(tmp_path / "windy", SCENARIO)
    lines = (windy / "journal.jsonl").read_text().splitlines()
    plans = [json.loads(line) for line in lines if '"event": "plan"' in line]
    assert plans and all("wind_m_s" in p["problem"] for p in plans)
    report = _replay(windy, capsys)
    assert report["identical"] is True and report["problems_equal"] == len(plans)
    # still air, journalled as before wind existed: no wind keys in the start line
    (tmp_path / "calm").mkdir()
    calm = simulate_text(tmp_path / "calm", CALM)
    journal = calm / "journal.jsonl"
    records = [json.loads(line) for line in journal.read_text().splitlines()]
    for record in records:
        if record.get("event") == "start":
            del record["core_config"]["wind_xy_m_s"], record["core_config"]["wind_aware"]
        assert "wind_m_s" not in record.get("problem", {})
    journal.write_text("".join(json.dumps(r) + "\n" for r in records))
    report = _replay(calm, capsys)
    assert report["identical"] is True and report["differences"] == []
    assert report["problems_equal"] == report["solves"] > 0


# ------------------------------------------------------------------ the first leg's wind
def _replan_core(fallback: tuple[float, float], **config: object) -> DecisionCore:
    return DecisionCore(CoreConfig(observer=ObserverConfig(model="kalman"), time_limit_s=1.0,
                                   wind_xy_m_s=fallback, **config))  # type: ignore[arg-type]


def _first_leg(core: DecisionCore) -> FlyToTarget:
    """Vehicle 1 at (0, 0) heading east, sent to a fixed target 2 km upwind of a west wind."""
    (fly,) = of_type(first_flight(core, -2000.0, 0.0)[1], FlyToTarget)
    return fly


def _wind_report(core: DecisionCore, t_s: float, wx: float, wy: float) -> list:
    out = core.handle(WindReport(t_s, "1", wx, wy))
    return out + solve_all(core, core.handle(Tick(t_s + 0.1)))


def test_the_first_estimate_replans_a_committed_leg_whose_arrival_it_moves() -> None:
    """Planned in still air (no --wind), the leg into 12 m/s of wind arrives far later: the
    first estimate makes the committed vehicle idle, and the next plan re-commands it."""
    core = _replan_core((0.0, 0.0))
    assert core.config.policy.commit and core.config.wind_replan_m_s == 2.0
    fly = _first_leg(core)
    assert fly.eta_s is not None
    out = _wind_report(core, 1.0, 12.0, 0.0)
    (note,) = [n for n in of_type(out, Note) if n.kind == "wind_replan"]
    assert (note.vehicle, note.target) == ("1", "A")
    (request,) = of_type(out, SolveRequest)
    assert request.reason == "wind changed" and [u.id for u in request.problem.uavs] == ["1"]
    (again,) = of_type(out, FlyToTarget)
    assert again.target == "A" and again.eta_s is not None
    record = core.vehicles["1"]
    flown = 1.1 + core._leg_time_s(record, (again.x_m, again.y_m))
    assert again.eta_s == pytest.approx(flown, abs=1e-6)
    assert again.eta_s - fly.eta_s > 30.0  # 2 km against 12 m/s: ~ +40 s
    assert f"{fly.eta_s:.1f} -> " in note.detail
    # the wind stays: no further replans
    out = _wind_report(core, 2.0, 12.2, 0.1)
    assert not of_type(out, FlyToTarget) and not of_type(out, Note)


def test_a_right_fallback_or_a_small_change_replans_nothing_a_large_one_does() -> None:
    core = _replan_core((12.0, 0.0))  # --wind 12,270: the leg was predicted right
    fly = _first_leg(core)
    out = _wind_report(core, 1.0, 12.1, 0.1)  # the first estimate, close to the fallback
    assert not of_type(out, FlyToTarget) and not [n for n in of_type(out, Note)
                                                  if n.kind == "wind_replan"]
    # the estimate is the mean of the vehicle's reports over 20 s: (12.1 + 13.6) / 2 is
    # 0.75 m/s from the wind the leg was last predicted in: not re-predicted
    out = _wind_report(core, 2.0, 13.6, 0.0)
    assert not of_type(out, FlyToTarget)
    out = _wind_report(core, 3.0, -10.0, 0.0)  # mean 5.2 m/s: the leg arrives much earlier
    (again,) = of_type(out, FlyToTarget)
    assert again.eta_s is not None and fly.eta_s is not None and again.eta_s < fly.eta_s - 5


def test_without_the_rule_or_without_wind_awareness_nothing_is_replanned() -> None:
    for core in (_replan_core((0.0, 0.0), wind_replan_m_s=None),
                 _replan_core((0.0, 0.0), wind_aware=False)):
        _first_leg(core)
        out = _wind_report(core, 1.0, 12.0, 0.0)
        assert not of_type(out, FlyToTarget) and not of_type(out, SolveRequest)


def test_without_commitment_the_leg_is_re_commanded_even_to_the_same_aim_point() -> None:
    """The target does not move, so the new aim point is the old one: only the rule makes
    the vehicle be told (and the journal hold) the new arrival."""
    policy = ReplanPolicy(on_events=True, period_s=None, commit=False)
    for rule, expected in ((2.0, 1), (None, 0)):
        core = _replan_core((0.0, 0.0), policy=policy, wind_replan_m_s=rule)
        fly = _first_leg(core)
        out = _wind_report(core, 1.0, 12.0, 0.0)
        again = of_type(out, FlyToTarget)
        assert len(again) == expected
        if again:
            assert (again[0].x_m, again[0].y_m) == (fly.x_m, fly.y_m)
            assert again[0].eta_s is not None and fly.eta_s is not None
            assert again[0].eta_s > fly.eta_s + 30.0


def test_wind_replan_skips_a_vehicle_at_its_aim_and_re_predicts_a_leg_once() -> None:
    """The rest of a leg is flown again in the old and the new wind from the same pose: the
    difference, the wind's alone, is what replans (here 2 and 11 s a m/s of east wind)."""
    rule = WindReplan(2.0, 5.0, fov_radius_m=150.0)
    calls: list[tuple[str, tuple[float, float]]] = []
    per_m_s = {"1": 0.0, "2": 2.0, "3": 11.0}

    def flight_time_s(v: VehicleRecord, aim: tuple[float, float],
                      wind: tuple[float, float]) -> float:
        calls.append((v.id, wind))
        return 100.0 + per_m_s[v.id] * wind[0]

    there = VehicleRecord("1", 1000.0, 100.0, 0.0, 22.0, 0.0, busy=True, target="A",
                          aim_xy_m=(1000.0, 0.0), eta_s=50.0, leg_wind_xy_m_s=(0.0, 0.0),
                          leg_wind_source="fallback")
    near = VehicleRecord("2", 0.0, 0.0, 0.0, 22.0, 0.0, busy=True, target="B",
                         aim_xy_m=(2000.0, 0.0), eta_s=103.0, leg_wind_xy_m_s=(0.0, 0.0),
                         leg_wind_source="fallback")
    far = VehicleRecord("3", 0.0, 0.0, 0.0, 22.0, 0.0, busy=True, target="C",
                        aim_xy_m=(2000.0, 0.0), eta_s=90.0, leg_wind_xy_m_s=(0.0, 0.0),
                        leg_wind_source="fallback")
    legs = rule.legs(1.0, (1.0, 0.0), "vehicles", [there, near, far], flight_time_s)
    # "1" is within the footprint of its aim point; the others flown in both winds
    assert calls == [("2", (1.0, 0.0)), ("2", (0.0, 0.0)), ("3", (1.0, 0.0)), ("3", (0.0, 0.0))]
    # "2" moved 2 s (kept), "3" 11 s: replanned, its arrival the commanded one moved by 11 s
    assert [(leg.vehicle.id, leg.eta_s, leg.new_eta_s) for leg in legs] == [("3", 90.0, 101.0)]
    assert rule.legs(2.0, (2.5, 0.0), "vehicles", [near], flight_time_s) == []
    assert len(calls) == 4  # 1.5 m/s from the wind it was last predicted in: not again
    assert rule.legs(3.0, (3.5, 0.0), "vehicles", [near], flight_time_s) == []
    assert calls[4:] == [("2", (3.5, 0.0)), ("2", (1.0, 0.0))]  # 2.5 m/s: 5 s, kept


def test_a_late_vehicle_in_a_right_wind_is_not_replanned_by_the_first_estimate() -> None:
    """A leg predicted in a right ``--wind`` whose vehicle is 20 s behind its prediction
    (a slow upload, a loaded host): the first estimate, 0.1 m/s from the fallback, changes
    the rest of the leg by far less than the margin, so nothing is replanned; the lateness
    is not the wind's. Compared as ``t + T(pose; w)`` against the commanded arrival, it
    replanned."""
    rule = WindReplan(2.0, 5.0, fov_radius_m=150.0)
    late = VehicleRecord("1", 0.0, 0.0, 0.0, 22.0, 30.0, busy=True, target="A",
                         aim_xy_m=(2200.0, 0.0), eta_s=110.0, leg_wind_xy_m_s=(-15.0, 0.0),
                         leg_wind_source="fallback")

    def flight_time_s(v: VehicleRecord, aim: tuple[float, float],
                      wind: tuple[float, float]) -> float:
        return math.dist((v.x_m, v.y_m), aim) / (22.0 + wind[0])  # straight, into the wind

    legs = rule.legs(30.0, (-14.9, 0.0), "vehicles", [late], flight_time_s)
    assert legs == []
    assert 30.0 + flight_time_s(late, (2200.0, 0.0), (-14.9, 0.0)) - 110.0 > 200.0
    assert late.leg_wind_source == "vehicles"  # counted as predicted in the estimate now


def test_wind_replan_settings_and_old_journals() -> None:
    assert CoreConfig().wind_replan_m_s == 2.0 and CoreConfig().wind_replan_margin_s == 5.0
    config = CoreConfig(wind_replan_m_s=3, wind_replan_margin_s=8)
    assert config_from_dict(json.loads(json.dumps(config_to_dict(config)))) == config
    assert config_from_dict({}).wind_replan_m_s is None  # a journal from before the rule
    for bad in ({"wind_replan_m_s": -1.0}, {"wind_replan_margin_s": math.inf},
                {"wind_replan_m_s": "2"}):
        with pytest.raises(ValueError, match="wind_replan"):
            CoreConfig(**bad)  # type: ignore[arg-type]
