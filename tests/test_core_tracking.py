"""The decision core with the multi-target tracker: scans buffered to the tick, track
birth, confirmation and deletion as notes, priors, search cells as planning targets."""

from __future__ import annotations

import json
from typing import Any

import pytest

from groundstation.core.commands import Command, FlyToTarget, Note, SolveRequest
from groundstation.core.config import CoreConfig, ReplanPolicy, config_from_dict, config_to_dict
from groundstation.core.decision import DecisionCore
from groundstation.core.events import (
    CameraFrame,
    Detection,
    PlanSolved,
    TargetAdded,
    Tick,
    VehicleJoined,
)
from groundstation.core.planning_targets import track_targets
from groundstation.core.records import event_to_record, record_to_event
from observer import Observer, ObserverConfig, Tracker, TrackerConfig
from planner import solve_plan
from planner.search_cells import SearchConfig


def make_core(scans: list[tuple[float, str, bool, int]] | None = None,
              **overrides: Any) -> DecisionCore:
    """A Kalman core; ``scans`` (if given) records each tracker scan as
    (t_s, vehicle, has footprint, detections) through a wrapper around the real tracker."""
    config = CoreConfig(
        policy=ReplanPolicy(on_events=True, period_s=None, commit=True),
        observer=ObserverConfig(model="kalman", q_per_s=0.01, r_m2=25.0),
        tracker=TrackerConfig(pd=0.9, clutter_per_frame=0.1),
        time_limit_s=1.0,
        **overrides,
    )

    def factory(observer: Observer, tracker_config: TrackerConfig) -> Tracker:
        tracker = Tracker(observer, tracker_config)
        if scans is not None:
            scan = tracker.scan

            def recording(t_s, vehicle, footprint, detections):  # type: ignore[no-untyped-def]
                scans.append((t_s, vehicle, footprint is not None, len(detections)))
                return scan(t_s, vehicle, footprint, detections)

            tracker.scan = recording  # type: ignore[method-assign]
        return tracker

    return DecisionCore(config, tracker_factory=factory)


def notes(commands: list[Command], kind: str) -> list[Note]:
    return [c for c in commands if isinstance(c, Note) and c.kind == kind]


def frame(core: DecisionCore, t_s: float, xy: tuple[float, float], *dets: tuple[float, float],
          vehicle: str = "1") -> list[Command]:
    """One camera frame over ``xy`` with unlabelled detections ``dets``, then the tick."""
    out = core.handle(CameraFrame(t_s, vehicle, xy[0], xy[1], 150.0))
    for x, y in dets:
        out += core.handle(Detection(t_s, vehicle, None, x, y, 25.0))
    return out + core.handle(Tick(t_s))


def test_scan_is_buffered_and_processed_at_the_next_tick_in_frame_order() -> None:
    scans: list[tuple[float, str, bool, int]] = []
    core = make_core(scans)
    core.handle(CameraFrame(1.0, "2", 0.0, 0.0, 150.0))
    core.handle(Detection(1.0, "2", None, 10.0, 5.0, 25.0))
    core.handle(Detection(1.0, "1", None, 900.0, 900.0, 25.0))  # a frame without footprint
    core.handle(Detection(1.0, "2", None, -40.0, 20.0, 25.0))
    assert scans == [] and core.observer.target_ids == []
    assert core.tracks.pending == 2
    assert core.handle(Tick(0.9)) == [] and scans == []  # not due yet
    out = core.handle(Tick(1.0))
    # (t_s, vehicle) order; the whole frame of vehicle 2 in one scan, with its footprint
    assert scans == [(1.0, "1", False, 1), (1.0, "2", True, 2)]
    born = notes(out, "track_born")
    assert len(born) == 3 and {n.vehicle for n in born} == {"1", "2"}
    assert {v.status for v in core.track_views()} == {"tentative"}
    assert core.tracks.pending == 0


