"""The multi-target tracker (observer.Tracker): association, lifecycle, stable ids.

The camera here is the smallest honest fake: a disc footprint, each iceberg inside it
detected with probability pd, Gaussian noise of variance r per axis, and a Poisson number of
false alarms uniform over the disc, all from a seeded numpy generator.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from observer import (
    Footprint,
    Observer,
    ObserverConfig,
    ScanDetection,
    Tracker,
    TrackerConfig,
    TrackEvent,
)

R_M2 = 5.0
RADIUS_M = 150.0


def frame(
    rng: np.random.Generator,
    truth_xy: np.ndarray,
    centre: tuple[float, float],
    pd: float,
    clutter: float,
) -> list[ScanDetection]:
    dets: list[ScanDetection] = []
    for x, y in truth_xy:
        if math.hypot(x - centre[0], y - centre[1]) <= RADIUS_M and rng.random() < pd:
            nx, ny = rng.normal(0.0, math.sqrt(R_M2), 2)
            dets.append(ScanDetection(x + nx, y + ny, R_M2))
    for _ in range(rng.poisson(clutter)):
        a = rng.uniform(0.0, 2.0 * math.pi)
        rr = RADIUS_M * math.sqrt(rng.random())
        dets.append(ScanDetection(centre[0] + rr * math.cos(a), centre[1] + rr * math.sin(a), R_M2))
    order = rng.permutation(len(dets))
    return [dets[k] for k in order]


def make(**kw: object) -> Tracker:
    return Tracker(Observer(ObserverConfig()), TrackerConfig(**kw))  # type: ignore[arg-type]


@pytest.mark.parametrize("association", ["gnn", "jpda"])
def test_two_close_icebergs_keep_their_ids(association: str) -> None:
    """Two icebergs 30 m apart drifting in parallel (0.3, 0.2 m/s), a camera that keeps both
    in view, pd 0.85, r = 5 m^2, 0.1 false alarms per frame, 2 Hz for 300 s: exactly two
    confirmed tracks, never deleted, each always nearest its own iceberg (no swap)."""
    rng = np.random.default_rng(7)
    tracker = make(association=association, pd=0.85, clutter_per_frame=0.1)
    start = np.array([[0.0, 0.0], [30.0, 0.0]])
    v = np.array([0.3, 0.2])
    events: list[TrackEvent] = []
    owner: dict[int, str] = {}
    for k in range(600):
        t = 0.5 * k
        truth = start + v * t
        centre = (float(truth[:, 0].mean()) + 20.0, float(truth[:, 1].mean()) - 10.0)
        dets = frame(rng, truth, centre, 0.85, 0.1)
        events += tracker.scan(t, "u1", Footprint(*centre, RADIUS_M), dets).events
        confirmed = [tracker.observer.track(r.id) for r in tracker.records()
                     if r.status == "confirmed"]
        if len(confirmed) == 2:
            for n, (x, y) in enumerate(truth):
                nearest = min(confirmed, key=lambda s: math.hypot(s.x_m - x, s.y_m - y))
                assert math.hypot(nearest.x_m - x, nearest.y_m - y) < 10.0
                assert owner.setdefault(n, nearest.id) == nearest.id, f"swap at t={t}"
    confirmations = [e for e in events if e.kind == "confirmed"]
    assert len(confirmations) == 2
    assert max(e.t_s for e in confirmations) < 10.0
    confirmed_ids = {e.track_id for e in confirmations}
    assert not [e for e in events if e.kind == "deleted" and e.track_id in confirmed_ids]
    assert set(owner.values()) == confirmed_ids


def test_clutter_alone_confirms_almost_nothing() -> None:
    """Only false alarms (Poisson 0.1 per frame over the 150 m disc), 2000 frames at 2 Hz.

    Bound: a clutter point starts a tentative track that dies after N - M + 1 = 3 misses, so
    it lives at most 4 more frames; to be confirmed 2 more false alarms must fall in its gate
    (area pi gamma sqrt(det S) <= pi 18.42 * 12 m^2 ~ 700 m^2 over those frames, i.e. with
    probability p <= 0.1 * 700 / 70686 ~ 1e-3 each frame): P(confirm) <= C(4, 2) p^2 ~ 6e-6
    per tentative track, ~200 tentative tracks: 1.2e-3 expected confirmations. Asserting at
    most 1 leaves room; all tentative tracks must also be gone again (no growth)."""
    rng = np.random.default_rng(11)
    tracker = make(pd=0.85, clutter_per_frame=0.1)
    events: list[TrackEvent] = []
    for k in range(2000):
        dets = frame(rng, np.zeros((0, 2)), (0.0, 0.0), 0.85, 0.1)
        events += tracker.scan(0.5 * k, "u1", Footprint(0.0, 0.0, RADIUS_M), dets).events
    born = [e for e in events if e.kind == "born"]
    assert 150 <= len(born) <= 260  # ~200 false alarms, each one a birth
    assert len([e for e in events if e.kind == "confirmed"]) <= 1
    assert len(tracker.records()) <= 3  # what is alive now: the last few frames' births
    assert tracker.counters["unassociated"] == len(born)


def misses_to_delete(existence: float, pd: float, delete: float) -> int:
    """Smallest n with odds(existence) (1 - pd)^n < odds(delete)."""
    odds, target = existence / (1.0 - existence), delete / (1.0 - delete)
    return math.floor(math.log(target / odds) / math.log(1.0 - pd)) + 1


@pytest.mark.parametrize(("existence_max", "expected"), [(0.999, 6), (0.9, 3)])
def test_confirmed_track_in_view_not_seen_is_deleted(existence_max: float, expected: int) -> None:
    """A precise confirmed track at the centre of the footprint, no detections: deleted
    after n frames with odds_max (1 - pd)^n < odds_delete (pd 0.85: 6 with the default
    existence_max 0.999, 3 with 0.9)."""
    assert misses_to_delete(existence_max, 0.85, 0.05) == expected
    tracker = make(pd=0.85, existence_max=existence_max)
    tracker.observer.add_target("A", 0.0, 10.0, 0.0, p0=[4.0, 4.0, 0.01, 0.01])
    tracker.adopt("A")
    deleted_at = None
    for k in range(1, 20):
        res = tracker.scan(0.5 * k, "u1", Footprint(0.0, 0.0, RADIUS_M), [])
        if [e for e in res.events if e.kind == "deleted"]:
            assert res.events[0] == TrackEvent(0.5 * k, "deleted", "A", "not seen in view")
            deleted_at = k
            break
    assert deleted_at == expected
    assert "A" not in tracker.observer.target_ids


def test_track_outside_every_footprint_is_never_deleted() -> None:
    tracker = make(pd=0.85)
    tracker.observer.add_target("far", 0.0, 5000.0, 0.0, p0=[100.0, 100.0, 0.0, 0.0], q_per_s=0.0)
    tracker.adopt("far")
    rng = np.random.default_rng(3)
    for k in range(1, 401):
        tracker.scan(0.5 * k, "u1", Footprint(0.0, 0.0, RADIUS_M),
                     frame(rng, np.zeros((0, 2)), (0.0, 0.0), 0.85, 0.1))
    assert tracker.status("far") == "confirmed"
    assert tracker.existence("far") == pytest.approx(0.999)


def test_prior_with_huge_covariance_survives_a_miss_and_a_precise_one_does_not() -> None:
    """A miss removes evidence in proportion to pd * Pin: a prior listed with sigma ~ 1 km
    centred in the footprint has Pin ~ 1 % and keeps existence ~ 0.5; a precise prior is
    deleted after 2 misses (odds 1 * 0.15^2 < 0.05 / 0.95)."""
    tracker = make(pd=0.85)
    tracker.observer.add_target("P1", 0.0, 0.0, 0.0, sigma0=2.0e6)
    tracker.adopt("P1", status="prior")
    tracker.observer.add_target("P2", 0.0, 2000.0, 0.0, sigma0=50.0)
    tracker.adopt("P2", status="prior", existence=0.5)
    tracker.scan(1.0, "u1", Footprint(0.0, 0.0, RADIUS_M), [])
    assert tracker.status("P1") == "prior"
    assert 0.49 < tracker.existence("P1") < 0.5
    events: list[TrackEvent] = []
    for t in (2.0, 3.0):
        events += tracker.scan(t, "u2", Footprint(2000.0, 0.0, RADIUS_M), []).events
    assert events == [TrackEvent(3.0, "deleted", "P2", "not seen in view")]
    assert tracker.track_ids == ["P1"]


def test_prior_is_confirmed_by_m_of_n_and_a_phantom_is_not_by_one_false_alarm() -> None:
    """A listed iceberg is confirmed by the same 3-of-5 as a new one (its listing is not
    evidence that it is there); a phantom hit by one false alarm and then missed is
    deleted."""
    tracker = make(pd=0.85)
    tracker.observer.add_target("P1", 0.0, 0.0, 0.0, sigma0=200.0)
    tracker.adopt("P1", status="prior")
    tracker.observer.add_target("P2", 0.0, 1000.0, 0.0, sigma0=1800.0)
    tracker.adopt("P2", status="prior")
    events: list[TrackEvent] = []
    for k in range(1, 4):
        res = tracker.scan(float(k), "u1", Footprint(0.0, 0.0, RADIUS_M),
                           [ScanDetection(4.0, -3.0, R_M2)])
        assert res.assigned == {0: "P1"}
        events += res.events
    assert events == [TrackEvent(3.0, "confirmed", "P1", "prior_seen")]
    rec = tracker.records()[0]
    assert (rec.status, rec.hits, rec.confirmed_s) == ("confirmed", 3, 3.0)
    res = tracker.scan(4.0, "u2", Footprint(1000.0, 0.0, RADIUS_M),
                       [ScanDetection(1040.0, 20.0, R_M2)])  # a false alarm in P2's gate
    assert res.assigned == {0: "P2"} and tracker.status("P2") == "prior"
    for t in (4.5, 5.0, 5.5, 6.0, 6.5):
        events += tracker.scan(t, "u2", Footprint(1000.0, 0.0, RADIUS_M), []).events
    assert events[-1].track_id == "P2" and events[-1].kind == "deleted"
    assert tracker.track_ids == ["P1"]


@pytest.mark.parametrize("association", ["gnn", "jpda"])
def test_birth_confirmation_and_unconfirmed_deletion(association: str) -> None:
    """M-of-N (3 of 5): a new object seen 3 times is confirmed; one seen once and then
    missed 3 times in view is deleted as unconfirmed; ids are never reused."""
    tracker = make(association=association, pd=0.85, clutter_per_frame=0.1)
    fp = Footprint(0.0, 0.0, RADIUS_M)
    kinds = []
    for k, dets in enumerate([[(10.0, 10.0), (-60.0, 40.0)], [(10.5, 10.0)], [(10.0, 9.5)],
                              [(10.2, 10.1)], [(9.9, 10.0)]]):
        res = tracker.scan(0.5 * k, "u1", fp, [ScanDetection(x, y, R_M2) for x, y in dets])
        kinds += [(e.kind, e.track_id) for e in res.events]
    assert kinds == [("born", "N1"), ("born", "N2"), ("confirmed", "N1"), ("deleted", "N2")]
    res = tracker.scan(3.0, "u1", fp, [ScanDetection(10.0, 10.0, R_M2),
                                       ScanDetection(-60.0, 40.0, R_M2)])
    assert [(e.kind, e.track_id) for e in res.events] == [("born", "N3")]
    assert res.assigned == {0: "N1"} and res.unassociated == 1


@pytest.mark.parametrize("association", ["gnn", "jpda"])
def test_bad_detections_are_rejected_and_counted(association: str) -> None:
    tracker = make(association=association)
    bad = [ScanDetection(math.nan, 0.0, R_M2), ScanDetection(0.0, math.inf, R_M2),
           ScanDetection(1.0, 1.0, 0.0), ScanDetection(1.0, 1.0, -1.0),
           ScanDetection(1.0, 1.0, math.nan), ScanDetection("x", 1.0, 5.0)]  # type: ignore[arg-type]
    res = tracker.scan(1.0, "u1", Footprint(0.0, 0.0, RADIUS_M),
                       [*bad, ScanDetection(5.0, 5.0, R_M2)])
    assert res.rejected == 6 and res.unassociated == 1
    assert [e.kind for e in res.events] == ["born"]
    res = tracker.scan(math.nan, "u1", None, [ScanDetection(5.0, 5.0, R_M2)])
    assert res.events == () and res.rejected == 1
    res = tracker.scan(2.0, "u1", Footprint(0.0, math.inf, -3.0), [ScanDetection(5.0, 5.0, R_M2)])
    assert res.assigned == {0: "N1"}  # a bad footprint is no footprint
    counters = tracker.counters
    assert counters["rejected_invalid"] == 7
    assert counters["rejected_scans"] == 1 and counters["rejected_footprint"] == 1


def test_no_footprint_miss_is_no_evidence() -> None:
    tracker = make(pd=0.85)
    tracker.observer.add_target("A", 0.0, 0.0, 0.0, p0=[4.0, 4.0, 0.01, 0.01])
    tracker.adopt("A")
    for k in range(1, 30):
        tracker.scan(0.5 * k, "u1", None, [ScanDetection(500.0, 500.0, R_M2)])
    assert tracker.status("A") == "confirmed" and tracker.existence("A") == pytest.approx(0.999)


def test_scan_before_the_observers_time_is_still_applied() -> None:
    """The core may have predicted the observer past a buffered scan's time. Within the
    committed grid step the view goes back to the scan's time exactly (same result); past it
    the detection updates the track at the track's own time (off by v dt, here < 0.1 m)."""
    results = []
    for ahead_s in (0.0, 1.52, 2.05):
        tracker = make()
        tracker.observer.add_target("A", 0.0, 0.0, 0.0, vx_m_s=0.2, p0=[4.0, 4.0, 0.1, 0.1])
        tracker.adopt("A")
        tracker.observer.predict_to(ahead_s)
        det = ScanDetection(1.0, 1.0, R_M2)
        res = tracker.scan(1.5, "u1", Footprint(0.0, 0.0, RADIUS_M), [det])
        assert res.assigned == {0: "A"} and res.events == ()
        tracker.observer.predict_to(3.0)
        results.append(tracker.observer.track("A"))
    assert results[0] == results[1]
    assert math.hypot(results[2].x_m - results[0].x_m, results[2].y_m - results[0].y_m) < 0.1


