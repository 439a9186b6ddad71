"""An upload on a constrained link resends a lost item itself (``MissionUpload``'s
``resend_items``, issue 28) instead of waiting for ArduPlane's re-request, every
1 s + stream slowdown: sans-IO rules, then against the built-in simulator's ArduPlane
mission protocol with chosen frames lost."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from test_mission_transfer_fake import via_wire

from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import mavlink2 as M
from groundstation.mavlink.mission_download import MissionDownload
from groundstation.mavlink.mission_items import (
    LoiterUnlimited,
    Waypoint,
    build_mission_items,
)
from groundstation.mavlink.mission_transfer import Action, Send, TransferCode
from groundstation.mavlink.mission_upload import MissionUpload
from groundstation.mavlink.mission_verify import compare_missions
from sitl.loopback import Loopback
from sitl.vehicle import SimVehicle, VehicleConfig

ORIGIN = GeoOrigin(78.93, 11.92)
GCS_SYS, GCS_COMP, VEH_SYS, VEH_COMP = 255, 190, 1, 1


def items() -> list[Any]:
    return build_mission_items(
        [Waypoint(1200.0, 0.0, 100.0), Waypoint(1200.0, 600.0, 100.0),
         Waypoint(600.0, 600.0, 100.0), LoiterUnlimited(600.0, 600.0, 100.0, radius_m=120)],
        ORIGIN,
    )


def upload(resend: bool, timeout_s: float = 0.4) -> MissionUpload:
    return MissionUpload(VEH_SYS, VEH_COMP, items(), timeout_s=timeout_s, own_system=GCS_SYS,
                         own_component=GCS_COMP, resend_items=resend)


def request(seq: int) -> Any:
    return via_wire(M.MAVLink_mission_request_message(GCS_SYS, GCS_COMP, seq, 0),
                    VEH_SYS, VEH_COMP)


def ack(kind: int) -> Any:
    return via_wire(M.MAVLink_mission_ack_message(GCS_SYS, GCS_COMP, kind, 0),
                    VEH_SYS, VEH_COMP)


def sent_seqs(actions: list[Action]) -> list[int]:
    return [int(a.msg.seq) for a in actions
            if isinstance(a, Send) and a.msg.get_type() == "MISSION_ITEM_INT"]


# ---------------------------------------------------------------------------- sans-IO


def test_silence_after_a_request_resends_that_item_only_when_asked_to() -> None:
    for resend, expected in ((True, [1]), (False, [])):
        up = upload(resend)
        up.start(0.0)
        up.receive(request(0), 0.1)
        assert sent_seqs(up.receive(request(1), 0.3)) == [1]
        assert sent_seqs(up.poll(0.71)) == expected  # one timeout of silence
        assert not up.done


def test_invalid_sequence_to_a_resent_item_sends_the_next_one_unasked() -> None:
    """The request for item 2 was lost: the copy of item 1 is answered INVALID_SEQUENCE,
    which says the vehicle holds 1 and waits for 2."""
    up = upload(True)
    up.start(0.0)
    up.receive(request(0), 0.1)
    up.receive(request(1), 0.3)
    assert sent_seqs(up.poll(0.71)) == [1]
    assert sent_seqs(up.receive(ack(M.MAV_MISSION_INVALID_SEQUENCE), 0.9)) == [2]
    assert up.items_pushed == 1
    # the vehicle asks for 3 and 4 as usual, then accepts: a success, every item delivered
    up.receive(request(3), 1.1)
    up.receive(request(4), 1.3)
    up.receive(ack(M.MAV_MISSION_ACCEPTED), 1.5)
    assert up.result is not None and up.result.code is TransferCode.SUCCESS


def test_invalid_sequence_after_a_newer_request_pushes_nothing() -> None:
    """A slow item, not a lost one: its request for the next came first (the radio keeps
    order), so the INVALID_SEQUENCE that answers the copy is only noted."""
    up = upload(True)
    up.start(0.0)
    up.receive(request(0), 0.1)
    up.receive(request(1), 0.3)
    up.poll(0.71)  # item 1 resent
    assert sent_seqs(up.receive(request(2), 0.8)) == [2]
    assert sent_seqs(up.receive(ack(M.MAV_MISSION_INVALID_SEQUENCE), 0.85)) == []
    assert up.items_pushed == 0 and not up.done


def test_invalid_sequence_without_a_resend_pushes_nothing() -> None:
    up = upload(True)
    up.start(0.0)
    up.receive(request(0), 0.1)
    assert sent_seqs(up.receive(ack(M.MAV_MISSION_INVALID_SEQUENCE), 0.2)) == []
    assert up.items_pushed == 0


def all_asked(up: MissionUpload) -> float:
    """Every item asked for and sent; the mission time of the last."""
    up.start(0.0)
    for seq in range(5):
        up.receive(request(seq), 0.1 * (seq + 1))
    return 0.5


def sends(actions: list[Action]) -> list[str]:
    return [a.msg.get_type() for a in actions if isinstance(a, Send)]


def test_silence_after_the_last_item_asks_with_a_list_request_not_a_stray_item() -> None:
    """ArduPlane done with the upload takes no stray item: silence there sends a
    MISSION_REQUEST_LIST (without ``resend_items``: nothing, as before)."""
    up = upload(True)
    t = all_asked(up)
    assert sends(up.poll(t + 0.41)) == ["MISSION_REQUEST_LIST"]
    quiet = upload(False)
    t = all_asked(quiet)
    assert sends(quiet.poll(t + 0.41)) == []


def test_a_count_answering_the_probe_ends_the_upload_as_maybe_stored() -> None:
    up = upload(True)
    t = all_asked(up)
    up.poll(t + 0.41)
    count = via_wire(M.MAVLink_mission_count_message(GCS_SYS, GCS_COMP, 5, 0), VEH_SYS,
                     VEH_COMP)
    up.receive(count, t + 0.6)
    assert up.result is not None and up.result.code is TransferCode.TIMEOUT
    assert up.result.maybe_stored and "final MISSION_ACK was lost" in up.result.message


def test_denied_answering_the_probe_resends_the_last_item() -> None:
    up = upload(True)
    t = all_asked(up)
    up.poll(t + 0.41)
    assert sent_seqs(up.receive(ack(M.MAV_MISSION_DENIED), t + 0.6)) == [4]
    up.receive(ack(M.MAV_MISSION_ACCEPTED), t + 0.8)
    assert up.result is not None and up.result.code is TransferCode.SUCCESS


def test_denied_after_the_vehicle_asked_again_is_only_noted() -> None:
    """The vehicle re-requested the last item before it answered the probe: the item went
    already; the DENIED sends nothing and does not end the upload."""
    up = upload(True)
    t = all_asked(up)
    up.poll(t + 0.41)
    assert sent_seqs(up.receive(request(4), t + 0.5)) == [4]
    assert sends(up.receive(ack(M.MAV_MISSION_DENIED), t + 0.6)) == []
    assert not up.done
    up.receive(ack(M.MAV_MISSION_ACCEPTED), t + 0.8)
    assert up.result is not None and up.result.code is TransferCode.SUCCESS


def test_denied_without_a_probe_still_ends_the_upload() -> None:
    up = upload(True)
    all_asked(up)
    up.receive(ack(M.MAV_MISSION_DENIED), 0.6)
    assert up.result is not None and up.result.code is not TransferCode.SUCCESS


def test_a_count_without_a_probe_is_ignored() -> None:
    up = upload(True)
    t = all_asked(up)
    count = via_wire(M.MAVLink_mission_count_message(GCS_SYS, GCS_COMP, 5, 0), VEH_SYS,
                     VEH_COMP)
    assert up.receive(count, t + 0.1) == [] and not up.done


def test_resends_use_the_retry_budget() -> None:
    up = MissionUpload(VEH_SYS, VEH_COMP, items(), timeout_s=0.4, retries=2,
                       own_system=GCS_SYS, own_component=GCS_COMP, resend_items=True)
    up.start(0.0)
    up.receive(request(0), 0.1)
    assert sent_seqs(up.poll(0.51)) == [0]
    assert sent_seqs(up.poll(0.92)) == [0]
    up.poll(1.33)
    assert up.result is not None and up.result.code is TransferCode.TIMEOUT


# ----------------------------------------------------------------- against the simulator


def sim() -> Loopback:
    cfg = VehicleConfig(system_id=VEH_SYS, origin=ORIGIN, home_lat_deg=78.93,
                        home_lon_deg=11.92, airborne=True, fast_boot=True, launch_x_m=105.0,
                        launch_y_m=0.0, launch_heading_rad=1.5708)
    lb = Loopback(SimVehicle(cfg))
    lb.advance(3.0)
    lb.inbox.clear()
    return lb


Drop = Callable[[Any, bool], bool]
"""(message, sent by the ground station) -> lose it."""


def run(lb: Loopback, up: MissionUpload, drop: Drop, limit_s: float = 20.0) -> float:
    """Drive ``up`` against the simulator, 20 ms steps, losing what ``drop`` says; the
    mission s the upload took."""
    t0 = lb.t_s
    pending = up.start(lb.t_s)
    while not up.done and lb.t_s < t0 + limit_s:
        replies: list[Any] = []
        for action in pending:
            if isinstance(action, Send) and not drop(action.msg, True):
                replies += lb.send(action.msg)
        replies += lb.advance(0.02, 0.02)
        pending = []
        for msg in replies:
            if msg.get_type().startswith("MISSION") and drop(msg, False):
                continue
            pending += up.receive(msg, lb.t_s)
        pending += up.poll(lb.t_s)
    return lb.t_s - t0


def lose_once(kind: str, seq: int, from_gcs: bool) -> Drop:
    lost: list[bool] = []

    def drop(msg: Any, gcs: bool) -> bool:
        if (gcs == from_gcs and msg.get_type() == kind and getattr(msg, "seq", 0) == seq
                and not lost):
            lost.append(True)
            return True
        return False

    return drop


def verified(lb: Loopback) -> bool:
    down = MissionDownload(VEH_SYS, VEH_COMP, own_system=GCS_SYS, own_component=GCS_COMP)
    run(lb, down, lambda msg, gcs: False)  # type: ignore[arg-type]
    return (down.result is not None and down.result.items is not None
            and compare_missions(items(), list(down.result.items)) == [])


def test_a_lost_item_costs_one_timeout_not_arduplanes_second() -> None:
    took = {}
    for resend in (False, True):
        lb = sim()
        up = upload(resend, timeout_s=0.3)
        took[resend] = run(lb, up, lose_once("MISSION_ITEM_INT", 2, from_gcs=True))
        assert up.result is not None and up.result.ok, up.result
        assert verified(lb)
    # ArduPlane re-requests after 1 s of silence; the resend goes after one 0.3 s timeout
    assert took[False] >= 1.0 and took[True] <= took[False] - 0.5, took


def test_a_lost_request_is_found_out_by_invalid_sequence_and_the_next_item_pushed() -> None:
    took = {}
    for resend in (False, True):
        lb = sim()
        up = upload(resend, timeout_s=0.3)
        took[resend] = run(lb, up, lose_once("MISSION_REQUEST", 3, from_gcs=False))
        assert up.result is not None and up.result.ok, up.result
        assert up.items_pushed == (1 if resend else 0)
        assert verified(lb)
    assert took[False] >= 1.0 and took[True] <= took[False] - 0.5, took


def test_a_lost_final_ack_costs_one_timeout() -> None:
    took = {}
    for resend in (False, True):
        lb = sim()
        up = MissionUpload(VEH_SYS, VEH_COMP, items(), timeout_s=0.3, ack_retries=4,
                           own_system=GCS_SYS, own_component=GCS_COMP, resend_items=resend)
        took[resend] = run(lb, up, lose_once("MISSION_ACK", 0, from_gcs=False))
        assert up.result is not None and up.result.maybe_stored, up.result
        assert verified(lb)
    # without the probe: ack_retries + 1 timeouts; with it: one, and the COUNT's way back
    assert took[False] >= 1.5 and took[True] <= 0.8, took


def test_a_lost_last_item_is_sent_again_on_the_probes_denied() -> None:
    lb = sim()
    up = upload(True, timeout_s=0.3)
    took = run(lb, up, lose_once("MISSION_ITEM_INT", 4, from_gcs=True))
    assert up.result is not None and up.result.ok, up.result
    assert any("probe answered DENIED" in note for note in up.result.notes), up.result
    assert took < 1.0 and verified(lb)
