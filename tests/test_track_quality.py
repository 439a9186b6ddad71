"""Track-quality measures (observer.track_quality): each definition on a tiny synthetic history."""

from __future__ import annotations

import math

import pytest

from observer.gospa import gospa
from observer.track_quality import TrackQualityRecorder


def test_gospa_mean_is_the_mean_of_the_samples() -> None:
    rec = TrackQualityRecorder()
    samples = [
        ({"N1": (3.0, 4.0)}, {"a": (0.0, 0.0)}),
        ({}, {"a": (0.0, 0.0), "b": (500.0, 0.0)}),
        ({"N1": (1.0, 0.0), "N2": (900.0, 0.0)}, {"a": (0.0, 0.0)}),
    ]
    expected = []
    for t, (tracks, truth) in enumerate(samples):
        got = rec.sample(float(t), tracks, truth)
        expected.append(gospa(list(tracks.values()), list(truth.values())).distance_m)
        assert got.distance_m == pytest.approx(expected[-1])
    assert rec.to_dict(3.0)["gospa_mean_m"] == pytest.approx(sum(expected) / 3)
    assert expected[0] == pytest.approx(5.0)
    assert expected[1] == pytest.approx(150.0)  # two missed: sqrt(2 * 150^2 / 2)


def test_true_confirmed_fraction_counts_the_last_sample_only() -> None:
    rec = TrackQualityRecorder()
    truth = {"a": (0.0, 0.0), "b": (1000.0, 0.0), "c": (2000.0, 0.0), "d": (3000.0, 0.0)}
    rec.sample(0.0, {"N1": (0.0, 0.0), "N2": (1000.0, 0.0), "N3": (2000.0, 0.0)}, truth)
    # At the end: N1 on a, N2 too far from b (200 m > c), a spare track N4 on nothing.
    rec.sample(1.0, {"N1": (1.0, 0.0), "N2": (1200.0, 0.0), "N4": (5000.0, 0.0)}, truth)
    assert rec.to_dict(2.0)["true_confirmed_fraction"] == pytest.approx(1 / 4)
    assert TrackQualityRecorder().to_dict(1.0)["true_confirmed_fraction"] is None


def test_time_to_confirm_from_first_footprint_to_first_assigned_sample() -> None:
    rec = TrackQualityRecorder()
    truth = {"a": (0.0, 0.0), "b": (1000.0, 0.0), "never": (9000.0, 0.0)}
    rec.sample(0.0, {}, truth)
    rec.frame(0.5, (100.0, 0.0, 150.0), truth)  # covers a (100 m) only
    rec.frame(2.5, (1000.0, 140.0, 150.0), truth)  # covers b
    rec.frame(3.0, (0.0, 0.0, 150.0), truth)  # a again: its first frame stays 0.5
    rec.sample(1.0, {}, truth)
    rec.sample(4.0, {"N1": (5.0, 0.0)}, truth)  # a confirmed: 3.5 s after 0.5
    rec.sample(9.0, {"N1": (5.0, 0.0), "N2": (1010.0, 0.0)}, truth)  # b: 6.5 s after 2.5
    assert rec.first_seen_s == {"a": 0.5, "b": 2.5}
    assert rec.time_to_confirm_s == {"a": 3.5, "b": 6.5}
    ttc = rec.to_dict(10.0)["time_to_confirm_s"]
    assert ttc == {"median": 5.0, "max": 6.5}


def test_a_known_target_tracked_before_any_frame_confirms_at_the_next_sample() -> None:
    rec = TrackQualityRecorder()
    truth = {"a": (0.0, 0.0)}
    rec.sample(0.0, {"T1": (0.0, 0.0)}, truth)
    rec.frame(0.5, (0.0, 0.0, 150.0), truth)
    rec.sample(1.0, {"T1": (0.0, 0.0)}, truth)
    assert rec.time_to_confirm_s == {"a": 0.5}
    assert TrackQualityRecorder().to_dict(1.0)["time_to_confirm_s"] == {
        "median": None,
        "max": None,
    }


def test_false_tracks_never_matched_while_confirmed_per_hour() -> None:
    rec = TrackQualityRecorder()
    truth = {"a": (0.0, 0.0)}
    rec.sample(0.0, {"N1": (0.0, 0.0), "N2": (400.0, 0.0)}, truth)  # N2 matches nothing
    # N3 starts far and later drifts onto a after N1 is gone: it matched once, so not false.
    rec.sample(1.0, {"N1": (0.0, 0.0), "N3": (700.0, 0.0)}, truth)
    rec.sample(2.0, {"N3": (20.0, 0.0), "N5": (-600.0, 0.0)}, truth)
    # Two tracks on the same iceberg: only one can be assigned; N6 is never assigned.
    rec.sample(3.0, {"N3": (1.0, 0.0), "N6": (2.0, 0.0)}, truth)
    assert rec.false_track_ids == ["N2", "N5", "N6"]
    assert rec.to_dict(1800.0)["false_tracks_per_hour"] == pytest.approx(6.0)


