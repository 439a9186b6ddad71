"""Telemetry reducer: frames, units, events, robustness (messages go through the codec)."""

from __future__ import annotations

import dataclasses
import math

import pytest

from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, MAVLinkMessage, mavlink2
from groundstation.mavlink.telemetry import (
    Armed,
    BatteryBelowThreshold,
    Disarmed,
    InvalidTelemetry,
    LoiterEndDetector,
    MissionCurrentChanged,
    MissionItemReached,
    ModeChanged,
    PrearmChanged,
    Rebooted,
    StatusText,
    VehicleTelemetry,
    _evolve,
)
from groundstation.mavlink.telemetry_events import VehicleSnapshot

M = mavlink2
ORIGIN = GeoOrigin(78.9, 11.9, 0.0)  # Ny-Alesund: cos(lat) ~ 0.19


def wire(msg: MAVLinkMessage, sysid: int = 1, compid: int = 1) -> MAVLinkMessage:
    out = MavlinkDecoder().feed(MavlinkEncoder(sysid, compid).encode(msg))
    assert len(out) == 1
    return out[0]


def gpi(
    lat_e7: int = 789000000,
    lon_e7: int = 119000000,
    *,
    boot_ms: int = 1000,
    rel_mm: int = 100_000,
    vx: int = 0,
    vy: int = 0,
    hdg: int = 65535,
) -> MAVLinkMessage:
    return wire(
        M.MAVLink_global_position_int_message(
            boot_ms, lat_e7, lon_e7, rel_mm + 5000, rel_mm, vx, vy, 0, hdg
        )
    )


def heartbeat(
    mode: int,
    armed: bool = False,
    *,
    sysid: int = 1,
    compid: int = 1,
    mav_type: int = 1,
    autopilot: int = 3,
) -> MAVLinkMessage:
    base = 1 | (128 if armed else 0)
    return wire(M.MAVLink_heartbeat_message(mav_type, autopilot, base, mode, 4, 3), sysid, compid)


def fresh() -> VehicleTelemetry:
    return VehicleTelemetry(1, ORIGIN)


@pytest.mark.parametrize(
    ("hdg_cdeg", "psi_rad"),
    [
        (0, math.pi / 2),
        (4500, math.pi / 4),
        (9000, 0.0),
        (18000, -math.pi / 2),
        (27000, -math.pi),
        (31500, 3 * math.pi / 4),
        (35999, math.pi / 2 + math.radians(0.01)),
    ],
)
def test_heading_from_global_position_int(hdg_cdeg: int, psi_rad: float) -> None:
    tel = fresh()
    assert tel.receive(gpi(hdg=hdg_cdeg), 1.0) == []
    got = tel.snapshot().heading_rad
    assert got is not None
    assert math.isclose(math.remainder(got - psi_rad, 2 * math.pi), 0.0, abs_tol=1e-9)
    assert -math.pi <= got < math.pi


def test_heading_from_vfr_hud_and_attitude() -> None:
    tel = fresh()
    tel.receive(wire(M.MAVLink_vfr_hud_message(21.5, 22.0, 90, 50, 100.0, 0.0)), 1.0)
    snap = tel.snapshot()
    assert snap.heading_rad == pytest.approx(0.0) and snap.speed_m_s == 22.0
    assert snap.airspeed_m_s == 21.5
    tel.receive(wire(M.MAVLink_attitude_message(2000, 0.0, 0.0, -math.pi / 2, 0, 0, 0)), 2.0)
    assert abs(tel.snapshot().heading_rad or 0.0) == pytest.approx(math.pi)  # west
    tel.receive(wire(M.MAVLink_attitude_message(3000, 0.0, 0.0, math.pi / 6, 0, 0, 0)), 3.0)
    assert tel.snapshot().heading_rad == pytest.approx(math.pi / 3)  # N30E = 60 deg from E


def _wgs84_offset(lat_deg: float, east_m: float, north_m: float) -> tuple[float, float]:
    """Independent small-offset geodesy: meridional (M) and prime-vertical (N) radii."""
    a, f = 6378137.0, 1 / 298.257223563
    e2 = f * (2 - f)
    s2 = math.sin(math.radians(lat_deg)) ** 2
    n_radius = a / math.sqrt(1 - e2 * s2)
    m_radius = a * (1 - e2) / (1 - e2 * s2) ** 1.5
    dlat = math.degrees(north_m / m_radius)
    dlon = math.degrees(east_m / (n_radius * math.cos(math.radians(lat_deg))))
    return dlat, dlon


