"""The GPS fix per vehicle (issue 29, item 4): GPS_RAW_INT's ``fix_type``,
``satellites_visible`` and ``eph`` parsed (unknown values and garbage shown as unknown,
never a crash), kept in the telemetry snapshot, asked for at 0.5 Hz on a constrained link
within the rate plan's budget, shown by the vehicle panel (``vehicle_view.py``), and sent by
the built-in simulator as ArduPlane SITL sends it. The end-to-end check over a simulated SiK
radio is ``test_gcs_run_shows_the_gps_fix_and_the_fence_over_a_radio`` below."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
from daemon_run import events, run_gcs

from domain.geodesy import GeoOrigin
from groundstation.daemon.control.controller import DaemonController
from groundstation.daemon.vehicle_view import GPS_STALE_S, vehicle_panel
from groundstation.link.tlog import TlogReader
from groundstation.mavlink.codec import mavlink2
from groundstation.mavlink.gps_message import GPS_FIX_NAMES, GpsFix, gps_fix_text, parse_gps_raw_int
from groundstation.mavlink.link_budget import SIK_DOWNLINK_BPS, TELEMETRY_SHARE, stream_plan
from groundstation.mavlink.telemetry import InvalidTelemetry, VehicleTelemetry
from groundstation.mavlink.telemetry_events import VehicleSnapshot
from sitl.loopback import Loopback
from sitl.vehicle import SimVehicle, VehicleConfig

M = mavlink2
ORIGIN = GeoOrigin(78.93, 11.92)


def gps_raw(fix_type: int = 3, eph: int = 80, satellites: int = 14) -> Any:
    """A GPS_RAW_INT as pymavlink decodes it (system 1, the autopilot)."""
    msg = M.MAVLink_gps_raw_int_message(123_000_000, fix_type, 789_300_000, 119_200_000,
                                        50_000, eph, 120, 2000, 9000, satellites)
    encoder = M.MAVLink(None, srcSystem=1, srcComponent=1)
    return encoder.decode(bytearray(msg.pack(encoder)))


# ------------------------------------------------------------------ the parse


def test_a_fix_is_parsed_with_its_satellites_and_hdop() -> None:
    fix = parse_gps_raw_int(gps_raw(3, 80, 14))
    assert fix == GpsFix(3, 14, 0.8)
    assert fix.has_fix and fix.name == "3D fix"
    assert gps_fix_text(fix) == "3D fix, 14 sats, HDOP 0.8"
    rtk = parse_gps_raw_int(gps_raw(6, 121, 10))
    assert gps_fix_text(rtk) == "RTK fixed, 10 sats, HDOP 1.2" and rtk.has_fix


def test_every_gps_fix_type_has_its_name_and_only_3d_up_is_a_fix() -> None:
    names = [parse_gps_raw_int(gps_raw(k)).name for k in range(9)]
    assert names == ["no GPS", "no fix", "2D fix", "3D fix", "DGPS", "RTK float",
                     "RTK fixed", "static", "PPP"]
    assert [parse_gps_raw_int(gps_raw(k)).has_fix for k in range(9)] == [
        False, False, False, True, True, True, True, True, True]
    assert set(GPS_FIX_NAMES) == set(range(9))


def test_unknown_satellites_and_hdop_are_unknown_not_bad() -> None:
    fix = parse_gps_raw_int(gps_raw(3, 65535, 255))  # UINT16_MAX, UINT8_MAX: unknown
    assert fix == GpsFix(3, None, None) and fix.bad == ()
    assert gps_fix_text(fix) == "3D fix, ? sats, HDOP ?"


@pytest.mark.parametrize(("fields", "bad"), [
    ({"fix_type": 9}, {"fix_type"}),
    ({"fix_type": 255}, {"fix_type"}),
    ({"satellites_visible": 200}, {"satellites_visible"}),
    ({"fix_type": None, "satellites_visible": "14", "eph": float("nan")},
     {"fix_type", "satellites_visible", "eph"}),
    ({"fix_type": True, "eph": -5}, {"fix_type", "eph"}),
    ({"eph": 70_000, "satellites_visible": -1}, {"eph", "satellites_visible"}),
])
def test_garbage_is_shown_as_unknown_and_named(fields: dict[str, Any], bad: set[str]) -> None:
    msg = SimpleNamespace(**{"fix_type": 3, "satellites_visible": 12, "eph": 90, **fields})
    fix = parse_gps_raw_int(msg)
    assert {b.field for b in fix.bad} == bad
    for name, attr in (("fix_type", "fix_type"), ("satellites_visible", "satellites"),
                       ("eph", "hdop")):
        assert (getattr(fix, attr) is None) == (name in bad)
    if "fix_type" in bad:
        assert fix.name == "unknown fix" and not fix.has_fix
    assert "\n" not in gps_fix_text(fix)


def test_a_message_without_the_fields_is_unknown_not_a_crash() -> None:
    fix = parse_gps_raw_int(object())
    assert fix.fix_type is fix.satellites is fix.hdop is None
    assert gps_fix_text(fix) == "unknown fix, ? sats, HDOP ?"


# ------------------------------------------------------------------ the reducer


def test_the_reducer_keeps_the_fix_and_reports_garbage() -> None:
    tel = VehicleTelemetry(1, ORIGIN)
    assert tel.snapshot().gps_fix is None
    assert tel.receive(gps_raw(6, 121, 10), 5.0) == []
    snap = tel.snapshot()
    assert snap.gps_fix == GpsFix(6, 10, 1.21) and snap.last_gps_s == 5.0
    got = tel.receive(gps_raw(42, 121, 10), 7.0)  # a forged fix type: unknown, reported
    assert got == [InvalidTelemetry(7.0, "GPS_RAW_INT", "fix_type", 42)]
    fix = tel.snapshot().gps_fix
    assert fix is not None and (fix.fix_type, fix.satellites, fix.hdop) == (None, 10, 1.21)
    assert not fix.has_fix


def test_a_reboot_forgets_the_fix() -> None:
    tel = VehicleTelemetry(1, ORIGIN)
    encoder = M.MAVLink(None, srcSystem=1, srcComponent=1)

    def attitude(boot_ms: int) -> Any:
        msg = M.MAVLink_attitude_message(boot_ms, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        return encoder.decode(bytearray(msg.pack(encoder)))

    t = 0.0
    for k in range(10):
        tel.receive(attitude(600_000 + 1000 * k), t)
        t += 1.0
    tel.receive(gps_raw(6, 121, 10), t)
    assert tel.snapshot().gps_fix is not None
    for k in range(5):  # back to a young clock, frame after frame: a reboot
        t += 1.0
        tel.receive(attitude(1000 + 1000 * k), t)
    assert tel.snapshot().gps_fix is None and tel.snapshot().last_gps_s is None


# ------------------------------------------------------------------ the rate plan


@pytest.mark.parametrize("capacity_bps", [SIK_DOWNLINK_BPS, 57_600.0])
def test_a_constrained_link_asks_for_the_gps_fix_within_its_budget(capacity_bps: float
                                                                   ) -> None:
    """On a SiK radio (24 kbit/s one way once it reports) and on a 57 600-baud serial
    link: GPS_RAW_INT at 0.5 Hz, the position at 2 Hz, within 40 % of the link; an
    unlimited link keeps it in its group at 1 Hz, as before."""
    plan = stream_plan(2.0, capacity_bps)
    rates = dict(plan.intervals)
    assert rates[M.MAVLINK_MSG_ID_GPS_RAW_INT] == 0.5
    assert rates[M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT] == 2.0
    assert plan.bytes_s <= TELEMETRY_SHARE * capacity_bps / 8
    # GPS_RAW_INT's 52-byte payload + 12 bytes of MAVLink 2 at 0.5 Hz: 32 B/s more
    assert plan.bytes_s == pytest.approx(285.0 + 32.0)
    signed = stream_plan(2.0, capacity_bps, signed=True)  # signing: 13 B a frame more
    assert signed.bytes_s <= TELEMETRY_SHARE * capacity_bps / 8
    unlimited = stream_plan(2.0, None)  # every group at 1 Hz, EXTENDED_STATUS included
    assert (M.MAV_DATA_STREAM_EXTENDED_STATUS, 1) in unlimited.groups
    assert M.MAVLINK_MSG_ID_GPS_RAW_INT not in dict(unlimited.intervals)  # none turned off


# ------------------------------------------------------------------ the panel


def test_the_panel_shows_the_fix_else_the_sys_status_health() -> None:
    base = VehicleSnapshot(system_id=1, sensors=(0x20, 0x20, 0x20), last_heard_s=30.0)
    panel = vehicle_panel(base, None, 120.0, "ok", 0.2, None)
    assert panel["gps_fix"] is None and panel["gps_text"] == "ok"  # no GPS_RAW_INT yet
    fixed = VehicleSnapshot(system_id=1, sensors=(0x20, 0x20, 0x20), last_heard_s=30.0,
                            gps_fix=GpsFix(3, 14, 0.8), last_gps_s=29.0)
    panel = vehicle_panel(fixed, None, 120.0, "ok", 0.2, None)
    assert panel["gps_fix"] == {"fix_type": 3, "fix": "3D fix", "satellites": 14,
                                "hdop": 0.8, "ok": True}
    assert panel["gps_text"] == "3D fix, 14 sats, HDOP 0.8" and panel["gps"] == "ok"
    lost = VehicleSnapshot(system_id=1, sensors=(0x20, 0x20, 0x20), last_heard_s=30.0,
                           gps_fix=GpsFix(1, 3, 1.21), last_gps_s=29.0)
    panel = vehicle_panel(lost, None, 120.0, "ok", 0.2, None)
    assert panel["gps_fix"]["ok"] is False and panel["gps_text"] == "no fix, 3 sats, HDOP 1.2"
    # a GPS_RAW_INT stream that stopped while the vehicle is heard: the health again
    stale = VehicleSnapshot(system_id=1, sensors=(0x20, 0x20, 0), gps_fix=GpsFix(6, 10, 1.21),
                            last_gps_s=10.0, last_heard_s=10.0 + GPS_STALE_S + 0.5)
    panel = vehicle_panel(stale, None, 120.0, "ok", 0.2, None)
    assert panel["gps_fix"] is None and panel["gps_text"] == "unhealthy"
    assert vehicle_panel(VehicleSnapshot(system_id=1), None, 120.0, "lost", None,
                         None)["gps_text"] is None


# ------------------------------------------------------------------ the simulator


def test_the_simulator_sends_gps_raw_int_as_arduplane_sitl() -> None:
    """ArduPlane SITL's u-blox: no fix and 3 satellites before the lock, then RTK fixed
    (NAV-PVT's fixed carrier solution), SIM_GPS1_NUMSATS 10, HDOP 1.21, VDOP 2.00."""
    lb = Loopback(SimVehicle(VehicleConfig(1, ORIGIN, 78.93, 11.92, fast_boot=True)))
    lb.advance(0.6)  # before the GPS lock (1 s with fast_boot)
    early = lb.take("GPS_RAW_INT")
    assert early and {(m.fix_type, m.satellites_visible, m.eph, m.epv) for m in early} == {
        (1, 3, 121, 200)}
    lb.advance(4.0)
    late = lb.take("GPS_RAW_INT")[-2:]
    assert late and {(m.fix_type, m.satellites_visible, m.eph, m.epv) for m in late} == {
        (6, 10, 121, 200)}
    assert all(m.lat != 0 for m in late)


# ------------------------------------------------------------------ end to end


def test_gcs_run_shows_the_gps_fix_and_the_fence_over_a_radio(tmp_path: Path) -> None:
    """``gcs run --vehicles sim:1`` over a simulated SiK radio at 20x: the rate plan asks
    for GPS_RAW_INT at 0.5 Hz, the vehicle sends it at that rate, the state document shows
    its fix, and the vehicle holds the area's fence, verified (the state's ``fence``)."""
    daemon, journal = run_gcs(tmp_path, "--vehicles", "sim:1", "--sim-radio", "sik",
                              "--speedup", "20", "--duration", "60", timeout_s=90)
    assert daemon.stop_reason == "duration", daemon.stop_reason
    frames = [r.message for r in TlogReader(daemon.run_dir / "flight.tlog")]
    asked = [m for m in frames if m.get_type() == "COMMAND_LONG"
             and int(m.command) == M.MAV_CMD_SET_MESSAGE_INTERVAL
             and int(m.param1) == M.MAVLINK_MSG_ID_GPS_RAW_INT]
    assert asked and {m.param2 for m in asked} == {2e6}  # 0.5 Hz, never -1 (off)
    state = DaemonController(daemon).state()
    (vehicle,) = state["vehicles"]
    assert vehicle["gps_fix"] == {"fix_type": 6, "fix": "RTK fixed", "satellites": 10,
                                  "hdop": 1.21, "ok": True}, vehicle["gps_fix"]
    assert vehicle["gps_text"] == "RTK fixed, 10 sats, HDOP 1.2"
    # the vehicle's GPS_RAW_INT at 0.5 Hz of mission time once asked (the tlog's stamps are
    # wall time: at 20x, 20 mission s are 1 s)
    gps = [m for m in frames if m.get_type() == "GPS_RAW_INT" and m.get_srcSystem() == 1]
    span_s = (gps[-1].time_usec - gps[len(gps) // 2].time_usec) / 1e6
    rate_hz = (len(gps) - 1 - len(gps) // 2) / span_s
    assert 0.4 <= rate_hz <= 0.6, (rate_hz, span_s)
    # the fence: the area's, in the state document, held verified by the vehicle
    fence = daemon.fence()
    assert fence is not None
    assert state["fence"] == {"x_m": fence.x_m, "y_m": fence.y_m, "radius_m": fence.radius_m}
    assert vehicle["fence_verified"] is True
    assert events(journal, "fence", ok=True)
