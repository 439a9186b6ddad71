"""The built-in ArduPlane in a watch from a moving ship (issue 27): the battery model, the
fall at 0 %, the ship's deck, DO_SET_HOME, rally points in RTL, recovery and turnaround.

Sans-IO and clock-free (``SimVehicle.step``/``receive`` through ``Loopback``), except the
last test, which goes through the simulator's real TCP socket with pymavlink."""

from __future__ import annotations

import math
import time
from typing import Any

import pytest
from test_sitl_server import ServerThread, wait

from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import mavlink2 as M
from sitl.loopback import Loopback
from sitl.mission_store import StoredItem
from sitl.server import ServerOptions, SitlServer
from sitl.sitl_setup import scenario_setup
from sitl.vehicle import SimVehicle, VehicleConfig
from world.battery import BatteryModel
from world.scenario import BoatSpec, WatchSpec, load_scenario
from world.wind import WindSpec

ORIGIN = GeoOrigin(78.93, 11.92)
RALLY = M.MAV_MISSION_TYPE_RALLY
SHIP = BoatSpec(0.0, 0.0, 0.0, 10.0)  # sailing east at 10 m/s from the origin
WATCH = WatchSpec(endurance_s=1200.0, turnaround_s=60.0, recovery_radius_m=150.0)


def config(**kw: Any) -> VehicleConfig:
    base: dict[str, Any] = dict(system_id=1, origin=ORIGIN, home_lat_deg=78.93,
                                home_lon_deg=11.92, fast_boot=True)
    base.update(kw)
    return VehicleConfig(**base)


def make(**kw: Any) -> Loopback:
    return Loopback(SimVehicle(config(**kw)))


def cmd_long(command: int, *p: float) -> Any:
    params = list(p) + [0.0] * (7 - len(p))
    return M.MAVLink_command_long_message(1, 1, command, 0, *params)


def cmd_int(command: int, frame: int, p1: float, x: int, y: int, z: float) -> Any:
    return M.MAVLink_command_int_message(1, 1, frame, command, 0, 0, p1, 0, 0, 0, x, y, z)


def ack(msgs: list[Any], command: int) -> int:
    acks = [m for m in msgs if m.get_type() == "COMMAND_ACK" and m.command == command]
    assert len(acks) == 1, msgs
    return int(acks[0].result)


def run(v: SimVehicle, until_s: float, step_s: float = 1.0) -> list[Any]:
    out: list[Any] = []
    t = v.t_s
    while t < until_s - 1e-9:
        t = min(until_s, t + step_s)
        out += v.step(t)
    return out


def rtl_target(v: SimVehicle) -> tuple[float, float]:
    nav = v.autopilot.nav
    assert nav is not None
    return nav.x_m, nav.y_m


def texts(msgs: list[Any]) -> list[str]:
    return [m.text for m in msgs if m.get_type() == "STATUSTEXT"]


# ------------------------------------------------------------------ battery
def test_endurance_at_cruise_in_still_air_is_the_models() -> None:
    model = BatteryModel(endurance_s=1200.0)
    v = SimVehicle(config(airborne=True, battery=model))
    while not v.motor_stopped and v.t_s < 2000.0:
        v.step(v.t_s + 1.0)
    assert v.motor_stopped
    assert v.t_s == pytest.approx(1200.0, rel=0.01)
    assert v.battery_current_a == pytest.approx(0.0, abs=1.0)  # no thrust after that


def test_current_is_the_models_and_grows_in_wind_and_climb() -> None:
    model = BatteryModel(endurance_s=1200.0)
    calm = SimVehicle(config(airborne=True, battery=model))
    windy = SimVehicle(config(airborne=True, battery=model, wind=WindSpec(10.0, 270.0)))
    run(calm, 30.0)
    run(windy, 30.0)
    assert calm.battery_current_a == pytest.approx(model.cruise_current_a, rel=1e-6)
    assert windy.battery_current_a == pytest.approx(1.10 * model.cruise_current_a, rel=1e-3)
    # a climb: RTL at 300 m from 100 m
    climbing = SimVehicle(config(airborne=True, battery=model,
                                 params={"ALT_HOLD_RTL": 30000.0}))
    run(climbing, 5.0)
    climbing.receive(cmd_long(M.MAV_CMD_NAV_RETURN_TO_LAUNCH), climbing.t_s)
    run(climbing, 15.0, 0.1)
    assert climbing.airframe.climb_m_s > 1.0
    assert climbing.battery_current_a > 1.2 * model.cruise_current_a


