"""The built-in vehicle's ``airspeed`` fault: ArduPlane's health check, its texts, its
SYS_STATUS bits and its WIND estimate without airspeed, in simulated time, over the real
codec (sitl/sim_airspeed.py)."""

from __future__ import annotations

import math
from typing import Any

import pytest

from domain.geodesy import GeoOrigin
from domain.wind_triangle import wind_from_vector
from groundstation.mavlink.codec import mavlink2 as M
from groundstation.mavlink.wind_message import parse_wind_message
from sitl.faults import FaultError, FaultEvent, VehicleFaults, apply_fault, parse_fault_spec
from sitl.loopback import Loopback
from sitl.sim_airspeed import wind_without_airspeed
from sitl.vehicle import SimVehicle, VehicleConfig
from world.wind import WindSpec

ORIGIN = GeoOrigin(78.93, 11.92)
DP = M.MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE


def test_the_spec_grammar() -> None:
    [(sysid, kind, options)] = parse_fault_spec("1:airspeed:at=120", 2)
    assert (sysid, kind, options) == (1, "airspeed", {"at": "120"})
    faults = VehicleFaults(0)
    apply_fault(faults, "airspeed", {"at": "120", "for": "60"})
    assert [(e.t_s, e.kind) for e in faults.events] == [(120.0, "airspeed"),
                                                        (180.0, "airspeed_ok")]
    assert [e.kind for e in faults.due_events(150.0)] == ["airspeed"]
    for bad in ("1:airspeed", "1:airspeed:for=10", "1:airspeed:at=5,pct=3", "1:airspeed:at=-1"):
        with pytest.raises(FaultError, match="fault"):
            parse_fault_spec(bad, 2)


def _fly(lb: Loopback, seconds: float) -> list[tuple[float, Any]]:
    """(time, message) of everything sent over ``seconds``, in 0.1 s steps."""
    got: list[tuple[float, Any]] = []
    for _ in range(round(seconds * 10)):
        got += [(lb.t_s, m) for m in lb.advance(0.1)]
    return got


def _wind(msg: Any) -> tuple[float, float]:
    parsed = parse_wind_message(msg)
    assert not hasattr(parsed, "field"), parsed
    return wind_from_vector(parsed.wx_m_s, parsed.wy_m_s)  # type: ignore[union-attr]


def test_a_failed_pitot_is_disabled_like_arduplane_and_its_wind_degrades() -> None:
    cfg = VehicleConfig(1, ORIGIN, 78.93, 11.92, fast_boot=True, airborne=True,
                        wind=WindSpec(15.0, 270.0))
    lb = Loopback(SimVehicle(cfg))
    before = _fly(lb, 40.0)
    assert not [m for _t, m in before if m.get_type() == "STATUSTEXT"
                and "Airspeed" in m.text]
    status = [m for _t, m in before if m.get_type() == "SYS_STATUS"][-1]
    assert status.onboard_control_sensors_present & DP
    assert status.onboard_control_sensors_enabled & DP
    assert status.onboard_control_sensors_health & DP
    speed, from_deg = _wind([m for _t, m in before if m.get_type() == "WIND"][-1])
    assert speed == pytest.approx(15.0, abs=0.1) and from_deg == pytest.approx(270.0, abs=0.5)

    t_fault = lb.t_s
    lb.vehicle.apply_fault(FaultEvent(t_fault, "airspeed"), t_fault)
    failed = _fly(lb, 60.0)
    texts = [(t, m.severity, m.text) for t, m in failed if m.get_type() == "STATUSTEXT"]
    # the health probability falls 0.9 per 0.2 s check: below 0.1 after 22 checks
    assert texts == [(pytest.approx(t_fault + 4.4), M.MAV_SEVERITY_ERROR,
                      "Airspeed sensor 1 failure. Disabling")]
    t_disabled = texts[0][0]
    for t, m in failed:
        if m.get_type() == "SYS_STATUS":  # present and healthy, enabled only while in use
            assert m.onboard_control_sensors_present & DP
            assert m.onboard_control_sensors_health & DP
            assert bool(m.onboard_control_sensors_enabled & DP) == (t < t_disabled)
    winds = [(t, _wind(m)) for t, m in failed if m.get_type() == "WIND"]
    # settles (5 s lag) to 0.45 x 15 m/s turned 20 deg anticlockwise: from 250 deg
    late = [w for t, w in winds if t > t_disabled + 25.0]  # 5 tau: 8.25 m/s e^-5 = 0.06
    assert late and all(s == pytest.approx(6.75, abs=0.1) and d == pytest.approx(250.0, abs=1.0)
                        for s, d in late)
    assert all(s > 14.9 for t, (s, _d) in winds if t < t_disabled)

    t_end = lb.t_s
    lb.vehicle.apply_fault(FaultEvent(t_end, "airspeed_ok"), t_end)
    back = _fly(lb, 60.0)
    texts = [(t, m.severity, m.text) for t, m in back if m.get_type() == "STATUSTEXT"]
    assert len(texts) == 1 and texts[0][1:] == (M.MAV_SEVERITY_NOTICE,
                                                 "Airspeed sensor 1 now OK. Re-enabled")
    assert 28.0 < texts[0][0] - t_end < 31.0  # (1 - p) x 0.98 per check, to below 0.05
    last = [m for _t, m in back if m.get_type() == "SYS_STATUS"][-1]
    assert last.onboard_control_sensors_enabled & DP
    speed, from_deg = _wind([m for _t, m in back if m.get_type() == "WIND"][-1])
    assert speed == pytest.approx(15.0, abs=0.2) and from_deg == pytest.approx(270.0, abs=1.0)


def test_the_degraded_wind_formula() -> None:
    wx, wy = wind_without_airspeed((15.0, 0.0))
    assert math.hypot(wx, wy) == pytest.approx(6.75)
    assert math.degrees(math.atan2(wy, wx)) == pytest.approx(20.0)


def test_a_reboot_uses_the_sensor_again_and_a_faulty_pitot_is_disabled_again() -> None:
    cfg = VehicleConfig(1, ORIGIN, 78.93, 11.92, fast_boot=True, airborne=True)
    lb = Loopback(SimVehicle(cfg))
    _fly(lb, 5.0)
    lb.vehicle.apply_fault(FaultEvent(lb.t_s, "airspeed"), lb.t_s)
    _fly(lb, 10.0)
    assert not lb.vehicle.airspeed_sensor.in_use
    lb.vehicle.apply_fault(FaultEvent(lb.t_s, "reboot"), lb.t_s)
    assert lb.vehicle.airspeed_sensor.in_use  # ARSPD_USE 0 was never saved
    t_reboot = lb.t_s
    again = [(t, m.text) for t, m in _fly(lb, 10.0) if m.get_type() == "STATUSTEXT"
             and m.text.startswith("Airspeed")]
    assert again == [(pytest.approx(t_reboot + 4.4), "Airspeed sensor 1 failure. Disabling")]
