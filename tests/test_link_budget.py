"""A traffic budget per link (docs/links.md, "Over a telemetry radio"): the round-trip
estimator and the timeouts it gives, the radio's txbuf hold, the stream rates per capacity,
the pipelined verifying download. Sans-IO machines, and the port on virtual time."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest
from test_mission_transfer_fake import GCS_COMP, GCS_SYS, VEH_COMP, VEH_SYS, mission, via_wire
from test_vehicle_port import Rig, run, settle

from domain.modes import ArduPlaneMode
from groundstation.daemon.config import parse_link_rate
from groundstation.mavlink.codec import mavlink2
from groundstation.mavlink.link_budget import (
    MAX_HOLD_S,
    TELEMETRY_SHARE,
    LinkBudget,
    RttEstimator,
    stream_plan,
)
from groundstation.mavlink.mission_download import MissionDownload
from groundstation.mavlink.mission_transfer import Send
from groundstation.mavlink.mission_upload import MissionUpload

M = mavlink2


def _radio_status(txbuf: int) -> Any:
    return via_wire(M.MAVLink_radio_status_message(120, 110, txbuf, 25, 30, 0, 0), 51, 68)


def _sends(actions: list[Any]) -> list[Any]:
    return [a.msg for a in actions if isinstance(a, Send)]


# --------------------------------------------------------------------------- RTT


def test_rtt_estimator_follows_rfc6298() -> None:
    rtt = RttEstimator(floor_s=1.5)
    assert rtt.rto_s is None and rtt.timeout_s() == 1.5  # nothing measured: the floor
    rtt.sample(0.5)  # first: SRTT = R, RTTVAR = R / 2, RTO = SRTT + 4 RTTVAR
    assert (rtt.srtt_s, rtt.rttvar_s, rtt.rto_s) == pytest.approx((0.5, 0.25, 1.5))
    rtt.sample(1.0)  # RTTVAR = 3/4 0.25 + 1/4 |0.5 - 1.0|; SRTT = 7/8 0.5 + 1/8 1.0
    assert (rtt.srtt_s, rtt.rttvar_s) == pytest.approx((0.5625, 0.3125))
    assert rtt.rto_s == pytest.approx(0.5625 + 4 * 0.3125)
    rtt.sample(float("nan"))
    rtt.sample(-1.0)
    assert rtt.samples == 2
    for _ in range(50):
        rtt.sample(3.0)
    assert rtt.timeout_s() == pytest.approx(3.0, abs=0.1)  # a slow link: above the floor
    for _ in range(50):
        rtt.sample(30.0)
    assert rtt.timeout_s() == 8.0  # never beyond the ceiling (ArduPlane's upload timeout)


def test_upload_samples_round_trips_but_never_a_resent_request() -> None:
    """Karn's rule: the answer to a MISSION_COUNT sent twice cannot be timed."""
    up = MissionUpload(VEH_SYS, VEH_COMP, mission(), timeout_s=1.5, own_system=GCS_SYS,
                       own_component=GCS_COMP)
    up.start(0.0)
    assert _sends(up.poll(1.5))[0].get_type() == "MISSION_COUNT"  # silence: resent
    req = M.MAVLink_mission_request_message(GCS_SYS, GCS_COMP, 0, 0)
    assert _sends(up.receive(via_wire(req, VEH_SYS, VEH_COMP), 1.6))  # item 0 goes at 1.6
    assert up.rtt_samples_s == []  # the count went twice: no sample
    req = M.MAVLink_mission_request_message(GCS_SYS, GCS_COMP, 1, 0)
    up.receive(via_wire(req, VEH_SYS, VEH_COMP), 2.0)
    assert up.rtt_samples_s == pytest.approx([0.4])  # item 0 sent once, answered 0.4 s later
    up.receive(via_wire(req, VEH_SYS, VEH_COMP), 3.0)  # the vehicle's own re-request
    assert up.rtt_samples_s == pytest.approx([0.4])


def test_a_slow_link_gets_no_duplicate_requests() -> None:
    """A 2 s round trip, longer than the 1.5 s configured timeout: once the link's RTT is
    measured, the verifying download asks for nothing twice."""

    async def main(budget: LinkBudget | None) -> list[str]:
        rig = Rig(latency_s=2.0, budget=lambda: budget)
        rig.plane.mission = [*mission()]
        assert (await rig.port.download()).ok
        return rig.kinds()

    budget = LinkBudget(timeout_floor_s=1.5)
    for _ in range(3):
        budget.rtt.sample(2.0)
    kinds = run(main(budget))
    assert kinds.count("MISSION_REQUEST_LIST") == 1
    assert kinds.count("MISSION_REQUEST_INT") == len(mission())