def test_no_watch_keeps_todays_figures() -> None:
    v = SimVehicle(config(airborne=True))
    run(v, 10.0)
    assert v.battery_current_a == pytest.approx(15.0, rel=1e-6)  # 15 A at cruise, as before
    ground = SimVehicle(config())
    run(ground, 10.0)
    assert ground.battery_current_a == pytest.approx(0.5)


def test_sys_status_and_battery_status_as_arduplane() -> None:
    lb = make(airborne=True, battery=BatteryModel(endurance_s=1200.0))
    lb.advance(5.0)
    v = lb.vehicle
    sys_status = lb.run_until(lambda m: m.get_type() == "SYS_STATUS", 2.0)
    assert sys_status is not None
    assert sys_status.voltage_battery == round(v.battery_voltage_v * 1000)  # mV
    assert sys_status.current_battery == round(v.battery_current_a * 100)  # cA
    assert sys_status.battery_remaining == round(100 * v.battery_remaining)
    battery = lb.run_until(lambda m: m.get_type() == "BATTERY_STATUS", 2.0)
    assert battery is not None
    # no cell monitoring: the pack in cell 0, UINT16_MAX in the rest (MAVLink's rule)
    assert battery.voltages[0] == round(v.battery_voltage_v * 1000)
    assert list(battery.voltages[1:]) == [65535] * 9
    assert battery.temperature == 32767  # INT16_MAX: unknown
    assert battery.current_battery == round(v.battery_current_a * 100)
    assert battery.current_consumed == round(v.battery_used_mah)
    assert battery.energy_consumed > 0
    assert 12_000 < battery.voltages[0] <= 12_600


# -------------------------------------------------------------------- fall
@pytest.mark.parametrize("crash_detect", [1.0, 0.0])
def test_at_zero_percent_the_plane_falls(crash_detect: float) -> None:
    lb = make(airborne=True, params={"CRASH_DETECT": crash_detect})
    lb.advance(2.0)
    v = lb.vehicle
    v.set_battery_remaining(0.0005)
    sent = lb.advance(5.0)
    assert v.motor_stopped
    assert any(t.startswith("Battery 1 is critical") for t in texts(sent))
    sent = lb.advance(90.0, 0.5)
    said = texts(sent)
    assert v.airframe.on_ground and v.airframe.alt_m == 0.0
    assert any(t.startswith("SIM Hit ground at") for t in said)
    # ArduPlane's crash check: nothing with CRASH_DETECT 0, else "Crash detected", disarm
    assert ("Crash detected" in said) is (crash_detect == 1.0)
    assert v.autopilot.armed is (crash_detect == 0.0)
    kinds = [e.kind for e in v.events]
    assert kinds == ["motor_stopped", "fell"]
    assert "fell at t=" in v.events[-1].text and "battery empty" in v.events[-1].text
    lb.inbox.clear()
    lb.advance(5.0)
    positions = lb.take("GLOBAL_POSITION_INT")
    assert positions and positions[-1].relative_alt == 0  # telemetry goes on, on the ground