def test_pda_update_with_one_certain_detection_is_the_kalman_update() -> None:
    a, b = Observer(ObserverConfig()), Observer(ObserverConfig())
    for obs in (a, b):
        obs.add_target("A", 0.0, 0.0, 0.0, p0=[9.0, 4.0, 0.5, 0.5])
        obs.predict_to(1.0)
    a.correct("A", 1.0, 2.0, -1.0, 5.0)
    b.correct_pda("A", 1.0, [[2.0, -1.0]], [1.0], 5.0)
    ta, tb = a.track("A"), b.track("A")
    assert (ta.x_m, ta.y_m) == pytest.approx((tb.x_m, tb.y_m), rel=1e-12)
    assert ta.cov_xy == pytest.approx(tb.cov_xy, rel=1e-12)
    b.correct_pda("A", 1.0, [[50.0, 50.0], [-50.0, 0.0]], [0.3, 0.3], 5.0)
    assert b.track("A").sigma > 0.0 and b.track("A").x_m != tb.x_m
    with pytest.raises(ValueError, match="betas"):
        b.correct_pda("A", 1.0, [[1.0, 1.0]], [1.5], 5.0)


@pytest.mark.parametrize(
    ("field", "value"),
    [("association", "nn"), ("pd", 0.0), ("pd", 1.5), ("clutter_per_frame", -1.0),
     ("confirm_hits", 6), ("confirm_window", 0), ("existence_delete", 1.0),
     ("gate_probability", math.nan), ("new_track_vel_var_m2_s2", 0.0), ("id_prefix", ""),
     ("confirm_hits", True), ("existence_confirm_min", 0.01), ("lost_sigma_m", 0.0),
     ("lost_sigma_m", math.inf)],
)
def test_config_errors_name_the_field(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=f"TrackerConfig.{field}") as err:
        TrackerConfig(**{field: value})  # type: ignore[arg-type]
    assert "\n" not in str(err.value)


