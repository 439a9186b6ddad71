"""The ship watch in the decision core: the ship's track, each vehicle's energy, staggered
relief, homes on the ship, and legs that leave no way home (``core/ship.py``,
``core/energy.py``, ``core/relief.py``, ``core/watch.py``)."""

from __future__ import annotations

import itertools
import math

import pytest

from groundstation.core.commands import FlyToTarget, LaunchVehicle, Note, SendHome, SetHome
from groundstation.core.config import CoreConfig, WatchConfig
from groundstation.core.decision import DecisionCore
from groundstation.core.energy import RETURN_MARGIN_S, VehicleEnergy
from groundstation.core.events import (
    BatteryReport,
    BoatPosition,
    PlanSolved,
    TargetAdded,
    Tick,
    VehicleJoined,
    VehicleLanded,
    VehicleOnDeck,
)
from groundstation.core.fleet import FleetStatus
from groundstation.core.relief import relief_spacing_s, staggered_returns
from groundstation.core.ship import ShipTrack
from planner import solve_plan

# ---------------------------------------------------------------- the ship's track


def test_ship_track_predicts_a_ship_on_a_steady_course_from_fixes_with_velocity() -> None:
    track = ShipTrack()
    for k in range(30):
        t = float(k)
        assert track.fix(BoatPosition(t, 100.0 + 8.0 * t, -50.0 + 6.0 * t, 8.0, 6.0))
    p = track.predict(89.0)
    assert p is not None
    assert math.hypot(p.x_m - (100.0 + 8.0 * 89), p.y_m - (-50.0 + 6.0 * 89)) < 2.0
    assert p.vx_m_s == pytest.approx(8.0, abs=0.1) and p.vy_m_s == pytest.approx(6.0, abs=0.1)
    assert p.fix_age_s == pytest.approx(60.0)


def test_ship_track_learns_the_velocity_from_positions_alone() -> None:
    track = ShipTrack()
    for k in range(120):
        track.fix(BoatPosition(float(k), 10.0 * k, 0.0))
    p = track.predict(119.0)
    assert p is not None and p.vx_m_s == pytest.approx(10.0, abs=0.3)


def test_ship_prediction_grows_less_certain_while_the_fixes_stop() -> None:
    track = ShipTrack()
    for k in range(20):
        track.fix(BoatPosition(float(k), 10.0 * k, 0.0, 10.0, 0.0))
    near, far = track.predict(25.0), track.predict(300.0)
    assert near is not None and far is not None
    assert far.sigma_m > 3 * near.sigma_m


def test_ship_track_refuses_non_finite_and_older_fixes() -> None:
    track = ShipTrack()
    assert not track.fix(BoatPosition(0.0, math.nan, 0.0))
    assert track.predict(0.0) is None
    assert track.fix(BoatPosition(5.0, 0.0, 0.0))
    assert not track.fix(BoatPosition(4.0, 50.0, 0.0))
    assert not track.fix(BoatPosition(6.0, 1.0, 0.0, math.inf, 0.0))
    assert track.fixes == 1


# ---------------------------------------------------------------- energy


def test_energy_learns_a_drain_twice_the_configured_one() -> None:
    e = VehicleEnergy(endurance_s=3600.0, reserve_pct=15.0)
    e.flying(0.0)
    true_rate = 2 * 100.0 / 3600.0  # the pack lasts 30 min, not 60
    for k in range(0, 601, 5):
        e.report(float(k), float(round(100.0 - true_rate * k)))
    assert e.rate_pct_s == pytest.approx(true_rate, rel=0.1)
    assert e.cautious_rate_pct_s > e.rate_pct_s
    assert e.remaining_pct(660.0) == pytest.approx(100.0 - true_rate * 660.0, abs=2.0)


def test_energy_assumes_a_full_pack_at_the_configured_rate_when_nothing_is_reported() -> None:
    e = VehicleEnergy(endurance_s=3600.0, reserve_pct=15.0)
    e.flying(100.0)
    assert not e.report(200.0, math.nan)
    assert not e.report(200.0, 140.0)
    assert not e.report(200.0, None)
    assert e.remaining_pct(1000.0) == pytest.approx(75.0)
    assert e.view(1000.0, None).source == "assumed"


def test_energy_says_which_legs_keep_the_reserve() -> None:
    e = VehicleEnergy(endurance_s=3600.0, reserve_pct=15.0)
    e.flying(0.0)
    e.report(0.0, 40.0)  # 25 points above the reserve
    left = e.endurance_left_s(0.0)
    assert left == pytest.approx(25.0 / e.cautious_rate_pct_s)
    assert e.leg_ok(0.0, left - 400.0 - RETURN_MARGIN_S, 300.0)
    assert not e.leg_ok(0.0, left - 200.0 - RETURN_MARGIN_S, 300.0)


