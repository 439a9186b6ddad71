"""A failed airspeed sensor: ArduPlane's word for it (STATUSTEXT, SYS_STATUS bits) judged on
evidence, the vehicle controller withdrawing that vehicle's wind, and the decision core
falling back at once (docs/wind.md, "A failed airspeed sensor")."""

from __future__ import annotations

import json
import math
from typing import Any

import pytest
from test_vehicle_controller import Rig, active_rig

from domain.geodesy import GeoOrigin
from domain.wind_triangle import wind_vector_m_s
from groundstation.core import events as ev
from groundstation.core.commands import Note, WindEstimate
from groundstation.core.config import CoreConfig
from groundstation.core.decision import DecisionCore
from groundstation.core.records import event_to_record, record_to_event
from groundstation.daemon.log_lines import is_operator_event, line_level
from groundstation.mavlink.airspeed_health import AirspeedHealth, airspeed_text
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, mavlink2
from groundstation.mavlink.telemetry import Rebooted, StatusText, VehicleTelemetry, WindReported
from groundstation.runners.replay.compare import NOTE_KINDS
from groundstation.vehicle import controller_io as vio

M = mavlink2
DP = M.MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE
OTHER = M.MAV_SYS_STATUS_SENSOR_3D_GYRO | M.MAV_SYS_STATUS_SENSOR_GPS
FAILURE = "Airspeed sensor 1 failure. Disabling"
RECOVERY = "Airspeed sensor 1 now OK. Re-enabled"
TRUE_WIND = wind_vector_m_s(15.0, 270.0)  # (15, 0): towards the east


def bits(enabled: bool = True, healthy: bool = True) -> tuple[int, int, int]:
    """SYS_STATUS present/enabled/health with the differential pressure sensor present."""
    return OTHER | DP, OTHER | (DP if enabled else 0), OTHER | (DP if healthy else 0)


# ------------------------------------------------------------------ the evidence
def test_arduplane_texts_are_recognised_and_nothing_else() -> None:
    assert airspeed_text(FAILURE) == ("failed", 1)
    assert airspeed_text("Airspeed sensor 2 failure. Disabling") == ("failed", 2)
    assert airspeed_text(RECOVERY) == ("recovered", 1)
    assert airspeed_text("Airspeed sensor 1, Re-enabled as GPS fall-back") == ("recovered", 1)
    # ArduPlane's warnings before a failure, and other airspeed texts, are not a verdict
    for text in ("Airspeed 1 warning 9.3m/s air to gnd speed diff", "Airspeed sensor 1 warning",
                 "Airspeed 1 calibrated", "PreArm: Airspeed 1 not healthy"):
        assert airspeed_text(text) is None


def test_the_failure_text_acts_at_once_and_the_recovery_text_clears_it() -> None:
    health = AirspeedHealth()
    assert health.text("Mission: 1 LoitUnlim", 10.0) is None
    change = health.text(FAILURE, 10.0)
    assert change is not None and change.failed and change.how == "statustext"
    assert change.detail == FAILURE and health.failed
    assert health.text(FAILURE, 11.0) is None  # said again: no new change
    recovered = health.text(RECOVERY, 40.0)
    assert recovered is not None and not recovered.failed and not health.failed


def test_two_sensors_recover_only_when_both_are_back() -> None:
    health = AirspeedHealth()
    assert health.text(FAILURE, 1.0) is not None
    assert health.text("Airspeed sensor 2 failure. Disabling", 2.0) is None
    assert health.text(RECOVERY, 3.0) is None and health.failed
    assert health.text("Airspeed sensor 2 now OK. Re-enabled", 4.0) is not None
    assert not health.failed