# -------------------------------------------------------------------- ship
def test_the_deck_moves_with_the_ship_and_home_follows_until_armed() -> None:
    lb = make(ship=SHIP)
    v = lb.vehicle
    lb.advance(3.0)  # fast boot: fix at 1 s, EKF and home at 2 s
    homes = lb.take("HOME_POSITION")
    assert homes
    hx, hy, _ = ORIGIN.to_local(homes[-1].latitude * 1e-7, homes[-1].longitude * 1e-7)
    assert hx == pytest.approx(20.0, abs=1.5) and hy == pytest.approx(0.0, abs=0.5)
    lb.advance(27.0)
    assert v.airframe.on_ground and v.on_deck
    assert v.airframe.x_m == pytest.approx(300.0, abs=1e-6)
    gpi = lb.take("GLOBAL_POSITION_INT")[-1]
    assert (gpi.vx, gpi.vy) == (0, 1000)  # north 0, east 10 m/s: the ship's velocity
    # ArduPlane's update_home: every 5 s while disarmed
    last = lb.take("HOME_POSITION")[-1]
    lx, _, _ = ORIGIN.to_local(last.latitude * 1e-7, last.longitude * 1e-7)
    assert 240.0 <= lx <= 300.0
    # a take-off starts from the deck
    v.store.write(1, StoredItem(M.MAV_CMD_NAV_TAKEOFF, M.MAV_FRAME_GLOBAL_RELATIVE_ALT, z=50.0))
    out = lb.send(cmd_long(M.MAV_CMD_COMPONENT_ARM_DISARM, 1))
    assert ack(out, 400) == 0
    # AP_Arming_Plane::arm updates an unlocked home: the deck now
    armed_home = [m for m in out if m.get_type() == "HOME_POSITION"]
    assert len(armed_home) == 1 and v.home_xy_m[0] == pytest.approx(v.airframe.x_m, abs=0.01)
    lb.send(cmd_long(M.MAV_CMD_DO_SET_MODE, 1, 10))
    x0 = v.airframe.x_m
    lb.advance(3.0)
    assert not v.on_deck and not v.airframe.on_ground
    assert abs(v.airframe.x_m - x0) < 60.0 and v.airframe.alt_m > 0.0
    home_at_arming = v.home_xy_m
    lb.advance(10.0)
    assert v.home_xy_m == home_at_arming  # armed: home no longer follows the ship


def test_setup_of_the_ship_watch_scenario() -> None:
    scenario = load_scenario("ship-watch")
    setup = scenario_setup(scenario, 5, (78.93, 11.92), False)
    c = setup.vehicle_config(0, airborne=False, airborne_alt_m=100.0, fast_boot=True,
                             unix_time_at_zero_s=0.0)
    assert c.battery is not None and c.battery.endurance_s == 3600.0
    assert c.ship == scenario.boat and c.watch == scenario.watch
    assert c.params["CRASH_DETECT"] == 1.0
    server = SitlServer([c], ServerOptions(base_port=0))
    lines = server.describe()
    assert any(line.startswith("ship:") for line in lines)
    assert any("within 150 m" in line for line in lines)
    assert any("endurance 3600 s" in line for line in lines)
    plain = scenario_setup(load_scenario("paper-boat"), 3, (78.93, 11.92), False)
    c = plain.vehicle_config(0, airborne=False, airborne_alt_m=100.0, fast_boot=True,
                             unix_time_at_zero_s=0.0)
    assert c.ship is None and c.watch is None and c.battery is None  # today's behaviour


# ------------------------------------------------------------- DO_SET_HOME
def _item0(lb: Loopback) -> Any:
    return next(m for m in lb.send(M.MAVLink_mission_request_int_message(1, 1, 0, 0))
            if m.get_type() == "MISSION_ITEM_INT")


