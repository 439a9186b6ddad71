"""The simulator's side of trust: a plane left in a pilot mode glides into the ground and
stays there (armed, as ArduPlane with CRASH_DETECT = 0), AUTO on the ground does not make
it fly, HEARTBEAT system_status and EXTENDED_SYS_STATE landed_state as ArduPlane reports
them, the kill/restart fault, and an import graph of ``sitl`` without cycles."""

from __future__ import annotations

import ast
import asyncio
from pathlib import Path
from typing import Any

import pytest

from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import MavlinkDecoder
from groundstation.mavlink.codec import mavlink2 as M
from sitl.autopilot import AUTO, FBWA, MANUAL, RTL
from sitl.faults import FaultError, FaultEvent, VehicleFaults, apply_fault, parse_fault_spec
from sitl.loopback import Loopback
from sitl.mission_store import StoredItem
from sitl.server import ServerOptions, SitlServer
from sitl.vehicle import SimVehicle, VehicleConfig

ORIGIN = GeoOrigin(78.93, 11.92)


def vehicle(airborne: bool = True, alt_m: float = 100.0) -> Loopback:
    config = VehicleConfig(
        1, ORIGIN, 78.93, 11.92, airborne=airborne, airborne_alt_m=alt_m, fast_boot=True
    )
    lb = Loopback(SimVehicle(config))
    lb.advance(3.0)
    return lb


def set_mode(lb: Loopback, mode: int) -> None:
    lb.vehicle.apply_fault(FaultEvent(lb.t_s, "mode", mode=mode), lb.t_s)


def last(lb: Loopback, kind: str) -> Any:
    msgs = lb.take(kind)
    assert msgs, f"no {kind}"
    return msgs[-1]


@pytest.mark.parametrize("mode", [FBWA, MANUAL, 2])
def test_pilot_mode_without_rc_glides_into_the_ground_and_stays_armed(mode: int) -> None:
    lb = vehicle(alt_m=100.0)
    assert last(lb, "HEARTBEAT").system_status == M.MAV_STATE_ACTIVE
    assert last(lb, "EXTENDED_SYS_STATE").landed_state == M.MAV_LANDED_STATE_IN_AIR
    set_mode(lb, mode)
    lb.advance(10.0)
    pos = last(lb, "GLOBAL_POSITION_INT")
    assert 60_000 < pos.relative_alt < 90_000  # ~2.2 m/s sink: 100 m -> ~78 m after 10 s
    hit = lb.run_until(
        lambda m: m.get_type() == "STATUSTEXT" and m.text.startswith("SIM Hit ground"), 60.0
    )
    assert hit is not None and lb.t_s < 3.0 + 60.0
    lb.advance(5.0)
    af = lb.vehicle.airframe
    assert af.on_ground and af.alt_m == 0.0 and af.speed_m_s == 0.0
    assert abs(last(lb, "GLOBAL_POSITION_INT").relative_alt) < 500
    assert last(lb, "VFR_HUD").groundspeed < 0.5
    hb = last(lb, "HEARTBEAT")
    assert hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED  # ArduPlane does not disarm
    assert hb.custom_mode == mode
    assert hb.system_status == M.MAV_STATE_STANDBY  # armed but not flying
    assert last(lb, "EXTENDED_SYS_STATE").landed_state == M.MAV_LANDED_STATE_ON_GROUND


def test_auto_on_the_ground_does_not_fly_unless_on_a_takeoff_item() -> None:
    lb = vehicle(alt_m=30.0)
    set_mode(lb, FBWA)
    assert lb.run_until(lambda m: m.get_type() == "STATUSTEXT" and "Hit ground" in m.text, 60.0)
    x0, y0 = lb.vehicle.airframe.x_m, lb.vehicle.airframe.y_m
    for mode in (AUTO, RTL):  # current item is the unlimited loiter: not a takeoff
        set_mode(lb, mode)
        lb.advance(20.0)
        af = lb.vehicle.airframe
        assert af.on_ground and af.alt_m == 0.0 and (af.x_m, af.y_m) == (x0, y0)
        assert last(lb, "HEARTBEAT").custom_mode == mode
        assert last(lb, "EXTENDED_SYS_STATE").landed_state == M.MAV_LANDED_STATE_ON_GROUND
    # a takeoff item as current item: AUTO flies (TAKEOFF state while climbing)
    lb.vehicle.store.write(
        1, StoredItem(M.MAV_CMD_NAV_TAKEOFF, M.MAV_FRAME_GLOBAL_RELATIVE_ALT, z=50.0)
    )
    set_mode(lb, FBWA)
    lb.vehicle.autopilot.current_seq = 1
    set_mode(lb, AUTO)
    lb.advance(3.0)
    assert not lb.vehicle.airframe.on_ground
    assert last(lb, "EXTENDED_SYS_STATE").landed_state == M.MAV_LANDED_STATE_TAKEOFF


