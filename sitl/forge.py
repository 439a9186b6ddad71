"""Forged and hostile MAVLink traffic for trust tests and the fuzz benchmark (sans-IO).

Everything here returns bytes; nothing sends them. The kinds:

* :func:`forged_frames`: single frames that would change what a ground station believes
  about a vehicle if it trusted them: a low battery (SYS_STATUS, BATTERY_STATUS), a smaller
  ``time_boot_ms`` (SYSTEM_TIME, ATTITUDE, GLOBAL_POSITION_INT: a reboot), a far larger
  one (SYSTEM_TIME, ATTITUDE at 4 000 000 000 ms: ``boot_time_ahead``), a HEARTBEAT in
  another mode (FBWA: an override), MISSION_ITEM_REACHED and MISSION_CURRENT (a loiter end),
  EXTENDED_SYS_STATE ON_GROUND (landed);
* :func:`random_valid_frame`: a well-formed frame of a common type with random field values;
* :func:`wrong_length_frame`: a MAVLink 2 frame whose payload length disagrees with its
  message id but whose CRC (with the message's CRC_EXTRA) is valid;
* :func:`random_bytes`: noise, sometimes with MAVLink start markers in it;
* :func:`flood_chunk`: many benign frames (DEBUG_VECT) to write at once.

Frames are MAVLink 2, unsigned, encoded by pymavlink (as any other GCS or companion
computer on the network would do).
"""

from __future__ import annotations

import random
import struct
from typing import Any

from pymavlink.generator.mavcrc import x25crc

from domain.modes import ArduPlaneMode
from groundstation.mavlink.codec import MavlinkEncoder, mavlink2

__all__ = [
    "AHEAD_BOOT_MS",
    "FORGED_KINDS",
    "flood_chunk",
    "forged_frames",
    "random_bytes",
    "random_valid_frame",
    "wrong_length_frame",
]

M = mavlink2
_P = ArduPlaneMode
_FORGED_MODES = (_P.FBWA, _P.RTL, _P.MANUAL, _P.LOITER)  # a forged mode switch: never floe's
FORGED_KINDS = (
    "battery", "boot_time", "mode", "item_reached", "current", "landed", "boot_time_ahead",
)
AHEAD_BOOT_MS = 4_000_000_000
"""The large ``time_boot_ms`` of the ``boot_time_ahead`` kind (46 days of uptime)."""


def _battery(rng: random.Random) -> list[Any]:
    pct = rng.randint(1, 9)
    return [
        M.MAVLink_sys_status_message(0, 0, 0, 200, 9_800, 1_500, pct, 0, 0, 0, 0, 0, 0),
        M.MAVLink_battery_status_message(
            0, 0, 1, 2000, [3_266] * 3 + [65535] * 7, 1_500, 4_800, -1, pct
        ),
    ]


