"""Fuzzing: whatever a peer sends, the vehicle's message handling never raises, and the
server keeps time: timestamps follow the speed-up."""

from __future__ import annotations

import math
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder
from groundstation.mavlink.codec import mavlink2 as M
from sitl.vehicle import SimVehicle, VehicleConfig

ORIGIN = GeoOrigin(78.93, 11.92)
_ENC = MavlinkEncoder(255, 190)


def wire(msg: Any) -> Any:
    """Through the codec, so the message has a header as a received one does."""
    got = MavlinkDecoder().feed(_ENC.encode(msg))
    assert len(got) == 1
    return got[0]


def fresh(airborne: bool) -> SimVehicle:
    cfg = VehicleConfig(1, ORIGIN, 78.93, 11.92, fast_boot=True, airborne=airborne)
    v = SimVehicle(cfg)
    v.step(3.0)
    return v


floats = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=32),
    st.sampled_from([0.0, 1.0, -1.0, 2989.0, 21196.0, 1e9, float("nan")]),
)
commands = st.one_of(
    st.sampled_from([400, 176, 224, 20, 178, 511, 512, 520, 410, 192, 246, 179, 0, 65535]),
    st.integers(0, 65535),
)
ints32 = st.integers(-(2**31), 2**31 - 1)


@st.composite
def messages(draw: st.DrawFn) -> Any:
    kind = draw(
        st.sampled_from(
            [
                "long",
                "int",
                "item",
                "item_int",
                "count",
                "set_mode",
                "stream",
                "param_set",
                "set_current",
                "request",
            ]
        )
    )
    target = draw(st.sampled_from([0, 1, 2]))
    if kind == "long":
        return M.MAVLink_command_long_message(
            target, 1, draw(commands), 0, *[draw(floats) for _ in range(7)]
        )
    if kind == "int":
        return M.MAVLink_command_int_message(
            target,
            1,
            draw(st.integers(0, 21)),
            draw(commands),
            0,
            0,
            *[draw(floats) for _ in range(4)],
            draw(ints32),
            draw(ints32),
            draw(floats),
        )
    if kind in ("item", "item_int"):
        args = (
            target,
            1,
            draw(st.integers(0, 700)),
            draw(st.integers(0, 21)),
            draw(commands),
            draw(st.integers(0, 3)),
            1,
            *[draw(floats) for _ in range(4)],
        )
        if kind == "item":
            return M.MAVLink_mission_item_message(
                *args, draw(floats), draw(floats), draw(floats), draw(st.integers(0, 2))
            )
        return M.MAVLink_mission_item_int_message(
            *args, draw(ints32), draw(ints32), draw(floats), draw(st.integers(0, 2))
        )
    if kind == "count":
        return M.MAVLink_mission_count_message(
            target, 1, draw(st.integers(0, 65535)), draw(st.integers(0, 2))
        )
    if kind == "set_mode":
        return M.MAVLink_set_mode_message(
            target, draw(st.integers(0, 255)), draw(st.integers(0, 2**32 - 1))
        )
    if kind == "stream":
        return M.MAVLink_request_data_stream_message(
            target,
            1,
            draw(st.integers(0, 255)),
            draw(st.integers(0, 65535)),
            draw(st.integers(0, 1)),
        )
    if kind == "param_set":
        name = draw(
            st.sampled_from([b"WP_LOITER_RAD", b"MAV_SYSID", b"BATT_CAPACITY", b"NOPE", b""])
        )
        return M.MAVLink_param_set_message(target, 1, name, draw(floats), 9)
    if kind == "set_current":
        return M.MAVLink_mission_set_current_message(target, 1, draw(st.integers(0, 65535)))
    return M.MAVLink_mission_request_int_message(
        target, 1, draw(st.integers(0, 65535)), draw(st.integers(0, 2))
    )


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(messages(), min_size=1, max_size=8), st.booleans())
def test_any_message_sequence_is_handled_without_exception(msgs: list[Any], airborne: bool) -> None:
    v = fresh(airborne)
    t = v.t_s
    for msg in msgs:
        v._receive(wire(msg), t)  # the unguarded handler: a bug here would raise
        t += 0.5
        v.step(t)
    v.step(t + 10.0)
    af = v.airframe
    assert all(math.isfinite(x) for x in (af.x_m, af.y_m, af.alt_m, af.heading_rad))
    for msg in v.step(t + 11.0):  # everything the vehicle sends still packs
        _ENC.encode(msg)


@settings(max_examples=100, deadline=None)
@given(st.binary(max_size=600))
def test_random_bytes_never_raise(data: bytes) -> None:
    v = fresh(False)
    for msg in MavlinkDecoder().feed(data):
        v._receive(msg, 4.0)


KNOWN_COMMANDS = [400, 176, 224, 20, 178, 511, 512, 520, 410, 192, 246, 300, 17, 31999]


def test_every_command_acks_nan_and_inf_parameters() -> None:
    for airborne in (False, True):
        v = fresh(airborne)
        for bad in (float("nan"), float("inf"), -float("inf"), 3e38):
            for command in KNOWN_COMMANDS:
                long_ = M.MAVLink_command_long_message(1, 1, command, 0, *([bad] * 7))
                acks = [m for m in v._receive(wire(long_), v.t_s) if m.get_type() == "COMMAND_ACK"]
                assert [a.command for a in acks] == [command], (command, bad)
                int_ = M.MAVLink_command_int_message(
                    1, 1, 6, command, 0, 0, bad, bad, bad, bad, 0, 0, bad
                )
                acks = [m for m in v._receive(wire(int_), v.t_s) if m.get_type() == "COMMAND_ACK"]
                assert [a.command for a in acks] == [command], (command, bad)
        assert v.handler_errors == 0