def test_position_at_78_9_north_has_cos_lat() -> None:
    tel = fresh()
    dlat, dlon = _wgs84_offset(78.9, 1000.0, 500.0)
    lat_e7 = round((78.9 + dlat) * 1e7)
    lon_e7 = round((11.9 + dlon) * 1e7)
    tel.receive(gpi(lat_e7, lon_e7, rel_mm=120_500, vx=-300, vy=2200), 1.0)
    snap = tel.snapshot()
    assert snap.x_m == pytest.approx(1000.0, abs=0.5)  # no cos(lat): ~192 m or ~5200 m
    assert snap.y_m == pytest.approx(500.0, abs=0.5)
    assert snap.alt_m == pytest.approx(120.5)
    assert (snap.ve_m_s, snap.vn_m_s) == (22.0, -3.0)  # vx is north, vy is east
    assert snap.speed_m_s == pytest.approx(math.hypot(22.0, 3.0))
    assert snap.course_rad == pytest.approx(math.atan2(-3.0, 22.0))
    assert snap.last_position_s == 1.0


def test_no_fix_zero_position_not_stored_and_not_an_error() -> None:
    tel = fresh()
    assert tel.receive(gpi(0, 0), 1.0) == []
    assert tel.snapshot().x_m is None


def test_chunked_statustext_reassembled() -> None:
    tel = fresh()
    text = "PreArm: " + "x" * 80 + " END"  # 92 chars: two chunks of 50 + 42
    chunks = [text[:50], text[50:]]
    assert tel.receive(wire(M.MAVLink_statustext_message(4, chunks[1].encode(), 7, 1)), 1.0) == []
    events = tel.receive(wire(M.MAVLink_statustext_message(4, chunks[0].encode(), 7, 0)), 1.1)
    assert events == [StatusText(1.1, 4, text)]
    single = tel.receive(wire(M.MAVLink_statustext_message(6, b"Mission: 2 LoiterTime")), 2.0)
    assert single == [StatusText(2.0, 6, "Mission: 2 LoiterTime")]


def test_chunked_statustext_missing_chunk_flushed_incomplete() -> None:
    tel = fresh()
    tel.receive(wire(M.MAVLink_statustext_message(3, b"a" * 50, 9, 0)), 1.0)
    tel.receive(wire(M.MAVLink_statustext_message(3, b"tail", 9, 2)), 1.1)
    assert tel.tick(2.0) == []
    events = tel.tick(3.5)
    assert events == [StatusText(3.5, 3, "a" * 50 + "[...]" + "tail", complete=False)]
    assert tel.tick(10.0) == []  # reported once


def test_reboot_detected_when_time_boot_goes_back_and_stays_back() -> None:
    # issue 10: one frame with a smaller time_boot_ms is a suspicion, not a reboot; the
    # frames after it keeping to the new timeline (3 over >= 1 s) confirm it
    tel = fresh()
    tel.receive(heartbeat(10, armed=True), 0.5)
    tel.receive(wire(M.MAVLink_mission_current_message(3, 5)), 0.6)
    tel.receive(gpi(boot_ms=600_000), 1.0)
    assert tel.receive(gpi(boot_ms=599_500), 1.1) == []  # UDP reordering: not a reboot
    assert tel.stale_messages == 1
    assert tel.receive(gpi(boot_ms=4_000), 30.0) == []
    assert tel.snapshot().reboot_suspected and tel.snapshot().time_boot_ms == 600_000
    assert tel.receive(wire(M.MAVLink_system_time_message(0, 4_500)), 30.5) == []
    events = tel.receive(wire(M.MAVLink_system_time_message(0, 5_000)), 31.0)
    assert events == [Rebooted(31.0, 600_000, 5_000)]
    snap = tel.snapshot()
    assert snap.time_boot_ms == 5_000 and snap.mission_current_seq is None and snap.mode is None
    assert not snap.reboot_suspected
    # the position after the reboot is accepted (not treated as stale)
    assert tel.receive(gpi(789_100_000, boot_ms=5_200), 31.2) == []
    assert tel.snapshot().last_position_s == 31.2