def _vague(tracker: Tracker, tid: str, x_m: float, y_m: float, var_m2: float) -> None:
    """A confirmed track unseen for long: position variance ``var_m2`` per axis, still."""
    tracker.observer.add_target(tid, 0.0, x_m, y_m, p0=[var_m2, var_m2, 0.1, 0.1], q_per_s=0.0)
    tracker.adopt(tid)


def _see(tracker: Tracker, xy: tuple[float, float], frames: int) -> list[TrackEvent]:
    """``frames`` frames at 2 Hz centred on an iceberg at ``xy`` that is seen in each."""
    events: list[TrackEvent] = []
    for k in range(1, frames + 1):
        det = ScanDetection(xy[0] + 0.1 * k, xy[1], R_M2)
        events += tracker.scan(0.5 * k, "u1", Footprint(xy[0], xy[1], RADIUS_M), [det]).events
    return events


@pytest.mark.parametrize(("var_m2", "merge"), [(1e5, "merged into A (p 0.91)"),
                                               (1e4, None)])
def test_a_stale_track_found_again_keeps_its_id(var_m2: float, merge: str | None) -> None:
    """A confirmed track unseen for long (sigma 316 or 100 m per axis), its iceberg found
    126 m from its mean, no other track near. sigma 100 m: it claims the detection against
    "clutter or new" (a_ij ~ 6) and, alone, against every other track (Q = 1): it takes it
    as any track does. sigma 316 m: too vague to claim one detection against "clutter or
    new"; the detections start a tentative track, and at confirmation P_A = g_A /
    (lambda_b + g_A) >= 0.9: the new track is merged into A, which keeps its id and takes
    the new, precise estimate; the merge names its probability (the journal's note)."""
    tracker = make(pd=0.85)
    _vague(tracker, "A", 0.0, 0.0, var_m2)
    _vague(tracker, "B", 3000.0, 0.0, 1e5)
    events = _see(tracker, (120.0, 40.0), 4)
    expected = [] if merge is None else [
        ("born", "N1", "unassociated detection"),
        ("deleted", "N1", merge),
    ]
    assert [(e.kind, e.track_id, e.reason) for e in events] == expected
    a = tracker.observer.track("A")
    assert math.hypot(a.x_m - 120.4, a.y_m - 40.0) < 3.0 and a.sigma < 20.0
    assert a.q_per_s == 0.0  # A keeps its own process noise
    assert tracker.track_ids == ["A", "B"] and tracker.status("A") == "confirmed"
    det = ScanDetection(120.5, 40.0, R_M2)
    res = tracker.scan(3.0, "u1", Footprint(120.0, 40.0, RADIUS_M), [det])
    assert res.assigned == {0: "A"}


