"""When the core sends a vehicle a new mission (``core/uploads.py``, issue 28): events in,
commands out, on mission time only."""

from __future__ import annotations

import itertools
import json
from importlib import resources
from pathlib import Path

from core_run import solve_all
from simulate_run import simulate_text

from groundstation.core.commands import (
    Command,
    FlyToTarget,
    Note,
    ReleaseVehicle,
    SendHome,
    SolveRequest,
)
from groundstation.core.config import CoreConfig, ReplanPolicy, config_from_dict
from groundstation.core.decision import DecisionCore
from groundstation.core.events import (
    BatteryLow,
    LoiterEnded,
    OperatorOverride,
    TargetAdded,
    Tick,
    VehicleJoined,
)
from groundstation.core.scenario_config import core_config_for
from groundstation.core.uploads import UploadRule
from observer import ObserverConfig
from world.scenario import load_scenario


def flies(commands: list[Command]) -> list[FlyToTarget]:
    return [c for c in commands if isinstance(c, FlyToTarget)]


def run_ticks(core: DecisionCore, t0_s: float, t1_s: float) -> list[Command]:
    """Ticks every 0.1 mission s over [t0, t1), plans solved inline."""
    out: list[Command] = []
    for k in range(round((t1_s - t0_s) * 10)):
        out += solve_all(core, core.handle(Tick(round(t0_s + k * 0.1, 1))))
    return out


def test_an_aim_that_moves_less_than_the_loiter_radius_is_not_sent_again() -> None:
    """Without commitment every periodic replan plans every vehicle; one that keeps its
    target is not sent a new mission while the aim point moved less than the loiter radius
    (120 m), and is once it moved farther."""
    core = DecisionCore(CoreConfig(
        policy=ReplanPolicy(on_events=True, period_s=5.0, commit=False),
        observer=ObserverConfig(model="kalman"), loiter_s=0.0, loiter_radius_m=120.0))
    core.handle(VehicleJoined(0.0, "1", 0.0, 0.0, 0.0, 22.0))
    # a target 2 km east drifting north at 10 m/s: its aim moves 50 m per 5 s replan
    core.handle(TargetAdded(0.0, "A", 2000.0, 0.0, vx_m_s=0.0, vy_m_s=10.0, sigma0=10.0))
    out = run_ticks(core, 0.0, 20.0)
    sent = flies(out)
    assert [round(f.t_s, 1) for f in sent] == [0.0, 15.0]
    assert 110.0 < sent[1].y_m - sent[0].y_m < 200.0  # moved past the radius, then re-sent


def test_a_new_target_waits_for_the_minimum_interval_but_safety_does_not() -> None:
    """A redirect 3 s after the last FlyToTarget is deferred to the end of the minimum
    interval (15 s by default) and replanned then; a send-home and an operator's override
    go at once."""
    core = DecisionCore(CoreConfig(
        policy=ReplanPolicy(on_events=True, period_s=None, commit=False),
        observer=ObserverConfig(model="kalman"), loiter_s=0.0))
    for vehicle, y_m in (("1", 0.0), ("2", 3000.0)):
        core.handle(VehicleJoined(0.0, vehicle, 0.0, y_m, 0.0, 22.0))
    core.handle(TargetAdded(0.0, "A", 2000.0, 0.0, sigma0=10.0))
    core.handle(TargetAdded(0.0, "C", 2000.0, 3000.0, sigma0=10.0))
    first = flies(run_ticks(core, 0.0, 1.0))
    assert {(f.vehicle, f.target) for f in first} == {("1", "A"), ("2", "C")}
    # a far more uncertain target appears next to vehicle 1 at t = 3 s
    core.handle(TargetAdded(3.0, "B", 0.0, 400.0, sigma0=5000.0))
    out = run_ticks(core, 3.0, 15.5)
    redirects = [f for f in flies(out) if f.vehicle == "1"]
    assert [(round(f.t_s, 1), f.target) for f in redirects] == [(15.0, "B")]
    assert any(isinstance(c, SolveRequest) and c.reason == "upload interval passed"
               for c in out)
    # safety right after an upload: never delayed
    home = core.handle(BatteryLow(15.5, "1"))
    assert [c.vehicle for c in home if isinstance(c, SendHome)] == ["1"]
    released = core.handle(OperatorOverride(15.6, "2"))
    assert [c.vehicle for c in released if isinstance(c, ReleaseVehicle)] == ["2"]