def test_tentative_track_is_born_confirmed_and_deleted_with_notes() -> None:
    core = make_core()
    core.handle(VehicleJoined(0.0, "1", 0.0, 0.0, 0.0, 22.0))
    iceberg = (500.0, 300.0)
    out = frame(core, 0.5, iceberg, iceberg)
    (born,) = notes(out, "track_born")
    track = born.target
    assert track is not None and core.tracks.status(track) == "tentative"
    confirmed: list[Note] = []
    t = 0.5
    for _ in range(8):
        t += 0.5
        confirmed += notes(frame(core, t, iceberg, (iceberg[0] + 1.0, iceberg[1] - 1.0)),
                           "track_confirmed")
        if confirmed:
            break
    assert [n.target for n in confirmed] == [track]
    assert core.tracks.status(track) == "confirmed"
    # a vehicle flies to it
    core.handle(TargetAdded(t, "K", 2000.0, 2000.0, sigma0=50.0))
    for c in core.handle(Tick(t)):
        if isinstance(c, SolveRequest):
            core.handle(PlanSolved(t, c.request_id, solve_plan(c.problem, c.hint)))
    assert core.vehicles["1"].target in (track, "K")
    holder = core.vehicles["1"].target
    # the camera looks at where the track is, again and again, and sees nothing
    deleted: list[Note] = []
    target_of_track = track
    for _ in range(40):
        t += 0.5
        deleted += notes(frame(core, t, iceberg), "track_deleted")
        if deleted:
            break
    assert [n.target for n in deleted] == [target_of_track]
    assert track not in core.observer.target_ids
    assert track not in {v.id for v in core.track_views()}
    if holder == track:
        assert core.vehicles["1"].target is None and not core.vehicles["1"].busy
    assert "K" in core.observer.target_ids  # far from the footprint: untouched


def test_prior_target_is_adopted_as_prior_and_round_trips() -> None:
    core = make_core()
    event = TargetAdded(0.0, "P1", 100.0, 200.0, sigma0=1800.0, prior=True)
    record = event_to_record(event)
    assert record["prior"] is True
    assert record_to_event(json.loads(json.dumps(record))) == event
    plain = event_to_record(TargetAdded(0.0, "A", 1.0, 2.0))
    assert "prior" not in plain  # labelled journals read as before
    core.handle(event)
    core.handle(TargetAdded(0.0, "A", 1.0, 2.0))
    views = {v.id: v for v in core.track_views()}
    assert views["P1"].status == "prior" and views["A"].status == "confirmed"
    assert views["P1"].existence < 1.0
    frame_event = CameraFrame(3.0, "2", 1.5, -2.5, 150.0)
    assert record_to_event(json.loads(json.dumps(event_to_record(frame_event)))) == frame_event


def test_labelled_detections_never_create_the_tracker() -> None:
    calls: list[str] = []

    def factory(observer: Observer, config: TrackerConfig) -> Tracker:
        calls.append("created")
        return Tracker(observer, config)

    core = DecisionCore(CoreConfig(observer=ObserverConfig(model="kalman")),
                        tracker_factory=factory)
    core.handle(TargetAdded(0.0, "A", 0.0, 0.0, sigma0=10.0))
    core.handle(Detection(0.5, "1", "A", 1.0, 1.0, 5.0))
    core.handle(Detection(0.5, "1", "B", 300.0, 1.0, 5.0))  # discovered, as before
    core.handle(Tick(1.0))
    assert calls == [] and core.tracks.tracker is None
    assert {v.status for v in core.track_views()} == {"confirmed"}
    assert core.observer.target_ids == ["A", "B"]


def test_search_cells_are_planned_and_covered_by_frames() -> None:
    core = make_core(search=SearchConfig(cell_m=500.0, growth_m2_per_s=50.0, max_cells=3),
                     area_m=(0.0, 1000.0, 0.0, 1000.0))
    assert [c.id for c in core.search_view()] == ["S0-0", "S0-1", "S1-0", "S1-1"]
    core.handle(VehicleJoined(0.0, "1", 0.0, 0.0, 0.0, 22.0))
    core.handle(CameraFrame(10.0, "1", 250.0, 250.0, 150.0))  # covers S0-0's centre
    out = core.handle(Tick(10.0))
    values = {c.id: c for c in core.search_view()}
    assert values["S0-0"].last_covered_s == 10.0 and values["S0-0"].value_m2 == 0.0
    assert values["S1-1"].value_m2 == 50.0 * 10.0 and values["S1-1"].last_covered_s is None
    (request,) = [c for c in out if isinstance(c, SolveRequest)]
    assert sorted(t.id for t in request.problem.targets) == ["S0-1", "S1-0", "S1-1"]
    result = solve_plan(request.problem, request.hint)
    fly = [c for c in core.handle(PlanSolved(10.0, request.request_id, result))
           if isinstance(c, FlyToTarget)]
    assert len(fly) == 1 and fly[0].target in {"S0-1", "S1-0", "S1-1"}
    cx, cy = {c.id: (c.x_m, c.y_m) for c in core.search_view()}[fly[0].target]
    assert (fly[0].x_m, fly[0].y_m) == (cx, cy)  # a cell does not move: aim at its centre