def test_do_set_home_in_both_encodings_sends_home_position_and_moves_item_0() -> None:
    lb = make()
    lb.advance(3.0)
    lat, lon, _ = ORIGIN.to_geodetic(1000.0, 500.0)
    out = lb.send(cmd_long(M.MAV_CMD_DO_SET_HOME, 0, 0, 0, 0, lat, lon, 12.5))
    assert ack(out, M.MAV_CMD_DO_SET_HOME) == M.MAV_RESULT_ACCEPTED
    home = [m for m in out if m.get_type() == "HOME_POSITION"][-1]
    # COMMAND_LONG's params are float32: degrees to about 1e-5
    assert home.latitude == pytest.approx(lat * 1e7, abs=100)
    assert home.longitude == pytest.approx(lon * 1e7, abs=100)
    assert home.altitude == 12500
    item = _item0(lb)
    assert (item.x, item.y) == (home.latitude, home.longitude)
    lat2, lon2, _ = ORIGIN.to_geodetic(-300.0, 200.0)
    out = lb.send(cmd_int(M.MAV_CMD_DO_SET_HOME, M.MAV_FRAME_GLOBAL, 0,
                          round(lat2 * 1e7), round(lon2 * 1e7), 0.0))
    assert ack(out, M.MAV_CMD_DO_SET_HOME) == M.MAV_RESULT_ACCEPTED
    home = [m for m in out if m.get_type() == "HOME_POSITION"][-1]
    assert (home.latitude, home.longitude) == (round(lat2 * 1e7), round(lon2 * 1e7))
    assert (_item0(lb).x, _item0(lb).y) == (round(lat2 * 1e7), round(lon2 * 1e7))
    assert lb.vehicle.home_xy_m == pytest.approx((-300.0, 200.0), abs=0.02)
    # param1 = 1: where the plane is
    out = lb.send(cmd_long(M.MAV_CMD_DO_SET_HOME, 1))
    assert ack(out, M.MAV_CMD_DO_SET_HOME) == M.MAV_RESULT_ACCEPTED
    assert lb.vehicle.home_xy_m == pytest.approx((0.0, 0.0), abs=0.02)
    assert lb.vehicle.home_locked


def test_do_set_home_refuses_bad_coordinates() -> None:
    lb = make()
    out = lb.send(cmd_long(M.MAV_CMD_DO_SET_HOME, 0, 0, 0, 0, 78.9, 11.9, 0))
    assert ack(out, M.MAV_CMD_DO_SET_HOME) == M.MAV_RESULT_FAILED  # no fix yet
    lb.advance(3.0)
    before = lb.vehicle.home_xy_m
    cases = [
        (cmd_long(M.MAV_CMD_DO_SET_HOME, 0, 0, 0, 0, 95.0, 11.9, 0), M.MAV_RESULT_FAILED),
        (cmd_long(M.MAV_CMD_DO_SET_HOME, 0, 0, 0, 0, 78.9, 190.0, 0), M.MAV_RESULT_FAILED),
        (cmd_long(M.MAV_CMD_DO_SET_HOME, 0, 0, 0, 0, math.nan, 11.9, 0), M.MAV_RESULT_FAILED),
        (cmd_long(M.MAV_CMD_DO_SET_HOME, 0, 0, 0, 0, 78.9, 11.9, math.nan), M.MAV_RESULT_DENIED),
        (cmd_long(M.MAV_CMD_DO_SET_HOME, 2, 0, 0, 0, 78.9, 11.9, 0), M.MAV_RESULT_FAILED),
        (cmd_int(M.MAV_CMD_DO_SET_HOME, M.MAV_FRAME_GLOBAL, 0, 950_000_000, 119_000_000, 0),
         M.MAV_RESULT_FAILED),
        (cmd_int(M.MAV_CMD_DO_SET_HOME, M.MAV_FRAME_LOCAL_NED, 0, 789_000_000, 119_000_000, 0),
         M.MAV_RESULT_DENIED),
    ]
    for msg, result in cases:
        out = lb.send(msg)
        assert ack(out, M.MAV_CMD_DO_SET_HOME) == result, msg
        assert not [m for m in out if m.get_type() == "HOME_POSITION"]
    assert lb.vehicle.home_xy_m == before


def test_rtl_target_is_fixed_at_entry() -> None:
    lb = make(airborne=True)
    v = lb.vehicle
    lb.advance(3.0)
    lb.send(cmd_long(M.MAV_CMD_NAV_RETURN_TO_LAUNCH))
    assert v.autopilot.nav is not None
    assert rtl_target(v) == pytest.approx((0.0, 0.0), abs=0.01)
    lat, lon, _ = ORIGIN.to_geodetic(2000.0, 0.0)
    lb.send(cmd_long(M.MAV_CMD_DO_SET_HOME, 0, 0, 0, 0, lat, lon, 0))
    lb.advance(5.0)
    assert rtl_target(v) == pytest.approx((0.0, 0.0), abs=0.01)
    lb.send(cmd_long(M.MAV_CMD_DO_SET_MODE, 1, 12))  # LOITER, then RTL again
    lb.send(cmd_long(M.MAV_CMD_NAV_RETURN_TO_LAUNCH))
    assert rtl_target(v) == pytest.approx((2000.0, 0.0), abs=1.0)


