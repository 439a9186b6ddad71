"""The built-in vehicles in wind, as ArduPlane: VFR_HUD airspeed and ground speed, ground
velocity in GLOBAL_POSITION_INT/GPS_RAW_INT, WIND (the EKF-like estimate, EXTRA3 at
1 Hz), ArduPilot SITL's SIM_WIND_* parameters, ``gcs sitl --wind`` (built-in and
``--ardupilot``) and the embedded simulator's ``wind``. Times are mission (simulated)
times; the socket test only bounds wall time."""

from __future__ import annotations

import asyncio
import itertools
import math
import shutil
from pathlib import Path
from typing import Any

import pytest
from environment import need

from domain.geodesy import GeoOrigin
from domain.wind_triangle import wind_vector_m_s
from groundstation.commands import sitl as cmd
from groundstation.commands import sitl_ardupilot
from groundstation.commands.embedded_sim import build_embedded_sim
from groundstation.daemon.config_parse import parse_config
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, mavlink2
from sitl.ardupilot import ArduPilotLaunch, ardupilot_commands, launch
from sitl.loopback import Loopback
from sitl.server import ServerOptions, SitlServer
from sitl.vehicle import SimVehicle, VehicleConfig
from world.wind import WindField, WindSpec

M = mavlink2
ORIGIN = GeoOrigin(78.93, 11.92)
FROM_WEST_10 = WindSpec(10.0, 270.0)  # the air moves east at 10 m/s


def config(**kw: Any) -> VehicleConfig:
    return VehicleConfig(1, ORIGIN, 78.93, 11.92, fast_boot=True, **kw)


def air_vector(airspeed_m_s: float, compass_cdeg: float) -> tuple[float, float]:
    """(east, north) of the air velocity at a compass heading in centidegrees."""
    a = math.radians(compass_cdeg / 100.0)
    return airspeed_m_s * math.sin(a), airspeed_m_s * math.cos(a)


def ground_vector(gpi: Any) -> tuple[float, float]:
    """(east, north) m/s of GLOBAL_POSITION_INT (vx north, vy east, cm/s)."""
    return gpi.vy / 100.0, gpi.vx / 100.0


def param_set(name: str, value: float) -> Any:
    return M.MAVLink_param_set_message(1, 1, name.encode(), value, M.MAV_PARAM_TYPE_REAL32)


def cmd_long(command: int, *p: float) -> Any:
    params = [*p, *([0.0] * (7 - len(p)))]
    return M.MAVLink_command_long_message(1, 1, command, 0, *params)


# --------------------------------------------------------------- over TCP


def _fly_over_tcp(vehicle: VehicleConfig, duration_s: float) -> list[Any]:
    """Serve ``vehicle`` on an ephemeral 127.0.0.1 port at 50x for ``duration_s``
    simulated seconds and return what a TCP client received."""

    async def body() -> list[Any]:
        server = SitlServer([vehicle], ServerOptions(speedup=50.0, base_port=0))
        await server.start()
        runner = asyncio.create_task(server.run(duration_s))
        got: list[Any] = []
        try:
            reader, writer = await asyncio.open_connection("127.0.0.1", server.tcp_ports[0])
            writer.write(MavlinkEncoder(255, 190).encode(M.MAVLink_heartbeat_message(
                6, 8, 0, 0, 0, 3)))
            decoder = MavlinkDecoder()
            while not runner.done():
                try:
                    data = await asyncio.wait_for(reader.read(65536), 0.5)
                except TimeoutError:
                    continue
                got += decoder.feed(data)
            writer.close()
        finally:
            server.stop()
            await runner
            await server.close()
        return got

    return asyncio.run(asyncio.wait_for(body(), 60.0))