def test_core_config_with_tracker_and_search_round_trips() -> None:
    config = CoreConfig(tracker=TrackerConfig(pd=0.85, confirm_hits=2),
                        search=SearchConfig(cell_m=300.0), area_m=(0.0, 3000.0, 0.0, 3000.0))
    data = json.loads(json.dumps(config_to_dict(config)))
    assert config_from_dict(data) == config


def test_clutter_born_and_deleted_unconfirmed_asks_for_no_plan() -> None:
    """A tentative track deleted unconfirmed that no route holds (tentative_weight 0: never
    planned) changes no plan, so no solve is requested; once tentative tracks are planned
    (weight 5) and a plan routes a vehicle through it, its deletion asks for one."""
    for weight, expected in ((0.0, []), (5.0, ["track deleted"])):
        core = DecisionCore(CoreConfig(
            policy=ReplanPolicy(on_events=True, period_s=None, commit=False),
            observer=ObserverConfig(model="kalman", q_per_s=0.01, r_m2=25.0),
            tracker=TrackerConfig(pd=0.9, clutter_per_frame=0.1),
            tentative_weight=weight,
        ))
        core.handle(VehicleJoined(0.0, "1", 0.0, 0.0, 0.0, 22.0))
        core.handle(TargetAdded(0.0, "K", 3000.0, 3000.0, sigma0=50.0))  # always a target
        out = frame(core, 0.5, (500.0, 300.0), (520.0, 310.0))  # one false alarm
        (born,) = notes(out, "track_born")
        core.handle(TargetAdded(0.5, "K2", 3000.0, -3000.0, sigma0=50.0))  # asks for a plan
        for c in core.handle(Tick(0.5)):
            if isinstance(c, SolveRequest):
                core.handle(PlanSolved(0.5, c.request_id, solve_plan(c.problem, c.hint)))
        assert (born.target in core.vehicles["1"].route) is (weight > 0)
        reasons: list[str] = []
        deleted: list[Note] = []
        t = 0.5
        while not deleted and t < 10.0:
            t += 0.5
            out = frame(core, t, (500.0, 300.0))
            deleted += notes(out, "track_deleted")
            reasons += [c.reason for c in out if isinstance(c, SolveRequest)]
        assert [n.detail for n in deleted] == ["unconfirmed"]
        assert reasons == expected


def test_tentative_visit_is_worth_its_existence_times_the_mean_firm_sigma() -> None:
    """sigma_plan = tentative_weight * existence * max(sigma, mean firm sigma): a lone false
    alarm's track (existence ~0.09) is worth a tenth of a likely iceberg's (existence 0.9),
    confirmed tracks their own sigma, covered tracks nothing, weight 0 nothing planned."""
    obs = Observer(ObserverConfig(model="kalman", q_per_s=0.0, r_m2=5.0))
    for tid, p0 in (("A", 100.0), ("B", 300.0), ("C", 2.0), ("D", 2.0), ("E", 2.0)):
        obs.add_target(tid, 0.0, 10.0, 20.0, p0=[p0, p0, 0.0, 0.0])
    status = {"A": "confirmed", "B": "prior", "C": "tentative", "D": "tentative",
              "E": "tentative"}
    existence = {"A": 1.0, "B": 0.5, "C": 0.09, "D": 0.9, "E": 0.9}
    targets = track_targets(obs.tracks(), status.__getitem__, {"E"}, 2.0, existence.__getitem__)
    got = {t.id: t.sigma for t in targets}
    mean_firm = (200.0 + 600.0) / 2
    assert got == pytest.approx({"A": 200.0, "B": 600.0, "C": 2.0 * 0.09 * mean_firm,
                                 "D": 2.0 * 0.9 * mean_firm})
    zero = track_targets(obs.tracks(), status.__getitem__, set(), 0.0, existence.__getitem__)
    assert {t.id: t.sigma for t in zero if t.sigma > 0} == {"A": 200.0, "B": 600.0}
