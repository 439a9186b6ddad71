"""Property tests: whatever the peer sends, the state machines never raise and always end.

Two sources of peer input: real frames (any field values the wire can carry, from our
vehicle or another system), and decoded-looking messages with *any* Python values in their
fields (None, strings, bytes, NaN, huge or negative numbers; from any system and component),
which is what a frame with a wrong length or a buggy dialect can hand over. After the end,
every further input returns no actions.
"""

from __future__ import annotations

from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_commands import MissionClear, MissionSetCurrent
from groundstation.mavlink.mission_download import MissionDownload
from groundstation.mavlink.mission_items import LoiterUnlimited, Waypoint, build_mission_items
from groundstation.mavlink.mission_transfer import Finished, Send, TransferBase
from groundstation.mavlink.mission_upload import MissionUpload
from groundstation.mavlink.vehicle_commands import CommandLong, ParamRead, ParamSet

M = mavlink2
ITEMS = build_mission_items(
    [Waypoint(100.0, 0.0, 100.0), LoiterUnlimited(200.0, 0.0, 100.0, radius_m=80)],
    GeoOrigin(78.9, 11.9),
)

u8 = st.integers(0, 255)
u16 = st.integers(0, 65535)
floats = st.floats(allow_nan=True, allow_infinity=True, width=32)
i32 = st.integers(-(2**31), 2**31 - 1)

peer_message = st.one_of(
    st.builds(M.MAVLink_mission_request_message, u8, u8, u16, u8),
    st.builds(M.MAVLink_mission_request_int_message, u8, u8, u16, u8),
    st.builds(M.MAVLink_mission_ack_message, u8, u8, u8, u8),
    st.builds(M.MAVLink_mission_count_message, u8, u8, u16, u8),
    st.builds(
        M.MAVLink_mission_item_int_message,
        u8,
        u8,
        u16,
        u8,
        u16,
        u8,
        u8,
        floats,
        floats,
        floats,
        floats,
        i32,
        i32,
        floats,
        u8,
    ),
    st.builds(M.MAVLink_mission_current_message, u16, u16),
    st.builds(M.MAVLink_command_ack_message, u16, u8, u8, i32, u8, u8),
    st.builds(M.MAVLink_heartbeat_message, u8, u8, u8, st.integers(0, 2**32 - 1), u8, u8),
    st.builds(
        M.MAVLink_param_value_message,
        st.sampled_from([b"WP_LOITER_RAD", b"WP_RADIUS", b""]),
        floats,
        u8,
        u16,
        u16,
    ),
)

KINDS = ["upload", "download", "clear", "set_current", "command", "param_set", "param_read"]
machines = st.sampled_from(KINDS)


def make(kind: str) -> Any:
    if kind == "upload":
        return MissionUpload(1, 1, ITEMS, own_system=255)
    if kind == "download":
        return MissionDownload(1, 1)
    if kind == "clear":
        return MissionClear(1, 1)
    if kind == "command":
        return CommandLong(1, 1, M.MAV_CMD_DO_SET_MODE, [1.0, 10.0], own_system=255)
    if kind == "param_set":
        return ParamSet(1, 1, "WP_LOITER_RAD", 80.0)
    if kind == "param_read":
        return ParamRead(1, 1, "WP_LOITER_RAD")
    return MissionSetCurrent(1, 1, 2)


@settings(max_examples=300, deadline=None)
@given(
    kind=machines,
    script=st.lists(
        st.tuples(peer_message, st.sampled_from([1, 2]), st.floats(0.0, 3.0)), max_size=40
    ),
)
def test_state_machines_never_raise_and_always_finish(
    kind: str, script: list[tuple[MAVLinkMessage, int, float]]
) -> None:
    sm = make(kind)
    now = 0.0
    actions = sm.start(now)
    finished = 0
    for msg, sysid, dt in script:
        if sm.done:
            break
        now += dt
        (decoded,) = MavlinkDecoder().feed(MavlinkEncoder(sysid, 1).encode(msg))
        actions = sm.receive(decoded, now) + sm.poll(now)
        finished += sum(isinstance(a, Finished) for a in actions)
        assert all(isinstance(a, Send | Finished) for a in actions)
        # a single message never triggers a burst (no resend storm)
        assert sum(isinstance(a, Send) for a in actions) <= 2
    while not sm.done:
        deadline = sm.next_deadline_s()
        assert deadline is not None and deadline >= now
        now = deadline
        finished += sum(isinstance(a, Finished) for a in sm.poll(now))
    assert finished == 1
    assert sm.result is not None and sm.next_deadline_s() is None