def test_over_tcp_airspeed_22_and_groundspeed_differs_by_the_wind_along_track() -> None:
    msgs = _fly_over_tcp(config(airborne=True, wind=FROM_WEST_10), 60.0)
    gpi = [m for m in msgs if m.get_type() == "GLOBAL_POSITION_INT"]
    huds = [m for m in msgs if m.get_type() == "VFR_HUD"]
    assert len(gpi) >= 50 and len(huds) >= 50
    wx, wy = FROM_WEST_10.mean_xy_m_s
    for m in gpi:  # ground velocity = air vector (22 m/s along the yaw) + wind
        ve, vn = ground_vector(m)
        ae, an = air_vector(22.0, m.hdg)
        assert (ve - ae, vn - an) == pytest.approx((wx, wy), abs=0.1)
    last_gpi = None
    speeds = []
    for m in msgs:  # VFR_HUD follows GLOBAL_POSITION_INT in the same tick
        if m.get_type() == "GLOBAL_POSITION_INT":
            last_gpi = m
        elif m.get_type() == "VFR_HUD" and last_gpi is not None:
            assert m.airspeed == pytest.approx(22.0, abs=0.01)
            ve, vn = ground_vector(last_gpi)
            track = math.atan2(vn, ve)
            along = wx * math.cos(track) + wy * math.sin(track)
            cross = wx * math.sin(track) - wy * math.cos(track)
            # the wind triangle: |v_g| = w_along + sqrt(V^2 - w_cross^2)
            assert m.groundspeed == pytest.approx(along + math.sqrt(22.0**2 - cross**2), abs=0.05)
            assert m.groundspeed == pytest.approx(math.hypot(ve, vn), abs=0.02)
            assert abs((m.heading - last_gpi.hdg / 100 + 180) % 360 - 180) <= 0.51  # yaw
            speeds.append(m.groundspeed)
    # a loiter flies downwind (about 32 m/s over ground) and upwind (about 12)
    assert max(speeds) > 29.0 and min(speeds) < 15.0
    winds = [m for m in msgs if m.get_type() == "WIND"]
    assert len(winds) >= 50 and winds[-1].speed == pytest.approx(10.0, abs=0.1)


# --------------------------------------------------------------- loopback


def test_gps_reports_ground_speed_and_course_over_ground() -> None:
    lb = Loopback(SimVehicle(config(airborne=True, wind=WindSpec(12.0, 0.0))))  # from north
    lb.advance(30.0)
    msgs = lb.inbox
    checked = 0
    for i, m in enumerate(msgs):  # GPS_RAW_INT precedes GLOBAL_POSITION_INT in a tick
        if m.get_type() != "GPS_RAW_INT":
            continue
        gpi = next((n for n in msgs[i:] if n.get_type() == "GLOBAL_POSITION_INT"), None)
        if gpi is None:
            continue
        ve, vn = ground_vector(gpi)
        assert m.vel == pytest.approx(100 * math.hypot(ve, vn), abs=2)
        cog = math.degrees(math.atan2(ve, vn)) % 360
        assert abs((m.cog / 100 - cog + 180) % 360 - 180) < 0.5
        checked += 1
    assert checked >= 25
    # in a cross wind course and heading differ (crab): at least once by > 20 degrees
    gpi = lb.take("GLOBAL_POSITION_INT")
    gps = lb.take("GPS_RAW_INT")
    pairs = zip(gps, gpi, strict=True)
    assert max(abs((g.cog - p.hdg + 18000) % 36000 - 18000) for g, p in pairs) > 2000


def test_wind_estimate_converges_after_take_off_in_mission_time() -> None:
    lb = Loopback(SimVehicle(config(airborne=True, wind=FROM_WEST_10)))
    lb.advance(40.0)
    winds = lb.take("WIND")
    assert 39 <= len(winds) <= 41  # EXTRA3 at 1 Hz
    speeds = [w.speed for w in winds]
    assert speeds[0] < 2.0 and all(b >= a - 1e-4 for a, b in itertools.pairwise(speeds))
    # first-order lag, tau 5 s: within 5 % after 15 s, 0.1 % after 35 s
    assert speeds[15] == pytest.approx(10.0, rel=0.05)
    assert speeds[-1] == pytest.approx(10.0, rel=0.001)
    # ArduPlane's direction: degrees(atan2(-wind.y, -wind.x)) of the NED air motion, i.e.
    # where the wind comes from, in (-180, 180]: from the west is -90
    assert all(w.direction == pytest.approx(-90.0, abs=0.01) for w in winds[1:])
    assert all(w.speed_z == 0.0 for w in winds)


def test_no_estimate_before_the_vehicle_flies_and_no_drift_on_the_ground() -> None:
    lb = Loopback(SimVehicle(config(wind=WindSpec(15.0, 90.0, 3.0))))
    lb.advance(20.0)
    winds = lb.take("WIND")
    assert len(winds) >= 19
    assert all(w.speed == 0.0 and w.direction == -180.0 for w in winds)  # atan2(-0, -0)
    positions = {(m.lat, m.lon) for m in lb.take("GLOBAL_POSITION_INT") if m.lat}
    assert len(positions) == 1
    assert all(m.groundspeed == 0.0 for m in lb.take("VFR_HUD"))


