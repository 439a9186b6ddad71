"""A track deleted by coalescence goes on under its successor's id (observer/tracker.py,
``TrackEvent.successor``): the core's vehicles flying to it, or through it, fly to the
successor, so a new id alone is no new leg (``UploadRule.same_leg``) and sends no mission."""

from __future__ import annotations

from groundstation.core.fleet import VehicleRecord, free_vehicles, hand_over
from groundstation.core.uploads import UploadRule


def _record(vid: str, target: str, route: tuple[str, ...], through: tuple[str, ...]
            ) -> VehicleRecord:
    return VehicleRecord(vid, 0.0, 0.0, 0.0, 22.0, 0.0, busy=True, target=target,
                         aim_xy_m=(500.0, 0.0), route=route, through=through)


def test_a_succeeded_track_hands_its_vehicles_over_to_its_successor() -> None:
    flying = _record("1", "A", ("A", "B"), ("C1", "A"))
    other = _record("2", "B", ("B", "A"), ())
    assert hand_over([flying, other], "A", "N7")
    assert (flying.target, flying.route, flying.through) == ("N7", ("N7", "B"), ("C1", "N7"))
    assert flying.busy and flying.aim_xy_m == (500.0, 0.0)
    assert (other.target, other.route) == ("B", ("B", "N7"))
    # the next plan's leg to the successor at the same aim is the leg it flies: no upload
    rule = UploadRule(15.0, 120.0, None)
    assert rule.same_leg(flying.target, flying.aim_xy_m, "N7", (510.0, 0.0))
    assert not hand_over([other], "A", "N8")  # nobody flew to A any more


def test_a_plain_deletion_still_frees_its_vehicles() -> None:
    flying = _record("1", "A", ("A",), ())
    assert free_vehicles([flying], "A")
    assert flying.target is None and not flying.busy and flying.aim_xy_m is None
