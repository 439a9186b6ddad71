"""Missions that fly through the next targets of a vehicle's planned route
(``core/route.py``, issue 28): events in, commands out, on mission time only."""

from __future__ import annotations

from core_run import solve_all

from groundstation.core.commands import Command, FlyToTarget
from groundstation.core.config import CoreConfig, ReplanPolicy, config_from_dict
from groundstation.core.decision import DecisionCore
from groundstation.core.events import (
    Detection,
    LoiterEnded,
    TargetAdded,
    Telemetry,
    Tick,
    VehicleJoined,
)
from groundstation.vehicle.state import FlyRecord
from observer import ObserverConfig
from planner.search_cells import SearchConfig


def fly_to(core: DecisionCore, t0_s: float, t1_s: float, x0_m: float, x1_m: float
           ) -> list[FlyToTarget]:
    """The vehicle flies east along y = 0 from x0 to x1 over [t0, t1) (telemetry and a
    tick every 0.1 s, plans solved inline); the FlyToTargets it is sent."""
    out: list[Command] = []
    n = round((t1_s - t0_s) * 10)
    for k in range(n):
        t_s = round(t0_s + k * 0.1, 1)
        core.handle(Telemetry(t_s, "1", x0_m + (x1_m - x0_m) * k / n, 0.0, 0.0, 22.0))
        out += solve_all(core, core.handle(Tick(t_s)))
    return [c for c in out if isinstance(c, FlyToTarget)]


def route_core() -> DecisionCore:
    """One vehicle at the origin heading east; icebergs A, B, C 1, 2 and 3 km east, all
    passes (loiter_s 0); every vehicle replanned every 5 s (no commitment). Routes are
    flown in runs that search (here no cell is planned: ``max_cells`` 0)."""
    core = DecisionCore(CoreConfig(
        policy=ReplanPolicy(on_events=True, period_s=5.0, commit=False),
        observer=ObserverConfig(model="kalman"), loiter_s=0.0, area_m=(0.0, 3000.0, -1500.0,
                                                                        1500.0),
        search=SearchConfig(cell_m=500.0, growth_m2_per_s=25.0, max_cells=0)))
    core.handle(VehicleJoined(0.0, "1", 0.0, 0.0, 0.0, 22.0))
    for target, x_m in (("A", 1000.0), ("B", 2000.0), ("C", 3000.0)):
        core.handle(TargetAdded(0.0, target, x_m, 0.0, sigma0=100.0))
    return core


def test_moving_on_to_the_next_target_of_the_route_is_not_a_new_mission() -> None:
    """The first mission holds the head A and flies through B and C; the camera seeing A
    and the vehicle flying on to B (the plan's new head) sends nothing; seeing B and
    then a new iceberg D (far more uncertain, off the route) becoming the head does."""
    core = route_core()
    first = fly_to(core, 0.0, 1.0, 0.0, 22.0)
    assert [f.target for f in first] == ["A"]
    # A seen as the vehicle passes it; it flies on towards B through 40 s of replans
    core.handle(Detection(44.0, "1", "A", 1000.0, 0.0, r_m2=5.0))
    assert fly_to(core, 44.0, 84.0, 1000.0, 1880.0) == []
    assert [(c.target, round(c.x_m)) for c in first[0].through] == [
        ("B", 2000), ("C", 3000), ("C", 3000)]  # route_cells 3: the last point repeated
    assert core.vehicles["1"].target == "B" and core.vehicles["1"].through == ("C", "C")
    assert core.counters["route_moved_on"] >= 1
    # a new head: an iceberg off the route, far more uncertain, is a new mission
    core.handle(Detection(84.0, "1", "B", 2000.0, 0.0, r_m2=5.0))
    core.handle(TargetAdded(84.0, "D", 1900.0, 800.0, sigma0=1e7))
    sent = fly_to(core, 84.0, 90.0, 1880.0, 2000.0)
    assert [f.target for f in sent] == ["D"]