def test_wind_rate_follows_request_data_stream_and_set_message_interval() -> None:
    lb = Loopback(SimVehicle(config(airborne=True, wind=FROM_WEST_10)))
    lb.send(M.MAVLink_request_data_stream_message(1, 1, M.MAV_DATA_STREAM_EXTRA3, 4, 1))
    lb.inbox.clear()
    lb.advance(10.0)
    assert 38 <= len(lb.take("WIND")) <= 42
    lb.send(cmd_long(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_WIND, 500_000))
    lb.inbox.clear()
    lb.advance(10.0)
    assert 19 <= len(lb.take("WIND")) <= 21
    lb.send(cmd_long(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_WIND, -1))
    lb.inbox.clear()
    lb.advance(5.0)
    assert lb.take("WIND") == [] and lb.take("SYSTEM_TIME")


def test_param_set_sim_wind_changes_the_flown_wind() -> None:
    lb = Loopback(SimVehicle(config(airborne=True)))
    out = lb.send(M.MAVLink_param_request_list_message(1, 1))
    values = {m.param_id: m.param_value for m in out}
    assert (values["SIM_WIND_SPD"], values["SIM_WIND_DIR"], values["SIM_WIND_TURB"]) == (
        0.0, 180.0, 0.0)  # calm: ArduPilot SITL's defaults
    lb.advance(5.0)
    gpi = lb.take("GLOBAL_POSITION_INT")[-1]
    assert ground_vector(gpi) == pytest.approx(air_vector(22.0, gpi.hdg), abs=0.02)
    out = lb.send(param_set("SIM_WIND_SPD", 12.0))  # MAVProxy: param set SIM_WIND_SPD 12
    assert out[0].param_id == "SIM_WIND_SPD" and out[0].param_value == 12.0
    lb.inbox.clear()
    lb.advance(30.0)
    for m in lb.take("GLOBAL_POSITION_INT")[1:]:  # from 180 (south): the air moves north
        ve, vn = ground_vector(m)
        ae, an = air_vector(22.0, m.hdg)
        assert (ve - ae, vn - an) == pytest.approx((0.0, 12.0), abs=0.1)
    wind = lb.take("WIND")[-1]
    assert wind.speed == pytest.approx(12.0, rel=0.01) and abs(abs(wind.direction) - 180) < 1
    lb.send(param_set("SIM_WIND_DIR", 90.0))
    assert lb.send(param_set("SIM_WIND_SPD", float("nan")))[0].param_value == 12.0  # refused
    assert lb.send(param_set("SIM_WIND_SPD", -3.0))[0].param_value == 12.0
    lb.inbox.clear()
    lb.advance(5.0)
    m = lb.take("GLOBAL_POSITION_INT")[-1]
    ve, vn = ground_vector(m)
    ae, an = air_vector(22.0, m.hdg)
    assert (ve - ae, vn - an) == pytest.approx((-12.0, 0.0), abs=0.1)  # from the east


def test_vehicles_fly_the_seeded_field_and_turb_sets_the_gusts() -> None:
    spec = WindSpec(8.0, 45.0, 2.0, 4.0)
    vehicle = SimVehicle(config(airborne=True, wind=spec, wind_seed=7))
    field = WindField(spec, 7)
    assert [vehicle.wind.at(t, vehicle.params) for t in (0.0, 3.3, 50.0)] == [
        field.at(t) for t in (0.0, 3.3, 50.0)]
    assert vehicle.params.get("SIM_WIND_TURB") == 2.0
    assert vehicle.params.get("SIM_WIND_DIR") == 45.0
    vehicle.params.set("SIM_WIND_TURB", 0.0)
    assert vehicle.wind.at(50.0, vehicle.params) == pytest.approx(wind_vector_m_s(8.0, 45.0))


def test_calm_vehicle_reports_as_before_and_wind_zero() -> None:
    lb = Loopback(SimVehicle(config(airborne=True)))
    lb.advance(20.0)
    assert all(m.airspeed == m.groundspeed for m in lb.take("VFR_HUD"))
    gps, gpi = lb.take("GPS_RAW_INT"), lb.take("GLOBAL_POSITION_INT")
    assert all(g.cog == p.hdg for g, p in zip(gps, gpi, strict=False))
    assert {(w.speed, w.speed_z) for w in lb.take("WIND")} == {(0.0, 0.0)}


# ---------------------------------------------------------- command lines


