"""The decision core's read model (``core/views.py``), the verdicts ``handle`` returns, the
state lines of ``core/records.py``, the observer's single writer and ``core/mission.py``."""

from __future__ import annotations

from test_core_tracking import make_core

from groundstation.core.commands import FlyToTarget
from groundstation.core.config import CoreConfig
from groundstation.core.events import (
    CameraFrame,
    Detection,
    TargetAdded,
    TargetRemoved,
    Tick,
    VehicleJoined,
)
from groundstation.core.mission import target_mission
from groundstation.core.records import (
    SearchSchedule,
    search_record,
    track_records,
    truth_records,
)
from observer import ObserverConfig
from planner.search_cells import SearchConfig


def test_view_copies_the_tracks_floats_with_their_status() -> None:
    core = make_core()
    core.handle(VehicleJoined(0.0, "1", 5.0, 6.0, 0.5, 22.0))
    core.handle(TargetAdded(0.0, "A", 100.0, 200.0, 1.0, -1.0, 4.0))
    core.handle(TargetAdded(0.0, "P", 900.0, 0.0, prior=True))
    core.handle(Tick(2.0))
    view = core.view()
    assert view.t_s == 2.0 and view.target_ids == {"A", "P"}
    for snap in core.observer.tracks():
        tv = view.track(snap.id)
        assert tv is not None
        assert (tv.x_m, tv.y_m, tv.vx_m_s, tv.vy_m_s, tv.sigma, tv.cov_xy, tv.lost,
                tv.last_seen_s, tv.t_s) == (snap.x_m, snap.y_m, snap.vx_m_s, snap.vy_m_s,
                                            snap.sigma, snap.cov_xy, snap.lost,
                                            snap.last_seen_s, snap.t_s)
    assert view.status() == {"A": "confirmed", "P": "prior"}
    assert [v.id for v in view.firm_tracks()] == ["A", "P"]
    (vehicle,) = view.vehicles
    assert (vehicle.id, vehicle.x_m, vehicle.y_m, vehicle.heading_rad) == ("1", 5.0, 6.0, 0.5)
    assert view.wind == core.wind_state and not view.searching and view.search_cells == ()
    assert view.track("nope") is None
    assert view.plans_adopted == core.plans_adopted == 0
    assert view.wind_outliers == core.wind.flagged == frozenset()


def test_handle_returns_the_verdict_on_each_detection() -> None:
    core = make_core()
    core.handle(TargetAdded(0.0, "A", 0.0, 0.0, sigma0=100.0))
    accepted = core.handle(Detection(1.0, "1", "A", 1.0, 1.0, 25.0))
    gated = core.handle(Detection(1.1, "1", "A", 5000.0, 5000.0, 25.0))
    found = core.handle(Detection(1.2, "2", "B", 300.0, 300.0, 25.0))
    assert [(v.vehicle, v.target, v.accepted, v.reason) for v in accepted.verdicts] == [
        ("1", "A", True, "accepted")]
    assert [(v.target, v.accepted) for v in gated.verdicts] == [("A", False)]
    assert gated.verdicts[0].reason != "accepted"
    assert [(v.target, v.accepted, v.reason) for v in found.verdicts] == [
        ("B", False, "discovered")]
    assert core.handle(Tick(1.3)).verdicts == ()


def test_an_unlabelled_detection_is_decided_at_the_tick_that_scans_its_frame() -> None:
    core = make_core()
    core.handle(TargetAdded(0.0, "A", 0.0, 0.0, sigma0=100.0))
    core.handle(CameraFrame(1.0, "1", 0.0, 0.0, 150.0))
    buffered = core.handle(Detection(1.0, "1", None, 2.0, -1.0, 25.0))
    assert [(v.target, v.accepted, v.reason) for v in buffered.verdicts] == [
        (None, None, "buffered")]
    tick = core.handle(Tick(1.0))
    assert [(v.t_s, v.vehicle, v.target, v.accepted, v.reason) for v in tick.verdicts] == [
        (1.0, "1", "A", True, "assigned")]


def test_state_lines_are_the_views_floats() -> None:
    core = make_core(search=SearchConfig(cell_m=500.0, growth_m2_per_s=50.0, max_cells=3),
                     area_m=(0.0, 1000.0, 0.0, 1000.0))
    core.handle(TargetAdded(0.0, "A", 100.0 / 3, 200.0, sigma0=4.0))
    core.handle(Tick(3.0))
    view = core.view()
    (line,) = track_records(3.0, view)
    tv = view.tracks[0]
    assert line == {"event": "track", "t": 3.0, "target": "A", "x_m": tv.x_m, "y_m": tv.y_m,
                    "vx_m_s": tv.vx_m_s, "vy_m_s": tv.vy_m_s, "sigma": tv.sigma_m2,
                    "lost": False, "status": "confirmed"}
    assert truth_records(3.0, {"T2": (1.5, 2.5), "T1": (0.0, 0.0)}) == [
        {"event": "truth", "t": 3.0, "target": "T2", "x_m": 1.5, "y_m": 2.5},
        {"event": "truth", "t": 3.0, "target": "T1", "x_m": 0.0, "y_m": 0.0}]
    search = search_record(3.0, view)
    assert [c[0] for c in search["cells"]] == ["S0-0", "S0-1", "S1-0", "S1-1"]
    assert search["cells"][0][4] == view.search_cells[0].value_m2 == 150.0
    schedule = SearchSchedule()
    assert [t for t in (0.0, 1.0, 9.9, 10.0, 15.0, 25.0) if schedule.due(t, view)] == [
        0.0, 10.0, 25.0]
    assert not SearchSchedule().due(0.0, make_core().view())  # no search: never


def test_a_target_the_tracker_deleted_is_not_removed_twice() -> None:
    core = make_core()
    core.handle(TargetAdded(0.0, "A", 0.0, 0.0, sigma0=100.0))
    for k in range(1, 40):  # looked for where it is predicted, never seen
        core.handle(CameraFrame(float(k), "1", 0.0, 0.0, 150.0))
        core.handle(Tick(float(k)))
    assert "A" not in core.view().target_ids
    out = core.handle(TargetRemoved(40.0, "A"))
    assert [c.kind for c in out if hasattr(c, "kind")] == ["unknown_target"]
    core.tracks.remove("A")  # the single writer's remove is a no-op on a gone track
    assert "A" not in core.observer.target_ids


def test_a_fly_command_means_a_pass_under_a_second_else_a_timed_loiter() -> None:
    def fly(loiter_s: float) -> FlyToTarget:
        return FlyToTarget(0.0, "1", "A", 10.0, 20.0, loiter_s, 120.0, ("A",))

    passing = target_mission(fly(0.0))
    assert passing.pass_over and (passing.x_m, passing.y_m) == (10.0, 20.0)
    assert target_mission(fly(0.99)).pass_over
    timed = target_mission(fly(29.6), (5.0, 6.0), 80.0)
    assert (timed.loiter_s, timed.x_m, timed.y_m, timed.loiter_radius_m) == (30, 5.0, 6.0, 80.0)
    assert not timed.pass_over


def test_the_tick_is_the_observers_grid() -> None:
    assert CoreConfig().tick_s == 0.1
    assert CoreConfig(observer=ObserverConfig(max_step_s=0.2)).tick_s == 0.2
