"""Property tests: whatever the peer sends, the state machines never raise and always end."""

from __future__ import annotations

from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_commands import MissionClear, SetCurrent
from groundstation.mavlink.mission_download import MissionDownload
from groundstation.mavlink.mission_items import LoiterUnlimited, Waypoint, build_mission_items
from groundstation.mavlink.mission_transfer import Finished, Send
from groundstation.mavlink.mission_upload import MissionUpload

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
)

machines = st.sampled_from(["upload", "download", "clear", "set_current"])


def make(kind: str) -> Any:
    if kind == "upload":
        return MissionUpload(1, 1, ITEMS, own_system=255)
    if kind == "download":
        return MissionDownload(1, 1)
    if kind == "clear":
        return MissionClear(1, 1)
    return SetCurrent(1, 1, 2)


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