def test_one_forged_boot_time_changes_nothing() -> None:
    tel = fresh()
    tel.receive(heartbeat(10, armed=True), 0.5)
    tel.receive(wire(M.MAVLink_mission_current_message(3, 5)), 0.6)
    tel.receive(gpi(boot_ms=600_000), 1.0)
    for i in range(20):  # forged small boot times, each followed by the real timeline
        assert tel.receive(wire(M.MAVLink_system_time_message(0, 10 + i)), 2.0 + i) == []
        assert tel.receive(gpi(boot_ms=602_000 + 1000 * i), 2.1 + i) == []
    snap = tel.snapshot()
    assert snap.mission_current_seq == 3 and snap.mode == 10 and not snap.reboot_suspected
    assert tel.reboot.rejected == 20


def test_booting_heartbeat_confirms_a_suspected_reboot_at_once() -> None:
    tel = fresh()
    tel.receive(heartbeat(10, armed=True), 0.5)
    tel.receive(gpi(boot_ms=600_000), 1.0)
    booting = wire(M.MAVLink_heartbeat_message(1, 3, 1, 16, M.MAV_STATE_BOOT, 3))
    # booting with no suspicion: nothing to confirm
    assert not [e for e in tel.receive(booting, 1.5) if isinstance(e, Rebooted)]
    assert tel.receive(gpi(boot_ms=800), 2.0) == []
    events = tel.receive(booting, 2.1)
    assert [type(e) for e in events][:1] == [Rebooted]
    assert tel.snapshot().system_status == M.MAV_STATE_BOOT


def test_landed_state_and_system_status_kept_foreign_components_counted() -> None:
    tel = fresh()
    tel.receive(wire(M.MAVLink_extended_sys_state_message(0, 2)), 1.0)
    assert tel.snapshot().landed_state == 2
    tel.receive(wire(M.MAVLink_extended_sys_state_message(0, 0)), 2.0)
    assert tel.snapshot().landed_state is None  # UNDEFINED: not reported
    events = tel.receive(wire(M.MAVLink_extended_sys_state_message(0, 9)), 3.0)
    assert isinstance(events[0], InvalidTelemetry)
    tel.receive(wire(M.MAVLink_heartbeat_message(1, 3, 129, 10, M.MAV_STATE_CRITICAL, 3)), 4.0)
    assert tel.snapshot().system_status == M.MAV_STATE_CRITICAL
    forged = wire(M.MAVLink_mission_item_reached_message(1), compid=2)
    assert tel.receive(forged, 5.0) == [] and tel.foreign_messages == 1


def test_nan_and_out_of_range_values_dropped_and_reported() -> None:
    tel = fresh()
    tel.receive(wire(M.MAVLink_vfr_hud_message(20.0, 21.0, 45, 50, 100.0, 0.0)), 1.0)
    before = tel.snapshot()
    events = tel.receive(
        wire(M.MAVLink_vfr_hud_message(float("nan"), float("inf"), 720, 50, 100.0, 0.0)), 2.0
    )
    assert {(e.message, e.field) for e in events if isinstance(e, InvalidTelemetry)} == {
        ("VFR_HUD", "airspeed"),
        ("VFR_HUD", "groundspeed"),
        ("VFR_HUD", "heading"),
    }
    after = tel.snapshot()
    assert (after.speed_m_s, after.airspeed_m_s, after.heading_rad) == (
        before.speed_m_s,
        before.airspeed_m_s,
        before.heading_rad,
    )
    events = tel.receive(wire(M.MAVLink_attitude_message(1, 0, 0, float("nan"), 0, 0, 0)), 3.0)
    assert [e.field for e in events if isinstance(e, InvalidTelemetry)] == ["yaw"]
    assert tel.snapshot().heading_rad == before.heading_rad
    events = tel.receive(gpi(950_000_000, 0, boot_ms=2000, hdg=40000), 4.0)
    assert sorted(e.field for e in events if isinstance(e, InvalidTelemetry)) == ["hdg", "lat/lon"]
    assert tel.snapshot().x_m is None
    sys_status = M.MAVLink_sys_status_message(0, 0, 0, 0, 12000, 0, 120, 0, 0, 0, 0, 0, 0)
    events = tel.receive(wire(sys_status), 5.0)
    assert [e.field for e in events if isinstance(e, InvalidTelemetry)] == ["battery_remaining"]
    assert tel.snapshot().battery_remaining_pct is None
    assert tel.snapshot().battery_voltage_v == 12.0