@pytest.mark.parametrize(("var_m2", "might"), [(1e5, "A (p 0.48), B (p 0.47)"),
                                               (1e4, "A (p 0.54), B (p 0.45)")])
@pytest.mark.parametrize("association", ["gnn", "jpda"])
def test_a_crossing_pair_after_a_gap_does_not_hand_over_an_old_id(
    var_m2: float, might: str, association: str
) -> None:
    """Icebergs a and b passed each other while unseen: their tracks A and B are stale
    (sigma 316 or 100 m per axis) and 120 m apart, and b is found 45 m from A's mean and
    75 m from B's. Positions cannot say whose iceberg it is (P_A ~ P_B ~ 0.5). Before, b's
    detections went to A (sigma 100 m: the likeliest association) or its new track was
    merged into A (sigma 316 m: the likeliest coalescence): a confident wrong identity.
    Now the new track replaces A's estimate as coalescence did (A, the likeliest, is
    deleted: no stale duplicate is left to draw the planner) but keeps a new id, and its
    confirmation and record say which old tracks it might continue; B stays as it was."""
    tracker = make(pd=0.85, association=association)
    _vague(tracker, "A", 0.0, 0.0, var_m2)
    _vague(tracker, "B", 120.0, 0.0, var_m2)
    events = _see(tracker, (45.0, 0.0), 4)
    p_a = might.split("(p ")[1].split(")")[0]
    assert [(e.kind, e.track_id, e.reason) for e in events] == [
        ("born", "N1", "unassociated detection"),
        ("confirmed", "N1", f"m_of_n; might continue {might}"),
        ("deleted", "A", f"succeeded by N1 (p {p_a})"),
    ]
    assert tracker.track_ids == ["B", "N1"]
    # the deletion names the track that goes on with A's estimate (the core hands A's
    # vehicles over to it: core/fleet.py hand_over)
    assert [e.successor for e in events] == [None, None, "N1"]
    record = {r.id: r for r in tracker.records()}["N1"]
    assert [oid for oid, _ in record.might_continue] == ["A", "B"]
    old = tracker.observer.track("B")
    assert (old.x_m, old.y_m) == (120.0, 0.0) and old.sigma >= 2 * var_m2
    new = tracker.observer.track("N1")
    assert math.hypot(new.x_m - 45.4, new.y_m) < 3.0 and new.sigma < 20.0


