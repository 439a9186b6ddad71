"""Evidence rules: single forged frames change nothing; the real sequences do."""

from __future__ import annotations

import pytest

from domain.modes import TAKEN_MODES, ArduPlaneMode, mode_name
from groundstation.mavlink.evidence import (
    BatteryEvidence,
    LoiterEndEvidence,
    NewSystemEvidence,
    RebootEvidence,
    Sustained,
)


@pytest.mark.parametrize(
    ("observations", "confirmed"),
    [
        ([(True, 0.0)], False),  # one frame
        ([(True, 0.0), (True, 0.1), (True, 0.2)], False),  # three frames in a burst
        ([(True, 0.0), (True, 1.0), (True, 2.0)], True),
        ([(True, 0.0), (True, 1.0), (False, 1.5), (True, 2.0)], False),  # contradicted
        ([(True, 0.0), (True, 5.0)], False),  # long, but two frames only
    ],
)
def test_sustained(observations: list[tuple[bool, float]], confirmed: bool) -> None:
    rule = Sustained(min_frames=3, min_span_s=2.0)
    verdicts = [rule.observe(holds, t) for holds, t in observations]
    assert verdicts[-1] is confirmed and rule.confirmed is confirmed


@pytest.mark.parametrize(
    ("frames", "verdicts"),
    [
        # a stray frame, then the old timeline again
        ([(600_000, 0.0), (5, 0.5), (601_000, 1.0)], ["ok", "suspect", "ok"]),
        # reordering within the backstep
        ([(600_000, 0.0), (598_500, 0.1)], ["ok", "ok"]),
        # a real restart: the new timeline holds over 3 frames and >= 1 s
        ([(600_000, 0.0), (500, 10.0), (1_000, 10.5), (1_500, 11.0)],
         ["ok", "suspect", "suspect", "reboot"]),
        # forged frames that do not keep to one timeline
        ([(600_000, 0.0), (9_000, 1.0), (10, 1.5), (9_500, 2.0)],
         ["ok", "suspect", "suspect", "suspect"]),
    ],
)  # fmt: skip
def test_reboot_evidence(frames: list[tuple[int, float]], verdicts: list[str]) -> None:
    rule = RebootEvidence(backstep_ms=3000, min_frames=3, min_span_s=1.0)
    accepted: int | None = None
    got = []
    for boot_ms, t in frames:
        verdict = rule.observe(accepted, boot_ms, t)
        got.append(verdict)
        if verdict in ("ok", "reboot"):
            accepted = boot_ms if accepted is None or verdict == "reboot" else max(
                accepted, boot_ms
            )
    assert got == verdicts


def test_reboot_confirmed_at_once_by_a_booting_autopilot_only_when_suspected() -> None:
    rule = RebootEvidence()
    assert rule.booting() is False
    assert rule.observe(600_000, 200, 1.0) == "suspect"
    assert rule.booting() is True and not rule.suspected


def test_battery_one_low_frame_with_critical_is_nothing() -> None:
    rule = BatteryEvidence(low_pct=25.0, min_frames=3, min_span_s=2.0, alone_span_s=20.0)
    rule.reading(5.0, 0.0)
    rule.autopilot_agrees()
    rule.reading(80.0, 1.0)
    rule.reading(80.0, 2.0)
    assert not rule.confirmed(30.0) and not rule.low_readings


def test_battery_low_sustained_and_confirmed() -> None:
    rule = BatteryEvidence(low_pct=25.0, min_frames=3, min_span_s=2.0, alone_span_s=20.0)
    for t in (0.0, 1.0, 2.0):
        rule.reading(10.0, t)
    assert not rule.confirmed(2.0)  # low readings alone, not for long
    rule.autopilot_agrees()
    assert rule.confirmed(2.0)


def test_battery_low_alone_for_long_is_enough() -> None:
    rule = BatteryEvidence(low_pct=25.0, min_frames=3, min_span_s=2.0, alone_span_s=20.0)
    for t in range(0, 21):
        rule.reading(10.0, float(t))
    assert rule.confirmed(20.0)


