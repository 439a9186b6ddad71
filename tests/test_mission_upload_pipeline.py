"""A pipelined upload on a constrained link (``MissionUpload``'s ``window``, issue 28): the
items go ahead of the vehicle's requests, which ArduPlane takes when each is the one it
expects next. Rules sans-IO, then against the built-in simulator's ArduPlane mission
protocol, with chosen frames lost and with random loss."""

from __future__ import annotations

import random
from typing import Any

import pytest
from test_mission_upload_resend import (
    GCS_COMP,
    GCS_SYS,
    VEH_COMP,
    VEH_SYS,
    ack,
    items,
    lose_once,
    request,
    run,
    sent_seqs,
    sim,
    verified,
)

from domain.errors import LocalProtocolError
from groundstation.mavlink.codec import mavlink2 as M
from groundstation.mavlink.mission_transfer import Send
from groundstation.mavlink.mission_upload import MissionUpload, UploadState

WINDOW = 8


def upload(window: int = WINDOW, timeout_s: float = 0.3, **kw: Any) -> MissionUpload:
    return MissionUpload(VEH_SYS, VEH_COMP, items(), timeout_s=timeout_s, own_system=GCS_SYS,
                         own_component=GCS_COMP, resend_items=True, window=window, **kw)


# ---------------------------------------------------------------------------- sans-IO


def test_item_0_goes_with_the_count_and_the_window_once_the_upload_is_open() -> None:
    n = len(items())
    up = upload(window=3)
    out = up.start(0.0)
    assert [a.msg.get_type() for a in out if isinstance(a, Send)] == [
        "MISSION_COUNT", "MISSION_ITEM_INT"]
    assert sent_seqs(out) == [0]
    # the first request shows the upload open: the window goes
    assert sent_seqs(up.receive(request(0), 0.2)) == [1, 2]
    # requests for items already sent only move the window on
    assert sent_seqs(up.receive(request(1), 0.4)) == [3]
    assert sent_seqs(up.receive(request(2), 0.4)) == [4]
    assert up.rtt_samples_s == [pytest.approx(0.2)]  # one sample: count -> first request
    assert n == 5 and up.state is UploadState.SENDING_ITEMS
    up.receive(request(3), 0.4)
    up.receive(request(4), 0.4)
    assert up.state is UploadState.WAITING_ACK
    up.receive(ack(M.MAV_MISSION_ACCEPTED), 0.2)
    assert up.result is not None and up.result.ok and up.items_sent == n


def test_invalid_sequence_resends_from_the_newest_request_once() -> None:
    up = upload()
    up.start(0.0)
    assert sent_seqs(up.receive(request(0), 0.2)) == [1, 2, 3, 4]
    up.receive(request(1), 0.2)  # item 1 is held; item 2 was lost
    assert sent_seqs(up.receive(request(2), 0.2)) == []
    assert sent_seqs(up.receive(ack(M.MAV_MISSION_INVALID_SEQUENCE), 0.2)) == [2, 3, 4]
    # the rest of the batch answers alike: nothing more
    assert sent_seqs(up.receive(ack(M.MAV_MISSION_INVALID_SEQUENCE), 0.2)) == []
    assert sent_seqs(up.receive(ack(M.MAV_MISSION_INVALID_SEQUENCE), 0.2)) == []
    # progress, and a new loss further on: again once
    up.receive(request(3), 0.4)
    assert sent_seqs(up.receive(ack(M.MAV_MISSION_INVALID_SEQUENCE), 0.4)) == [3, 4]


def test_the_vehicles_own_re_request_resends_from_there() -> None:
    up = upload()
    up.start(0.0)
    up.receive(request(0), 0.2)
    up.receive(request(1), 0.2)
    assert sent_seqs(up.receive(request(1), 1.2)) == [1, 2, 3, 4]


def test_silence_before_any_request_sends_count_and_item_0_again() -> None:
    up = upload()
    up.start(0.0)
    again = up.poll(0.31)
    assert [a.msg.get_type() for a in again if isinstance(a, Send)] == [
        "MISSION_COUNT", "MISSION_ITEM_INT"]
    assert sent_seqs(again) == [0]