# ------------------------------------------------------------------- rally
def _rally(lb: Loopback, points: list[tuple[float, float, float]]) -> list[Any]:
    out = lb.send(M.MAVLink_mission_count_message(1, 1, len(points), RALLY))
    for seq, (x, y, alt) in enumerate(points):
        assert [m.seq for m in out if m.get_type() == "MISSION_REQUEST"] == [seq]
        lat, lon, _ = ORIGIN.to_geodetic(x, y)
        out = lb.send(M.MAVLink_mission_item_int_message(
            1, 1, seq, M.MAV_FRAME_GLOBAL_RELATIVE_ALT, M.MAV_CMD_NAV_RALLY_POINT, 0, 1,
            0, 0, 0, 0, round(lat * 1e7), round(lon * 1e7), alt, RALLY))
    return out


def test_rally_points_upload_download_and_rtl_to_the_nearest() -> None:
    lb = make(airborne=True)
    v = lb.vehicle
    lb.advance(3.0)
    out = _rally(lb, [(3000.0, 0.0, 150.0), (-800.0, 300.0, 90.0)])
    assert [m.type for m in out if m.get_type() == "MISSION_ACK"] == [M.MAV_MISSION_ACCEPTED]
    assert v.params.get("RALLY_TOTAL") == 2
    count = next(m for m in lb.send(M.MAVLink_mission_request_list_message(1, 1, RALLY))
             if m.get_type() == "MISSION_COUNT")
    assert (count.count, count.mission_type) == (2, RALLY)
    got = next(m for m in lb.send(M.MAVLink_mission_request_int_message(1, 1, 1, RALLY))
           if m.get_type() == "MISSION_ITEM_INT")
    assert (got.command, got.mission_type, got.z) == (M.MAV_CMD_NAV_RALLY_POINT, RALLY, 90.0)
    assert len([m for m in lb.send(M.MAVLink_mission_request_list_message(1, 1, 0))
                if m.get_type() == "MISSION_COUNT"]) == 1  # the mission is apart
    # ArduPlane's defaults (RALLY_INCL_HOME 0, RALLY_LIMIT_KM 5): the nearest rally point
    lb.send(cmd_long(M.MAV_CMD_NAV_RETURN_TO_LAUNCH))
    nav = v.autopilot.nav
    assert nav is not None
    assert (nav.x_m, nav.y_m, nav.alt_m) == pytest.approx((-800.0, 300.0, 90.0), abs=0.05)
    # RALLY_INCL_HOME 1: home when it is nearer than every rally point
    v.params.set("RALLY_INCL_HOME", 1)
    lb.send(cmd_long(M.MAV_CMD_DO_SET_MODE, 1, 12))
    lb.send(cmd_long(M.MAV_CMD_NAV_RETURN_TO_LAUNCH))
    assert rtl_target(v) == pytest.approx((0.0, 0.0), abs=0.05)
    # ... and the rally point when it is nearer than home
    lat, lon, _ = ORIGIN.to_geodetic(5000.0, 5000.0)
    lb.send(cmd_long(M.MAV_CMD_DO_SET_HOME, 0, 0, 0, 0, lat, lon, 0))
    lb.send(cmd_long(M.MAV_CMD_DO_SET_MODE, 1, 12))
    lb.send(cmd_long(M.MAV_CMD_NAV_RETURN_TO_LAUNCH))
    assert rtl_target(v) == pytest.approx((-800.0, 300.0), abs=0.05)
    # RALLY_LIMIT_KM: rally points beyond it are ignored
    v.params.set("RALLY_LIMIT_KM", 0.5)
    lb.send(cmd_long(M.MAV_CMD_DO_SET_MODE, 1, 12))
    lb.send(cmd_long(M.MAV_CMD_NAV_RETURN_TO_LAUNCH))
    assert rtl_target(v) == pytest.approx((5000.0, 5000.0), abs=1.0)
    # rally points are in EEPROM: a reboot keeps them
    v.reboot(lb.t_s)
    count = next(m for m in lb.send(M.MAVLink_mission_request_list_message(1, 1, RALLY))
             if m.get_type() == "MISSION_COUNT")
    assert count.count == 2