def _boot_time(rng: random.Random) -> list[Any]:
    boot_ms = rng.randint(100, 1_500)
    return [
        M.MAVLink_system_time_message(int(1.7e15), boot_ms),
        M.MAVLink_attitude_message(boot_ms, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        M.MAVLink_global_position_int_message(boot_ms, 0, 0, 0, 0, 0, 0, 0, 0),
    ]


def _boot_time_ahead() -> list[Any]:
    """A ``time_boot_ms`` far beyond the vehicle's: taken as its timeline, the real frames
    after it would look like a step back (a reboot)."""
    return [
        M.MAVLink_system_time_message(int(1.7e15), AHEAD_BOOT_MS),
        M.MAVLink_attitude_message(AHEAD_BOOT_MS, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    ]


def _mode(rng: random.Random) -> list[Any]:
    base = (
        M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        | M.MAV_MODE_FLAG_STABILIZE_ENABLED
        | M.MAV_MODE_FLAG_SAFETY_ARMED
    )
    mode = rng.choice(_FORGED_MODES)
    return [
        M.MAVLink_heartbeat_message(
            M.MAV_TYPE_FIXED_WING, M.MAV_AUTOPILOT_ARDUPILOTMEGA, base, mode, 4, 3
        )
    ]


def _item_reached(seqs: range) -> list[Any]:
    return [M.MAVLink_mission_item_reached_message(seq) for seq in seqs]


def _current(seqs: range) -> list[Any]:
    return [M.MAVLink_mission_current_message(seq, 4, 2, 0) for seq in seqs]


def _landed() -> list[Any]:
    return [
        M.MAVLink_extended_sys_state_message(
            M.MAV_VTOL_STATE_UNDEFINED, M.MAV_LANDED_STATE_ON_GROUND
        )
    ]


def forged_frames(
    system_id: int,
    component_id: int,
    kinds: tuple[str, ...] = FORGED_KINDS,
    seed: int = 0,
    seqs: range = range(0, 6),
) -> list[bytes]:
    """One encoded frame per forged message of each kind in ``kinds`` (see the module
    docstring), claiming to come from ``system_id``/``component_id``."""
    rng = random.Random(seed)
    encoder = MavlinkEncoder(system_id, component_id)
    msgs: list[Any] = []
    for kind in kinds:
        if kind == "battery":
            msgs += _battery(rng)
        elif kind == "boot_time":
            msgs += _boot_time(rng)
        elif kind == "mode":
            msgs += _mode(rng)
        elif kind == "item_reached":
            msgs += _item_reached(seqs)
        elif kind == "current":
            msgs += _current(seqs)
        elif kind == "landed":
            msgs += _landed()
        elif kind == "boot_time_ahead":
            msgs += _boot_time_ahead()
        else:
            raise ValueError(f"unknown forged kind {kind!r} (one of {', '.join(FORGED_KINDS)})")
    return [encoder.encode(m) for m in msgs]


def _random_field(rng: random.Random, fmt: str, length: int) -> Any:
    """A random value for one pymavlink field type (arrays: a list of ``length``)."""
    one: Any
    if fmt in ("f", "d"):
        choices = (0.0, -1.0, 1e9, float("nan"), float("inf"), rng.uniform(-1e4, 1e4))
        one = lambda: rng.choice(choices)  # noqa: E731
    elif fmt == "c":
        return bytes(rng.randrange(32, 127) for _ in range(max(1, length))).decode("ascii")
    else:
        bits = {"b": 7, "B": 8, "h": 15, "H": 16, "i": 31, "I": 32, "q": 63, "Q": 64}.get(fmt, 8)
        signed = fmt.islower()
        one = (
            (lambda: rng.randrange(-(1 << bits), 1 << bits))
            if signed
            else (lambda: rng.randrange(0, 1 << bits))
        )
    if length > 1:
        return [one() for _ in range(length)]
    return one()


_RANDOM_TYPES = (
    "HEARTBEAT",
    "SYS_STATUS",
    "SYSTEM_TIME",
    "GPS_RAW_INT",
    "ATTITUDE",
    "GLOBAL_POSITION_INT",
    "MISSION_CURRENT",
    "MISSION_ITEM_REACHED",
    "VFR_HUD",
    "STATUSTEXT",
    "EXTENDED_SYS_STATE",
    "BATTERY_STATUS",
    "COMMAND_ACK",
    "MISSION_ACK",
    "MISSION_REQUEST",
    "MISSION_COUNT",
    "HOME_POSITION",
)
_FORMATS = {
    "float": "f",
    "double": "d",
    "char": "c",
    "int8_t": "b",
    "uint8_t": "B",
    "int16_t": "h",
    "uint16_t": "H",
    "int32_t": "i",
    "uint32_t": "I",
    "int64_t": "q",
    "uint64_t": "Q",
    "uint8_t_mavlink_version": "B",
}
_CLASSES = {cls.msgname: cls for cls in M.mavlink_map.values() if cls.msgname in _RANDOM_TYPES}


def random_valid_frame(rng: random.Random, system_id: int, component_id: int) -> bytes:
    """A well-formed, CRC-valid frame of a common type with random field values."""
    cls = _CLASSES[rng.choice(_RANDOM_TYPES)]
    args = []
    for i, name in enumerate(cls.fieldnames):
        ctype = cls.fieldtypes[i]
        length = cls.array_lengths[cls.ordered_fieldnames.index(name)]
        args.append(_random_field(rng, _FORMATS.get(ctype, "B"), length))
    encoder = MavlinkEncoder(system_id, component_id)
    try:
        return encoder.encode(cls(*args))
    except Exception:  # a value pymavlink cannot pack: fall back to noise of that size
        return random_bytes(rng, 32)


def wrong_length_frame(rng: random.Random, system_id: int, component_id: int) -> bytes:
    """A MAVLink 2 frame of a known message id whose payload is longer or shorter than the
    message's, with a CRC that is valid for what is sent (X.25 over header and payload plus
    the message's CRC_EXTRA)."""
    cls = _CLASSES[rng.choice(_RANDOM_TYPES)]
    msg_id = cls.id
    length = rng.choice((0, 1, 255, rng.randrange(0, 256)))
    payload = bytes(rng.randrange(256) for _ in range(length))
    seq = rng.randrange(256)
    header = bytes([length, 0, 0, seq, system_id, component_id]) + msg_id.to_bytes(3, "little")
    crc = x25crc(header + payload)
    crc.accumulate(bytes([cls.crc_extra]))
    return b"\xfd" + header + payload + struct.pack("<H", crc.crc)


def random_bytes(rng: random.Random, n: int) -> bytes:
    """``n`` random bytes, about one in 40 a MAVLink 1 or 2 start marker."""
    out = bytearray(rng.randrange(256) for _ in range(n))
    for i in range(0, n, 40):
        out[i] = rng.choice((0xFD, 0xFE, out[i]))
    return bytes(out)


def flood_chunk(system_id: int, component_id: int, count: int, start_us: int = 0) -> bytes:
    """``count`` benign DEBUG_VECT frames (a companion computer's, no vehicle state in them)
    from ``system_id``/``component_id``."""
    encoder = MavlinkEncoder(system_id, component_id)
    frames = []
    for k in range(count):
        msg = M.MAVLink_debug_vect_message(b"flood", start_us + k, float(k), 0.0, 0.0)
        frames.append(encoder.encode(msg))
    return b"".join(frames)