def test_the_takeoff_climbs_out_faster_than_the_cruise_then_cruises() -> None:
    """As ArduPilot SITL's plane: ~28 m/s airspeed during the NAV_TAKEOFF climb-out (issue
    25 measured 27.6-28.1), the cruise (AIRSPEED_CRUISE, 22) once the take-off is done."""
    lb = vehicle(airborne=False)
    lb.vehicle.store.write(
        1, StoredItem(M.MAV_CMD_NAV_TAKEOFF, M.MAV_FRAME_GLOBAL_RELATIVE_ALT, z=100.0)
    )
    lb.vehicle.store.write(
        2, StoredItem(M.MAV_CMD_NAV_LOITER_UNLIM, M.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                       x=round(78.94 * 1e7), y=round(11.92 * 1e7), z=100.0)
    )
    lb.vehicle.autopilot.armed = True
    lb.vehicle.autopilot.current_seq = 1
    set_mode(lb, AUTO)
    lb.advance(18.0)  # still climbing (at most 5 m/s)
    climb = lb.take("VFR_HUD")
    assert lb.vehicle.autopilot.nav is not None and lb.vehicle.autopilot.nav.kind == "takeoff"
    assert 27.5 <= climb[-1].airspeed <= 28.0 + 1e-6 and climb[-1].climb > 1.0
    done = lb.run_until(
        lambda m: m.get_type() == "STATUSTEXT" and m.text.startswith("Takeoff complete"), 60.0
    )
    assert done is not None
    lb.advance(10.0)
    assert last(lb, "VFR_HUD").airspeed == pytest.approx(22.0)
    assert lb.vehicle.params.get("AIRSPEED_CRUISE") == 22.0


def test_system_status_while_booting_and_in_a_failsafe() -> None:
    config = VehicleConfig(1, ORIGIN, 78.93, 11.92)  # slow boot: INITIALISING for 2 s
    lb = Loopback(SimVehicle(config))
    lb.advance(1.0)
    hb = last(lb, "HEARTBEAT")
    assert hb.custom_mode == 16 and hb.system_status == M.MAV_STATE_CALIBRATING
    lb.advance(3.0)
    hb = last(lb, "HEARTBEAT")
    assert hb.custom_mode == MANUAL and hb.system_status == M.MAV_STATE_STANDBY
    lb.vehicle.apply_fault(FaultEvent(lb.t_s, "battery", fraction=0.05), lb.t_s)
    lb.advance(2.0)
    assert last(lb, "HEARTBEAT").system_status == M.MAV_STATE_CRITICAL


def test_kill_silences_the_vehicle_then_it_reboots_on_the_ground() -> None:
    lb = vehicle(alt_m=100.0)
    lb.advance(30.0)
    store_before = list(lb.vehicle.store.items)
    lb.inbox.clear()
    lb.vehicle.apply_fault(FaultEvent(lb.t_s, "kill", duration_s=20.0), lb.t_s)
    assert not lb.vehicle.alive
    assert lb.advance(19.5) == []  # dead: nothing at all
    arm = M.MAVLink_command_long_message(
        1, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0
    )
    assert lb.send(arm) == [] and not lb.vehicle.received  # and it hears nothing
    lb.advance(0.8)  # back at +20 s; first HEARTBEAT 0.137 s later (de-phased streams)
    assert lb.vehicle.alive and lb.vehicle.reboots == 1 and lb.vehicle.kills == 1
    hb = last(lb, "HEARTBEAT")
    assert hb.custom_mode == 16 and not hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED
    assert last(lb, "SYSTEM_TIME").time_boot_ms < 1_000
    lb.advance(2.0)
    hb = last(lb, "HEARTBEAT")
    assert hb.custom_mode == MANUAL and not hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED
    af = lb.vehicle.airframe
    assert af.on_ground and af.alt_m == 0.0  # not airborne again, although configured so
    assert last(lb, "EXTENDED_SYS_STATE").landed_state == M.MAV_LANDED_STATE_ON_GROUND
    assert list(lb.vehicle.store.items) == store_before  # mission kept in "EEPROM"
    # the received-command log records what reaches it, with its state at the time
    lb.send(arm)
    got = lb.vehicle.received[-1]
    assert got.kind == "COMMAND_LONG" and got.command == M.MAV_CMD_COMPONENT_ARM_DISARM
    assert got.src_system == 255 and not got.armed and got.on_ground