def test_id_switches_between_consecutive_assigned_samples() -> None:
    rec = TrackQualityRecorder()
    truth = {"a": (0.0, 0.0), "b": (60.0, 0.0)}
    rec.sample(0.0, {"N1": (0.0, 0.0), "N2": (60.0, 0.0)}, truth)
    rec.sample(1.0, {"N1": (0.0, 0.0), "N2": (60.0, 0.0)}, truth)  # no change
    rec.sample(2.0, {"N1": (60.0, 0.0), "N2": (0.0, 0.0)}, truth)  # swap: a and b switch
    assert rec.to_dict(3.0)["id_switches"] == 2
    rec.sample(3.0, {"N2": (0.0, 0.0)}, truth)  # b loses its track
    rec.sample(4.0, {"N2": (0.0, 0.0), "N7": (60.0, 0.0)}, truth)  # b re-acquired by N7
    assert rec.to_dict(5.0)["id_switches"] == 2  # a gap: fragmentation, not a switch
    assert rec.truth_changes == 2  # the swap, seen from the tracks


def test_truth_changes_count_a_track_taking_over_another_iceberg_after_a_gap() -> None:
    rec = TrackQualityRecorder()
    truth = {"a": (0.0, 0.0), "b": (2000.0, 0.0)}
    rec.sample(0.0, {"N1": (0.0, 0.0)}, truth)
    rec.sample(1.0, {"N1": (900.0, 0.0)}, truth)  # stale: matches nothing
    rec.sample(2.0, {"N1": (2000.0, 5.0)}, truth)  # takes over b
    assert rec.truth_changes == 1
    assert rec.to_dict(3.0)["id_switches"] == 0  # neither iceberg saw two ids in a row
    assert rec.identity_errors == 1


def test_identity_errors_count_tracks_not_changes() -> None:
    """A track matched to a, then b, then a again is one identity error (three truth
    changes would count it thrice); a track that only ever matched a is none."""
    rec = TrackQualityRecorder()
    truth = {"a": (0.0, 0.0), "b": (2000.0, 0.0)}
    for k, x in enumerate((0.0, 2000.0, 0.0, 2000.0)):
        rec.sample(float(k), {"N1": (x, 0.0), "N2": (2000.0 - x, 3.0)}, truth)
    rec.sample(9.0, {"N3": (1.0, 0.0)}, truth)
    assert rec.truth_changes == 6
    assert rec.identity_errors == 2  # N1 and N2, not N3


def test_results_do_not_depend_on_the_callers_order() -> None:
    tracks = {"N1": (0.0, 0.0), "N2": (10.0, 0.0)}
    truth = {"a": (5.0, 0.0), "b": (200.0, 0.0)}
    one, two = TrackQualityRecorder(), TrackQualityRecorder()
    one.sample(0.0, tracks, truth)
    two.sample(0.0, dict(reversed(tracks.items())), dict(reversed(truth.items())))
    assert one.to_dict(1.0) == two.to_dict(1.0)
    assert one.false_track_ids == two.false_track_ids


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda r: r.frame(math.nan, (0.0, 0.0, 1.0), {}), "t_s"),
        (lambda r: r.frame(0.0, (0.0, 0.0), {}), "footprint_xy_r"),
        (lambda r: r.frame(0.0, (0.0, 0.0, -1.0), {}), "radius_m"),
        (lambda r: r.frame(0.0, (0.0, 0.0, 1.0), {"a": (math.inf, 0.0)}), "truth_xy"),
        (lambda r: r.sample(0.0, {"N1": "xy!"}, {}), "confirmed"),
        (lambda r: r.sample(0.0, {}, [(0.0, 0.0)]), "truth_in_area"),
        (lambda r: r.to_dict(0.0), "duration_s"),
    ],
)
def test_bad_input_names_the_field(call: object, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        call(TrackQualityRecorder())  # type: ignore[operator]


def test_bad_parameters() -> None:
    with pytest.raises(ValueError, match="c_m"):
        TrackQualityRecorder(c_m=-1.0)


def test_a_track_on_a_real_iceberg_outside_the_area_is_not_false() -> None:
    rec = TrackQualityRecorder()
    inside = {"a": (0.0, 0.0)}
    outside = {"d": (-500.0, 0.0)}
    # N1 on a; N2 on d (outside the area); N3 near nothing; N4 a second track on d: the
    # outside assignment is one-to-one too, so only one of N2/N4 is a real iceberg's track.
    rec.sample(0.0, {"N1": (0.0, 0.0), "N2": (-510.0, 0.0), "N3": (900.0, 0.0),
                     "N4": (-495.0, 0.0)}, inside, outside)
    assert rec.false_track_ids == ["N2", "N3"]
    # the outside icebergs count for nothing else: the fraction and GOSPA see the area only
    assert rec.to_dict(1800.0)["true_confirmed_fraction"] == 1.0
    alone = TrackQualityRecorder()
    alone.sample(0.0, {"N1": (0.0, 0.0), "N2": (-510.0, 0.0), "N3": (900.0, 0.0),
                       "N4": (-495.0, 0.0)}, inside)
    assert alone.false_track_ids == ["N2", "N3", "N4"]
    assert alone.to_dict(1800.0)["gospa_mean_m"] == rec.to_dict(1800.0)["gospa_mean_m"]
