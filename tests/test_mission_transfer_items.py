"""floe steps -> MAVLink items, and read-back comparison."""

from __future__ import annotations

import math
import struct
from dataclasses import replace
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from domain.errors import LocalProtocolError
from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, mavlink2
from groundstation.mavlink.mission_items import (
    ChangeSpeed,
    HomePosition,
    LoiterTime,
    LoiterUnlimited,
    MissionItem,
    Takeoff,
    Waypoint,
    build_mission_items,
)
from groundstation.mavlink.mission_verify import arduplane_readback, compare_missions

M = mavlink2
ORIGIN = GeoOrigin(78.9, 11.9, 12.0)


def loiter_mission() -> list[MissionItem]:
    return build_mission_items(
        [
            Takeoff(alt_m=80.0),
            ChangeSpeed(22.0),
            Waypoint(1200.0, -300.0, 100.0),
            LoiterTime(1500.0, 400.0, 100.0, time_s=30, clockwise=False),
            LoiterUnlimited(1500.0, 400.0, 100.0, radius_m=80),
        ],
        ORIGIN,
        home=HomePosition(10.0, 20.0, 3.0),
    )


def test_items_layout_and_commands() -> None:
    items = loiter_mission()
    assert [i.seq for i in items] == list(range(6))
    assert [i.command for i in items] == [16, 22, 178, 16, 19, 17]
    home, takeoff, speed, _wp, loiter, hold = items
    assert home.frame == M.MAV_FRAME_GLOBAL_INT and home.z == pytest.approx(15.0)
    assert takeoff.frame == M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    assert (takeoff.param1, takeoff.z, takeoff.x, takeoff.y) == (15.0, 80.0, 0, 0)
    assert (speed.frame, speed.param1, speed.param2, speed.param3) == (2, 0.0, 22.0, -1.0)
    assert (loiter.param1, loiter.param3) == (30.0, -1.0)  # counter-clockwise: negative
    assert (hold.param3, hold.z) == (80.0, 100.0)
    assert all(i.autocontinue == 1 and i.current == 0 for i in items)


@pytest.mark.parametrize("index", [3, 4, 5])
def test_positions_round_trip_through_geodesy(index: int) -> None:
    items = loiter_mission()
    expected = {3: (1200.0, -300.0), 4: (1500.0, 400.0), 5: (1500.0, 400.0)}[index]
    x_m, y_m, _ = ORIGIN.to_local(items[index].x * 1e-7, items[index].y * 1e-7)
    # degE7 quantisation: 1e-7 deg is 1.1 cm north, 0.2 cm east at 78.9 N
    assert x_m == pytest.approx(expected[0], abs=0.01)
    assert y_m == pytest.approx(expected[1], abs=0.02)


def test_item_survives_the_wire() -> None:
    item = loiter_mission()[4]
    data = MavlinkEncoder(255, 190).encode(item.to_message(1, 1))
    msg: Any
    (msg,) = MavlinkDecoder().feed(data)
    assert msg.get_type() == "MISSION_ITEM_INT" and msg.target_system == 1
    assert MissionItem.from_message(msg) == item


def test_mission_item_float_variant_is_converted() -> None:
    msg = M.MAVLink_mission_item_message(
        255, 190, 3, 3, 16, 0, 1, 0, 0, 0, 0, 78.91234567, 11.9, 50.0, 0
    )
    item = MissionItem.from_message(msg)
    assert item is not None and abs(item.x - 789123457) <= 8  # float32 lat: ~1e-6 deg
    nan_msg = M.MAVLink_mission_item_message(
        255, 190, 3, 3, 16, 0, 1, 0, 0, 0, 0, float("nan"), 11.9, 50.0, 0
    )
    assert MissionItem.from_message(nan_msg) is None