@pytest.mark.parametrize(
    ("mode", "name"),
    [
        (0, "MANUAL"),
        (2, "STABILIZE"),
        (5, "FBWA"),
        (10, "AUTO"),
        (11, "RTL"),
        (12, "LOITER"),
        (15, "GUIDED"),
        (16, "INITIALISING"),
        (99, "MODE_99"),
    ],
)
def test_mode_names(mode: int, name: str) -> None:
    tel = fresh()
    events = tel.receive(heartbeat(mode), 1.0)
    assert events == [ModeChanged(1.0, None, mode, None, name)]
    assert tel.snapshot().mode_name == name and tel.snapshot().mode == mode


def test_mode_and_arming_transitions() -> None:
    tel = fresh()
    tel.receive(heartbeat(16), 0.0)
    assert tel.receive(heartbeat(16), 1.0) == []
    assert tel.receive(heartbeat(10, armed=True), 2.0) == [
        Armed(2.0),
        ModeChanged(2.0, 16, 10, "INITIALISING", "AUTO"),
    ]
    assert tel.receive(heartbeat(11, armed=False), 3.0) == [
        Disarmed(3.0),
        ModeChanged(3.0, 10, 11, "AUTO", "RTL"),
    ]
    assert tel.snapshot().armed is False and tel.snapshot().last_heartbeat_s == 3.0


def test_other_systems_and_non_autopilot_components_ignored() -> None:
    tel = fresh()
    tel.receive(heartbeat(10), 0.0)
    tel.receive(gpi(boot_ms=600_000), 0.0)
    assert tel.receive(heartbeat(0, sysid=2), 1.0) == []
    assert tel.receive(heartbeat(0, compid=100, mav_type=30, autopilot=8), 1.0) == []  # camera
    # a companion computer's own uptime must not look like an autopilot reboot
    assert tel.receive(wire(M.MAVLink_system_time_message(0, 5), compid=191), 1.0) == []
    assert tel.receive(heartbeat(0, mav_type=6, autopilot=8), 1.0) == []  # a GCS, same sysid
    snap = tel.snapshot()
    assert snap.mode == 10 and snap.last_heard_s == 0.0 and snap.time_boot_ms == 600_000


def test_prearm_and_battery_low_once_with_hysteresis() -> None:
    tel = VehicleTelemetry(1, ORIGIN, battery_low_pct=30.0)

    def status(remaining: int, healthy: bool) -> MAVLinkMessage:
        bit = 0x10000000
        return wire(
            M.MAVLink_sys_status_message(
                bit, bit, bit if healthy else 0, 0, 12600, 0, remaining, 0, 0, 0, 0, 0, 0
            )
        )

    assert tel.receive(status(80, False), 1.0) == [PrearmChanged(1.0, False)]
    assert tel.receive(status(80, True), 2.0) == [PrearmChanged(2.0, True)]
    assert tel.snapshot().prearm_ok is True
    assert tel.receive(status(29, True), 3.0) == [BatteryBelowThreshold(3.0, 29.0, 12.6, 30.0)]
    assert tel.receive(status(28, True), 4.0) == []
    assert tel.receive(status(31, True), 5.0) == []  # within hysteresis: stays reported
    assert tel.receive(status(36, True), 6.0) == []  # recovered: re-armed
    assert tel.receive(status(20, True), 7.0) == [BatteryBelowThreshold(7.0, 20.0, 12.6, 30.0)]


def test_link_status() -> None:
    tel = fresh()
    assert tel.link_status(0.0, lost_after_s=10.0) == "lost"
    tel.receive(heartbeat(10), 100.0)
    assert tel.link_status(101.0, lost_after_s=10.0) == "ok"
    assert tel.link_status(103.0, lost_after_s=10.0) == "degraded"
    assert tel.link_status(110.5, lost_after_s=10.0) == "lost"
    assert tel.link_status(101.5, lost_after_s=10.0, degraded_after_s=1.0) == "degraded"


