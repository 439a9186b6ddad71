"""The tracker's state in the operator views: status JSON pieces from the core's views
(``TrackView``/``SearchCellView``), which track notes are operator
events, and replay comparing the track notes."""

from __future__ import annotations

import logging
import math

from groundstation.core.views import SearchCellView, TrackView
from groundstation.daemon.log_lines import is_operator_event, line_level
from groundstation.daemon.track_views import (
    TrackNotes,
    count_line,
    search_dicts,
    track_counts,
    track_dicts,
)
from groundstation.runners.replay.compare import decision_of_record


def test_track_and_search_dicts_are_plain_rounded_json() -> None:
    views = [TrackView("N1", "tentative", 10.04, -3.06, 900.0, 0.41234, 12.5),
             TrackView("A", "confirmed", 500.0, 20.0, 4.0, 1.0, 12.5),
             TrackView("P1", "prior", 1.0, 2.0, math.nan, 0.5, 12.5)]
    tracks = track_dicts(views)
    assert tracks[0] == {"id": "N1", "status": "tentative", "x_m": 10.0, "y_m": -3.1,
                         "sigma_m2": 900.0, "existence": 0.412, "t_s": 12.5}
    assert tracks[2]["sigma_m2"] is None  # NaN is no JSON number
    assert track_counts(tracks) == {"confirmed": 1, "tentative": 1, "prior": 1}
    cells = search_dicts([SearchCellView("c3", 450.0, 150.0, 300.0, 1234.56, None),
                          SearchCellView("c4", 750.0, 150.0, 300.0, 0.0, 40.0)])
    assert cells == [
        {"id": "c3", "x_m": 450.0, "y_m": 150.0, "size_m": 300.0, "value_m2": 1234.6,
         "last_covered_s": None},
        {"id": "c4", "x_m": 750.0, "y_m": 150.0, "size_m": 300.0, "value_m2": 0.0,
         "last_covered_s": 40.0}]
    assert count_line(track_counts(tracks), len(cells)) == (
        "tracks: 1 confirmed, 1 tentative, 1 prior; 2 search cells")
    assert count_line({"confirmed": 3}, 0) == "tracks: 3 confirmed, 0 tentative, 0 prior"


def test_track_notes_decide_which_deletions_the_operator_sees() -> None:
    notes = TrackNotes()
    notes.prior("P1")
    assert notes.fields("track_born", "N1") == {}
    assert notes.fields("track_deleted", "N1") == {"confirmed": False}  # clutter
    assert notes.fields("track_born", "N2") == {}
    assert notes.fields("track_confirmed", "N2") == {}
    assert notes.fields("track_deleted", "N2") == {"confirmed": True}
    assert notes.fields("track_deleted", "P1") == {"confirmed": True}  # a prior entry
    assert notes.fields("track_deleted", "P1") == {"confirmed": False}  # once only
    assert notes.fields("target_discovered", "X") == {}
    line = {"t": 1.0, "event": "track_deleted", "target": "N1", "detail": "not confirmed"}
    assert not is_operator_event({**line, "confirmed": False})
    assert is_operator_event({**line, "confirmed": True})
    assert is_operator_event(line)  # a journal that does not say (gcs simulate's)
    assert not is_operator_event({"t": 1.0, "event": "track_born", "target": "N1"})
    confirmed = {"t": 2.0, "event": "track_confirmed", "target": "N2", "detail": "3 of 5"}
    assert is_operator_event(confirmed) and line_level(confirmed) == logging.INFO


def test_replay_compares_the_track_notes_in_either_spelling() -> None:
    for record in ({"event": "track_born", "t": 3.0, "target": "N4"},
                   {"event": "note", "kind": "track_born", "t": 3.0, "target": "N4"}):
        decision = decision_of_record(record)
        assert decision is not None and (decision.kind, decision.key) == (
            "note:track_born", "None/N4")
    for kind in ("track_confirmed", "track_deleted"):
        decision = decision_of_record({"event": kind, "t": 1.0, "target": "N4"})
        assert decision is not None and decision.kind == f"note:{kind}"