def test_kill_fault_spec() -> None:
    [(sysid, kind, options)] = parse_fault_spec("2:kill:at=60,for=30", 3)
    faults = VehicleFaults(1)
    apply_fault(faults, kind, options)
    assert sysid == 2 and faults.events == [FaultEvent(60.0, "kill", duration_s=30.0)]
    assert faults.due_events(61.0) == faults.events
    with pytest.raises(FaultError, match="kill needs for"):
        parse_fault_spec("1:kill:at=5", 2)


def test_server_drops_and_refuses_connections_while_the_vehicle_is_dead() -> None:
    async def main() -> dict[str, Any]:
        config = VehicleConfig(1, ORIGIN, 78.93, 11.92, airborne=True, fast_boot=True)
        faults = VehicleFaults(1)
        apply_fault(faults, "kill", {"at": "3", "for": "4"})
        server = SitlServer([config], ServerOptions(speedup=10.0, base_port=0), {1: faults})
        await server.start()
        task = asyncio.create_task(server.run(duration_s=30.0))
        reader, writer = await asyncio.open_connection("127.0.0.1", server.tcp_ports[0])
        decoder = MavlinkDecoder()
        seen: dict[str, Any] = {"before": 0, "closed_at": None, "after": []}
        while True:  # until the server closes the connection (the kill at t = 3 s)
            data = await asyncio.wait_for(reader.read(65536), 5.0)
            if not data:
                seen["closed_at"] = server.t_s
                break
            seen["before"] += len(decoder.feed(data))
        writer.close()
        while server.t_s < 7.5:  # dead until 7 s: the vehicle is back after that
            await asyncio.sleep(0.01)
        reader, writer = await asyncio.open_connection("127.0.0.1", server.tcp_ports[0])
        decoder = MavlinkDecoder()
        while not [m for m in seen["after"] if m.get_type() == "HEARTBEAT"]:
            seen["after"] += decoder.feed(await asyncio.wait_for(reader.read(65536), 5.0))
        writer.close()
        server.stop()
        await task
        await server.close()
        return seen

    seen = asyncio.run(asyncio.wait_for(main(), 30.0))
    assert seen["before"] > 0 and 3.0 <= seen["closed_at"] < 4.5
    hb = next(m for m in seen["after"] if m.get_type() == "HEARTBEAT")
    assert not hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED


def _imports(path: Path) -> set[str]:
    """Every ``sitl.*`` module a file imports, TYPE_CHECKING blocks and functions included."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("sitl"):
            if node.module == "sitl":
                out |= {f"sitl.{a.name}" for a in node.names}
            else:
                out.add(node.module)
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("sitl.")}
    return out


def test_sitl_import_graph_has_no_cycle() -> None:
    root = Path(__file__).resolve().parent.parent / "sitl"
    graph = {f"sitl.{p.stem}": _imports(p) for p in root.glob("*.py") if p.stem != "__init__"}
    state: dict[str, int] = {}

    def visit(node: str, path: list[str]) -> None:
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            assert state.get(nxt) != 1, "import cycle: " + " -> ".join([*path, node, nxt])
            if nxt not in state:
                visit(nxt, [*path, node])
        state[node] = 2

    for module in sorted(graph):
        if module not in state:
            visit(module, [])
    assert "sitl.vehicle" not in graph["sitl.command_handler"] | graph["sitl.vehicle_messages"]
