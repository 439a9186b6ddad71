"""pymavlink's own tools read a floe tlog as documented (docs/links.md): `mavlogdump.py`
of pymavlink 2.4.50 decodes MAVLink 2 frames without the `MAVLINK20=1` the docs used to
advise."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pymavlink
import pytest
from environment import need

from groundstation.link import TlogWriter
from groundstation.mavlink.codec import MavlinkEncoder, mavlink2


@pytest.mark.timeout(60)
def test_mavlogdump_reads_a_floe_tlog_without_mavlink20(tmp_path: Path) -> None:
    tool = Path(pymavlink.__file__).parent / "tools" / "mavlogdump.py"
    need(tool.is_file(), "pymavlink without its tools")
    path = tmp_path / "flight.tlog"
    writer = TlogWriter(path)
    encoder = MavlinkEncoder(7, 1)
    beat = mavlink2.MAVLink_heartbeat_message(
        mavlink2.MAV_TYPE_FIXED_WING, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 10, 4, 3
    )
    frames = [encoder.encode(beat) for _ in range(3)]
    assert all(f[0] == 0xFD for f in frames)  # MAVLink 2 frames
    for k, frame in enumerate(frames):
        writer.write(frame, 1_790_000_000.0 + k)
    writer.close()
    env = {k: v for k, v in os.environ.items() if k not in ("MAVLINK20", "MAVLINK09")}
    proc = subprocess.run(
        [sys.executable, str(tool), "--types", "HEARTBEAT", str(path)],
        env=env, capture_output=True, text=True, timeout=50, check=True,
    )  # fmt: skip
    lines = [line for line in proc.stdout.splitlines() if "HEARTBEAT" in line]
    assert len(lines) == 3, proc.stdout + proc.stderr
    assert all("custom_mode : 10" in line for line in lines)
