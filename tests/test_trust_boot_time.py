"""Issue 28: a reboot needs corroboration whatever the boot time, large or small.

One forged frame with a large ``time_boot_ms`` (ATTITUDE or SYSTEM_TIME, 4 000 000 000) was
taken as the vehicle's timeline; the real frames after it then looked like a step back and
"confirmed" a reboot: the vehicle left the plan, its upload was cancelled and a ``park``
mission uploaded. Now a boot time ahead of what the receive clock allows is held back
until frames keep to it (:class:`~groundstation.mavlink.evidence.RebootEvidence`).

Sans-IO (the rule, the reducer), then a probe through real MAVLink against the built-in
simulator (``gcs run --vehicles sim:2``): the forged frame changes nothing.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from daemon_run import events
from test_daemon_trust import FALSE_STATE_EVENTS, run_with_actions
from test_telemetry_reducer import gpi, heartbeat, wire

from domain.geodesy import GeoOrigin
from groundstation.daemon.daemon import Daemon
from groundstation.mavlink.codec import MAVLinkMessage, mavlink2
from groundstation.mavlink.evidence import RebootEvidence
from groundstation.mavlink.telemetry import Rebooted, VehicleTelemetry
from sitl.forge import AHEAD_BOOT_MS, forged_frames
from sitl.server import SitlServer

M = mavlink2
ORIGIN = GeoOrigin(78.9, 11.9, 0.0)
BOOT0_MS = 600_000  # the vehicle has been up 10 minutes at mission time 0


def attitude(boot_ms: int) -> MAVLinkMessage:
    return wire(M.MAVLink_attitude_message(boot_ms, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0))


def system_time(boot_ms: int) -> MAVLinkMessage:
    return wire(M.MAVLink_system_time_message(int(1.7e15), boot_ms))


def real(t_s: float, late_s: float = 0.05) -> int:
    """The vehicle's own time_boot_ms of a frame received at ``t_s``, ``late_s`` late."""
    return BOOT0_MS + round((t_s - late_s) * 1000)


def feed_real(tel: VehicleTelemetry, t0_s: float, t1_s: float, dt_s: float = 0.25) -> list:
    """Real frames (ATTITUDE) from t0 to t1; the events they caused."""
    out = []
    t = t0_s
    while t <= t1_s + 1e-9:
        out += tel.receive(attitude(real(t)), t)
        t += dt_s
    return out


# ---------------------------------------------------------------- the rule
def test_rule_one_large_frame_is_held_back_and_the_next_real_one_clears_it() -> None:
    rule = RebootEvidence()
    accepted = None
    for t in (0.0, 0.5, 1.0):
        assert rule.observe(accepted, real(t), t) == "ok"
        accepted = real(t)
    assert rule.observe(accepted, AHEAD_BOOT_MS, 1.2) == "ahead"
    assert rule.ahead_suspected and not rule.suspected
    assert rule.observe(accepted, real(1.5), 1.5) == "ok"
    assert not rule.ahead_suspected and rule.rejected == 1


def test_rule_an_accepted_value_never_reaches_a_step_back() -> None:
    # what may be accepted is at most ahead_ms + drift_cap_ms ahead of the receive clock,
    # below backstep_ms: the real frames after it are never "back"
    with pytest.raises(ValueError, match="below backstep_ms"):
        RebootEvidence(backstep_ms=3000, ahead_ms=3000)
    rule = RebootEvidence()
    assert rule.observe(None, real(0.0), 0.0) == "ok"
    limit = rule.limit_ms(60.0)  # even after a long silence
    assert limit is not None
    assert limit - real(60.0) <= rule.ahead_ms + rule.drift_cap_ms < rule.backstep_ms


# ---------------------------------------------------------------- the reducer
@pytest.mark.parametrize("forge", [attitude, system_time])
def test_one_forged_large_boot_time_among_real_frames_changes_nothing(forge) -> None:
    tel = VehicleTelemetry(1, ORIGIN)
    tel.receive(heartbeat(10, armed=True), 0.0)
    tel.receive(wire(M.MAVLink_mission_current_message(1, 2)), 0.0)
    feed_real(tel, 0.0, 10.0)
    before = tel.snapshot().time_boot_ms
    assert tel.receive(forge(AHEAD_BOOT_MS), 10.1) == []
    snap = tel.snapshot()
    assert snap.time_boot_ms == before and not snap.reboot_suspected  # no timeline change
    evs = feed_real(tel, 10.25, 30.0)
    assert not [e for e in evs if isinstance(e, Rebooted)]
    snap = tel.snapshot()
    assert snap.time_boot_ms == real(30.0) and not snap.reboot_suspected
    assert snap.mission_current_seq == 1 and snap.mode == 10  # nothing forgotten
    assert tel.reboot.rejected == 1


def test_forged_large_frames_repeated_now_and_then_make_no_timeline() -> None:
    # one every 0.6 s, each followed by real frames: never 3 in a row, never a timeline
    tel = VehicleTelemetry(1, ORIGIN)
    feed_real(tel, 0.0, 2.0)
    evs: list = []
    t = 2.0
    for k in range(30):
        evs += tel.receive(system_time(AHEAD_BOOT_MS + 1000 * k), t + 0.1)
        evs += feed_real(tel, t + 0.25, t + 0.5)
        t += 0.6
    assert not [e for e in evs if isinstance(e, Rebooted)]
    assert tel.snapshot().time_boot_ms == real(t - 0.1)
    assert tel.reboot.resyncs == 0