def test_one_stray_sys_status_frame_is_no_failure_but_sustained_bits_are() -> None:
    health = AirspeedHealth(min_frames=3, min_span_s=2.0)
    for t in range(5):
        assert health.sys_status(*bits(), float(t)) is None
    assert health.sys_status(*bits(enabled=False), 5.0) is None  # one stray frame
    for t in range(6, 9):
        assert health.sys_status(*bits(), float(t)) is None
    assert not health.failed
    # disabled by the health check: present, healthy, not enabled, frame after frame
    assert health.sys_status(*bits(enabled=False), 9.0) is None
    assert health.sys_status(*bits(enabled=False), 10.0) is None  # 2 frames, 1 s
    change = health.sys_status(*bits(enabled=False), 11.0)  # 3 frames over 2 s
    assert change is not None and change.failed and change.how == "sys_status"
    assert "not enabled" in change.detail
    # one healthy frame does not bring it back; three over 2 s do
    assert health.sys_status(*bits(), 12.0) is None
    assert health.sys_status(*bits(enabled=False), 13.0) is None and health.failed
    assert health.sys_status(*bits(), 14.0) is None
    assert health.sys_status(*bits(), 15.0) is None
    back = health.sys_status(*bits(), 16.0)
    assert back is not None and not back.failed and not health.failed


def test_a_used_sensor_that_stops_reading_is_failed_and_an_unused_one_never_judged() -> None:
    unhealthy = AirspeedHealth()
    changes = [unhealthy.sys_status(*bits(healthy=False), float(t)) for t in range(3)]
    assert changes[:2] == [None, None] and changes[2] is not None
    assert "not healthy" in changes[2].detail
    # ARSPD_USE 0 from the start (never seen enabled), or no sensor at all: no verdict
    unused, absent = AirspeedHealth(), AirspeedHealth()
    for t in range(10):
        assert unused.sys_status(*bits(enabled=False), float(t)) is None
        assert absent.sys_status(OTHER, OTHER, OTHER, float(t)) is None
    assert not unused.failed and not absent.failed


def test_bits_recover_a_text_failure_only_when_they_had_shown_it() -> None:
    # an autopilot whose bits never show the failure cannot clear it with them
    silent_bits = AirspeedHealth()
    silent_bits.text(FAILURE, 0.0)
    for t in range(1, 10):
        assert silent_bits.sys_status(*bits(), float(t)) is None
    assert silent_bits.failed
    # ArduPlane: the text, then the enabled bit cleared; the recovery text lost, the bits
    # enabled again over 2 s recover it
    arduplane = AirspeedHealth()
    assert arduplane.sys_status(*bits(), -1.0) is None  # in use before it failed
    arduplane.text(FAILURE, 0.0)
    for t in range(1, 5):
        assert arduplane.sys_status(*bits(enabled=False), float(t)) is None
    changes = [arduplane.sys_status(*bits(), float(t)) for t in range(5, 8)]
    assert changes[:2] == [None, None] and changes[2] is not None and not arduplane.failed
    arduplane.text(FAILURE, 8.0)
    arduplane.reset()  # a reboot: ArduPlane uses its sensor again
    assert not arduplane.failed


def test_the_reducer_keeps_the_sys_status_bitmasks() -> None:
    tel = VehicleTelemetry(1, GeoOrigin(78.9, 11.9, 0.0))
    present, enabled, health = bits(enabled=False)
    msg = M.MAVLink_sys_status_message(present, enabled, health, 200, 12000, 100, 80,
                                       0, 0, 0, 0, 0, 0)
    wire = MavlinkDecoder().feed(MavlinkEncoder(1, 1).encode(msg))[0]
    tel.receive(wire, 1.0)
    assert tel.snapshot().sensors == (present, enabled, health)


# ------------------------------------------------------------------ the controller
def _wind(rig: Rig) -> list[vio.Output]:
    return rig.frame("WIND", WindReported(rig.t, *TRUE_WIND, 0.0), wind_xy_m_s=TRUE_WIND)


def _reports(out: list[vio.Output]) -> list[ev.Event]:
    return [o.event for o in out if isinstance(o, vio.CoreEvent)
            and isinstance(o.event, ev.WindReport | ev.WindWithdrawn)]