def test_a_radio_link_pipelines_the_verifying_download() -> None:
    """On a constrained link the download asks for every item at once (ArduPlane answers
    each MISSION_REQUEST_INT on its own): two round trips instead of one per item."""
    down = MissionDownload(VEH_SYS, VEH_COMP, window=8, timeout_s=1.0, own_system=GCS_SYS)
    down.start(0.0)
    count = via_wire(M.MAVLink_mission_count_message(GCS_SYS, GCS_COMP, 3, 0), VEH_SYS, VEH_COMP)
    asked = _sends(down.receive(count, 0.3))
    assert [(m.get_type(), m.seq) for m in asked] == [("MISSION_REQUEST_INT", s) for s in range(3)]
    items = [it.to_message(GCS_SYS, GCS_COMP) for it in mission()[:3]]
    assert down.receive(via_wire(items[2], VEH_SYS, VEH_COMP), 0.6) == []  # any order
    assert [m.seq for m in _sends(down.poll(1.6))] == [0, 1]  # silence: what is missing
    down.receive(via_wire(items[0], VEH_SYS, VEH_COMP), 1.8)
    actions = down.receive(via_wire(items[1], VEH_SYS, VEH_COMP), 1.9)
    assert down.done and down.result is not None and down.result.ok
    assert [m.get_type() for m in _sends(actions)] == ["MISSION_ACK"]
    assert [it.seq for it in down.result.items or ()] == [0, 1, 2]
    assert down.rtt_samples_s == pytest.approx([0.3, 0.3])  # the count, the first item


# --------------------------------------------------------------------------- txbuf hold


def test_a_full_radio_buffer_holds_an_upload_but_never_a_mode_change() -> None:
    async def main() -> None:
        budget = LinkBudget(timeout_floor_s=1.5)
        rig = Rig(budget=lambda: budget)
        loop = asyncio.get_running_loop()
        for t_s, txbuf in ((0.0, 30), (1.0, 20), (2.0, 40), (3.0, 90)):
            loop.call_at(t_s, lambda txbuf=txbuf: budget.on_radio_status(
                rig.clock.now_s(), _radio_status(txbuf)))
        await settle()
        assert budget.congested(rig.clock.now_s())
        mode = await rig.port.set_mode(int(ArduPlaneMode.RTL))  # safety: at once
        assert mode == M.MAV_RESULT_ACCEPTED and rig.sent[0][0] < 0.1
        assert (await rig.port.upload(mission())).ok
        count_at = next(t for t, m in rig.sent if m.get_type() == "MISSION_COUNT")
        assert 3.0 <= count_at <= 3.2  # held until the radio reported 90 % free
        assert budget.holds == 1 and budget.held_s == pytest.approx(count_at, abs=0.15)

    run(main())


def test_a_radio_stuck_full_holds_an_upload_only_so_long() -> None:
    async def main() -> None:
        budget = LinkBudget(timeout_floor_s=1.5)
        rig = Rig(budget=lambda: budget)
        loop = asyncio.get_running_loop()
        for i in range(30):  # 10 %, once a second, for ever
            loop.call_at(float(i), lambda: budget.on_radio_status(
                rig.clock.now_s(), _radio_status(10)))
        await settle()
        assert (await rig.port.upload(mission())).ok
        count_at = next(t for t, m in rig.sent if m.get_type() == "MISSION_COUNT")
        assert MAX_HOLD_S <= count_at <= MAX_HOLD_S + 0.2

    run(main())


def test_a_stale_or_unreadable_radio_report_holds_nothing() -> None:
    budget = LinkBudget()
    assert budget.on_radio_status(0.0, object()) is None and budget.radio is None
    budget.on_radio_status(0.0, _radio_status(10))
    assert budget.congested(4.0) and not budget.congested(6.0)  # stale after 5 s


# --------------------------------------------------------------------------- streams


def test_stream_rates_fit_a_share_of_the_link() -> None:
    pos = M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT
    unlimited = stream_plan(2.0, None)  # as floe always asked: groups at 1 Hz, position 2 Hz
    assert unlimited.intervals == ((pos, 2.0),)
    assert dict(unlimited.groups)[M.MAV_DATA_STREAM_POSITION] == 2
    radio = stream_plan(2.0, 24_000.0)
    rates = dict(radio.intervals)
    assert rates[pos] == 2.0 and rates[M.MAVLINK_MSG_ID_SYS_STATUS] == 1.0
    assert rates[M.MAVLINK_MSG_ID_GPS_RAW_INT] == 0.5  # the panel's GPS fix, slowly
    assert radio.bytes_s <= TELEMETRY_SHARE * 24_000 / 8
    slow = stream_plan(2.0, 4_800.0)  # a 4 800-baud serial link
    assert slow.bytes_s == pytest.approx(TELEMETRY_SHARE * 4_800 / 8)
    assert dict(slow.intervals)[M.MAVLINK_MSG_ID_SYS_STATUS] < 1.0
    assert dict(slow.intervals)[pos] == 2.0  # the position is scaled last
    tiny = stream_plan(5.0, 1_200.0)
    assert dict(tiny.intervals)[pos] == 1.0  # never below 1 Hz