def test_mission_progress_events() -> None:
    tel = fresh()
    events = tel.receive(wire(M.MAVLink_mission_current_message(2, 4)), 1.0)
    assert events == [MissionCurrentChanged(1.0, None, 2, 4)]
    assert tel.receive(wire(M.MAVLink_mission_current_message(2, 4)), 2.0) == []
    assert tel.receive(wire(M.MAVLink_mission_item_reached_message(2)), 3.0) == [
        MissionItemReached(3.0, 2)
    ]
    snap = tel.snapshot()
    assert (snap.mission_current_seq, snap.mission_total) == (2, 4)


def test_loiter_end_by_item_reached_reported_once() -> None:
    det = LoiterEndDetector(2)
    assert not det.feed(MissionCurrentChanged(1.0, 1, 2, 4))
    assert det.feed(MissionItemReached(40.0, 2))
    assert not det.feed(MissionCurrentChanged(40.1, 2, 3, 4))  # same end: not twice
    assert (det.ended, det.ended_by, det.ended_at_s) == (True, "reached", 40.0)


def test_loiter_end_by_mission_current_when_reached_is_lost() -> None:
    det = LoiterEndDetector(2, current_seq=2)
    assert not det.feed(MissionItemReached(10.0, 1))
    assert det.feed(MissionCurrentChanged(41.0, 2, 3, 4))
    assert det.ended_by == "mission_current"


def test_loiter_end_ignores_previous_missions_current() -> None:
    # after a re-upload the plane still flies its old item 3 (> N); that is not the end
    det = LoiterEndDetector(2)
    assert not det.feed(MissionCurrentChanged(1.0, None, 3, 4))
    assert not det.feed(MissionItemReached(1.5, 3))
    assert not det.feed(MissionCurrentChanged(2.0, 3, 1, 4))
    assert not det.feed(MissionCurrentChanged(20.0, 1, 2, 4))
    assert det.feed(MissionCurrentChanged(60.0, 2, 3, 4))


def test_garbage_messages_never_raise() -> None:
    tel = fresh()
    msgs = [
        M.MAVLink_global_position_int_message(
            1, 2**31 - 1, -(2**31), 2**31 - 1, -(2**31), 32767, -32768, 0, 65534
        ),
        M.MAVLink_vfr_hud_message(-1e30, 1e30, -32768, 0, float("nan"), float("nan")),
        M.MAVLink_attitude_message(2**32 - 1, 0, 0, 1e9, 0, 0, 0),
        M.MAVLink_sys_status_message(
            0xFFFFFFFF, 0, 0xFFFFFFFF, 0, 65535, 0, -128, 0, 0, 0, 0, 0, 0
        ),
        M.MAVLink_statustext_message(255, b"\xff\xfe" * 25, 65535, 255),
        M.MAVLink_mission_current_message(65535, 65535),
        M.MAVLink_battery_status_message(0, 0, 0, 0, [65535] * 10, 0, 0, 0, 101),
    ]
    for i, msg in enumerate(msgs):
        events = tel.receive(wire(msg), float(i))
        assert all(not isinstance(e, Rebooted) for e in events) or i == 2
    snap = tel.snapshot()
    for value in (snap.x_m, snap.y_m, snap.heading_rad, snap.speed_m_s, snap.alt_m):
        assert value is None or math.isfinite(value)
    assert snap.battery_remaining_pct is None


def test_the_reducer_s_copies_are_what_dataclasses_replace_gives() -> None:
    """The reducer's own copy (``_evolve``, cheaper than ``dataclasses.replace``) gives an
    equal, frozen snapshot and refuses a name that is not a field, as ``replace`` does."""
    snap = VehicleSnapshot(system_id=3, x_m=1.0, mode=10, home=(78.9, 11.9, 5.0))
    changes: dict[str, object] = {"x_m": 2.5, "armed": True, "last_heard_s": 7.0}
    got = _evolve(snap, **changes)
    assert got == dataclasses.replace(snap, **changes)  # type: ignore[arg-type]
    assert snap.x_m == 1.0 and snap.armed is None  # the original untouched
    with pytest.raises(dataclasses.FrozenInstanceError):
        got.x_m = 3.0  # type: ignore[misc]
    with pytest.raises(TypeError, match="no_such_field"):
        _evolve(snap, no_such_field=1)