def _reporting_rig() -> Rig:
    rig = active_rig(wind_settle_s=2.0)
    sent: list[ev.Event] = []
    for _ in range(5):
        rig.t += 1.0
        sent += _reports(_wind(rig))
    assert sent and all(isinstance(e, ev.WindReport) for e in sent)
    return rig


def test_a_failure_text_withdraws_the_wind_at_once_until_the_recovery_text() -> None:
    rig = _reporting_rig()
    rig.t += 0.5
    out = rig.frame("STATUSTEXT", StatusText(rig.t, M.MAV_SEVERITY_ERROR, FAILURE))
    assert _reports(out) == [ev.WindWithdrawn(rig.t, "v1", "airspeed sensor failed")]
    warnings = [o.text for o in out if isinstance(o, vio.Warn)]
    assert warnings == [f"vehicle v1: airspeed sensor failed (ArduPlane: {FAILURE}): its "
                        "wind estimate is ignored until the sensor recovers"]
    line = rig.journal("airspeed_failed")[0]
    assert line.fields == {"how": "statustext", "detail": FAILURE} and line.logged
    t_failed = rig.t
    sent: list[ev.Event] = []
    for _ in range(20):  # the degraded estimate is never sent
        rig.t += 1.0
        sent += _reports(_wind(rig))
    assert sent == []
    rig.t += 0.5
    rig.frame("STATUSTEXT", StatusText(rig.t, M.MAV_SEVERITY_NOTICE, RECOVERY))
    t_back = rig.t
    assert rig.journal("airspeed_recovered")[0].fields["how"] == "statustext"
    for _ in range(5):
        rig.t += 1.0
        sent += _reports(_wind(rig))
    # sent again once the estimate settled again (wind_settle_s 2 s after the first frame)
    assert sent and all(isinstance(e, ev.WindReport) for e in sent)
    assert sent[0].t_s == pytest.approx(t_back + 3.0) and t_back > t_failed


def test_a_stray_sys_status_frame_withdraws_nothing_sustained_bits_do() -> None:
    rig = _reporting_rig()
    rig.t += 0.5
    out = rig.frame("SYS_STATUS", sensors=bits(enabled=False))
    rig.t += 0.5
    out += rig.frame("SYS_STATUS", sensors=bits())
    out += _wind(rig)
    assert [type(e) for e in _reports(out)] == [ev.WindReport] and not rig.journal(
        "airspeed_failed")
    out = []
    for _ in range(3):
        rig.t += 1.0
        out += rig.frame("SYS_STATUS", sensors=bits(enabled=False))
    assert [type(e) for e in _reports(out)] == [ev.WindWithdrawn]
    assert rig.journal("airspeed_failed")[0].fields["how"] == "sys_status"


def test_a_vehicle_that_never_reported_has_nothing_to_withdraw_and_a_reboot_clears() -> None:
    rig = Rig()
    rig.t = 1.0
    out = rig.frame("STATUSTEXT", StatusText(rig.t, M.MAV_SEVERITY_ERROR, FAILURE))
    assert _reports(out) == [] and rig.journal("airspeed_failed") and rig.c.airspeed.failed
    rig.t = 2.0
    rig.frame("HEARTBEAT", Rebooted(rig.t, 60_000, 500), time_boot_ms=500)
    assert not rig.c.airspeed.failed
    assert rig.journal("airspeed_recovered")[0].fields["how"] == "reboot"


# ------------------------------------------------------------------ the core
def _core(vehicles: str, fallback: tuple[float, float] = TRUE_WIND) -> DecisionCore:
    core = DecisionCore(CoreConfig(wind_xy_m_s=fallback))
    for v in vehicles:
        core.handle(ev.VehicleJoined(0.0, v, 0.0, 0.0, 0.0, 22.0))
    return core


def _second(core: DecisionCore, t: float, reports: dict[str, tuple[float, float]]) -> list[Any]:
    out: list[Any] = []
    for vehicle, w in reports.items():
        out += core.handle(ev.WindReport(t, vehicle, *w))
    return out + core.handle(ev.Tick(t + 0.5))


