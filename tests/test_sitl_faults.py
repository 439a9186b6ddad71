"""Fault injection: link impairments (sans-IO), scheduled faults on a vehicle, spec parsing."""

from __future__ import annotations

from typing import Any

import pytest

from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import mavlink2 as M
from sitl.faults import (
    FaultError,
    FaultEvent,
    LinkImpairment,
    VehicleFaults,
    apply_fault,
    parse_fault_spec,
)
from sitl.loopback import Loopback
from sitl.vehicle import SimVehicle, VehicleConfig

ORIGIN = GeoOrigin(78.93, 11.92)


def run_link(link: LinkImpairment, n: int, seed: int = 1) -> list[int]:
    import random

    rng = random.Random(seed)
    got: list[int] = []
    for i in range(n):
        link.push(i, i * 0.01, rng)
        got += link.pop_due(i * 0.01)
    got += link.pop_due(1e9)
    return got


def test_transparent_link_delivers_in_order_at_once() -> None:
    link = LinkImpairment()
    assert link.transparent
    assert run_link(link, 100) == list(range(100))


def test_loss_rate_close_to_p() -> None:
    got = run_link(LinkImpairment(loss=0.3), 5000)
    assert 0.65 * 5000 < len(got) < 0.75 * 5000
    assert got == sorted(got)


def test_duplication_and_reordering() -> None:
    dup = run_link(LinkImpairment(dup=0.5), 1000)
    assert 1400 < len(dup) < 1600
    reordered = run_link(LinkImpairment(reorder=0.2), 1000)
    assert sorted(reordered) == list(range(1000)) and reordered != list(range(1000))


def test_delay_holds_messages() -> None:
    import random

    link = LinkImpairment(delay_s=0.5)
    link.push("x", 10.0, random.Random(0))
    assert link.pop_due(10.4) == []
    assert link.pop_due(10.5) == ["x"]


def test_same_seed_same_faults() -> None:
    assert run_link(LinkImpairment(loss=0.5, reorder=0.3), 300, seed=7) == run_link(
        LinkImpairment(loss=0.5, reorder=0.3), 300, seed=7
    )


def test_link_drop_window_both_directions() -> None:
    faults = VehicleFaults(1)
    faults.add_event(FaultEvent(10.0, "drop", duration_s=5.0))
    for t in (9.0, 10.0, 14.9, 15.0):
        faults.send_up(("up", t), t)
        faults.send_down(("down", t), t)
    assert faults.up.pop_due(100) == [("up", 9.0), ("up", 15.0)]
    assert faults.down.pop_due(100) == [("down", 9.0), ("down", 15.0)]
    assert faults.due_events(100) == []  # a drop is not an autopilot event


@pytest.mark.parametrize(
    "spec",
    [
        "1:loss",
        "9:loss:p=0.1",
        "1:loss:p=2",
        "x:loss:p=0.1",
        "1:fly:p=1",
        "1:drop:at=5",
        "1:mode:at=5,mode=HOVER",
        "1:loss:q=0.1",
        "1:delay:s=-1",
        "1:loss:p=0.1,dir=sideways",
        "1:battery:at=3,pct=150",
        "loss",
    ],
)
def test_bad_specs_name_the_problem(spec: str) -> None:
    with pytest.raises(FaultError, match="fault"):
        parse_fault_spec(spec, 3)


def test_spec_all_and_directions() -> None:
    parsed = parse_fault_spec("all:loss:p=0.25,dir=up", 3)
    assert [p[0] for p in parsed] == [1, 2, 3]
    faults = VehicleFaults(0)
    apply_fault(faults, parsed[0][1], parsed[0][2])
    assert faults.up.loss == 0.25 and faults.down.loss == 0.0


def vehicle(**kw: Any) -> Loopback:
    cfg = VehicleConfig(1, ORIGIN, 78.93, 11.92, fast_boot=True, **kw)
    lb = Loopback(SimVehicle(cfg))
    lb.advance(3.0)
    return lb


def test_reboot_resets_time_boot_keeps_mission() -> None:
    lb = vehicle(airborne=True)
    lb.advance(50.0)
    before = lb.take("SYSTEM_TIME")[-1].time_boot_ms
    lb.inbox.clear()
    lb.vehicle.apply_fault(FaultEvent(lb.t_s, "reboot"), lb.t_s)
    lb.advance(1.0)
    after = lb.take("SYSTEM_TIME")[-1].time_boot_ms
    assert before > 50_000 and after < 2_000
    assert lb.vehicle.reboots == 1 and len(lb.vehicle.store) == 2
    assert not lb.vehicle.airframe.on_ground and lb.vehicle.airframe.alt_m > 90


def test_operator_mode_switch_and_low_battery() -> None:
    lb = vehicle(airborne=True)
    lb.inbox.clear()
    lb.vehicle.apply_fault(FaultEvent(lb.t_s, "mode", mode=5), lb.t_s)
    lb.advance(1.0)
    assert lb.take("HEARTBEAT")[-1].custom_mode == 5
    lb.vehicle.apply_fault(FaultEvent(lb.t_s, "battery", fraction=0.1), lb.t_s)
    lb.advance(1.0)
    assert lb.take("BATTERY_STATUS")[-1].battery_remaining <= 10
    assert any(t.startswith("Battery 1 is low") for t in lb.texts())
    assert lb.take("HEARTBEAT")[-1].system_status == M.MAV_STATE_CRITICAL