def test_silence_once_every_item_went_probes_and_never_sends_a_stray_item() -> None:
    up = upload()
    up.start(0.0)
    up.receive(request(0), 0.2)
    up.receive(request(2), 0.2)  # (the other requests lost)
    out = up.poll(0.6)
    assert [a.msg.get_type() for a in out if isinstance(a, Send)] == ["MISSION_REQUEST_LIST"]
    # DENIED: still receiving, so the items from the newest request go again
    denied = up.receive(ack(M.MAV_MISSION_DENIED), 0.8)
    assert sent_seqs(denied) == [2, 3, 4]


def test_an_error_ack_is_only_noted() -> None:
    up = upload()
    up.start(0.0)
    assert up.receive(ack(M.MAV_MISSION_ERROR), 0.2) == []
    assert not up.done
    assert up.receive(ack(M.MAV_MISSION_ERROR), 0.2) == []
    assert not up.done


def test_accepted_before_every_item_went_is_a_protocol_error() -> None:
    up = upload()
    up.start(0.0)
    up.receive(ack(M.MAV_MISSION_ACCEPTED), 0.2)
    assert up.result is not None and not up.result.ok


def test_window_is_checked() -> None:
    with pytest.raises(LocalProtocolError):
        upload(window=0)


# ----------------------------------------------------------------- against the simulator


def test_a_pipelined_upload_is_one_exchange_where_the_plain_one_is_one_per_item() -> None:
    took = {}
    for window in (1, WINDOW):
        lb = sim()
        up = upload(window=window)
        took[window] = run(lb, up, lambda msg, gcs: False)
        assert up.result is not None and up.result.ok, up.result
        assert up.items_sent == len(items())  # no item twice
        assert verified(lb)
    # 20 ms steps, one exchange a step: the count, then one per item (plain), or the count
    # with item 0, then every other item at once (pipelined)
    assert took[1] >= 0.02 * len(items()) and took[WINDOW] <= 0.041, took


LOSSES = [("MISSION_COUNT", 0, True), ("MISSION_REQUEST", 0, False),
          ("MISSION_ACK", 0, False)] + [
    ("MISSION_ITEM_INT", seq, True) for seq in range(5)] + [
    ("MISSION_REQUEST", seq, False) for seq in range(1, 5)]


@pytest.mark.parametrize(("kind", "seq", "from_gcs"), LOSSES)
def test_one_lost_frame_costs_at_most_two_timeouts(kind: str, seq: int, from_gcs: bool) -> None:
    lb = sim()
    up = upload()
    took = run(lb, up, lose_once(kind, seq, from_gcs))
    assert up.result is not None and (up.result.ok or up.result.maybe_stored), up.result
    assert verified(lb)
    assert took <= 0.7, (took, up.result.notes)
    # no stray item (an ERROR answer), but item 0 when the count alone was lost
    strays = sum("MAV_MISSION_ERROR" in note for note in up.result.notes)
    assert strays == (1 if kind == "MISSION_COUNT" else 0), up.result.notes


def lossy(rng: random.Random, loss: float) -> Any:
    return lambda msg, gcs: rng.random() < loss


def test_under_random_loss_a_pipelined_upload_verifies_as_often_and_sooner() -> None:
    """25 % of the frames lost each way, 120 uploads each way of sending: what ends ``ok``
    is always what the vehicle holds; the pipelined uploads end with a mission the
    verifying download finds (``ok``, or ``maybe_stored`` after a lost final ACK) at least
    as often as the plain ones, in under 0.7 of their mission time in total."""
    outcome: dict[int, tuple[int, float]] = {}
    for window in (1, WINDOW):
        held = 0
        total_s = 0.0
        for seed in range(120):
            lb = sim()
            up = upload(window=window)
            total_s += run(lb, up, lossy(random.Random(seed), 0.25))
            assert up.result is not None
            holds = verified(lb)
            if up.result.ok:
                assert holds, (seed, up.result.notes)
            held += (up.result.ok or up.result.maybe_stored) and holds
        outcome[window] = (held, total_s)
    assert outcome[WINDOW][0] >= outcome[1][0] >= 110, outcome
    assert outcome[WINDOW][1] < 0.7 * outcome[1][1], outcome