def test_a_replan_that_skips_an_unseen_target_of_the_mission_is_a_new_mission() -> None:
    """Moving on needs every earlier item seen since the mission was sent: a vehicle that
    is past A and B without having seen either, planned to C (the mission's last point),
    is sent a new mission to C (else it would fly back through A and B first), once the
    route interval (60 s: it keeps flying its route meanwhile) has passed."""
    core = route_core()
    fly_to(core, 0.0, 1.0, 0.0, 22.0)
    sent = fly_to(core, 1.0, 62.0, 2500.0, 2600.0)
    # it still has points of its route ahead: the new head waits for the route interval
    assert [(round(f.t_s), f.target, [c.target for c in f.through]) for f in sent][:1] == [
        (60, "C", ["B", "A", "A"])]
    assert "route_moved_on" not in core.counters


def test_the_mission_end_moves_the_record_to_its_last_point() -> None:
    """The pass of the last point flown through (the LoiterEnded of the mission) leaves
    the core's record of the vehicle at that point, so the next leg starts from there."""
    core = route_core()
    fly_to(core, 0.0, 1.0, 0.0, 22.0)
    core.handle(Telemetry(140.0, "1", 3000.0, 0.0, 0.0, 22.0))
    core.handle(LoiterEnded(140.0, "1"))
    record = core.vehicles["1"]
    assert record.target == "C" and record.through == ()


def test_journals_from_before_routes_replay_as_they_ran() -> None:
    """A start line without ``route_cells`` reads as None: missions end at their head."""
    assert config_from_dict({"loiter_s": 0.0}).route_cells is None
    core = DecisionCore(config_from_dict({
        "loiter_s": 0.0, "policy": {"on_events": True, "period_s": 5.0, "commit": False},
        "observer": {"model": "kalman"}}))
    core.handle(VehicleJoined(0.0, "1", 0.0, 0.0, 0.0, 22.0))
    for target, x_m in (("A", 1000.0), ("B", 2000.0)):
        core.handle(TargetAdded(0.0, target, x_m, 0.0, sigma0=100.0))
    sent = fly_to(core, 0.0, 1.0, 0.0, 22.0)
    assert [(f.target, f.through) for f in sent] == [("A", ())]


def test_the_no_progress_watch_follows_the_point_the_vehicle_flies_to() -> None:
    """The controller measures progress to the point of the route the vehicle flies to
    now (MISSION_CURRENT: item 1 the aim, items 2.. the points flown through, the last
    item at the last point), and a MISSION_CURRENT going back (a stray frame) does not
    move it back."""
    fly = FlyRecord("A", 1000.0, 0.0, ("A", "B", "C"),
                    through=((2000.0, 0.0), (3000.0, 0.0), (3000.0, 0.0)))
    assert fly.aim_now(1) == (1000.0, 0.0)
    assert fly.aim_now(2) == (2000.0, 0.0)
    assert fly.aim_now(1) == (2000.0, 0.0)  # never back
    assert fly.aim_now(None) == (2000.0, 0.0)
    assert fly.aim_now(5) == (3000.0, 0.0)  # the unlimited loiter at the last point


def test_a_routed_pass_is_redirected_at_most_once_per_route_interval() -> None:
    """Even when its mission holds no other point than its head (one iceberg: the head
    repeated), a vehicle on a routed pass keeps it for the route interval (60 s) before a
    new head is sent: not the 15 s upload interval, with which neighbouring heads flipped
    with every replan."""
    core = DecisionCore(CoreConfig(
        policy=ReplanPolicy(on_events=True, period_s=5.0, commit=False),
        observer=ObserverConfig(model="kalman"), loiter_s=0.0,
        area_m=(0.0, 3000.0, -1500.0, 1500.0),
        search=SearchConfig(cell_m=500.0, growth_m2_per_s=25.0, max_cells=0)))
    core.handle(VehicleJoined(0.0, "1", 0.0, 0.0, 0.0, 22.0))
    core.handle(TargetAdded(0.0, "A", 2500.0, 0.0, sigma0=100.0))
    first = fly_to(core, 0.0, 1.0, 0.0, 22.0)
    assert [(f.target, [c.target for c in f.through]) for f in first] == [
        ("A", ["A", "A", "A"])]
    core.handle(TargetAdded(10.0, "D", 300.0, 900.0, sigma0=1e7))
    sent = fly_to(core, 10.0, 70.0, 200.0, 600.0)
    assert sent, "the new head is sent once the route interval has passed"
    assert sent[0].target == "D" and 60.0 <= sent[0].t_s <= 61.0, (sent[0].t_s, sent[0].target)
