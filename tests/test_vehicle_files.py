"""Files other ground stations open (mavlink/mission_files.py, daemon/vehicle_files.py) and
the parameter download that fills the ``.parm`` (mavlink/param_list.py)."""

from __future__ import annotations

import errno
import os
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavparm, mavwp

from domain.geodesy import GeoOrigin
from groundstation import storage
from groundstation.daemon.vehicle_files import VehicleFiles
from groundstation.mavlink.codec import mavlink2 as M
from groundstation.mavlink.fence_items import FenceCircle, build_fence_items, compare_fence
from groundstation.mavlink.mission_files import parm_text, wpl_text
from groundstation.mavlink.mission_items import (
    ChangeSpeed,
    LoiterTime,
    LoiterUnlimited,
    MissionItem,
    Takeoff,
    Waypoint,
    build_mission_items,
)
from groundstation.mavlink.mission_transfer import Send, TransferCode
from groundstation.mavlink.mission_verify import compare_missions
from groundstation.mavlink.param_list import ParamList

ORIGIN = GeoOrigin(-64.77, -64.05)  # west and south: negative lat/lon


def mission() -> list[MissionItem]:
    return build_mission_items([
        Takeoff(120.0), ChangeSpeed(19.5), LoiterTime(-3210.7, 4567.9, 120.25, 45),
        Waypoint(1234.5, -987.6, 130.0), LoiterUnlimited(50.0, 60.0, 120.0, 150.0, False),
    ], ORIGIN)  # fmt: skip


def test_mavproxys_wp_load_gives_back_the_mission_item_for_item(tmp_path: Path) -> None:
    items = mission()
    path = tmp_path / "m.waypoints"
    path.write_text(wpl_text(items))
    assert path.read_text().splitlines()[0] == "QGC WPL 110"
    assert all(len(line.split("\t")) == 12 for line in path.read_text().splitlines()[1:])
    loader = mavwp.MAVWPLoader()
    assert loader.load(str(path)) == len(items)
    back = [MissionItem.from_message(loader.wp(i)) for i in range(loader.count())]
    assert None not in back
    assert compare_missions(items, back, autopilot="exact", skip_home=False) == []  # type: ignore[arg-type]
    # degE7 exactly, not the 6 decimals (~10 cm) of "%f"
    assert [b.x for b in back] == [i.x for i in items]  # type: ignore[union-attr]
    assert [b.y for b in back] == [i.y for i in items]  # type: ignore[union-attr]


def test_mavproxys_param_load_reads_the_snapshot(tmp_path: Path) -> None:
    values = {"WP_LOITER_RAD": 60.0, "AIRSPEED_CRUISE": 22.5, "BATT_LOW_VOLT": 10.5,
              "A_VERY_LONG_NAME": -3.0, "SIM_WIND_DIR": 0.1}
    path = tmp_path / "v.parm"
    path.write_text(parm_text(values))
    loaded = mavparm.MAVParmDict()
    loaded.load(str(path), use_excludes=False)
    assert dict(loaded) == pytest.approx(values)
    assert path.read_text().splitlines()[0] == "AIRSPEED_CRUISE  22.5"  # sorted, padded


def test_the_fence_read_back_as_arduplane_stores_it_verifies() -> None:
    fence = FenceCircle(100.0, -50.0, 10300.0)
    sent = build_fence_items(fence, ORIGIN)
    assert [(i.command, i.mission_type, i.param1) for i in sent] == [
        (M.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION, M.MAV_MISSION_TYPE_FENCE, 10300.0),
        (M.MAV_CMD_NAV_FENCE_RETURN_POINT, M.MAV_MISSION_TYPE_FENCE, 0.0)]
    # ArduPlane reads back frame GLOBAL, z 0
    back = [MissionItem(i.seq, i.command, frame=M.MAV_FRAME_GLOBAL, param1=i.param1, x=i.x,
                        y=i.y, mission_type=i.mission_type) for i in sent]
    assert compare_fence(sent, back) == []
    moved = build_fence_items(FenceCircle(100.0, -40.0, 10300.0), ORIGIN)
    assert [m.field for m in compare_fence(sent, moved)] == ["x", "x"]
    smaller = build_fence_items(FenceCircle(100.0, -50.0, 10000.0), ORIGIN)
    assert [m.field for m in compare_fence(sent, smaller)] == ["param1"]
    assert [m.field for m in compare_fence(sent, sent[:1])] == ["count"]