def test_tentative_tracks_never_looked_at_again_die_when_lost() -> None:
    """A tentative track the camera never covers again cannot be confirmed by any frame once
    the observer calls it lost (sqrt(trace P) > fov_radius_m): deleted, so false alarms at a
    footprint's trailing edge do not pile up. Tracks the caller removed are dropped."""
    tracker = make(pd=0.85)
    res = tracker.scan(0.0, "u1", Footprint(0.0, 0.0, RADIUS_M), [ScanDetection(140.0, 0.0, R_M2)])
    assert [e.kind for e in res.events] == ["born"]
    tracker.observer.add_target("A", 0.0, 0.0, 0.0, p0=[1e4, 1e4, 0.1, 0.1])
    tracker.adopt("A")
    tracker.observer.add_target("gone", 0.0, 0.0, 0.0)
    tracker.adopt("gone")
    tracker.observer.remove_target("gone")
    deleted_at = None
    for k in range(1, 400):
        res = tracker.scan(0.5 * k, "u1", Footprint(5000.0, 0.0, RADIUS_M), [])
        if res.events:
            assert res.events == (TrackEvent(0.5 * k, "deleted", "N1", "unconfirmed"),)
            deleted_at = 0.5 * k
            break
    sigma_lost = tracker.observer.config.fov_radius_m ** 2
    assert deleted_at is not None and 30.0 < deleted_at < 120.0
    assert tracker.track_ids == ["A"]  # a confirmed track is never deleted for being vague
    assert tracker.observer.sigma("A") > sigma_lost


