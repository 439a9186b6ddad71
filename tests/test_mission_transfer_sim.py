"""The protocol layer against the built-in simulator (sitl.SimVehicle over a Loopback).

What the daemon composes, in virtual time: upload -> download-verify -> set current, then
the telemetry reducer and the loiter-end detector follow the flight to the end of the timed
loiter. Every message goes through the real codec.
"""

from __future__ import annotations

from typing import Any

import pytest

from domain.geodesy import GeoOrigin
from groundstation.mavlink.mission_commands import MissionSetCurrent
from groundstation.mavlink.mission_download import MissionDownload
from groundstation.mavlink.mission_items import (
    LoiterTime,
    LoiterUnlimited,
    Takeoff,
    Waypoint,
    build_mission_items,
)
from groundstation.mavlink.mission_transfer import Finished, Send, TransferCode, TransferResult
from groundstation.mavlink.mission_upload import MissionUpload
from groundstation.mavlink.mission_verify import compare_missions
from groundstation.mavlink.telemetry import (
    LoiterEndDetector,
    ModeChanged,
    Rebooted,
    StatusText,
    VehicleTelemetry,
)
from sitl.loopback import Loopback
from sitl.vehicle import SimVehicle, VehicleConfig

ORIGIN = GeoOrigin(78.93, 11.92)


def make() -> Loopback:
    cfg = VehicleConfig(
        system_id=1,
        origin=ORIGIN,
        home_lat_deg=78.93,
        home_lon_deg=11.92,
        airborne=True,
        fast_boot=True,
        launch_x_m=105.0,
        launch_y_m=0.0,
        launch_heading_rad=1.5708,
    )
    lb = Loopback(SimVehicle(cfg))
    lb.advance(3.0)
    lb.inbox.clear()
    return lb


def drive(
    lb: Loopback,
    sm: Any,
    telemetry: VehicleTelemetry,
    limit_s: float = 30.0,
    reboot_after_sends: int | None = None,
    boot_s: float = 0.0,
) -> Any:
    """Run ``sm`` against the vehicle as the daemon's session would: every message also
    feeds the telemetry reducer, whose Rebooted event is reported to the state machine."""
    end = lb.t_s + limit_s
    pending = sm.start(lb.t_s)
    sends = 0
    deaf_until_s = -1.0
    while not sm.done and lb.t_s < end:
        replies: list[Any] = []
        for action in pending:
            if isinstance(action, Send):
                if lb.t_s >= deaf_until_s:
                    replies += lb.send(action.msg)
                sends += 1
                if sends == reboot_after_sends:
                    lb.vehicle.reboot(lb.t_s)
                    deaf_until_s = lb.t_s + boot_s  # a booting autopilot hears nothing
            else:
                assert isinstance(action, Finished)
        if not replies:
            replies = lb.advance(0.05, 0.05)
        pending = []
        for msg in replies:
            events = telemetry.receive(msg, lb.t_s)
            if not sm.done and any(isinstance(e, Rebooted) for e in events):
                pending += sm.notify_vehicle_rebooted(lb.t_s)
            if not sm.done:
                pending += sm.receive(msg, lb.t_s)
        if not sm.done:
            pending += sm.poll(lb.t_s)
    assert isinstance(sm.result, TransferResult)
    return sm.result


def test_upload_verify_set_current_and_loiter_end_on_the_simulator() -> None:
    lb = make()
    tel = VehicleTelemetry(1, ORIGIN)
    items = build_mission_items(
        [
            Waypoint(1200.0, 0.0, 100.0),
            LoiterTime(1200.0, 800.0, 100.0, time_s=30),
            LoiterUnlimited(1200.0, 800.0, 100.0, radius_m=120),
        ],
        ORIGIN,
    )
    up = drive(lb, MissionUpload(1, 1, items, own_system=255, own_component=190), tel)
    assert up.ok, up
    down = drive(lb, MissionDownload(1, 1, own_system=255), tel)
    assert down.ok and down.items is not None
    assert compare_missions(items, list(down.items)) == []
    current = tel.snapshot().mission_current_seq
    sc = drive(lb, MissionSetCurrent(1, 1, 1, known_current_seq=current), tel)
    assert sc.ok, sc
    detector = LoiterEndDetector(2, current_seq=tel.snapshot().mission_current_seq)
    texts: list[str] = []
    t_end = lb.t_s + 400.0
    while not detector.ended and lb.t_s < t_end:
        for msg in lb.advance(0.5, 0.1):
            for event in tel.receive(msg, lb.t_s):
                detector.feed(event)
                if isinstance(event, StatusText):
                    texts.append(event.text)
                assert not isinstance(event, ModeChanged) or event.new_name == "AUTO"
    assert detector.ended and detector.ended_by in ("reached", "mission_current")
    assert "Loiter time complete" in texts
    snap = tel.snapshot()
    assert snap.mode_name == "AUTO" and snap.armed is True
    assert snap.x_m is not None and snap.y_m is not None
    # the plane is on the loiter circle around (1200, 800), in local metres
    assert 60.0 < ((snap.x_m - 1200.0) ** 2 + (snap.y_m - 800.0) ** 2) ** 0.5 < 300.0


