"""Flight in wind (world/dynamics.py), the offline simulator's ``--wind`` and the
arrival-error metric (groundstation/core/arrivals.py)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

import world
from domain.wind_triangle import crab_heading_rad, wind_vector_m_s
from groundstation.cli import main
from groundstation.core.arrivals import ArrivalTracker, percentile
from world.dynamics import (
    LoiterCommand,
    UavState,
    ground_velocity_m_s,
    step_kinematics,
    turn_rate_to_circle,
    turn_rate_to_point,
)

V_M_S = 22.0
R_MIN_M = 105.0
DT_S = 0.1


def fly_to(state: UavState, x_m: float, y_m: float, wind: tuple[float, float],
           seconds: float) -> list[UavState]:
    states = [state]
    for _ in range(round(seconds / DT_S)):
        u = turn_rate_to_point(state, x_m, y_m, R_MIN_M, wind_xy_m_s=wind)
        state = step_kinematics(state, u, DT_S, wind_xy_m_s=wind)
        states.append(state)
    return states


def test_a_step_is_the_exact_air_arc_plus_the_drift() -> None:
    wind = (6.0, -8.0)
    one = UavState(10.0, 20.0, 0.4, V_M_S)
    many = one
    for _ in range(100):
        many = step_kinematics(many, 0.15, 0.1, wind_xy_m_s=wind)
    one = step_kinematics(one, 0.15, 10.0, wind_xy_m_s=wind)
    assert (many.x_m, many.y_m, many.heading_rad) == pytest.approx(
        (one.x_m, one.y_m, one.heading_rad), abs=1e-6
    )
    calm = step_kinematics(UavState(10.0, 20.0, 0.4, V_M_S), 0.15, 10.0)
    assert (one.x_m - calm.x_m, one.y_m - calm.y_m) == pytest.approx((60.0, -80.0))
    assert one.speed_m_s == V_M_S  # airspeed is held


@pytest.mark.parametrize("from_deg", [0.0, 45.0, 180.0])
def test_a_straight_leg_holds_its_ground_course_crabbing_into_a_cross_wind(
    from_deg: float,
) -> None:
    wind = wind_vector_m_s(10.0, from_deg)
    goal = (3000.0, 0.0)
    states = fly_to(UavState(0.0, 0.0, 0.0, V_M_S), *goal, wind, 80.0)
    # drifted at most a few metres while taking up the crab, then straight at the point
    assert max(abs(s.y_m) for s in states) < 12.0
    settled = [s for s in states if 600.0 < s.x_m < 2800.0]
    assert len(settled) > 200, "the leg did not get under way"
    first = settled[0]
    for s in settled:
        bearing = math.atan2(goal[1] - s.y_m, goal[0] - s.x_m)
        vx, vy = ground_velocity_m_s(s, wind)
        assert math.atan2(vy, vx) == pytest.approx(bearing, abs=math.radians(0.2))
        assert s.heading_rad == pytest.approx(crab_heading_rad(bearing, wind, V_M_S),
                                              abs=math.radians(0.2))
        # on the straight line from where it settled to the point
        chord = math.atan2(goal[1] - first.y_m, goal[0] - first.x_m)
        off_m = (s.x_m - first.x_m) * math.sin(chord) - (s.y_m - first.y_m) * math.cos(chord)
        assert abs(off_m) < 0.5
    if from_deg == 0.0:  # a pure cross wind needs a real crab angle
        assert abs(crab_heading_rad(0.0, wind, V_M_S)) > math.radians(20.0)


@pytest.mark.parametrize(("from_deg", "ground_m_s"), [
    (270.0, V_M_S + 10.0),                    # from the west: tail wind on an eastward leg
    (90.0, V_M_S - 10.0),                     # head wind
    (0.0, math.sqrt(V_M_S**2 - 10.0**2)),     # cross wind: the crab costs speed
])
def test_a_2_km_leg_takes_distance_over_ground_speed(from_deg: float,
                                                     ground_m_s: float) -> None:
    wind = wind_vector_m_s(10.0, from_deg)
    start = UavState(0.0, 0.0, crab_heading_rad(0.0, wind, V_M_S), V_M_S)
    states = fly_to(start, 10_000.0, 0.0, wind, 400.0)
    t_cross_s = next(k for k, s in enumerate(states) if s.x_m >= 2000.0) * DT_S
    assert t_cross_s == pytest.approx(2000.0 / ground_m_s, abs=DT_S + 1e-9)


@pytest.mark.parametrize("from_deg", [270.0, 30.0])
def test_a_loiter_stays_round_over_ground_in_10_m_s_of_wind(from_deg: float) -> None:
    wind = wind_vector_m_s(10.0, from_deg)
    circle = LoiterCommand(0.0, 0.0, 300.0, clockwise=True)
    state = UavState(-900.0, 400.0, 0.3, V_M_S)
    radii: list[float] = []
    rates: list[float] = []
    for k in range(6000):
        u = turn_rate_to_circle(state, circle, R_MIN_M, wind_xy_m_s=wind)
        state = step_kinematics(state, u, DT_S, wind_xy_m_s=wind)
        if k >= 3000:  # three minutes to settle, then five circles
            radii.append(math.hypot(state.x_m, state.y_m))
            rates.append(u)
    assert max(abs(r - 300.0) for r in radii) < 0.03 * 300.0
    assert state.speed_m_s == V_M_S
    # the bank varies round the circle: faster turns downwind, where ground speed is high
    assert max(rates) < 0.0 and min(rates) / max(rates) > 1.8
    # still-air guidance in the same wind drifts off the circle
    state = UavState(0.0, 300.0, 0.0, V_M_S)
    for _ in range(1200):
        state = step_kinematics(state, turn_rate_to_circle(state, circle, R_MIN_M), DT_S,
                                wind_xy_m_s=wind)
    assert abs(math.hypot(state.x_m, state.y_m) - 300.0) > 30.0


def test_calm_is_the_still_air_arithmetic() -> None:
    s = UavState(1.0, 2.0, 0.7, V_M_S)
    circle = LoiterCommand(400.0, 100.0, 150.0, clockwise=False)
    assert step_kinematics(s, 0.1, 0.1, wind_xy_m_s=(0.0, 0.0)) == step_kinematics(s, 0.1, 0.1)
    assert turn_rate_to_point(s, 500.0, -300.0, R_MIN_M, wind_xy_m_s=(-0.0, -0.0)) == (
        turn_rate_to_point(s, 500.0, -300.0, R_MIN_M)
    )
    assert turn_rate_to_circle(s, circle, R_MIN_M, wind_xy_m_s=(0.0, 0.0)) == (
        turn_rate_to_circle(s, circle, R_MIN_M)
    )


# ------------------------------------------------------------------ arrival error
def approach(tracker: ArrivalTracker, vehicle: str, x0_m: float, speed_m_s: float,
             t0_s: float, until_s: float) -> None:
    """Position samples every 0.1 s of a straight eastward flight along y = 0."""
    for k in range(round((until_s - t0_s) / 0.1) + 1):
        t = t0_s + 0.1 * k
        tracker.position(t, vehicle, x0_m + speed_m_s * (t - t0_s), 0.0)


def test_arrival_error_compares_the_eta_with_the_flown_arrival_at_the_aim_point() -> None:
    tracker = ArrivalTracker()
    tracker.position(0.0, "1", 0.0, 0.0)
    # aim 1000 m east, flown at 25 m/s: there at 40 s; predicted 38 s -> 2 s late
    tracker.commanded(0.0, "1", "A", 1000.0, 0.0, 38.0, 150.0)
    approach(tracker, "1", 0.0, 25.0, 0.0, 60.0)
    tracker.position(0.0, "2", 0.0, 0.0)
    tracker.commanded(0.0, "2", "B", 600.0, 0.0, 33.0, 150.0)  # flown: 30 s, 3 s early
    approach(tracker, "2", 0.0, 20.0, 0.0, 40.0)
    out = tracker.to_dict()
    assert out["arrivals"] == {"counted": 2, "superseded": 0, "inside_at_command": 0,
                               "unfinished": 0}
    assert sorted(tracker.errors_s) == pytest.approx([-3.0, 2.0], abs=1e-9)
    assert out["arrival_error_s"]["median"] == pytest.approx(2.5)
    assert out["arrival_error_s"]["p90"] == pytest.approx(2.9)
    assert out["arrival_bias_s"] == pytest.approx(-0.5)


def test_arrival_error_is_split_into_each_vehicles_first_leg_and_the_later_ones() -> None:
    tracker = ArrivalTracker()
    tracker.position(0.0, "1", 0.0, 0.0)
    tracker.commanded(0.0, "1", "A", 1000.0, 0.0, 30.0, 150.0)  # flown 40 s: 10 s late
    approach(tracker, "1", 0.0, 25.0, 0.0, 40.0)
    tracker.commanded(40.0, "1", "B", 2000.0, 0.0, 81.0, 150.0)  # flown 80 s: 1 s early
    approach(tracker, "1", 1000.0, 25.0, 40.0, 80.0)
    tracker.commanded(80.0, "1", "C", 3000.0, 0.0, 123.0, 150.0)  # flown 120 s: 3 s early
    approach(tracker, "1", 2000.0, 25.0, 80.0, 120.0)
    # vehicle 2's first flight is replanned on the way (say by the first wind estimate):
    # its first leg is measured against the replanned prediction
    tracker.position(0.0, "2", 0.0, 0.0)
    tracker.commanded(0.0, "2", "D", 600.0, 0.0, 40.0, 150.0)
    tracker.commanded(1.0, "2", "D", 600.0, 0.0, 22.0, 150.0)  # flown 25 s: 3 s late
    approach(tracker, "2", 0.0, 25.0, 1.0, 30.0)
    out = tracker.to_dict()
    assert sorted(tracker.first_errors_s) == pytest.approx([3.0, 10.0], abs=1e-9)
    assert sorted(tracker.later_errors_s) == pytest.approx([-3.0, -1.0], abs=1e-9)
    assert out["arrival_error_first_s"] == pytest.approx(
        {"median": 6.5, "p90": 9.3, "max": 10.0, "counted": 2})
    assert out["arrival_error_later_s"] == pytest.approx(
        {"median": 2.0, "p90": 2.8, "max": 3.0, "counted": 2})
    assert out["arrival_bias_first_s"] == pytest.approx(6.5)
    assert out["arrival_bias_later_s"] == pytest.approx(-2.0)
    assert out["arrivals"]["counted"] == 4 and out["arrivals"]["superseded"] == 1
    empty = ArrivalTracker().to_dict()
    assert empty["arrival_error_first_s"] is None and empty["arrival_error_later_s"] is None


def test_redirected_inside_and_unfinished_commands_are_not_counted() -> None:
    tracker = ArrivalTracker()
    assert tracker.to_dict()["arrival_error_s"] is None
    tracker.position(0.0, "1", 0.0, 0.0)
    tracker.commanded(0.0, "1", "A", 1000.0, 0.0, 40.0, 150.0)
    approach(tracker, "1", 0.0, 25.0, 0.0, 10.0)
    tracker.commanded(10.0, "1", "B", 5000.0, 0.0, 200.0, 150.0)  # A superseded
    tracker.commanded(10.0, "1", "C", 300.0, 0.0, 12.0, 150.0)   # B too; C is within 150 m
    tracker.position(0.0, "2", 0.0, 0.0)
    tracker.commanded(0.0, "2", "D", 900.0, 0.0, 40.0, 150.0)
    tracker.abandoned("2")                                       # released
    tracker.position(0.0, "3", 0.0, 0.0)
    tracker.commanded(0.0, "3", "E", 9000.0, 0.0, 400.0, 150.0)  # still flying at the end
    out = tracker.to_dict()
    assert out["arrivals"] == {"counted": 0, "superseded": 3, "inside_at_command": 1,
                               "unfinished": 1}
    assert out["arrival_error_s"] is None and out["arrival_bias_s"] is None
    assert percentile([5.0], 0.9) == 5.0
    assert percentile([1.0, 2.0, 3.0, 4.0, 5.0], 0.5) == 3.0


# ------------------------------------------------------------------ gcs simulate --wind
TIMING_KEYS = {"wall_time_s", "realtime_factor", "solve_time_s"}


def simulate(tmp_path: Path, name: str, *extra: str,
             scenario: str = "paper-boat") -> dict[str, Any]:
    out = tmp_path / name
    status = main(["simulate", "--scenario", scenario, "--uavs", "3", "--seed", "0",
                   "--duration", "60", "--quiet", "--out", str(out), *extra])
    assert status == 0
    metrics: dict[str, Any] = json.loads((out / "metrics.json").read_text())
    return metrics


def test_simulate_flies_in_the_wind_it_is_given(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    calm = simulate(tmp_path, "calm", "--no-plots")
    zero = simulate(tmp_path, "zero", "--no-plots", "--wind", "0,0")
    windy = simulate(tmp_path, "windy", "--wind", "10,270")
    out = capsys.readouterr().out
    assert "wind: 10 m/s from 270 deg" in out
    # calm: the explicit still air is the scenario's, figure for figure
    assert {k: v for k, v in calm.items() if k not in TIMING_KEYS} == {
        k: v for k, v in zero.items() if k not in TIMING_KEYS
    }
    assert calm["wind"] == {"speed_m_s": 0.0, "from_deg": 0.0, "gust_m_s": 0.0}
    # in still air the planner's Dubins-at-airspeed eta is what the pass-over flies
    assert calm["arrivals"]["counted"] >= 3
    assert calm["arrival_error_s"]["p90"] < 0.01
    # in wind: the run differs; the wind-aware eta holds, a wind-blind one is off by seconds
    blind_file = tmp_path / "blind.yaml"
    blind_file.write_text(
        (Path(world.__file__).parent / "scenarios" / "paper-boat.yaml").read_text()
        .replace("planner: {", "planner: {wind_aware: false, "))
    blind = simulate(tmp_path, "blind", "--no-plots", "--wind", "10,270",
                     scenario=str(blind_file))
    assert windy["wind"] == {"speed_m_s": 10.0, "from_deg": 270.0, "gust_m_s": 0.0}
    assert windy["uncertainty_series"] != calm["uncertainty_series"]
    assert windy["arrivals"]["counted"] >= 1 and blind["arrivals"]["counted"] >= 1
    assert windy["arrival_error_s"]["median"] < 0.5
    assert blind["arrival_error_s"]["median"] > 1.0
    assert isinstance(windy["arrival_bias_s"], float)
    for key in calm:  # every key a calm run writes is still there
        assert key in windy
    start = json.loads((tmp_path / "windy" / "journal.jsonl").read_text().splitlines()[0])
    assert start["event"] == "start" and start["wind"] == windy["wind"]
    fly = [json.loads(line) for line in (tmp_path / "windy" / "journal.jsonl").read_text()
           .splitlines() if '"fly"' in line]
    assert fly and all(r["eta_s"] > r["t"] for r in fly)
    assert (tmp_path / "windy" / "map.png").read_bytes().startswith(b"\x89PNG")


@pytest.mark.parametrize(("wind", "message"), [
    ("10", "expected SPEED_M_S,FROM_DEG"),
    ("ten,270", "not numbers"),
    ("10,400", "FROM_DEG must be a compass direction"),
    ("nan,10", "must be finite"),
    ("-3,10", "speed_m_s must be in"),
])
def test_bad_wind_is_one_line_and_status_2(wind: str, message: str, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    status = main(["simulate", f"--wind={wind}", "--out", str(tmp_path), "--quiet"])
    assert status == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "metrics.json").exists()
