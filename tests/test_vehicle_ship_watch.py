"""The vehicle controller's side of the ship watch, sans-IO: battery reports, on deck and
landed, the core's SetHome (one verified DO_SET_HOME) and LaunchVehicle (launch or ask).

Fake time, fake frames (the :class:`Rig` of ``test_vehicle_controller``), the home set's
outcome answered by the test or as a cooperative ArduPlane would."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace
from typing import Any

import pytest
from test_vehicle_controller import FLYING, ON_GROUND, Rig

from domain.modes import ArduPlaneMode
from groundstation.core import events as ev
from groundstation.mavlink.telemetry_events import Rebooted
from groundstation.vehicle import controller_io as vio
from groundstation.vehicle.controller import VehicleState

S = VehicleState
AIRBORNE: dict[str, Any] = {**FLYING, "landed_state": None}


class HomeRig(Rig):
    """A :class:`Rig` whose vehicle answers DO_SET_HOME too (``home_answer``: the outcome,
    None: the test answers)."""

    def __init__(self, **settings: Any) -> None:
        super().__init__(**settings)
        self.homes: list[vio.MoveHome] = []
        self.home_answer: bool | None = True

    def _collect(self, out: list[vio.Output]) -> None:
        for o in out:
            if isinstance(o, vio.MoveHome):
                assert self.pending is None, "two exchanges at once"
                self.pending = o
                self.homes.append(o)
        super()._collect([o for o in out if not isinstance(o, vio.MoveHome)])
        self.out += [o for o in out if isinstance(o, vio.MoveHome)]

    def auto(self) -> None:
        if isinstance(self.pending, vio.MoveHome):
            if self.home_answer is None:
                return
            r = self.pending
            self.answer(vio.HomeOutcome(True, r.x_m + 0.5, r.y_m, 0.5, 0) if self.home_answer
                        else vio.HomeOutcome(False, error="vehicle answered MAV_RESULT_DENIED"))
        super().auto()

    def new_home(self, x_m: float, y_m: float) -> None:
        self.feed(vio.NewHome(self.t, x_m, y_m))
        self.auto()

    def warnings(self) -> list[str]:
        return [o.text for o in self.out if isinstance(o, vio.Warn)]


def grounded_rig(**settings: Any) -> HomeRig:
    rig = HomeRig(**settings)
    rig.snap = replace(rig.snap, **ON_GROUND)
    rig.run(5.0)
    return rig


def airborne_rig(**settings: Any) -> HomeRig:
    rig = HomeRig(**settings)
    rig.run(4.0)
    assert rig.c.state is S.ACTIVE
    return rig


# ------------------------------------------------------------------ battery
def test_battery_report_every_5_s_or_at_once_on_a_one_point_move() -> None:
    rig = grounded_rig()
    rig.run(20.0, battery_voltage_v=12.3, battery_current_a=0.4)
    reports = rig.core(ev.BatteryReport)
    gaps = [b.t_s - a.t_s for a, b in itertools.pairwise(reports)]
    assert reports and all(g == pytest.approx(5.0) for g in gaps), gaps
    assert reports[-1].remaining_pct == 80.0 and reports[-1].voltage_v == 12.3
    assert reports[-1].current_a == 0.4
    assert reports[-1].t_s == 21.0 and rig.t == 25.0
    rig.run(2.0, battery_remaining_pct=79.5)  # the periodic one at 26 s
    assert rig.core(ev.BatteryReport)[-1].t_s == 26.0
    rig.run(1.0, battery_remaining_pct=79.2)  # SYS_STATUS at 28 s, less than a point: waits
    assert rig.core(ev.BatteryReport)[-1].t_s == 26.0
    rig.run(1.0, battery_remaining_pct=78.5)  # SYS_STATUS at 29 s, a point: at once
    now = rig.core(ev.BatteryReport)[-1]
    assert now.remaining_pct == 78.5 and now.t_s == 29.0


@pytest.mark.parametrize("garbage", [math.nan, 150.0, -5.0, math.inf])
def test_garbage_battery_readings_are_none_never_a_crash(garbage: float) -> None:
    rig = grounded_rig()
    rig.run(11.0, battery_remaining_pct=garbage, battery_voltage_v=garbage,
            battery_current_a=garbage if not math.isfinite(garbage) else 5000.0)
    reports = [r for r in rig.core(ev.BatteryReport) if r.t_s > 5.0]
    assert reports == []  # nothing known: nothing sent
    rig.run(2.0, battery_voltage_v=11.9)
    (report,) = [r for r in rig.core(ev.BatteryReport) if r.t_s > 16.0]
    assert report.remaining_pct is None and report.current_a is None
    assert report.voltage_v == 11.9


# ------------------------------------------------------------------ on deck, landed
def test_on_deck_is_sent_when_readiness_changes() -> None:
    rig = grounded_rig(ready_pct=95.0)
    (deck,) = rig.core(ev.VehicleOnDeck)
    assert deck.ready is False and deck.battery_pct == 80.0  # not charged enough
    rig.run(10.0, battery_remaining_pct=97.0)
    decks = rig.core(ev.VehicleOnDeck)
    assert [d.ready for d in decks] == [False, True] and decks[-1].battery_pct == 97.0
    rig.run(10.0)
    assert len(rig.core(ev.VehicleOnDeck)) == 2  # no change, nothing sent


def test_without_a_watch_a_vehicle_that_never_flew_is_a_ready_spare() -> None:
    rig = grounded_rig()
    assert [d.ready for d in rig.core(ev.VehicleOnDeck)] == [True]


def test_a_flying_vehicle_is_not_on_deck_and_landing_is_told_once() -> None:
    rig = airborne_rig()
    assert rig.core(ev.VehicleOnDeck) == []
    rig.run(10.0, **{**ON_GROUND, "x_m": 40.0, "y_m": -30.0})
    (landed,) = rig.core(ev.VehicleLanded)
    assert (landed.x_m, landed.y_m) == (40.0, -30.0)
    # it left the plan first (VehicleLost), then it is told down there
    kinds = [type(o.event) for o in rig.out if isinstance(o, vio.CoreEvent)
             and isinstance(o.event, ev.VehicleLost | ev.VehicleLanded)]  # fmt: skip
    assert kinds == [ev.VehicleLost, ev.VehicleLanded]
    decks = rig.core(ev.VehicleOnDeck)
    assert [d.ready for d in decks] == [False]  # it flew: no spare until it is booted again
    rig.run(10.0)
    assert len(rig.core(ev.VehicleLanded)) == 1


def test_a_ready_spare_whose_link_is_lost_is_no_longer_ready() -> None:
    rig = grounded_rig()
    rig.t += 10.0
    rig.feed(vio.TimePassed(rig.t))
    decks = rig.core(ev.VehicleOnDeck)
    assert [d.ready for d in decks] == [True, False]


# ------------------------------------------------------------------ SetHome
def test_set_home_to_a_vehicle_in_the_air_is_one_verified_exchange() -> None:
    rig = airborne_rig()
    rig.new_home(300.0, -200.0)
    assert [(h.x_m, h.y_m) for h in rig.homes] == [(300.0, -200.0)]
    (done,) = rig.journal("home_set")
    assert done.fields["x_m"] == 300.5 and done.fields["error_m"] == 0.5
    assert rig.c.home_xy_m == (300.5, -200.0)
    assert rig.c.state is S.ACTIVE  # no mode, no mission changed
    assert not rig.requests(vio.SetMode)


@pytest.mark.parametrize("mode", [ArduPlaneMode.FBWA, ArduPlaneMode.RTL])
def test_set_home_reaches_a_vehicle_the_operator_took(mode: ArduPlaneMode) -> None:
    rig = airborne_rig()
    rig.run(5.0, mode=int(mode), mode_name=mode.name)
    assert rig.c.state is S.OVERRIDDEN
    asked = len(rig.asked)
    rig.new_home(100.0, 50.0)
    assert len(rig.homes) == 1 and rig.journal("home_set")
    assert len(rig.asked) == asked  # nothing else: no mode, no upload
    assert rig.c.state is S.OVERRIDDEN


def test_set_home_reaches_a_vehicle_floe_sent_home() -> None:
    rig = airborne_rig()
    rig.feed(vio.Release(rig.t, "battery low", home=True))
    rig.auto()
    rig.run(2.0, mode=int(ArduPlaneMode.RTL), mode_name="RTL")
    assert rig.c.state is S.HOME
    rig.new_home(-50.0, 0.0)
    assert rig.journal("home_set")


def test_set_home_is_never_sent_to_a_vehicle_on_the_ground() -> None:
    rig = grounded_rig()
    rig.new_home(10.0, 10.0)
    rig.run(5.0)
    assert rig.homes == []
    (skipped,) = rig.journal("home_set_skipped")
    assert not rig.journal("home_set_failed")
    assert "on the ground" in skipped.fields["reason"]


def test_set_home_waits_while_a_reboot_is_suspected_or_the_link_is_degraded() -> None:
    rig = airborne_rig()
    rig.t += 0.1
    rig.frame("GLOBAL_POSITION_INT", reboot_suspected=True)
    rig.new_home(1.0, 2.0)
    assert rig.homes == [] and not rig.journal("home_set")
    rig.run(1.0, reboot_suspected=False)
    assert rig.journal("home_set")
    # a degraded link: held until heard again
    rig.t += 3.0
    rig.feed(vio.TimePassed(rig.t))
    assert rig.c.link.value == "degraded"
    rig.new_home(5.0, 6.0)
    assert len(rig.journal("home_set")) == 1
    rig.run(1.0)
    assert len(rig.journal("home_set")) == 2


def test_a_newer_set_home_supersedes_the_one_running() -> None:
    rig = airborne_rig()
    rig.home_answer = None  # the vehicle has not answered yet
    rig.new_home(100.0, 0.0)
    first = rig.pending
    assert isinstance(first, vio.MoveHome)
    rig.new_home(200.0, 0.0)
    assert any(isinstance(o, vio.CancelExchange) for o in rig.out)
    assert not rig.c.wants(first)
    rig.answer(None)  # the cancelled exchange ends without an answer
    assert isinstance(rig.pending, vio.MoveHome) and rig.pending.x_m == 200.0
    rig.home_answer = True
    rig.auto()
    (done,) = rig.journal("home_set")
    assert done.fields["requested_x_m"] == 200.0
    assert not rig.journal("home_set_failed")


def test_a_refused_set_home_is_journalled_and_warned() -> None:
    rig = airborne_rig()
    rig.home_answer = False
    rig.new_home(100.0, 0.0)
    (failed,) = rig.journal("home_set_failed")
    assert "DENIED" in failed.fields["reason"]
    assert any("home could not be moved" in w for w in rig.warnings())
    rig.new_home(300.0, 0.0)  # the same refusal again: journalled, not warned again
    assert len(rig.journal("home_set_failed")) == 2
    assert len([w for w in rig.warnings() if "home could not be moved" in w]) == 1
    rig.home_answer = True
    rig.new_home(400.0, 0.0)
    rig.home_answer = False
    rig.new_home(500.0, 0.0)  # after a success: told again
    assert len([w for w in rig.warnings() if "home could not be moved" in w]) == 2


def test_a_set_home_cut_short_by_a_lost_link_is_sent_again_when_it_is_back() -> None:
    rig = airborne_rig()
    rig.home_answer = None
    rig.new_home(100.0, 0.0)
    rig.t += 6.0
    rig.feed(vio.TimePassed(rig.t))  # lost: the job is aborted
    assert rig.c.link.value == "lost"
    rig.answer(None)
    rig.home_answer = True
    rig.run(6.0)
    assert [h.x_m for h in rig.homes] == [100.0, 100.0] and rig.journal("home_set")


# ------------------------------------------------------------------ LaunchVehicle
def test_with_a_watch_on_station_launch_waits_for_the_core_order() -> None:
    rig = grounded_rig(launch=True, launch_on_order=True, ready_pct=75.0)
    rig.run(10.0)
    assert rig.c.state is S.ON_GROUND and rig.asked == []
    rig.feed(vio.LaunchWanted(rig.t, "on station"))
    rig.auto()
    rig.run(2.0)
    assert [type(r) for r in rig.asked] == [vio.UploadMission, vio.Arm, vio.SetCurrent,
                                            vio.SetMode]
    (wanted,) = rig.journal("launch_wanted")
    assert wanted.fields["action"] == "launch"
    rig.run(10.0, **AIRBORNE)
    assert rig.journal("vehicle_joined")[0].fields["how"] == "launched"
    assert rig.c.launch_wanted is None


def test_without_launch_the_operator_is_asked() -> None:
    rig = grounded_rig(ready_pct=75.0, launch_on_order=True)
    rig.feed(vio.LaunchWanted(rig.t, "relief", relieves="2"))
    rig.run(5.0)
    assert rig.asked == []
    (wanted,) = rig.journal("launch_wanted")
    assert wanted.fields["action"] == "ask" and wanted.logged
    assert rig.warnings() == [
        "launch vehicle v1 (relief of 2): catapult it, or 'gcs vehicle launch v1'"]
    assert rig.c.launch_wanted == vio.LaunchWanted(rig.t - 5.0, "relief", "2")


def land_after_rtl(rig: HomeRig) -> None:
    rig.feed(vio.Release(rig.t, "battery low", home=True))
    rig.auto()
    rig.run(3.0, mode=int(ArduPlaneMode.RTL), mode_name="RTL")
    rig.run(10.0, **{**ON_GROUND, "mode": int(ArduPlaneMode.RTL), "mode_name": "RTL",
                     "battery_remaining_pct": 20.0})


def reboot(rig: HomeRig, pct: float) -> None:
    rig.t += 1.0
    rig.frame("HEARTBEAT", Rebooted(rig.t, 500_000, 1_000), time_boot_ms=1_000,
              battery_remaining_pct=pct, mode=int(ArduPlaneMode.MANUAL), mode_name="MANUAL")
    rig.run(6.0)


def test_a_vehicle_recovered_from_an_rtl_and_rebooted_full_is_a_spare_again() -> None:
    rig = airborne_rig(launch=True, launch_on_order=True, ready_pct=95.0)
    land_after_rtl(rig)
    assert rig.c.came_down is not None
    asked = len(rig.asked)
    rig.feed(vio.LaunchWanted(rig.t, "relief", "2"))  # not booted again: asked, not launched
    rig.run(3.0)
    assert len(rig.asked) == asked and rig.journal("launch_wanted")[-1].fields["action"] == "ask"
    reboot(rig, 60.0)  # booted, battery not swapped: not ready
    assert rig.core(ev.VehicleOnDeck)[-1].ready is False
    reboot(rig, 100.0)
    assert rig.core(ev.VehicleOnDeck)[-1].ready is True
    rig.feed(vio.LaunchWanted(rig.t, "relief", "2"))
    rig.auto()
    rig.run(2.0)
    assert rig.journal("launch_wanted")[-1].fields["action"] == "launch"
    assert vio.Arm in [type(r) for r in rig.asked[asked:]]
    assert not rig.journal("launch_held")


def test_without_a_watch_a_vehicle_that_came_down_is_never_launched_on_floe_s_own() -> None:
    rig = airborne_rig(launch=True)
    land_after_rtl(rig)
    reboot(rig, 100.0)
    asked = len(rig.asked)
    rig.feed(vio.LaunchWanted(rig.t, "relief", "2"))
    rig.run(5.0)
    assert not [r for r in rig.asked[asked:] if isinstance(r, vio.Arm | vio.UploadMission)]
    assert rig.core(ev.VehicleOnDeck)[-1].ready is False
    assert rig.journal("launch_wanted")[-1].fields["action"] == "ask"


def test_a_vehicle_that_came_down_outside_an_rtl_is_never_a_spare() -> None:
    rig = airborne_rig(launch=True, launch_on_order=True, ready_pct=95.0)
    rig.run(3.0, mode=int(ArduPlaneMode.FBWA), mode_name="FBWA")  # the pilot's
    rig.run(10.0, **{**ON_GROUND, "mode": int(ArduPlaneMode.FBWA), "mode_name": "FBWA"})
    reboot(rig, 100.0)
    assert rig.core(ev.VehicleOnDeck)[-1].ready is False
    asked = len(rig.asked)
    rig.feed(vio.LaunchWanted(rig.t, "relief", "2"))
    rig.run(5.0)
    assert not [r for r in rig.asked[asked:] if isinstance(r, vio.Arm | vio.UploadMission)]
    assert rig.journal("launch_wanted")[-1].fields["action"] == "ask"