def test_a_lost_target_is_not_sent_to_the_same_vehicle_at_the_same_place_again() -> None:
    """A loiter that saw nothing of its target is a miss: the vehicle is not sent back to
    that empty water at every replan (the field's loop: 5 loiter ends in 25 s), only once
    the target's uncertainty doubled."""
    core = DecisionCore(CoreConfig(
        policy=ReplanPolicy(on_events=True, period_s=5.0, commit=True),
        observer=ObserverConfig(model="kalman", q_per_s=0.1), loiter_s=5.0))
    core.handle(VehicleJoined(0.0, "1", 0.0, 0.0, 0.0, 22.0))
    core.handle(TargetAdded(0.0, "A", 1500.0, 0.0, sigma0=2000.0))
    out = run_ticks(core, 0.0, 1.0)
    assert [f.target for f in flies(out)] == ["A"]
    sent_s = [f.t_s for f in flies(out)]
    notes: list[Note] = []
    sigma_at_miss = 0.0
    for k in range(5):  # the loiter ends every 5 s without a detection of A
        t_s = 5.0 * (k + 1)
        out = core.handle(LoiterEnded(t_s, "1"))
        if k == 0:
            sigma_at_miss = core.observer.track("A").sigma
        out += run_ticks(core, t_s, t_s + 5.0)
        notes += [c for c in out if isinstance(c, Note) and c.kind == "visit_missed"]
        sent_s += [f.t_s for f in flies(out)]
    assert sent_s == [0.0]
    assert [(n.vehicle, n.target) for n in notes] == [("1", "A")]
    # once A's uncertainty doubled, a new visit is worth it: sent back, once
    later: list[Command] = []
    t_s = 30.0
    while not flies(later) and t_s < 300.0:
        later = run_ticks(core, t_s, t_s + 1.0)
        t_s += 1.0
    again = flies(later)
    assert [f.target for f in again] == ["A"]
    assert core.observer.track("A").sigma >= 2.0 * sigma_at_miss


def test_journals_from_before_the_rule_replay_as_they_ran() -> None:
    """A start line without the rule's keys reads as the old behaviour: no interval, no
    revisit rule, the 50 m threshold."""
    config = config_from_dict({"loiter_s": 0.0})
    assert config.upload_min_interval_s is None
    assert config.revisit_growth is None
    assert config.retarget_m == 50.0
    assert CoreConfig().retarget_m == CoreConfig().loiter_radius_m


def test_the_hourly_budget_delays_redirects_never_answers() -> None:
    """The token bucket (core/uploads.py, "Hourly budget"): 36 an hour (one token per
    100 s), two held. Two redirects go at once, the third waits for a token; a loiter end's
    answer (the caller skips too_soon) spends one all the same, in debt, and the next
    redirect waits until the debt is repaid. A rejoining vehicle's command never waits."""
    rule = UploadRule(None, 100.0, None, budget_per_h=36.0)
    assert not rule.too_soon("1", 0.0)
    rule.sent("1", 0.0)
    assert not rule.too_soon("1", 1.0)
    rule.sent("1", 1.0)
    assert rule.too_soon("1", 2.0)  # 0.02 tokens left: due when one has refilled
    assert not rule.due(99.9) and rule.due(100.0)
    assert not rule.too_soon("1", 101.0)
    rule.sent("1", 101.0)
    rule.sent("1", 102.0)  # a loiter end's answer: never asked, spends into debt
    assert rule.too_soon("1", 150.0)  # at -0.98 + 0.48: due at 300 s
    assert not rule.due(299.9) and rule.due(300.0)
    rule.reset("1", 160.0)  # rejoined: its next command is not delayed
    assert not rule.too_soon("1", 160.0)
    # over an hour at most burst + rate tokens: here 2 + 36, whatever the pressure
    busy = UploadRule(15.0, 100.0, None, budget_per_h=36.0)
    sent = 0
    for k in range(3600):
        if not busy.too_soon("2", float(k)):
            busy.sent("2", float(k))
            sent += 1
    assert sent == 2 + 36 - 1  # the last token would be due at 3600 s exactly
    # journals from before the budget read without it
    assert config_from_dict({"loiter_s": 0.0}).upload_budget_per_h is None
    assert CoreConfig().upload_budget_per_h is None  # paper-boat: the paper's replanning
    assert core_config_for(load_scenario("discovery")).upload_budget_per_h == 50.0


