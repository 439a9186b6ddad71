"""`gcs replay --serve URL --pace K`: frames spaced by mission time / K, whatever the
speed-up the run was recorded at, so a 50x run can be watched in MAVProxy or QGroundControl.

The tlogs here are written as a 50x run writes them: 10 mission seconds of frames within
0.2 s of Unix time; mission time comes from the vehicle's time_boot_ms (a bare tlog) or the
run's journal (a run folder)."""

from __future__ import annotations

import itertools
import json
import socket
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from groundstation.cli import main
from groundstation.link import TlogWriter
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, mavlink2
from groundstation.runners.replay.mission_timeline import MissionTimeline, mission_timeline
from groundstation.runners.replay.serve import serving_schedule

T0 = 1_790_000_000.0
RECORDED_X = 50.0
MISSION_S = 10.0
STEP_S = 0.1  # mission seconds between ATTITUDE frames


def _write_run(path: Path, *, with_boot_ms: bool = True) -> int:
    """A 50x recording of one vehicle; returns the number of vehicle frames."""
    encoder = MavlinkEncoder(1, 1)
    writer = TlogWriter(path)
    frames = 0
    steps = round(MISSION_S / STEP_S)
    for k in range(steps + 1):
        t_mission = k * STEP_S
        unix = T0 + t_mission / RECORDED_X
        if with_boot_ms:
            msg = mavlink2.MAVLink_attitude_message(round(1000 * (5.0 + t_mission)),
                                                    0, 0, 0, 0, 0, 0)
        else:
            msg = mavlink2.MAVLink_vfr_hud_message(22, 22, 90, 50, 100, 0)
        writer.write(encoder.encode(msg), unix)
        frames += 1
        if k % 10 == 0:
            beat = mavlink2.MAVLink_heartbeat_message(
                mavlink2.MAV_TYPE_FIXED_WING, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 10, 4, 3
            )
            writer.write(encoder.encode(beat), unix)
            frames += 1
    writer.close()
    return frames


def test_timeline_from_boot_ms_and_from_the_journal(tmp_path: Path) -> None:
    bare = tmp_path / "bare.tlog"
    _write_run(bare)
    timeline = mission_timeline(bare, [1])
    assert "time_boot_ms" in timeline.source
    assert timeline.rate == pytest.approx(RECORDED_X, rel=1e-3)
    assert timeline.at(T0 + 0.1) - timeline.at(T0) == pytest.approx(5.0, abs=0.01)
    run = tmp_path / "run"
    run.mkdir()
    _write_run(run / "flight.tlog", with_boot_ms=False)
    with (run / "journal.jsonl").open("w") as f:
        for t in range(11):
            f.write(json.dumps({"t": float(t), "unix_s": T0 + t / RECORDED_X, "event": "x"}))
            f.write("\n")
    timeline = mission_timeline(run / "flight.tlog", [1])
    assert "journal.jsonl" in timeline.source
    assert timeline.at(T0 + 0.1) == pytest.approx(5.0, abs=1e-6)
    # no anchors: the tlog's own time (K = 1)
    none = MissionTimeline.from_anchors([], "")
    assert none.at(T0 + 3.0) - none.at(T0) == pytest.approx(3.0) and none.rate == 1.0


def test_schedule_spaces_frames_by_mission_time_over_pace(tmp_path: Path) -> None:
    path = tmp_path / "fast.tlog"
    count = _write_run(path)
    _, frames = serving_schedule(path, pace=10.0)
    items = list(frames)
    assert len(items) == count
    assert items[-1].at_s == pytest.approx(MISSION_S / 10.0, abs=0.005)
    for a, b in itertools.pairwise(items):
        assert b.at_s - a.at_s == pytest.approx((b.t_s - a.t_s) / 10.0, abs=1e-9)
    # the same tlog by its recorded wall pace (--speed 1) would take 0.2 s
    _, by_wall = serving_schedule(path, speed=1.0)
    assert list(by_wall)[-1].at_s == pytest.approx(MISSION_S / RECORDED_X, abs=0.001)