def test_the_port_asks_a_constrained_link_only_for_what_floe_reads() -> None:
    async def main() -> list[tuple[int, float]]:
        budget = LinkBudget(configured_bps=57_600.0)
        rig = Rig(budget=lambda: budget)
        rig.port.request_rates(2.0)
        first = len(rig.sent)
        rig.port.request_rates(2.0)  # the same plan again soon after: not sent again
        assert len(rig.sent) == first
        await settle(0.1)
        return [(int(m.param1), m.param2) for _, m in rig.sent
                if m.get_type() == "COMMAND_LONG" and m.command == M.MAV_CMD_SET_MESSAGE_INTERVAL]

    intervals = dict(run(main()))
    assert intervals[M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT] == pytest.approx(5e5)
    assert intervals[M.MAVLINK_MSG_ID_GPS_RAW_INT] == pytest.approx(2e6)  # 0.5 Hz
    assert intervals[M.MAVLINK_MSG_ID_SYSTEM_TIME] == -1  # never read: disabled
    assert intervals[M.MAVLINK_MSG_ID_ATTITUDE] == pytest.approx(2e6)


def test_link_rate_grammar() -> None:
    assert parse_link_rate("tcp:127.0.0.1:5760=64k") == ("tcp:127.0.0.1:5760", 64_000.0)
    assert parse_link_rate("/dev/ttyUSB0,57600=19200") == ("serial:/dev/ttyUSB0:57600", 19200.0)
    for bad in ("tcp:127.0.0.1:5760", "tcp:127.0.0.1:5760=fast", "tcp:127.0.0.1:5760=0",
                "=64k", "zmq:1.2.3.4:5=64k"):
        with pytest.raises(ValueError, match="link rate"):
            parse_link_rate(bad)


def test_a_radio_link_verifies_an_upload_in_one_round_trip() -> None:
    """With the count just uploaded, the item requests go with MISSION_REQUEST_LIST; a
    vehicle holding fewer items fails the download (and so the verification)."""
    down = MissionDownload(VEH_SYS, VEH_COMP, window=8, expect_count=3, own_system=GCS_SYS)
    asked = _sends(down.start(0.0))
    assert [m.get_type() for m in asked] == ["MISSION_REQUEST_LIST"] + 3 * ["MISSION_REQUEST_INT"]
    items = [it.to_message(GCS_SYS, GCS_COMP) for it in mission()[:3]]
    for seq in (0, 1):  # the items may come before the count
        assert down.receive(via_wire(items[seq], VEH_SYS, VEH_COMP), 0.3) == []
    count = via_wire(M.MAVLink_mission_count_message(GCS_SYS, GCS_COMP, 3, 0), VEH_SYS, VEH_COMP)
    assert down.receive(count, 0.3) == []
    down.receive(via_wire(items[2], VEH_SYS, VEH_COMP), 0.3)
    assert down.result is not None and down.result.ok and len(down.result.items or ()) == 3

    short = MissionDownload(VEH_SYS, VEH_COMP, window=8, expect_count=3, own_system=GCS_SYS)
    short.start(0.0)
    two = via_wire(M.MAVLink_mission_count_message(GCS_SYS, GCS_COMP, 2, 0), VEH_SYS, VEH_COMP)
    short.receive(two, 0.3)
    nack = M.MAVLink_mission_ack_message(GCS_SYS, GCS_COMP, M.MAV_MISSION_INVALID_SEQUENCE, 0)
    short.receive(via_wire(nack, VEH_SYS, VEH_COMP), 0.3)
    assert short.result is not None and not short.result.ok


def test_a_lost_final_ack_costs_two_timeouts_on_a_radio_link() -> None:
    """ArduPlane sends its final MISSION_ACK once: with ``ack_retries`` 1 the upload ends
    after two silent timeouts as maybe stored (the download then verifies it)."""
    items = mission()
    up = MissionUpload(VEH_SYS, VEH_COMP, items, timeout_s=1.0, own_system=GCS_SYS,
                       own_component=GCS_COMP, ack_retries=1)
    up.start(0.0)
    for seq in range(len(items)):
        req = M.MAVLink_mission_request_message(GCS_SYS, GCS_COMP, seq, 0)
        up.receive(via_wire(req, VEH_SYS, VEH_COMP), 0.1 * (seq + 1))
    t_last = 0.1 * len(items)
    assert up.poll(t_last + 1.0) == [] and not up.done  # one retry
    up.poll(t_last + 2.0)
    assert up.result is not None and up.result.maybe_stored