@pytest.mark.parametrize("text", ["abc", "10", "10,400", "nan,90", "-5,90", "10,90,1,2", "99,90"])
def test_gcs_sitl_bad_wind_is_one_line_exit_2(
    text: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cmd.run(["--base-port", "0", "--duration", "1", f"--wind={text}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--wind" in err and "Traceback" not in err


def test_gcs_sitl_wind_overrides_the_scenarios_and_seeds_like_the_icebergs(tmp_path: Path) -> None:
    scenario = tmp_path / "s.yaml"
    scenario.write_text(
        "name: t\ndescription: t\nduration_s: 100\norigin: {lat_deg: 70.0, lon_deg: 20.0}\n"
        "fleet: {count: 2}\ntargets:\n  list:\n    - {id: A, x_m: 800, y_m: 300}\n"
        "wind: {speed_m_s: 6, from_deg: 30, gust_m_s: 1}\n",
        encoding="utf-8",
    )
    base = ["--scenario", str(scenario), "--base-port", "0", "--seed", "3"]
    configs, *_ = cmd.build(cmd.parse_options(base))
    assert {(c.wind, c.wind_seed) for c in configs} == {(WindSpec(6.0, 30.0, 1.0), 3)}
    configs, *_ = cmd.build(cmd.parse_options([*base, "--wind", "10,270,2"]))
    assert {c.wind for c in configs} == {WindSpec(10.0, 270.0, 2.0)}
    configs, *_ = cmd.build(cmd.parse_options(["--base-port", "0"]))
    assert configs[0].wind.calm


def test_embedded_sim_takes_a_wind(tmp_path: Path) -> None:
    config = parse_config({"vehicles": ["sim:2"], "seed": 5, "sim_airborne": True}, {})
    sim = build_embedded_sim(config, None, wind=WindSpec(8.0, 90.0, 1.0))
    assert {(s.config.wind, s.config.wind_seed) for s in sim.server.slots} == {
        (WindSpec(8.0, 90.0, 1.0), 5)}
    assert all(s.config.wind.calm for s in build_embedded_sim(config, None).server.slots)

    async def fly() -> list[tuple[float, float]]:
        await sim.start()
        try:
            sim.server.tick()
            return [v.wind.at(12.0, v.params) for v in sim.server.vehicles()]
        finally:
            await sim.close()

    assert asyncio.run(fly()) == [WindField(WindSpec(8.0, 90.0, 1.0), 5).at(12.0)] * 2


def test_ardupilot_sitl_gets_the_wind_in_a_second_defaults_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    plane = tmp_path / "plane.parm"
    launches = ardupilot_commands(
        tmp_path / "arduplane", 2, 10.0, (78.93, 11.92), plane, tmp_path / "w",
        wind=WindSpec(10.0, 270.0, 2.0),
    )
    for x in launches:
        wind_file = x.cwd / "floe-wind.parm"
        assert x.argv[x.argv.index("--defaults") + 1] == f"{plane},{wind_file}"
        lines = [ln for ln in x.wind_defaults.splitlines() if not ln.startswith("#")]
        assert lines == ["SIM_WIND_SPD 10", "SIM_WIND_DIR 270", "SIM_WIND_TURB 2"]
    calm = ardupilot_commands(tmp_path / "arduplane", 1, 10.0, (78.93, 11.92), plane, tmp_path)
    assert calm[0].argv[calm[0].argv.index("--defaults") + 1] == str(plane)

    # gcs sitl --ardupilot --wind: the launcher is given those command lines
    binary = tmp_path / "arduplane"
    binary.write_text("", encoding="utf-8")
    plane.write_text("", encoding="utf-8")
    seen: list[list[ArduPilotLaunch]] = []

    async def fake_launch(launches: list[ArduPilotLaunch], *_: Any) -> int:
        seen.append(launches)
        return 0

    monkeypatch.setattr(sitl_ardupilot, "launch", fake_launch)
    argv = ["--ardupilot", str(binary), "--ardupilot-defaults", str(plane), "--detections", "none"]
    assert cmd.run([*argv, "--wind", "12,180"]) == 0
    assert cmd.run(argv) == 0
    windy, default = seen
    assert "SIM_WIND_SPD 12\nSIM_WIND_DIR 180\n" in windy[0].wind_defaults
    assert windy[0].argv[-3] == f"{plane},{windy[0].cwd / 'floe-wind.parm'}"
    assert default[0].wind_defaults == "" and default[0].argv[-3] == str(plane)

    # the launcher writes the file into the instance's directory before starting it
    true = shutil.which("true")
    need(true is not None, "no `true` binary to stand in for ArduPilot")
    assert true is not None
    one = ArduPilotLaunch(0, 1, [true], tmp_path / "run" / "I0", 1, 3, "SIM_WIND_SPD 5\n")
    asyncio.run(launch([one], None, None, ORIGIN, 10.0, 100.0))
    assert (one.cwd / "floe-wind.parm").read_text(encoding="ascii") == "SIM_WIND_SPD 5\n"