def test_gcs_simulate_discovery_keeps_each_vehicle_under_sixty_uploads_an_hour(
        tmp_path: Path) -> None:
    """End to end: ``gcs simulate`` discovery, 3 vehicles, 900 mission s at the default
    settings: missions fly through the next targets of the route (``core/route.py``), so
    every vehicle's FlyToTargets (metrics.json ``uploads``, the journal's ``fly`` lines)
    stay at most 60 an hour; before routes the same run sent each 130-160 an hour."""
    text = resources.files("world").joinpath("scenarios/discovery.yaml").read_text()
    out = simulate_text(tmp_path, text, "--duration", "900", "--seed", "0")
    metrics = json.loads((out / "metrics.json").read_text())
    flies = [json.loads(line) for line in (out / "journal.jsonl").read_text().splitlines()
             if '"event": "fly"' in line]
    per_vehicle = {v: sum(1 for f in flies if f["vehicle"] == v) for v in ("1", "2", "3")}
    assert metrics["uploads"] == per_vehicle and min(per_vehicle.values()) > 0
    assert set(metrics["uploads_per_hour"]) == {"1", "2", "3"}
    assert max(metrics["uploads_per_hour"].values()) <= 60.0
    links = {e["vehicle"]: e for e in metrics["links"]}  # the same under links, no link
    assert {v: e["uploads"] for v, e in links.items()} == per_vehicle
    assert all(e["link"] is None and e["upload_ok_pct"] == 100.0 for e in links.values())
    assert any(f.get("through") for f in flies)  # routes flown through, not one target each
    for v in ("1", "2", "3"):
        times = [f["t"] for f in flies if f["vehicle"] == v]
        assert all(b - a >= 15.0 - 1e-6 for a, b in itertools.pairwise(times))


def _two_targets_one_each(policy: ReplanPolicy) -> DecisionCore:
    """Two vehicles, two targets: each vehicle's planned route is its one target, so a
    loiter end leaves nothing along the route; the minimum interval is 15 s (default)."""
    core = DecisionCore(CoreConfig(policy=policy, observer=ObserverConfig(model="kalman"),
                                   loiter_s=0.0))
    for vehicle, y_m in (("1", 0.0), ("2", 3000.0)):
        core.handle(VehicleJoined(0.0, vehicle, 0.0, y_m, 0.0, 22.0))
    core.handle(TargetAdded(0.0, "A", 600.0, 0.0, vx_m_s=0.0, vy_m_s=3.0, sigma0=10.0))
    core.handle(TargetAdded(0.0, "C", 600.0, 3000.0, vx_m_s=0.0, vy_m_s=3.0, sigma0=10.0))
    return core


def test_a_loiter_end_is_answered_at_the_next_tick_under_a_periodic_only_policy() -> None:
    """Issue 30: with replanning every 10 s only (no events), a vehicle whose route ends at
    the target it just passed was left holding until the next period; now the loiter end
    plans at the next tick, and its answer (a new leg, 3 s after the last one) is not
    deferred by the 15 s upload interval."""
    core = _two_targets_one_each(ReplanPolicy(on_events=False, period_s=10.0, commit=False))
    first = flies(run_ticks(core, 0.0, 1.0))
    assert {(f.vehicle, f.target) for f in first} == {("1", "A"), ("2", "C")}
    # a new, very uncertain target near vehicle 1 (no replan: events do not replan here)
    core.handle(TargetAdded(2.0, "B", 0.0, 400.0, sigma0=5000.0))
    assert not flies(run_ticks(core, 1.0, 3.0))
    out = solve_all(core, core.handle(LoiterEnded(3.0, "1")))
    out += run_ticks(core, 3.0, 3.3)
    requests = [c for c in out if isinstance(c, SolveRequest)]
    assert [(round(r.t_s, 1), r.reason) for r in requests] == [(3.0, "loiter end answer")]
    answer = [f for f in flies(out) if f.vehicle == "1"]
    assert [(round(f.t_s, 1), f.target) for f in answer] == [(3.0, "B")]
    # the interval starts again from the answer: the 10 s period's redirect is deferred
    core.handle(TargetAdded(5.0, "D", 0.0, -400.0, sigma0=50000.0))
    later = run_ticks(core, 5.0, 11.0)
    assert any(isinstance(c, SolveRequest) and c.reason == "period" for c in later)
    assert not [f for f in flies(later) if f.vehicle == "1"]


def test_a_loiter_end_with_commitment_is_answered_at_once_under_a_periodic_policy() -> None:
    """With commitment and periodic replanning only, the idle vehicle is planned at the
    next tick, not at the next period."""
    core = _two_targets_one_each(ReplanPolicy(on_events=False, period_s=10.0, commit=True))
    run_ticks(core, 0.0, 1.0)
    core.handle(TargetAdded(2.0, "B", 0.0, 3400.0, sigma0=5000.0))
    out = solve_all(core, core.handle(LoiterEnded(4.0, "2")))
    out += run_ticks(core, 4.0, 4.3)
    assert [(round(f.t_s, 1), f.vehicle, f.target) for f in flies(out)] == [(4.0, "2", "B")]