@pytest.mark.timeout(60)
def test_serve_at_pace_10_takes_a_tenth_of_the_mission_time(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "fast.tlog"
    count = _write_run(path)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(0.1)
    port = sock.getsockname()[1]
    received: list[tuple[float, Any]] = []
    stop = threading.Event()

    def receive() -> None:
        decoder = MavlinkDecoder()
        while not stop.is_set():
            try:
                data, _ = sock.recvfrom(65536)
            except TimeoutError:
                continue
            now = time.monotonic()
            received.extend((now, m) for m in decoder.feed(data))

    thread = threading.Thread(target=receive, daemon=True)
    thread.start()
    try:
        status = main(["replay", str(path), "--serve", f"udp:127.0.0.1:{port}",
                       "--pace", "10", "--json"])
    finally:
        time.sleep(0.2)
        stop.set()
        thread.join(5)
        sock.close()
    assert status == 0
    result = json.loads(capsys.readouterr().out)
    assert result["pace"] == 10.0 and "time_boot_ms" in result["clock"]
    assert result["frames_sent"] == count == len(received)
    # 10 mission s at --pace 10: at least ~0.9 s of wall time, on both sides of the link
    assert result["wall_s"] >= 0.9
    assert received[-1][0] - received[0][0] >= 0.85
    # in recorded order: the vehicle's clock only goes forward
    boots = [m.time_boot_ms for _, m in received if m.get_type() == "ATTITUDE"]
    assert boots == sorted(boots) and len(boots) == round(MISSION_S / STEP_S) + 1


def test_pace_and_speed_are_exclusive(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["replay", str(tmp_path), "--serve", "udp:127.0.0.1:9", "--pace", "2",
              "--speed", "3"])
    assert info.value.code == 2
    assert "not allowed with" in capsys.readouterr().err


def test_anchors_are_thinned_not_cut_so_a_long_recording_keeps_its_late_drift() -> None:
    from groundstation.runners.replay.mission_timeline import ANCHOR_SPACING_S, _add_anchor

    anchors: list[tuple[float, float]] = []
    for k in range(300_001):  # 300 s of journal lines every 1 ms; the host slows at 200 s
        unix_s = k * 0.001
        _add_anchor(anchors, unix_s, 50 * unix_s if unix_s < 200 else 10_000 + 20 * (unix_s - 200))
    assert len(anchors) <= 300 / ANCHOR_SPACING_S + 1
    assert anchors[-1][0] > 300 - 2 * ANCHOR_SPACING_S  # anchors reach the end
    timeline = MissionTimeline.from_anchors(anchors, "journal")
    assert timeline.at(250.0) == pytest.approx(11_000, abs=5)  # the late, slower rate is kept


def _boot_tlog(path: Path, readings: list[tuple[int, float, int]]) -> None:
    """A bare tlog of ATTITUDE frames: (system id, unix s, time_boot_ms) each."""
    writer = TlogWriter(path)
    encoders = {s: MavlinkEncoder(s, 1) for s, _, _ in readings}
    for system_id, unix, boot_ms in readings:
        msg = mavlink2.MAVLink_attitude_message(boot_ms, 0, 0, 0, 0, 0, 0)
        writer.write(encoders[system_id].encode(msg), unix)
    writer.close()


def test_one_stray_clock_reading_moves_nothing_a_confirmed_reboot_goes_on(
    tmp_path: Path,
) -> None:
    """A 5x recording (1 mission s per 0.2 s): one frame whose time_boot_ms leaps ahead by
    hours, one that leaps back to 0, neither followed: the timeline ignores both. Then a
    real reboot (the clock starts again from 0 and goes on): mission time continues from
    where it was."""
    readings = [(1, T0 + k * 0.2, 5000 + 1000 * k) for k in range(50)]
    readings.insert(20, (1, T0 + 19 * 0.2 + 0.1, 9_000_000))  # forged: hours ahead
    readings.insert(35, (1, T0 + 33 * 0.2 + 0.1, 0))  # forged: back to boot
    t_reboot = T0 + 50 * 0.2
    readings += [(1, t_reboot + k * 0.2, 1000 * k) for k in range(20)]  # a real reboot
    path = tmp_path / "bare.tlog"
    _boot_tlog(path, readings)
    timeline = mission_timeline(path, [1])
    assert max(timeline.mission_s) == pytest.approx(54.0 + 19.0), max(timeline.mission_s)
    # before the reboot: the vehicle's own clock, the stray frames notwithstanding
    assert timeline.at(T0 + 30 * 0.2) == pytest.approx(5.0 + 30.0, abs=1e-6)
    assert timeline.at(T0 + 40 * 0.2) == pytest.approx(5.0 + 40.0, abs=1e-6)
    # after it: on from where it was (54 s), at the same 5x
    assert timeline.at(t_reboot + 10 * 0.2) == pytest.approx(54.0 + 10.0, abs=1e-6)


def test_a_bare_tlogs_vehicles_share_one_mission_clock(tmp_path: Path) -> None:
    """Two autopilots booted 500 s apart: the core on the tlog sees both at the mission
    time of the first one's clock, at each frame's reception, not each one's own."""
    from groundstation.runners.replay.tlog_core import _positions

    path = tmp_path / "two.tlog"
    writer = TlogWriter(path)
    encoders = {1: MavlinkEncoder(1, 1), 2: MavlinkEncoder(2, 1)}
    beat = mavlink2.MAVLink_heartbeat_message(
        mavlink2.MAV_TYPE_FIXED_WING, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 10, 4, 3)
    for k in range(40):
        unix = T0 + k * 0.01
        for system_id, boot_s in ((1, 5.0), (2, 505.0)):
            if k % 10 == 0:
                writer.write(encoders[system_id].encode(beat), unix)
            msg = mavlink2.MAVLink_global_position_int_message(
                round(1000 * (boot_s + k * 0.5)), 789_300_000 + 10 * k, 119_200_000, 100_000,
                100_000, 2200, 0, 0, 9000)
            writer.write(encoders[system_id].encode(msg), unix + 0.001 * system_id)
    writer.close()
    events, _, _ = _positions(path)
    times: dict[str, list[float]] = {}
    for t_s, event in events:
        if type(event).__name__ == "Telemetry":
            times.setdefault(event.vehicle, []).append(t_s)  # type: ignore[attr-defined]
    assert len(times["1"]) == len(times["2"]) == 40
    for t1, t2 in zip(times["1"], times["2"], strict=True):
        assert t1 < t2 < t1 + 0.2  # vehicle 2's frame 1 ms later: 0.05 mission s at 50x
        assert t1 < 30.0