def test_a_full_disk_is_a_logged_fault_and_the_next_write_after_it_succeeds(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    lines: list[tuple[str, dict[str, Any]]] = []
    files = VehicleFiles(tmp_path, lambda event, **fields: lines.append((event, fields)))
    real_fsync = os.fsync

    def full(fd: int) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(storage.os, "fsync", full)
    assert files.mission("plane/1", "target", mission()) is None
    assert files.mission("plane/1", "target", mission()) is None
    assert files.params("plane/1", {"X": 1.0}) is None
    assert [(e, f["kind"], f["logged"]) for e, f in lines] == [
        ("file_write_failed", "mission", False),  # told once (logged=False: the journal
        ("file_write_failed", "mission", True),   # line is the operator's warning)
        ("file_write_failed", "params", False),
    ]
    assert "No space left on device" in lines[0][1]["error"]
    assert not list(tmp_path.rglob("*.waypoints")) and not list(tmp_path.rglob(".*.tmp"))
    monkeypatch.setattr(storage.os, "fsync", real_fsync)
    path = files.mission("plane/1", "target", mission())
    assert path is not None and path.name == "003-target.waypoints"
    assert path.parent == tmp_path / "missions" / "plane_1"  # a name is never a path
    lines.clear()
    assert files.mission("plane/1", "target", mission()) is not None and lines == []


def _value(name: str, value: float, index: int, count: int) -> Any:
    msg = M.MAVLink_param_value_message(name.encode(), value, M.MAV_PARAM_TYPE_REAL32, count,
                                        index)
    msg._header.srcSystem, msg._header.srcComponent = 1, 1
    return msg


def test_the_parameter_download_asks_again_by_index_for_the_lost_ones() -> None:
    machine = ParamList(1, 1, timeout_s=1.0, retries=2)
    [start] = machine.start(0.0)
    assert isinstance(start, Send) and start.msg.get_type() == "PARAM_REQUEST_LIST"
    for index in (0, 1, 3):  # 2 and 4 lost
        assert machine.receive(_value(f"P{index}", index * 1.5, index, 5), 0.1) == []
    asks = machine.poll(1.2)
    assert [(a.msg.get_type(), a.msg.param_index) for a in asks if isinstance(a, Send)] == [
        ("PARAM_REQUEST_READ", 2), ("PARAM_REQUEST_READ", 4)]
    machine.receive(_value("P2", 3.0, 2, 5), 1.3)
    machine.receive(_value("P0", 9.0, 65535, 5), 1.3)  # a read by name: updates P0
    assert machine.receive(_value("P4", 6.0, 4, 5), 1.4)  # Finished
    assert machine.result is not None and machine.result.ok
    assert machine.values == {"P0": 9.0, "P1": 1.5, "P2": 3.0, "P3": 4.5, "P4": 6.0}


def test_a_silent_vehicle_ends_the_parameter_download_with_a_timeout() -> None:
    machine = ParamList(1, 1, timeout_s=1.0, retries=2)
    machine.start(0.0)
    resent = [a for t in (1.0, 2.0) for a in machine.poll(t) if isinstance(a, Send)]
    assert [a.msg.get_type() for a in resent] == ["PARAM_REQUEST_LIST"] * 2
    machine.poll(3.0)
    assert machine.result is not None and machine.result.code is TransferCode.TIMEOUT