# ---------------------------------------------------------------- relief


def test_staggered_returns_space_three_vehicles_launched_together() -> None:
    spacing = relief_spacing_s(3600.0, 15.0, 3)
    assert spacing == pytest.approx(1020.0)
    plan = staggered_returns({"1": 3000.0, "2": 3001.0, "3": 3002.0}, spacing)
    times = sorted(plan.values())
    assert times[-1] == pytest.approx(3002.0)
    assert times[1] == pytest.approx(3002.0 - spacing)
    assert times[0] == pytest.approx(3002.0 - 2 * spacing)
    assert all(plan[v] <= d for v, d in {"1": 3000.0, "2": 3001.0, "3": 3002.0}.items())


# ---------------------------------------------------------------- the watch in the core


def _core(on_station: int = 1, endurance_s: float = 1200.0) -> DecisionCore:
    watch = WatchConfig(on_station=on_station, endurance_s=endurance_s, reserve_pct=15.0)
    return DecisionCore(CoreConfig(loiter_s=10.0, time_limit_s=0.5, watch=watch))


def _drive(core: DecisionCore, t0: float, t1: float, ship_v: tuple[float, float] = (10.0, 0.0),
           step_s: float = 0.1) -> list:
    out: list = []
    k0, k1 = round(t0 / step_s), round(t1 / step_s)
    for k in range(k0, k1 + 1):
        t = k * step_s
        if k % 10 == 0:
            out += core.handle(BoatPosition(t, ship_v[0] * t, ship_v[1] * t, *ship_v))
        for command in core.handle(Tick(t)):
            out.append(command)
            if hasattr(command, "problem") and type(command).__name__ == "SolveRequest":
                result = solve_plan(command.problem, command.hint, random_seed=0)
                out += core.handle(PlanSolved(t, command.request_id, result))
    return out


def test_a_watch_launches_spares_to_fill_the_station_and_no_more() -> None:
    core = _core(on_station=1)
    core.handle(BoatPosition(0.0, 0.0, 0.0, 10.0, 0.0))
    for v in ("1", "2"):
        core.handle(VehicleOnDeck(0.0, v, True, 100.0))
    out = _drive(core, 0.0, 5.0)
    launches = [c for c in out if isinstance(c, LaunchVehicle)]
    assert [(c.vehicle, c.reason) for c in launches] == [("1", "on station")]
    assert core.vehicles["1"].status is FleetStatus.LAUNCHING
    assert core.vehicles["2"].status is FleetStatus.SPARE


def test_a_vehicle_short_of_charge_is_sent_home_to_where_the_ship_will_be() -> None:
    core = _core(on_station=1)
    core.handle(TargetAdded(0.0, "A", 3000.0, 3000.0))
    core.handle(VehicleJoined(0.0, "1", 2000.0, 0.0, 0.0, 22.0))
    core.handle(BatteryReport(0.0, "1", 60.0))
    out = _drive(core, 0.0, 2.0)
    assert not any(isinstance(c, SendHome) for c in out)
    # the charge falls to just above the reserve: no time left for anything
    core.handle(BatteryReport(2.5, "1", 18.0))
    out = _drive(core, 2.6, 4.0)
    homes = [c for c in out if isinstance(c, SendHome)]
    assert [c.vehicle for c in homes] == ["1"] and homes[0].reason.startswith("energy")
    set_home = [c for c in out if isinstance(c, SetHome) and c.t_s <= homes[0].t_s][-1]
    # the ship sails east at 10 m/s: the home is ahead of where it is now
    assert set_home.x_m > 10.0 * homes[0].t_s + 100.0
    assert core.vehicles["1"].status is FleetStatus.HOME


def test_a_leg_that_leaves_no_way_home_is_not_flown() -> None:
    core = _core(on_station=1, endurance_s=3600.0)
    core.handle(VehicleJoined(0.0, "1", 0.0, 0.0, 0.0, 22.0))
    core.handle(BatteryReport(0.0, "1", 30.0))
    # 15 points above the reserve at the cautious rate is about 6 min: a target 9 km away
    # and back is not flyable
    core.handle(TargetAdded(0.0, "far", 9000.0, 0.0))
    out = _drive(core, 0.0, 3.0, ship_v=(0.0, 0.0))
    assert not any(isinstance(c, FlyToTarget) for c in out)
    assert any(isinstance(c, SendHome) and c.vehicle == "1" for c in out)