def test_a_forged_large_position_does_not_freeze_the_real_ones() -> None:
    # the positions' order follows only accepted boot times: before, one forged
    # GLOBAL_POSITION_INT at 4e9 made every real position after it "stale"
    tel = VehicleTelemetry(1, ORIGIN)
    tel.receive(gpi(boot_ms=real(1.0)), 1.0)
    tel.receive(gpi(789_100_000, boot_ms=AHEAD_BOOT_MS), 1.5)
    tel.receive(gpi(789_200_000, boot_ms=real(2.0)), 2.0)
    assert tel.snapshot().last_position_s == 2.0 and tel.stale_messages == 0


def test_a_real_reboot_is_still_detected_within_its_bound() -> None:
    # even right after a forged large frame: 3 frames of the new timeline over 1 s
    tel = VehicleTelemetry(1, ORIGIN)
    feed_real(tel, 0.0, 20.0)
    tel.receive(attitude(AHEAD_BOOT_MS), 20.1)
    got = []
    for k, t in enumerate((21.0, 21.5, 22.0)):
        got += tel.receive(attitude(500 + 500 * k), t)
    assert [type(e) for e in got] == [Rebooted]
    assert got[0].t_s == 22.0 and tel.snapshot().time_boot_ms == 1500


def test_a_long_silence_then_the_same_timeline_is_no_reboot_and_no_suspicion() -> None:
    tel = VehicleTelemetry(1, ORIGIN)
    feed_real(tel, 0.0, 10.0)
    evs = feed_real(tel, 70.0, 75.0)  # 60 s of silence (a lost link), then it is back
    assert not [e for e in evs if isinstance(e, Rebooted)]
    assert tel.snapshot().time_boot_ms == real(75.0)
    assert tel.reboot.held_ahead == 0 and not tel.snapshot().reboot_suspected


def test_a_backlog_drained_at_once_is_a_new_timeline_not_a_reboot() -> None:
    # frames 20 s late (a backlog), then fresh ones: the jump ahead is held back until
    # 3 fresh frames over 1 s keep to it, then accepted; nothing is forgotten
    tel = VehicleTelemetry(1, ORIGIN)
    tel.receive(heartbeat(10, armed=True), 0.0)
    t = 0.0
    while t <= 5.0:
        tel.receive(attitude(real(t, late_s=20.0)), t)
        t += 0.25
    evs = []
    for t in (5.25, 5.75, 6.25, 6.5):
        evs += tel.receive(attitude(real(t)), t)
    assert not [e for e in evs if isinstance(e, Rebooted)]
    assert tel.reboot.resyncs == 1 and tel.snapshot().time_boot_ms == real(6.5)
    assert tel.snapshot().mode == 10


# ---------------------------------------------------------------- end to end
def _forge_ahead(daemon: Daemon, server: SitlServer) -> None:
    """ATTITUDE and SYSTEM_TIME at 4e9 ms on vehicle 1's own link, from its autopilot's
    own ids, between its real frames."""
    data = b"".join(forged_frames(1, 1, kinds=("boot_time_ahead",)))
    slot = next(s for s in server.slots if s.config.system_id == 1)
    assert slot.clients, "the daemon is not connected to vehicle 1"
    for writer in slot.clients:
        writer.write(data)


@pytest.mark.timeout(120)
def test_a_forged_large_boot_time_through_the_daemon_changes_nothing(tmp_path: Path) -> None:
    injections = [30.0, 50.0, 70.0]
    _, server, journal = run_with_actions(
        tmp_path,
        ["--vehicles", "sim:2", "--scenario", "default", "--sim-airborne", "--loiter", "10",
         "--speedup", "25", "--duration", "100"],
        [(t, _forge_ahead) for t in injections],
    )  # fmt: skip
    assert not events(journal, "task_error")
    for name in (*FALSE_STATE_EVENTS, "power_up"):
        assert not events(journal, name), f"{name}: {events(journal, name)}"
    # no park mission, no cancelled upload, no vehicle taken out of the plan
    parks = [e for e in events(journal, "upload", vehicle="1") if e.get("purpose") == "park"]
    assert not [e for e in parks if e["t"] > injections[0]], parks
    assert not [e for e in events(journal, "upload", vehicle="1", ok=False)
                if "no longer wanted" in (e.get("error") or "")]
    lost = [e for e in events(journal, "input") if e.get("vehicle") == "1"
            and e.get("kind") in ("VehicleLost", "VehicleRebooted")]
    assert not lost, lost
    # it keeps its plan: its loiter ends as planned, and it is sent on to the next target
    assert [e for e in events(journal, "loiter_end", vehicle="1") if e["t"] > injections[0]]
    assert [e for e in events(journal, "upload", vehicle="1", ok=True, purpose="target")
            if e["t"] > injections[0]]
    v1 = next(v for v in server.vehicles() if v.system_id == 1)
    assert v1.reboots == 0  # (the simulator's own vehicle really did not reboot)