DEGRADED = (0.45 * 15.0 * math.cos(math.radians(20.0)), 0.45 * 15.0 * math.sin(math.radians(20.0)))


def test_one_plane_withdrawn_falls_back_to_the_configured_wind_at_once() -> None:
    core = _core("1")
    for t in range(10):  # the only plane reports the degraded wind (6.75 m/s)
        _second(core, float(t), {"1": DEGRADED})
    assert core.wind_state.source == "vehicles"
    assert core.planning_wind_m_s() == pytest.approx(DEGRADED)
    out = core.handle(ev.WindWithdrawn(9.7, "1", "airspeed sensor failed"))
    # at once: not 30 s later when its last report ages out
    assert core.planning_wind_m_s() == TRUE_WIND and core.wind_state.source == "fallback"
    winds = [c for c in out if isinstance(c, WindEstimate)]
    assert [(w.t_s, w.source, (w.wx_m_s, w.wy_m_s)) for w in winds] == [
        (9.7, "fallback", TRUE_WIND)]
    notes = [c for c in out if isinstance(c, Note)]
    assert [(n.kind, n.vehicle) for n in notes] == [("wind_fallback", "1")]
    assert notes[0].detail == ("vehicle 1's wind estimate is withdrawn (airspeed sensor failed) "
                               "and no other vehicle reports one: planning falls back to the "
                               "configured wind, 15.0 m/s from 270 deg")
    for k in range(1, 40):  # the fallback holds while it reports nothing
        core.handle(ev.Tick(9.7 + k))
        assert core.planning_wind_m_s() == TRUE_WIND
    _second(core, 60.0, {"1": TRUE_WIND})  # reports again after recovering
    assert core.wind_state.source == "vehicles" and core.wind_state.vehicles == ("1",)


def test_withdrawn_in_a_fleet_the_others_carry_the_estimate_without_a_fallback() -> None:
    # two planes: the degraded one disagrees by > 5 m/s; before the withdrawal the anchor
    # (the configured wind) decided; after it, the other plane alone, with no warning
    calm_anchor = _core("12", fallback=(0.0, 0.0))
    for t in range(10):
        _second(calm_anchor, float(t), {"1": TRUE_WIND, "2": DEGRADED})
    assert calm_anchor.wind_state.vehicles == ("2",)  # closer to calm: the wrong one won
    out = calm_anchor.handle(ev.WindWithdrawn(9.7, "2", "airspeed sensor failed"))
    assert calm_anchor.planning_wind_m_s() == TRUE_WIND
    assert calm_anchor.wind_state.vehicles == ("1",)
    assert not [c for c in out if isinstance(c, Note)]
    # three planes: the median had outvoted it; withdrawn, the two others agree
    fleet = _core("123", fallback=(0.0, 0.0))
    for t in range(10):
        _second(fleet, float(t), {"1": TRUE_WIND, "2": (15.4, 0.2), "3": DEGRADED})
    assert fleet.planning_wind_m_s() == pytest.approx((15.0, 0.2))  # component-wise median
    out = fleet.handle(ev.WindWithdrawn(9.7, "3", "airspeed sensor failed"))
    assert fleet.planning_wind_m_s() == pytest.approx((15.2, 0.1))
    assert fleet.wind_state.vehicles == ("1", "2")
    assert not [c for c in out if isinstance(c, Note)]


def test_withdrawn_round_trips_is_a_warning_and_replay_compares_its_note() -> None:
    event = ev.WindWithdrawn(12.25, "2", "airspeed sensor failed")
    assert record_to_event(json.loads(json.dumps(event_to_record(event)))) == event
    assert "wind_fallback" in NOTE_KINDS
    for name in ("wind_fallback", "airspeed_failed"):
        assert line_level({"event": name}) == 30  # logging.WARNING
    assert is_operator_event({"event": "airspeed_recovered"})
