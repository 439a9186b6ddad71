"""Tlog writer and reader: round trip, pymavlink compatibility, damage and truncation."""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from environment import need

from groundstation.link import TlogReader, TlogWriter
from groundstation.mavlink.codec import MavlinkEncoder

T0 = 1_763_700_000.0  # a November 2025 Unix time


def frames() -> list[bytes]:
    """A few different frames, MAVLink 2 and one MAVLink 1."""
    enc = MavlinkEncoder(1, 1)
    mav = enc.mav
    out = [
        enc.encode(mav.heartbeat_encode(1, 3, 0, 10, 4)),
        enc.encode(mav.attitude_encode(1000, 0.1, -0.2, 1.5, 0.0, 0.0, 0.0)),
        enc.encode(mav.statustext_encode(6, b"Mission: 2 LoiterTime")),
        enc.encode(
            mav.global_position_int_encode(2000, 789000000, 119000000, 100000, 50000, 1, 2, 3, 9000)
        ),
        enc.encode(mav.mission_item_reached_encode(3)),
    ]
    v1 = MavlinkEncoder(2, 1)
    out.append(bytes(v1.mav.heartbeat_encode(1, 3, 0, 10, 4).pack(v1.mav, force_mavlink1=True)))
    return out


def write_tlog(path: Path, link_numbers: bool = False) -> list[tuple[float, bytes]]:
    records = [(T0 + 0.25 * i, f) for i, f in enumerate(frames())]
    with TlogWriter(path) as w:
        for i, (t, f) in enumerate(records):
            assert w.write(f, t, (i % 4) if link_numbers else None)
    return records


def test_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "flight.tlog"
    records = write_tlog(path)
    # The format: nothing but (8-byte big-endian microseconds + frame) records.
    expected = b"".join(struct.pack(">Q", round(t * 1e6)) + f for t, f in records)
    assert path.read_bytes() == expected
    reader = TlogReader(path)
    got = list(reader)
    assert [r.raw for r in got] == [f for _, f in records]
    assert [r.t_unix_s for r in got] == pytest.approx([t for t, _ in records], abs=1e-6)
    assert [r.message.get_type() for r in got] == [
        "HEARTBEAT",
        "ATTITUDE",
        "STATUSTEXT",
        "GLOBAL_POSITION_INT",
        "MISSION_ITEM_REACHED",
        "HEARTBEAT",
    ]
    assert got[2].message.text == "Mission: 2 LoiterTime"
    assert got[5].message.get_srcSystem() == 2
    assert reader.skipped == [] and reader.records == 6
    # Reading from bytes gives the same.
    assert [r.raw for r in TlogReader(path.read_bytes())] == [f for _, f in records]


def test_records_reach_the_os_before_close(tmp_path: Path) -> None:
    """A crash loses at most the record being written: each write is in the file at once."""
    path = tmp_path / "live.tlog"
    w = TlogWriter(path)
    fs = frames()
    w.write(fs[0], T0)
    w.write(fs[1], T0 + 1)
    assert path.stat().st_size == 16 + len(fs[0]) + len(fs[1])
    assert [r.raw for r in TlogReader(path)] == fs[:2]
    w.close()
    w.close()
    assert w.write(fs[2]) is False  # closed: not written, no exception


def test_write_errors_are_counted_not_raised(tmp_path: Path) -> None:
    need(os.path.exists("/dev/full"), "needs /dev/full")
    w = TlogWriter("/dev/full", append=True)
    assert w.write(frames()[0], T0) is False
    assert w.write(frames()[0], T0) is False
    # a full disk: held in memory for a retry (within retry_s no second attempt is made)
    assert w.write_errors == 1 and w.records == 0 and w.held == 2
    w.close()  # one last attempt, then the held records are reported lost
    assert w.write_errors == 2 and w.records == 0