@pytest.mark.parametrize(
    ("step", "field"),
    [
        (Waypoint(float("nan"), 0.0, 100.0), "x_m"),
        (Waypoint(0.0, 0.0, float("inf")), "alt_m"),
        (LoiterTime(0.0, 0.0, 100.0, time_s=0), "time_s"),
        (LoiterTime(0.0, 0.0, 100.0, time_s=70000), "time_s"),
        (LoiterUnlimited(0.0, 0.0, 100.0, radius_m=0.2), "radius_m"),
        (Waypoint(0.0, 0.0, 100.0, acceptance_radius_m=300), "acceptance_radius_m"),
        (ChangeSpeed(-3.0), "speed_m_s"),
        (Takeoff(alt_m=50.0, pitch_deg=120), "pitch_deg"),
    ],
)
def test_bad_steps_raise_naming_the_field(step: object, field: str) -> None:
    with pytest.raises(LocalProtocolError, match=field) as info:
        build_mission_items([step], ORIGIN)  # type: ignore[list-item]
    assert "mission step 1" in str(info.value)


def test_generated_items_are_arduplane_canonical() -> None:
    items = loiter_mission()
    readback = [arduplane_readback(i) for i in items]
    assert compare_missions(items, readback) == []
    assert compare_missions(items, readback, skip_home=False) == []
    assert [arduplane_readback(i) for i in readback] == readback  # idempotent


def test_arduplane_readback_loses_what_arduplane_loses() -> None:
    wp = MissionItem(
        seq=1, command=16, param1=5.0, param2=30.4, param3=-7.0, param4=1.0, x=1, y=2, z=100.004
    )
    back = arduplane_readback(wp)
    assert (back.param1, back.param2, back.param3, back.param4) == (0.0, 30.0, 0.0, 0.0)
    assert back.frame == M.MAV_FRAME_GLOBAL_RELATIVE_ALT and back.z == pytest.approx(100.0)
    lt = arduplane_readback(MissionItem(seq=1, command=19, param1=30.7, param3=80.0))
    assert (lt.param1, lt.param3) == (30.0, 1.0)
    speed = arduplane_readback(MissionItem(seq=1, command=178, frame=2, param2=20.0, x=5))
    assert (speed.frame, speed.x, speed.param2) == (0, 0, 20.0)


def test_compare_reports_each_difference() -> None:
    items = loiter_mission()
    back = [arduplane_readback(i) for i in items]
    back[3] = replace(back[3], y=back[3].y - 2)
    back[4] = replace(back[4], param1=31.0)
    back[5] = replace(back[5], z=back[5].z + 0.02)
    back[2] = replace(back[2], command=177)
    found = {(m.seq, m.field) for m in compare_missions(items, back)}
    assert found == {(3, "y"), (4, "param1"), (5, "z"), (2, "command")}
    assert compare_missions(items, back[:-1])[0].field == "count"
    # within tolerance: 1e-7 deg and 1 cm; home differences ignored by default
    ok = [arduplane_readback(i) for i in items]
    ok[3] = replace(ok[3], x=ok[3].x + 1, z=ok[3].z - 0.01)
    ok[0] = replace(ok[0], x=123, z=999.0)
    assert compare_missions(items, ok) == []
    assert {m.field for m in compare_missions(items, ok, skip_home=False)} == {"x", "z"}


def test_compare_exact_mode_params_as_float32_and_nan() -> None:
    item = MissionItem(seq=1, command=31000, frame=6, param1=0.1, param4=float("nan"))
    echoed = replace(item, param1=struct.unpack("<f", struct.pack("<f", 0.1))[0], frame=3)
    assert echoed.param1 != 0.1
    assert compare_missions([item], [echoed], skip_home=False, autopilot="exact") == []
    bad = replace(item, param4=0.0)
    assert [
        m.field for m in compare_missions([item], [bad], skip_home=False, autopilot="exact")
    ] == ["param4"]


@settings(max_examples=200, deadline=None)
@given(
    east_m=st.floats(-20_000, 20_000),
    north_m=st.floats(-20_000, 20_000),
    lat0=st.floats(-85, 85),
    lon0=st.floats(-179, 179),
)
def test_positions_within_one_e7_deg_anywhere(
    east_m: float, north_m: float, lat0: float, lon0: float
) -> None:
    origin = GeoOrigin(lat0, lon0)
    items = build_mission_items([Waypoint(east_m, north_m, 100.0)], origin)
    lat, lon, _ = origin.to_geodetic(east_m, north_m, 0.0)
    assert abs(items[1].x - lat * 1e7) <= 0.5 + 1e-6
    assert abs(((items[1].y - lon * 1e7) + 1.8e9) % 3.6e9 - 1.8e9) <= 0.5 + 1e-6
    assert math.isfinite(items[1].z)