@pytest.mark.parametrize(
    ("signals", "ended_by"),
    [
        ([("reached", 1, 0.0)], None),  # forged MISSION_ITEM_REACHED alone
        ([("current", 2, 0.0)], None),  # one forged MISSION_CURRENT
        ([("current", 2, 0.0), ("current", 1, 1.0), ("current", 2, 2.0)], None),  # flicker
        ([("reached", 1, 0.0), ("current", 1, 1.0), ("current", 2, 2.0)], None),  # contradicted
        # a burst (any number of frames at once) is no evidence: it has no span
        ([("reached", 1, 5.0), ("current", 2, 5.0)], None),
        ([("reached", 1, 5.0)] + [("current", 2, 5.0 + k * 1e-3) for k in range(50)], None),
        ([("current", 2, 5.0), ("current", 3, 5.0), ("current", 4, 5.0)], None),
        # ... and the vehicle's own next MISSION_CURRENT cancels it
        ([("current", 2, 5.0), ("current", 3, 5.0), ("current", 1, 5.6), ("current", 2, 6.0)],
         None),
        ([("reached", 1, 0.0), ("current", 2, 0.1), ("current", 2, 1.1)], "reached"),  # real
        ([("reached", 1, 0.0), ("current", 2, 0.9)], "reached"),  # real, slower stream
        ([("current", 2, 0.0), ("current", 2, 1.0)], "mission_current"),  # REACHED lost
        ([("reached", 0, 0.0), ("current", 2, 1.0), ("current", 2, 2.0)], "mission_current"),
    ],
)  # fmt: skip
def test_loiter_end_evidence(
    signals: list[tuple[str, int, float]], ended_by: str | None
) -> None:
    rule = LoiterEndEvidence(1, current_seq=1)
    ends = 0
    for kind, seq, t_s in signals:
        observe = rule.observe_reached if kind == "reached" else rule.observe_current
        ends += observe(seq, t_s)
    assert rule.ended_by == ended_by and ends == (ended_by is not None)
    if ended_by is not None:
        assert rule.observe_current(3, 10.0) is False  # once


def test_loiter_end_ignores_the_previous_missions_current() -> None:
    rule = LoiterEndEvidence(1, current_seq=5)  # the old mission was on item 5
    assert not rule.observe_current(5, 0.0) and not rule.observe_current(5, 1.0)
    assert not rule.ended
    assert not rule.observe_current(1, 2.0)
    assert not rule.observe_current(2, 3.0)
    assert rule.observe_current(2, 4.0) and rule.ended_by == "mission_current"


PLANE = (1, 3)  # MAV_TYPE_FIXED_WING, MAV_AUTOPILOT_ARDUPILOTMEGA


@pytest.mark.parametrize(
    ("beats", "confirmed_at"),
    [
        ([("a", PLANE, 0, 0.0), ("a", PLANE, 9, 1.0), ("a", PLANE, 18, 2.0)], 2),  # real
        ([("a", PLANE, 0, 0.0), ("a", PLANE, 1, 0.0), ("a", PLANE, 2, 0.0)], None),  # burst
        ([("a", PLANE, 5, 0.0), ("a", PLANE, 5, 1.0), ("a", PLANE, 5, 2.0)], None),  # replay
        ([("a", PLANE, 0, 0.0), ("a", (2, 3), 1, 1.0), ("a", PLANE, 2, 2.0)], None),  # type
        ([("a", PLANE, 0, 0.0), ("a", (1, 12), 1, 1.0), ("a", PLANE, 2, 2.0)], None),  # AP
        ([("a", PLANE, 0, 0.0), ("b", PLANE, 1, 1.0), ("a", PLANE, 2, 2.0)], None),  # places
        ([("a", PLANE, 0, 0.0), ("a", PLANE, 1, 6.0), ("a", PLANE, 2, 7.0)], None),  # gap
        # a duplicate in between adds nothing and breaks nothing
        ([("a", PLANE, 0, 0.0), ("a", PLANE, 0, 0.5), ("a", PLANE, 1, 1.0),
          ("a", PLANE, 2, 2.0)], 3),
        # the count starts again from a heartbeat that broke it
        ([("a", (2, 3), 0, 0.0), ("a", PLANE, 1, 1.0), ("a", PLANE, 2, 2.0),
          ("a", PLANE, 3, 3.0)], 3),
    ],
)  # fmt: skip
def test_new_system_evidence(
    beats: list[tuple[str, tuple[int, int], int, float]], confirmed_at: int | None
) -> None:
    rule = NewSystemEvidence()
    verdicts = [rule.heartbeat(42, place, sig, seq, t) for place, sig, seq, t in beats]
    first = verdicts.index(True) if True in verdicts else None
    assert first == confirmed_at, verdicts
    assert rule.pending == 1 and rule.heartbeats == len(beats)
    rule.forget(42)
    assert rule.pending == 0


def test_new_system_evidence_is_kept_per_system_id() -> None:
    rule = NewSystemEvidence()
    for k in range(3):  # two system ids interleaved on one place: each its own count
        assert not rule.heartbeat(7, "a", PLANE, k, float(k)) or k == 2
        assert not rule.heartbeat(8, "a", PLANE, k, float(k) + 0.5) or k == 2
    assert rule.heartbeat(7, "a", PLANE, 3, 3.0) and rule.heartbeat(8, "a", PLANE, 3, 3.5)
    assert rule.restarts == 0


def test_modes() -> None:
    assert ArduPlaneMode.AUTO == 10 and mode_name(5) == "FBWA"
    assert mode_name(99) == "MODE_99"
    assert {ArduPlaneMode.AUTO, ArduPlaneMode.GUIDED} == TAKEN_MODES