def test_a_kept_track_loses_existence_in_view_but_is_never_deleted() -> None:
    """``keep`` (an operator's target): the same misses that delete a plain confirmed track
    lower its existence to the same value but leave it tracked and confirmed."""
    tracker = make(pd=0.85)
    for tid, keep in (("A", False), ("K", True)):
        tracker.observer.add_target(tid, 0.0, 10.0, 0.0, p0=[4.0, 4.0, 0.01, 0.01])
        tracker.adopt(tid, keep=keep)
    deleted: list[str] = []
    for k in range(1, 20):
        res = tracker.scan(0.5 * k, "u1", Footprint(0.0, 0.0, RADIUS_M), [])
        deleted += [e.track_id for e in res.events if e.kind == "deleted"]
    assert deleted == ["A"]
    assert tracker.status("K") == "confirmed" and "K" in tracker.observer.target_ids
    assert tracker.existence("K") < 0.05


def test_lost_sigma_deletes_vague_confirmed_and_prior_tracks_when_they_pass_it() -> None:
    """``lost_sigma_m``: a confirmed or prior track is deleted (``lost``) at the first scan
    where ``sqrt(trace P_xy)`` exceeds it, wherever the camera looks; a kept track and a
    precise one stay. The time follows from P: with P0 = diag(100, 100, 0.1, 0.1) and no
    process noise, trace P(t) = 200 + 0.2 t^2, which passes 300^2 at t = 670.4 s."""
    tracker = make(pd=0.85, lost_sigma_m=300.0)
    for tid, status, keep in (("C", "confirmed", False), ("P", "prior", False),
                              ("K", "confirmed", True)):
        tracker.observer.add_target(tid, 0.0, 0.0, 1000.0 * len(tid), p0=[100.0, 100.0, 0.1, 0.1],
                                    q_per_s=0.0)
        tracker.adopt(tid, status=status, keep=keep)
    tracker.observer.add_target("S", 0.0, 0.0, 9000.0, p0=[1.0, 1.0, 1e-6, 1e-6], q_per_s=0.0)
    tracker.adopt("S")
    events: list[TrackEvent] = []
    for k in range(1, 1601):
        events += tracker.scan(0.5 * k, "u1", Footprint(-5000.0, 0.0, RADIUS_M), []).events
    t_lost = math.sqrt((300.0**2 - 200.0) / 0.2)
    assert [(e.kind, e.track_id, e.reason) for e in events] == [
        ("deleted", "C", "lost"), ("deleted", "P", "lost")]
    assert all(t_lost <= e.t_s < t_lost + 0.5 for e in events)
    assert tracker.track_ids == ["K", "S"]
    assert "C" not in tracker.observer.target_ids and "P" not in tracker.observer.target_ids
