"""GOSPA (observer.gospa): hand cases and a brute-force enumeration over small random sets."""

from __future__ import annotations

import itertools
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from observer.gospa import gospa


def brute_force(
    tracks: list[tuple[float, float]], truth: list[tuple[float, float]], c: float, p: float
) -> float:
    """The defining minimum, over every partial one-to-one assignment (any distance)."""
    best = math.inf
    n, m = len(tracks), len(truth)
    for k in range(min(n, m) + 1):
        for rows in itertools.combinations(range(n), k):
            for cols in itertools.permutations(range(m), k):
                cost = sum(
                    math.dist(tracks[i], truth[j]) ** p for i, j in zip(rows, cols, strict=True)
                )
                cost += c**p / 2.0 * (n + m - 2 * k)
                best = min(best, cost)
    return best ** (1.0 / p)


coordinate = st.floats(min_value=-400.0, max_value=400.0, allow_nan=False)
point_sets = st.lists(st.tuples(coordinate, coordinate), max_size=4)


@settings(max_examples=150, deadline=None)
@given(
    tracks=point_sets,
    truth=point_sets,
    c=st.sampled_from([50.0, 150.0, 300.0]),
    p=st.sampled_from([1.0, 2.0, 3.0]),
)
def test_matches_brute_force(
    tracks: list[tuple[float, float]], truth: list[tuple[float, float]], c: float, p: float
) -> None:
    result = gospa(tracks, truth, c_m=c, p=p)
    expected = brute_force(tracks, truth, c, p)
    assert result.distance_m == pytest.approx(expected, rel=1e-9, abs=1e-9)
    # The parts add up, the counts balance, and every match is inside the cut-off.
    recomposed = result.localisation_m**p + c**p / 2.0 * (result.missed + result.false)
    assert result.distance_m**p == pytest.approx(recomposed, rel=1e-9, abs=1e-9)
    assert result.missed - result.false == len(truth) - len(tracks)
    assert len(result.matches) == len(tracks) - result.false
    assert len({i for i, _ in result.matches}) == len(result.matches)
    assert len({j for _, j in result.matches}) == len(result.matches)
    for i, j in result.matches:
        assert math.dist(tracks[i], truth[j]) < c


def test_empty_sets() -> None:
    assert gospa([], []).distance_m == 0.0
    c, p = 150.0, 2.0
    for n in (1, 3, 7):
        pts = [(float(k), 0.0) for k in range(n)]
        expected = c / 2.0 ** (1.0 / p) * n ** (1.0 / p)
        only_tracks = gospa(pts, [], c_m=c, p=p)
        assert only_tracks.distance_m == pytest.approx(expected)
        assert (only_tracks.false, only_tracks.missed) == (n, 0)
        only_truth = gospa([], pts, c_m=c, p=p)
        assert only_truth.distance_m == pytest.approx(expected)
        assert (only_truth.false, only_truth.missed) == (0, n)


def test_hand_cases() -> None:
    # One match at 3-4-5, one track 500 m from anything: sqrt(25 + 150^2 / 2 * 2).
    r = gospa([(3.0, 4.0), (600.0, 0.0)], [(0.0, 0.0), (100.0, 0.0)], c_m=150.0)
    # (3,4)->(0,0) is 5 m, (600,0)->(100,0) is 500 m > c: one false, one missed.
    assert r.localisation_m == pytest.approx(5.0)
    assert (r.missed, r.false) == (1, 1)
    assert r.distance_m == pytest.approx(math.sqrt(25.0 + 150.0**2))
    assert r.matches == ((0, 0),)
    # The optimal assignment is global, not greedy: the nearest-neighbour choice for the
    # first track (10 m) would leave the second one 145 m away (10^2 + 145^2 > 15^2 + 120^2).
    r = gospa([(10.0, 0.0), (-120.0, 0.0)], [(0.0, 0.0), (25.0, 0.0)], c_m=150.0)
    assert r.matches == ((0, 1), (1, 0))
    assert r.distance_m == pytest.approx(math.sqrt(15.0**2 + 120.0**2))
    # Exactly at the cut-off counts as unassigned.
    r = gospa([(150.0, 0.0)], [(0.0, 0.0)], c_m=150.0)
    assert (r.missed, r.false, r.matches) == (1, 1, ())


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"tracks_xy": [(math.nan, 0.0)], "truth_xy": []}, "tracks_xy[0]"),
        ({"tracks_xy": [], "truth_xy": [(0.0, 1.0, 2.0)]}, "truth_xy[0]"),
        ({"tracks_xy": [], "truth_xy": ["ab"]}, "truth_xy[0]"),
        ({"tracks_xy": [], "truth_xy": [], "c_m": 0.0}, "c_m"),
        ({"tracks_xy": [], "truth_xy": [], "p": 0.5}, "p must be >= 1"),
        ({"tracks_xy": [], "truth_xy": [], "alpha": 1.0}, "alpha"),
    ],
)
def test_bad_input_names_the_field(kwargs: dict[str, object], field: str) -> None:
    with pytest.raises(ValueError, match=field.replace("[", r"\[").replace("]", r"\]")):
        gospa(**kwargs)  # type: ignore[arg-type]