# ----------------------------------------------------- recovery, turnaround
SLOW_SHIP = BoatSpec(0.0, 0.0, 0.0, 2.0)
NEAR_WATCH = WatchSpec(endurance_s=1200.0, turnaround_s=60.0, recovery_radius_m=300.0)


def _watch_vehicle(watch: WatchSpec | None = NEAR_WATCH) -> Loopback:
    lb = make(airborne=True, ship=SLOW_SHIP, watch=watch, params={"CRASH_DETECT": 1.0})
    lb.advance(3.0)
    return lb


def test_auto_over_the_ship_is_not_recovered_rtl_near_it_is() -> None:
    lb = _watch_vehicle()
    v = lb.vehicle
    lb.advance(8.0)  # AUTO, loitering over home, within 150 m of the ship
    assert not v.airframe.on_ground and v.autopilot.armed
    assert not v.events
    v.set_battery_remaining(0.5)
    sent = lb.send(cmd_long(M.MAV_CMD_NAV_RETURN_TO_LAUNCH)) + lb.advance(1.0)
    assert v.airframe.on_ground and v.on_deck and not v.autopilot.armed
    assert "SIM Recovered on deck" in texts(sent)
    assert [e.kind for e in v.events] == ["recovered"]
    sx, sy = v.ship.position_m(v.t_s) if v.ship else (0.0, 0.0)
    assert (v.airframe.x_m, v.airframe.y_m) == pytest.approx((sx, sy))
    lb.advance(30.0)  # it moves with the ship while waiting
    assert v.airframe.x_m == pytest.approx(v.ship.position_m(v.t_s)[0] if v.ship else 0.0)
    assert v.battery_remaining == pytest.approx(0.5, abs=0.01)
    # the turnaround (60 s): a fresh pack and a new boot on deck
    lb.inbox.clear()
    sent = lb.advance(31.0)
    assert [e.kind for e in v.events] == ["recovered", "turnaround"]
    assert v.battery_remaining == pytest.approx(1.0, abs=1e-3) and v.reboots == 1
    beats = [m for m in sent if m.get_type() == "HEARTBEAT"]
    assert M.MAV_MODE_FLAG_SAFETY_ARMED & beats[-1].base_mode == 0
    assert any(b.custom_mode == 16 for b in beats) and beats[-1].custom_mode == 0
    assert min(m.time_boot_ms for m in sent if m.get_type() == "GLOBAL_POSITION_INT") < 3000
    homes = [m for m in sent if m.get_type() == "HOME_POSITION"]
    hx, _, _ = ORIGIN.to_local(homes[-1].latitude * 1e-7, homes[-1].longitude * 1e-7)
    # home on deck: set at the fix, then every 5 s (the last report may be 5 s old too)
    assert hx == pytest.approx(v.ship.position_m(v.t_s)[0] if v.ship else 0.0, abs=22.0)
    assert v.on_deck and v.airframe.on_ground


def test_no_recovery_without_a_watch() -> None:
    lb = _watch_vehicle(watch=None)
    v = lb.vehicle
    lb.send(cmd_long(M.MAV_CMD_NAV_RETURN_TO_LAUNCH))
    lb.advance(10.0)
    assert not v.airframe.on_ground and v.autopilot.armed and not v.events


def test_rtl_far_from_the_ship_is_recovered_only_once_near_it() -> None:
    ship = BoatSpec(0.0, 0.0, 0.0, 0.0)  # anchored at home
    lb = make(airborne=True, ship=ship, watch=WATCH)
    v = lb.vehicle
    lb.advance(3.0)
    v.airframe.x_m = -3000.0  # the plane is 3 km west of the ship
    lb.send(cmd_long(M.MAV_CMD_NAV_RETURN_TO_LAUNCH))
    lb.advance(60.0)
    assert not v.airframe.on_ground  # 3 km at 22 m/s: not there yet
    lb.advance(120.0)
    assert v.on_deck and not v.autopilot.armed
    assert math.hypot(v.airframe.x_m, v.airframe.y_m) < 1e-6