# --------------------------------------------------------------------------- any field values

wild_value = st.one_of(
    st.none(),
    st.integers(-(2**70), 2**70),
    st.integers(-3, 70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=20),
    st.binary(max_size=20),
    st.booleans(),
    st.just(b"WP_LOITER_RAD"),
    st.just("WP_LOITER_RAD"),
)
WILD_TYPES = [
    M.MAVLink_mission_request_message,
    M.MAVLink_mission_request_int_message,
    M.MAVLink_mission_ack_message,
    M.MAVLink_mission_count_message,
    M.MAVLink_mission_item_int_message,
    M.MAVLink_mission_item_message,
    M.MAVLink_mission_current_message,
    M.MAVLink_command_ack_message,
    M.MAVLink_param_value_message,
]


# Half the time a field gets a value the machines accept, so that wild values in the other
# fields reach the code behind the addressing and mission-type checks.
PLAUSIBLE: dict[str, list[Any]] = {
    "target_system": [255, 0],
    "target_component": [190, 0],
    "mission_type": [0],
    "seq": [0, 1, 2],
    "count": [0, 2, 3],
    "type": [0, 13, 5],
    "command": [M.MAV_CMD_DO_SET_MODE, M.MAV_CMD_DO_SET_MISSION_CURRENT],
    "result": [0, 4, 5],
    "param_id": ["WP_LOITER_RAD", b"WP_LOITER_RAD"],
    "param_value": [80.0],
}


@st.composite
def wild_message(draw: st.DrawFn) -> Any:
    """A pymavlink message of a type the machines read, with arbitrary field values."""
    cls = draw(st.sampled_from(WILD_TYPES))
    msg = cls(*[b"" if name == "param_id" else 0 for name in cls.fieldnames])
    for name in cls.fieldnames:
        plausible = PLAUSIBLE.get(name)
        if plausible is not None and draw(st.booleans()):
            setattr(msg, name, draw(st.sampled_from(plausible)))
        else:
            setattr(msg, name, draw(wild_value))
    msg._header.srcSystem = draw(st.sampled_from([1, 1, 1, 1, 2, 0, None, 300]))
    msg._header.srcComponent = draw(st.sampled_from([1, 1, 42, 0, None]))
    return msg


class _NotAMessage:
    """Something that is not a MAVLink message at all."""

    def get_type(self) -> str:
        raise RuntimeError("unreadable")


@settings(max_examples=200, deadline=None)
@given(
    kind=machines,
    script=st.lists(
        st.tuples(st.one_of(wild_message(), st.just(_NotAMessage())), st.floats(0.0, 2.0)),
        max_size=30,
    ),
)
def test_any_field_values_never_raise_and_input_after_the_end_is_ignored(
    kind: str, script: list[tuple[Any, float]]
) -> None:
    sm: TransferBase[Any] = make(kind)
    now = 0.0
    sm.start(now)
    finished = 0
    for msg, dt in script:
        now += dt
        actions = sm.receive(msg, now) + sm.poll(now)
        assert all(isinstance(a, Send | Finished) for a in actions)
        finished += sum(isinstance(a, Finished) for a in actions)
        for action in actions:
            if isinstance(action, Send):
                MavlinkEncoder(255, 190).encode(action.msg)  # what we send always packs
    assert finished == (1 if sm.done else 0)
    if not sm.done:
        sm.cancel(now)
    result = sm.result
    assert result is not None and sm.state.name == "DONE"
    for msg, _ in script:
        assert sm.receive(msg, now) == []
    assert sm.poll(now + 1e9) == [] and sm.cancel(now) == []
    assert sm.notify_vehicle_rebooted(now) == [] and sm.result is result