def test_takeoff_mission_round_trips() -> None:
    lb = make()
    tel = VehicleTelemetry(1, ORIGIN)
    items = build_mission_items(
        [Takeoff(alt_m=80.0), LoiterUnlimited(0.0, 600.0, 100.0, radius_m=150, clockwise=False)],
        ORIGIN,
    )
    assert drive(lb, MissionUpload(1, 1, items), tel).ok
    down = drive(lb, MissionDownload(1, 1), tel)
    assert down.ok and down.items is not None
    assert compare_missions(items, list(down.items)) == []
    assert down.items[2].param3 == -150.0


@pytest.mark.parametrize(
    ("boot_s", "code"),
    [
        # a real autopilot takes seconds to boot: the upload falls silent, and the first
        # telemetry after the boot shows time_boot_ms going back
        (3.0, TransferCode.VEHICLE_REBOOTED),
        # an instant reboot answers our next item as a stray one: MAV_MISSION_ERROR
        (0.0, TransferCode.REMOTE_ERROR),
    ],
)
def test_reboot_mid_upload(boot_s: float, code: TransferCode) -> None:
    lb = make()
    lb.advance(20.0)  # some uptime, so that the reboot sends time_boot_ms clearly back
    tel = VehicleTelemetry(1, ORIGIN)
    for msg in lb.advance(2.0):
        tel.receive(msg, lb.t_s)
    items = build_mission_items(
        [Waypoint(900.0, 0.0, 100.0), LoiterUnlimited(900.0, 0.0, 100.0, radius_m=120)], ORIGIN
    )
    result = drive(lb, MissionUpload(1, 1, items), tel, reboot_after_sends=2, boot_s=boot_s)
    assert result.code is code and result.retryable
    assert lb.vehicle.reboots == 1


def test_set_current_on_a_waypoint_passed_at_once_is_confirmed_at_once() -> None:
    """Issue 11 on the simulator: re-upload while flying to A=(0, 1500) a waypoint B just
    ahead of the plane (near y=300, heading north), within WP_RADIUS (90 m), so it is reached
    as soon as it starts; set current 1 is confirmed by the vehicle's MISSION_ITEM_REACHED 1
    after its ACK, without waiting out the 6 s window. (A waypoint behind the line through it
    normal to the old leg is not passed at once: ArduPlane's set_next_WP then starts the leg
    where the plane is; tests/test_sitl_mission.py.)"""
    lb = make()
    tel = VehicleTelemetry(1, ORIGIN)

    def to(x_m: float, y_m: float) -> list[Any]:
        return build_mission_items(
            [Waypoint(x_m, y_m, 100.0), LoiterUnlimited(x_m, y_m, 100.0, radius_m=120)], ORIGIN
        )

    assert drive(lb, MissionUpload(1, 1, to(0.0, 1500.0)), tel).ok
    assert drive(lb, MissionSetCurrent(1, 1, 1), tel).ok
    texts: list[str] = []
    while (tel.snapshot().y_m or 0.0) < 300.0:
        for msg in lb.advance(0.5, 0.1):
            tel.receive(msg, lb.t_s)
    assert tel.snapshot().mission_current_seq == 1
    items = to(0.0, (tel.snapshot().y_m or 0.0) + 60.0)
    assert drive(lb, MissionUpload(1, 1, items), tel).ok
    t0_s = lb.t_s
    original = tel.receive

    def keep_texts(msg: Any, t_s: float) -> list[Any]:
        events = original(msg, t_s)
        texts.extend(e.text for e in events if isinstance(e, StatusText))
        return events

    tel.receive = keep_texts  # type: ignore[method-assign]
    sc = drive(lb, MissionSetCurrent(1, 1, 1, known_current_seq=1), tel)
    assert sc.ok and sc.retries_used == 0, sc
    assert lb.t_s - t0_s < 0.5
    for msg in lb.advance(0.5, 0.1):  # ArduPlane's ACK and queued MISSION_CURRENT 1 came
        keep_texts(msg, lb.t_s)  # first: the waypoint is reached in the next navigation steps
    assert any(t.startswith("Reached waypoint #1") for t in texts), texts
    assert tel.snapshot().mission_current_seq == 2