def test_the_same_vehicle_flies_a_near_leg() -> None:
    core = _core(on_station=1, endurance_s=3600.0)
    core.handle(VehicleJoined(0.0, "1", 0.0, 0.0, 0.0, 22.0))
    core.handle(BatteryReport(0.0, "1", 30.0))
    core.handle(TargetAdded(0.0, "near", 1500.0, 0.0))
    out = _drive(core, 0.0, 3.0, ship_v=(0.0, 0.0))
    assert any(isinstance(c, FlyToTarget) and c.target == "near" for c in out)
    assert not any(isinstance(c, SendHome) for c in out)


def test_a_landing_near_the_ship_is_a_recovery_and_far_from_it_a_loss() -> None:
    core = _core(on_station=2)
    core.handle(BoatPosition(0.0, 0.0, 0.0, 0.0, 0.0))
    for v in ("1", "2"):
        core.handle(VehicleJoined(0.0, v, 500.0, 0.0, 0.0, 22.0))
    out = list(core.handle(VehicleLanded(10.0, "1", 60.0, 40.0)))
    out += core.handle(VehicleLanded(10.0, "2", 3000.0, 0.0))
    kinds = [(c.kind, c.vehicle) for c in out if isinstance(c, Note)]
    assert ("vehicle_recovered", "1") in kinds and ("vehicle_down", "2") in kinds
    assert core.vehicles["1"].status is FleetStatus.DECK
    assert core.vehicles["2"].status is FleetStatus.DOWN
    # the swap done, the recovered vehicle is a spare again
    core.handle(VehicleOnDeck(700.0, "1", True, 100.0))
    assert core.vehicles["1"].status is FleetStatus.SPARE


def test_homes_follow_the_ship_in_steps_of_home_update_m() -> None:
    core = _core(on_station=1, endurance_s=3600.0)
    core.handle(VehicleJoined(0.0, "1", 0.0, 500.0, 0.0, 22.0))
    out = _drive(core, 0.0, 60.0)
    homes = [c for c in out if isinstance(c, SetHome) and c.vehicle == "1"]
    assert len(homes) >= 3
    steps = [math.dist((a.x_m, a.y_m), (b.x_m, b.y_m)) for a, b in itertools.pairwise(homes)]
    assert all(s > 150.0 for s in steps)
    assert all(s < 400.0 for s in steps)  # the ship moves 10 m/s: no big jumps


def test_an_alarm_when_no_vehicle_can_fly_and_it_clears() -> None:
    core = _core(on_station=1)
    core.handle(VehicleJoined(0.0, "1", 0.0, 0.0, 0.0, 22.0))
    out = _drive(core, 0.0, 2.0)
    core.handle(VehicleLanded(2.5, "1", 5000.0, 0.0))  # down, far from the ship
    out = _drive(core, 3.0, 5.0)
    alarms = [c for c in out if isinstance(c, Note) and c.kind == "watch_alarm"]
    assert any("no vehicle in the plan" in c.detail for c in alarms)
    core.handle(VehicleOnDeck(6.0, "2", True, 100.0))
    out = _drive(core, 6.0, 8.0)
    assert any(isinstance(c, Note) and c.kind == "watch_clear" for c in out)


def test_the_watch_reads_for_the_operator_and_as_json() -> None:
    """The console's lines and the API's ``watch`` from the core's view: the ship, each
    vehicle's charge and turn-home time, the spares; plain JSON (no NaN, no infinity)."""
    import json

    from groundstation.daemon.watch_lines import ship_text, watch_dict, watch_rows

    core = _core(on_station=1, endurance_s=3600.0)
    core.handle(VehicleOnDeck(0.0, "2", True, 100.0))
    core.handle(VehicleJoined(0.0, "1", 1000.0, 0.0, 0.0, 22.0))
    core.handle(BatteryReport(0.0, "1", 80.0))
    _drive(core, 0.0, 3.0)
    view = core.view().watch
    assert view is not None
    assert ship_text(view).startswith("ship at (30, 0) m, 10.0 m/s to 090 deg")
    (row,) = [r for r in watch_rows(view, 3.0) if r[0] == "1"]
    assert row[1] == "80" and row[5] == "yes" and row[4].startswith("t=")
    doc = json.loads(json.dumps(watch_dict(view), allow_nan=False))
    assert doc["spares"] == ["2"] and doc["on_station"] == 1
    assert doc["energy"]["1"]["source"] == "reported"
    assert doc["ship"]["course_deg"] == pytest.approx(90.0)
