"""End to end through real MAVLink (tcp on 127.0.0.1) against the built-in simulator: the
operating area becomes each vehicle's enabled geofence at join, and every mission floe
verified is a QGC WPL 110 file that MAVProxy's ``wp load`` reads back item for item."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import pytest
from daemon_run import Journal, events, run_gcs
from pymavlink import mavparm, mavutil, mavwp

from groundstation.commands.embedded_sim import build_embedded_sim
from groundstation.mavlink.codec import mavlink2 as M
from groundstation.mavlink.fence_items import (
    build_fence_items,
    compare_fence,
    fence_circle,
    keep_in_m,
)
from groundstation.mavlink.mission_items import MissionItem
from groundstation.mavlink.mission_verify import compare_missions
from groundstation.runners.report.data import load_run_data
from groundstation.runners.report.page import render_html

RADIUS_M = 4000.0


def _fenced_and_flying(journal: Journal) -> bool:
    return (bool(events(journal, "fence", ok=True))
            and bool(events(journal, "upload", ok=True, purpose="target"))
            and len(events(journal, "params_snapshot", ok=True)) == 2)


def _uploads_in_tlog(path: Path, gcs_system: int) -> list[list[MissionItem]]:
    """Every complete mission upload floe sent, from the tlog: per vehicle (target
    system), the MISSION_ITEM_INTs of mission type MISSION after each MISSION_COUNT, one
    per seq (the last one sent)."""
    log = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
    uploads: list[list[MissionItem]] = []
    current: dict[int, tuple[int, dict[int, MissionItem]]] = {}  # target -> (count, items)

    def close(target: int) -> None:
        count, items = current.pop(target, (0, {}))
        if items and len(items) == count:
            uploads.append([items[i] for i in range(count)])

    while (msg := log.recv_match(type=["MISSION_COUNT", "MISSION_ITEM_INT"])) is not None:
        if msg.get_srcSystem() != gcs_system or msg.mission_type != M.MAV_MISSION_TYPE_MISSION:
            continue
        if msg.get_type() == "MISSION_COUNT":
            close(msg.target_system)
            current[msg.target_system] = (msg.count, {})
            continue
        item = MissionItem.from_message(msg)
        assert item is not None and msg.target_system in current
        current[msg.target_system][1][item.seq] = item
    for target in list(current):
        close(target)
    return uploads


@pytest.mark.timeout(200)
def test_the_area_is_each_vehicles_fence_and_its_missions_are_wpl_files(tmp_path: Path) -> None:
    sims: list[Any] = []

    def vehicles(config: Any, scenario: Any, keys: Any, wind: Any) -> Any:
        sims.append(build_embedded_sim(config, scenario, keys, wind))
        return sims[0]

    daemon, journal = run_gcs(
        tmp_path, "--vehicles", "sim:2", "--scenario", "default", "--launch",
        "--operating-radius", str(RADIUS_M), "--speedup", "40", "--duration", "400",
        until=_fenced_and_flying, timeout_s=170.0, embedded=vehicles,
    )  # fmt: skip
    assert daemon.stop_reason == "test: awaited events seen", daemon.stop_reason
    # the fence went with the join, before the first target mission, as the area is
    fence = fence_circle((0.0, 0.0), RADIUS_M)
    assert fence is not None and fence.radius_m == RADIUS_M  # the area itself
    first = events(journal, "fence", ok=True)[0]
    assert (first["x_m"], first["y_m"], first["radius_m"]) == (0.0, 0.0, fence.radius_m)
    joined = events(journal, "vehicle_joined", vehicle=first["vehicle"])
    targets = events(journal, "upload", ok=True, purpose="target", vehicle=first["vehicle"])
    assert joined and joined[0]["t"] <= first["t"]
    assert not targets or first["t"] <= targets[0]["t"]
    # what the vehicle holds, read from the simulator itself: the area's fence, enabled
    expected = build_fence_items(fence, daemon.origin)
    fenced = {e["vehicle"] for e in events(journal, "fence", ok=True)}
    for vehicle in sims[0].server.vehicles():
        if str(vehicle.system_id) not in fenced:
            continue
        held = [MissionItem(seq=i, command=s.command, frame=s.frame, param1=s.param1,
                            x=s.x, y=s.y, mission_type=M.MAV_MISSION_TYPE_FENCE)
                for i, s in enumerate(vehicle.geo.stores[M.MAV_MISSION_TYPE_FENCE])]
        assert compare_fence(expected, held) == []
        assert vehicle.params.get("FENCE_ENABLE") == 1
        assert int(vehicle.params.get("FENCE_TYPE")) & 4
        assert vehicle.params.get("FENCE_ACTION") == 1
        assert vehicle.fence.present and vehicle.fence.enabled and not vehicle.fence.breached
    # the parameter snapshot of each vehicle, as MAVProxy's ``param load`` reads it: every
    # parameter the vehicle has, with the value it had when floe read it
    for vehicle in sims[0].server.vehicles():
        path = daemon.run_dir / "params" / f"{vehicle.system_id}.parm"
        loaded = mavparm.MAVParmDict()
        loaded.load(str(path), use_excludes=False)
        assert sorted(loaded) == sorted(vehicle.params.names())
        assert loaded["SYSID_THISMAV"] == vehicle.system_id
        assert loaded["AIRSPEED_CRUISE"] == pytest.approx(vehicle.params.get("AIRSPEED_CRUISE"))
    # the WPL files: one per verified upload, in order; MAVProxy's loader gives back what
    # floe sent (the tlog's MISSION_ITEM_INTs), item for item
    uploads = _uploads_in_tlog(daemon.run_dir / "flight.tlog", daemon.config.links.gcs_system_id)
    ok_uploads = events(journal, "upload", ok=True)
    files = sorted((daemon.run_dir / "missions").glob("*/*.waypoints"))
    # (a mission verified just before the stop may still await its set-current and AUTO:
    # its file is written, its journal line not yet)
    assert len(files) >= len(ok_uploads) >= 2
    sent = {tuple((i.seq, i.command, i.x, i.y) for i in up): up for up in uploads}
    for path in files:
        assert path.read_text().startswith("QGC WPL 110\n")
        loader = mavwp.MAVWPLoader()
        count = loader.load(str(path))
        loaded = [MissionItem.from_message(loader.wp(i)) for i in range(count)]
        assert None not in loaded
        key = tuple((i.seq, i.command, i.x, i.y) for i in loaded)  # type: ignore[union-attr]
        assert key in sent, f"{path.name}: not a mission floe sent"
        assert compare_missions(sent[key], loaded, autopilot="exact",  # type: ignore[arg-type]
                                skip_home=False) == []
    # gcs report links both, relative to the page
    out_dir = tmp_path / "report"
    page = render_html(load_run_data(daemon.run_dir), [], out_dir)
    links = re.findall(r'<a href="([^"]+)">', page)
    wanted = {*files, daemon.run_dir / "params" / "1.parm", daemon.run_dir / "params" / "2.parm"}
    assert {(out_dir / link).resolve() for link in links} == {p.resolve() for p in wanted}


def _breach_cleared(journal: Journal) -> bool:
    return any(e["event"] == "statustext" and e["text"] == "Fence breach cleared"
               for e in journal)


@pytest.mark.timeout(200)
def test_a_pilot_flying_out_of_the_area_is_brought_back_by_the_fence(tmp_path: Path) -> None:
    """The pilot takes vehicle 1 in CRUISE at 60 s and flies straight on: floe commands
    nothing more to it, and the autopilot's own fence (set by floe at join) turns it home
    when it crosses the fence.

    CRUISE, not FBWA: with no RC input (throttle closed) ArduPlane's FBWA glides, and the
    simulator's does too, so a plane that was heading inward when the pilot took it came
    down (``SIM Hit ground`` about 45 s later) before it reached the fence; which way it
    headed at 60 mission s depended on the load (2 of 10 runs beside two busy loops).
    CRUISE holds altitude and heading: the breach comes within the area's width."""
    daemon, journal = run_gcs(
        tmp_path, "--vehicles", "sim:1", "--scenario", "default", "--launch",
        "--operating-radius", "1000", "--sim-fault", "1:mode:at=60,mode=CRUISE",
        "--speedup", "40", "--duration", "300",
        until=_breach_cleared, timeout_s=170.0,
    )  # fmt: skip
    assert daemon.stop_reason == "test: awaited events seen", daemon.stop_reason
    [fence] = events(journal, "fence", ok=True)
    assert fence["radius_m"] == 1000
    # floe's own waypoint for the one target inside the area (A, 854 m out) was kept a
    # loiter's room inside the fence: radius + capture overshoot from the edge
    band_m = keep_in_m(120.0, around_boat=False)  # the default scenario loiters 120 m
    clipped = events(journal, "clipped", vehicle="1")
    assert clipped and all(
        abs(math.hypot(c["x_m"], c["y_m"]) - (1000 - band_m)) < 0.5 for c in clipped
    ), (band_m, clipped)
    [override] = events(journal, "override", vehicle="1")
    assert override["mode"] == "CRUISE" and fence["t"] < override["t"]
    [breach] = [e for e in journal if e["event"] == "statustext"
                and e["text"] == "Fence breached: Polygon"]
    assert breach["t"] > override["t"]
    # the vehicle's own RTL is the next mode it reports. The daemon reads the mode from the
    # 1 Hz HEARTBEAT, and at 40x a frame read 25 ms of wall late is 1 mission s late: the
    # bound is two heartbeats (1.055 s was seen beside two busy loops)
    modes_after = [e for e in events(journal, "mode", vehicle="1") if e["t"] >= breach["t"]]
    assert modes_after and modes_after[0]["mode"] == "RTL"
    assert modes_after[0]["cause"] == "vehicle" and modes_after[0]["t"] - breach["t"] < 2.0
    # nothing commanding went to the pilot's vehicle after the override: no transfer, no
    # parameter, no command but the telemetry rates
    log = mavutil.mavlink_connection(str(daemon.run_dir / "flight.tlog"), dialect="ardupilotmega")
    gcs = daemon.config.links.gcs_system_id
    after: list[str] = []
    heartbeats_after = 0
    while (msg := log.recv_match()) is not None:
        late = msg.get_srcSystem() == gcs and getattr(msg, "_timestamp", 0) > override["unix_s"]
        heartbeats_after += late and msg.get_type() == "HEARTBEAT"
        if (late
                and msg.get_type() not in ("HEARTBEAT", "REQUEST_DATA_STREAM", "TIMESYNC",
                                           "SYSTEM_TIME")):
            kind = msg.get_type()
            if kind == "COMMAND_LONG" and msg.command == M.MAV_CMD_SET_MESSAGE_INTERVAL:
                continue
            after.append(kind)
    assert heartbeats_after > 10  # the tlog does hold floe's frames of that time
    assert after == []