def test_pymavlink_reads_what_we_write(tmp_path: Path) -> None:
    path = tmp_path / "flight.tlog"
    records = write_tlog(path, link_numbers=True)
    script = (
        "import json, sys\n"
        "from pymavlink import mavutil\n"
        "m = mavutil.mavlink_connection(sys.argv[1])\n"
        "out = []\n"
        "while True:\n"
        "    msg = m.recv_msg()\n"
        "    if msg is None:\n"
        "        break\n"
        "    out.append([msg.get_type(), msg._timestamp, msg.get_srcSystem(),\n"
        "                bytes(msg.get_msgbuf()).hex(), msg._link])\n"
        "print(json.dumps(out))\n"
    )
    env = {**os.environ, "MAVLINK20": "1", "MAVLINK_DIALECT": "ardupilotmega"}
    proc = subprocess.run(
        [sys.executable, "-c", script, str(path)],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    got = json.loads(proc.stdout)
    assert [g[0] for g in got] == [
        "HEARTBEAT",
        "ATTITUDE",
        "STATUSTEXT",
        "GLOBAL_POSITION_INT",
        "MISSION_ITEM_REACHED",
        "HEARTBEAT",
    ]
    assert [g[1] for g in got] == pytest.approx([t for t, _ in records], abs=1e-5)
    assert [bytes.fromhex(g[3]) for g in got] == [f for _, f in records]
    assert got[5][2] == 2
    assert [g[4] for g in got] == [0, 1, 2, 3, 0, 1]  # MAVProxy's link numbers
    assert [r.link_number for r in TlogReader(path)] == [0, 1, 2, 3, 0, 1]


def test_damage_is_skipped_and_reported(tmp_path: Path) -> None:
    fs = frames()
    recs = [struct.pack(">Q", round((T0 + i) * 1e6)) + f for i, f in enumerate(fs)]
    bad_crc = bytearray(recs[2])
    bad_crc[-1] ^= 0x55
    garbage = b"\x00\xfd\xfe garbage \xfd" * 3
    truncated = recs[5][:-4]
    data = recs[0] + garbage + recs[1] + bytes(bad_crc) + recs[3] + recs[4] + truncated
    path = tmp_path / "damaged.tlog"
    path.write_bytes(data)

    reader = TlogReader(path)
    got = list(reader)
    assert [r.raw for r in got] == [fs[0], fs[1], fs[3], fs[4]]
    assert [r.t_unix_s for r in got] == pytest.approx([T0, T0 + 1, T0 + 3, T0 + 4], abs=1e-6)
    g0 = len(recs[0])
    r2 = g0 + len(garbage) + len(recs[1])
    end = len(data)
    assert reader.skipped == [
        (g0, g0 + len(garbage)),  # garbage between records
        (r2, r2 + len(bad_crc)),  # the record with a bad CRC
        (end - len(truncated), end),  # the truncated last record
    ]
    assert reader.skipped_bytes == len(garbage) + len(bad_crc) + len(truncated)
    assert [r.offset for r in got] == [
        0,
        g0 + len(garbage),
        r2 + len(bad_crc),
        r2 + len(bad_crc) + len(recs[3]),
    ]


def test_bad_timestamp_and_empty_file(tmp_path: Path) -> None:
    fs = frames()
    zero_time = struct.pack(">Q", 0) + fs[0]  # not a plausible reception time
    good = struct.pack(">Q", round(T0 * 1e6)) + fs[1]
    reader = TlogReader(zero_time + good)
    assert [r.raw for r in reader] == [fs[1]]
    assert reader.skipped == [(0, len(zero_time))]
    empty = tmp_path / "empty.tlog"
    empty.write_bytes(b"")
    assert list(TlogReader(empty)) == []
    assert list(TlogReader(b"\x00" * 5)) == []


def test_unknown_message_ids_need_a_sane_next_record() -> None:
    # A frame with a message id not in the dialect has no CRC to check.
    header = bytes([0xFD, 2, 0, 0, 0, 1, 1]) + (0xABCDE).to_bytes(3, "little")
    unknown = header + b"\x01\x02" + b"\x00\x00"
    good = struct.pack(">Q", round(T0 * 1e6)) + frames()[0]
    ts = struct.pack(">Q", round(T0 * 1e6))
    got = list(TlogReader(ts + unknown + good))
    assert [r.message.get_type() for r in got][-1] == "HEARTBEAT"
    assert got[0].raw == unknown  # followed by a sane record: kept
    reader = TlogReader(ts + unknown + b"\x07" * 20 + good)
    kept = list(reader)
    assert [r.raw for r in kept] == [frames()[0]]  # followed by junk: treated as damage
    assert reader.skipped and reader.skipped[0][0] == 0