# ------------------------------------------------------------- real sockets
def test_do_set_home_over_tcp_with_pymavlink(monkeypatch: pytest.MonkeyPatch) -> None:
    from pymavlink import mavutil

    monkeypatch.setenv("MAVLINK20", "1")
    server = SitlServer([config()], ServerOptions(speedup=20.0, base_port=0))
    with ServerThread(server):
        port = server.tcp_ports[0]
        conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", dialect="ardupilotmega",
                                          source_system=255, source_component=190)
        try:
            wait(conn, "HOME_POSITION", timeout_s=15.0)
            lat, lon, _ = ORIGIN.to_geodetic(700.0, -400.0)
            conn.mav.command_int_send(1, 1, M.MAV_FRAME_GLOBAL, M.MAV_CMD_DO_SET_HOME, 0, 0,
                                      0, 0, 0, 0, round(lat * 1e7), round(lon * 1e7), 5.0)
            got = wait(conn, "COMMAND_ACK", cond=lambda m: m.command == M.MAV_CMD_DO_SET_HOME)
            assert got.result == M.MAV_RESULT_ACCEPTED
            home = wait(conn, "HOME_POSITION",
                        cond=lambda m: m.latitude == round(lat * 1e7))
            assert (home.longitude, home.altitude) == (round(lon * 1e7), 5000)
        finally:
            conn.close()


def test_the_servers_journal_records_a_fall() -> None:
    from sitl.faults import build_faults

    cfgs = [config(system_id=1, airborne=True, params={"CRASH_DETECT": 1.0}),
            config(system_id=2, airborne=True, params={"CRASH_DETECT": 1.0})]
    faults = build_faults(["2:battery:at=1,pct=0"], [1, 2], 0)
    server = SitlServer(cfgs, ServerOptions(speedup=100.0, base_port=0), faults)
    with ServerThread(server):
        end = time.monotonic() + 15.0
        while time.monotonic() < end and not any(e.kind == "fell" for e in server.events):
            time.sleep(0.05)
    fell = [e for e in server.events if e.kind == "fell"]
    assert [e.system_id for e in fell] == [2]
    assert fell[0].text.startswith("vehicle 2 fell at t=") and "(battery empty)" in fell[0].text
    assert [e.kind for e in server.events if e.system_id == 2] == ["motor_stopped", "fell"]


def test_gcs_sitl_ship_watch_says_what_it_simulates(capsys: pytest.CaptureFixture[str]) -> None:
    from groundstation.commands import sitl as cmd

    status = cmd.run(["--scenario", "ship-watch", "--base-port", "0", "--speedup", "50",
                      "--duration", "5", "--fast-boot", "--detections", "none"])
    out = capsys.readouterr().out
    assert status == 0
    scenario = load_scenario("ship-watch")
    boat, watch = scenario.boat, scenario.watch
    assert boat is not None and watch is not None
    assert (f"ship: from ({boat.x_m:g}, {boat.y_m:g}) m at {boat.speed_m_s:g} m/s, looping a "
            f"route of {len(boat.route)} waypoints") in out
    assert (f"recovery: RTL or LAND within {watch.recovery_radius_m:g} m of the ship; "
            f"turnaround {watch.turnaround_s:g} s") in out
    assert f"battery: endurance {watch.endurance_s:g} s at 22 m/s" in out
    configs, _faults, _feed, _options = cmd.build(
        cmd.parse_options(["--scenario", "ship-watch", "--base-port", "0"]))
    assert len(configs) == 5 and all(c.ship is not None and c.watch for c in configs)


def test_the_daemons_sim_vehicles_get_the_watch_from_the_scenario() -> None:
    from groundstation.commands.embedded_sim import build_embedded_sim
    from groundstation.daemon.config_parse import parse_config

    scenario = load_scenario("ship-watch")
    sim = build_embedded_sim(parse_config({"vehicles": ["sim:5"]}, {}), scenario)
    for slot in sim.server.slots:
        c = slot.config
        assert c.ship == scenario.boat and c.watch == scenario.watch
        assert c.battery is not None and c.battery.endurance_s == 3600.0
        assert c.params["CRASH_DETECT"] == 1.0
