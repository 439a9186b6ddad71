"""``gcs run`` under faults, against the built-in simulator on 127.0.0.1 (ephemeral ports):
20 % packet loss on every link plus one vehicle's link cut for 30 s; an operator switching
a vehicle to FBWA and back to AUTO; a low battery; another ground station uploading a
mission through ``--out``."""

from __future__ import annotations

import asyncio
import socket
from pathlib import Path
from typing import Any

import pytest
from daemon_run import Journal, after, events, run_gcs

from groundstation.commands.run import build_config, run_daemon
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.journal import read_journal
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, mavlink2


def _link_cut_done(journal: Journal) -> bool:
    """Mission time 200 s has passed (the window the test always watched) and everything it
    asserts on has happened: vehicle 2 lost and restored, then planned and sent a verified
    mission again; every vehicle sent one; six in all."""
    lost = events(journal, "link_lost", vehicle="2")
    if not journal or journal[-1]["t"] < 200.0 or not lost:
        return False
    restored = after(events(journal, "link_restored", vehicle="2"), lost[0]["t"])
    if not restored:
        return False
    t_back = restored[0]["t"]
    targets = events(journal, "upload", ok=True, purpose="target")
    return (
        len(targets) >= 6
        and {e["vehicle"] for e in targets} == {"1", "2", "3"}
        and bool(after(events(journal, "upload", vehicle="2", ok=True, purpose="target"), t_back))
        and any(p["t"] > t_back and "2" in p["routes"] for p in events(journal, "plan"))
    )


def test_packet_loss_and_link_cut(tmp_path: Path) -> None:
    # replanning every 10 s without commitment: every plan covers every target with the
    # vehicles in it, and flying vehicles are redirected by verified re-uploads (through
    # the 20 % loss). The run ends after 200 mission s once everything asserted on has
    # happened (--duration 400 only bounds it): on a loaded host the built-in simulator
    # catches up in steps of up to 0.25 mission s per event-loop turn, so the daemon's
    # answers, the retries through the loss included, take more mission time than on a
    # quiet one.
    daemon, journal = run_gcs(
        tmp_path, "--vehicles", "sim:3", "--scenario", "default", "--sim-airborne",
        "--sim-loss", "0.2", "--sim-fault", "2:drop:at=60,for=30", "--no-commit",
        "--replan", "both", "--period", "10", "--speedup", "50", "--duration", "400",
        until=_link_cut_done,
    )  # fmt: skip
    assert daemon.stop_reason == "test: awaited events seen", daemon.stop_reason
    assert not events(journal, "task_error") and not events(journal, "core_error")
    # uploads succeed through 20 % loss (retried, verified by download)
    for vid in ("1", "2", "3"):
        assert events(journal, "upload", vehicle=vid, ok=True, purpose="target")
    assert daemon.summary()["uploads_ok"] >= 6
    # vehicle 2: lost after the configured silence, restored when the link comes back
    lost = events(journal, "link_lost", vehicle="2")
    assert lost and 60.0 <= lost[0]["t"] <= 72.0
    t_lost = lost[0]["t"]
    restored = [e for e in events(journal, "link_restored", vehicle="2") if e["t"] > t_lost]
    assert restored and 88.0 <= restored[0]["t"] <= 100.0
    t_back = restored[0]["t"]
    # the others are never declared lost: loss alone does not cut the link
    assert not [e for e in events(journal, "link_lost") if e["vehicle"] != "2"]
    # while it is lost it is in no plan, and the target it was flying to is not left to it:
    # every plan puts it before the others (in the problem), and routes it to one of them
    # unless the planner's 10 % rule drops it (its uncertainty was just reset: vehicle 2
    # may have been loitering over it when its link was cut, so it can stay below 10 % of
    # the mean for the whole silence); every target not dropped is routed (no commitment)
    flown = [e for e in events(journal, "fly", vehicle="2") if e["t"] < t_lost]
    assert flown
    target = flown[-1]["target"]
    plans_while_lost = [p for p in events(journal, "plan") if t_lost < p["t"] < t_back]
    assert plans_while_lost
    for p in plans_while_lost:
        assert "2" not in p["routes"] and "2" not in p["result"]["idle"], p["t"]
        assert [u["id"] for u in p["problem"]["uavs"]] and "2" not in {
            u["id"] for u in p["problem"]["uavs"]
        }
        problem_targets = {tg["id"] for tg in p["problem"]["targets"]}
        routed = {tg for route in p["routes"].values() for tg in route}
        excluded = set(p["result"]["excluded"])
        assert target in problem_targets, (p["t"], target, problem_targets)
        assert routed | excluded == problem_targets, (p["t"], routed, excluded)
        sigmas = {tg["id"]: tg["sigma"] for tg in p["problem"]["targets"]}
        mean_sigma = sum(sigmas.values()) / len(sigmas)
        for dropped in excluded:  # dropped only by the 10 % rule
            assert sigmas[dropped] < 0.1 * mean_sigma, (p["t"], dropped, sigmas)
    # no camera data from a vehicle whose link is down
    assert not [e for e in events(journal, "detection", vehicle="2") if t_lost < e["t"] < t_back]
    # taken back into the plan when it returns: planned again, a new verified mission
    assert [p for p in events(journal, "plan") if p["t"] > t_back and "2" in p["routes"]]
    assert after(events(journal, "upload", vehicle="2", ok=True, purpose="target"), t_back)


@pytest.mark.timeout(100)
def test_operator_override_and_low_battery(tmp_path: Path) -> None:
    _, journal = run_gcs(
        tmp_path,
        "--vehicles",
        "sim:3",
        "--scenario",
        "default",
        "--sim-airborne",
        "--sim-fault",
        "1:mode:at=50,mode=FBWA",
        "--sim-fault",
        # back before it glides into the ground (FBWA without RC input sinks ~2.2 m/s
        # from 100 m): a plane still flying can be taken back
        "1:mode:at=75,mode=AUTO",
        "--sim-fault",
        "3:battery:at=80,pct=10",
        "--loiter",
        "20",
        "--speedup",
        "50",
        "--duration",
        "220",
    )
    assert not events(journal, "task_error")
    # vehicle 1: FBWA by the operator -> released, replanned without it
    override = events(journal, "override", vehicle="1")
    assert override and override[0]["reason"] == "mode FBWA" and override[0]["t"] >= 50.0
    t_over = override[0]["t"]
    resume = events(journal, "resume", vehicle="1")
    assert resume and resume[0]["reason"] == "mode AUTO" and resume[0]["t"] >= 75.0
    t_resume = resume[0]["t"]
    between = [p for p in events(journal, "plan") if t_over < p["t"] < t_resume]
    assert all("1" not in p["routes"] for p in between)
    # with commitment the override frees no one, so plans come from the others' loiter
    # ends: each one inside the override's window was followed by a plan without vehicle 1
    # (how many fall inside depends on upload latency, i.e. on the machine's load)
    ends = [e["t"] for e in events(journal, "loiter_end") if t_over < e["t"] < t_resume - 1.0]
    assert all(any(t <= p["t"] for p in between) for t in ends)
    assert not [e for e in events(journal, "fly", vehicle="1") if t_over < e["t"] < t_resume]
    assert not [e for e in events(journal, "upload", vehicle="1") if t_over < e["t"] < t_resume]
    # AUTO again -> taken back: a new verified mission
    assert after(events(journal, "upload", vehicle="1", ok=True, purpose="target"), t_resume)
    # vehicle 3: low battery -> RTL, out of the plan, and not mistaken for an override
    low = events(journal, "battery_low", vehicle="3")
    assert low and low[0]["t"] >= 80.0
    t_low = low[0]["t"]
    assert not events(journal, "override", vehicle="3")
    rtl_mode = [e for e in events(journal, "mode", vehicle="3", mode="RTL") if e["t"] >= 80.0]
    assert rtl_mode
    later_plans = [p for p in events(journal, "plan") if p["t"] > t_low + 1.0]
    assert later_plans and all("3" not in p["routes"] for p in later_plans)
    assert not after(events(journal, "fly", vehicle="3"), t_low + 1.0)


class _FakeGcs(asyncio.DatagramProtocol):
    """A second ground station (QGroundControl-like, system id 255) on a UDP socket."""

    def __init__(self) -> None:
        self.decoder = MavlinkDecoder()
        self.heard: set[int] = set()
        self.peer: Any = None
        self.transport: asyncio.DatagramTransport | None = None

    def connection_made(self, transport: Any) -> None:
        self.transport = transport

    def datagram_received(self, data: bytes, addr: Any) -> None:
        self.peer = addr
        for msg in MavlinkDecoder().feed(data):
            self.heard.add(msg.get_srcSystem())


@pytest.mark.timeout(60)
def test_mission_upload_by_another_gcs_is_an_override(tmp_path: Path) -> None:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    config = build_config(
        [
            "--vehicles",
            "sim:2",
            "--scenario",
            "default",
            "--sim-airborne",
            "--speedup",
            "50",
            "--duration",
            "200",
            "--out",
            f"udpout:127.0.0.1:{port}",
            "--run-dir",
            str(tmp_path),
            "--http",
            "off",
            "--detections",
            "off",
            "--status",
            "quiet",
        ]
    )
    state: dict[str, Any] = {}

    async def main() -> Daemon:
        loop = asyncio.get_running_loop()
        gcs = _FakeGcs()
        await loop.create_datagram_endpoint(lambda: gcs, sock=sock)
        started: asyncio.Future[Daemon] = loop.create_future()
        task = asyncio.create_task(
            run_daemon(
                config,
                print_fn=lambda _: None,
                install_signals=False,
                on_started=started.set_result,
            )
        )
        daemon = await started
        # wait until vehicle 1 flies a mission of ours and vehicle 2 has joined (its join
        # now waits for evidence that it flies, so it may come after vehicle 1's upload)
        while not (
            daemon.sessions.get(1) and daemon.sessions[1].uploads_ok
            and daemon.sessions.get(2) and daemon.sessions[2].status == "active"
        ):
            await asyncio.sleep(0.01)
        assert gcs.peer is not None and 1 in gcs.heard  # traffic forwarded to the other GCS
        encoder = MavlinkEncoder(255, 190)
        assert gcs.transport is not None
        gcs.transport.sendto(
            encoder.encode(mavlink2.MAVLink_mission_count_message(1, 1, 2, 0)), gcs.peer
        )
        state["t_sent"] = daemon.clock.now_s()
        while daemon.sessions[1].status != "overridden":
            await asyncio.sleep(0.01)
        state["status_2"] = daemon.sessions[2].status
        daemon.request_stop("test")
        result = await task
        gcs.transport.close()
        return result

    daemon = asyncio.run(asyncio.wait_for(main(), 50.0))
    journal = read_journal(daemon.run_dir / "journal.jsonl")
    override = events(journal, "override", vehicle="1")
    assert override and "MISSION_COUNT from GCS system 255" in override[0]["reason"]
    assert state["status_2"] == "active"
    assert not after(events(journal, "fly", vehicle="1"), override[0]["t"])
    stop = events(journal, "stop")
    assert stop and stop[0]["reason"] == "test"


def _taken_back_after_reboot(journal: Journal) -> bool:
    """Vehicle 1 rebooted, joined again after it and then got a verified target mission:
    the last thing the test asserts on (at ~49 of the 120 mission s, measured; its span of
    plans without vehicle 1 ends at the join)."""
    reboot = events(journal, "reboot", vehicle="1")
    if not reboot:
        return False
    rejoined = after(events(journal, "vehicle_joined", vehicle="1"), reboot[0]["t"])
    return bool(rejoined) and bool(
        after(events(journal, "upload", vehicle="1", ok=True, purpose="target"), rejoined[0]["t"])
    )


@pytest.mark.timeout(60)
def test_reboot_in_flight_is_taken_back(tmp_path: Path) -> None:
    daemon, journal = run_gcs(
        tmp_path,
        "--vehicles",
        "sim:2",
        "--scenario",
        "default",
        "--sim-airborne",
        "--sim-fault",
        "1:reboot:at=40",
        "--speedup",
        "50",
        "--duration",
        "120",
        until=_taken_back_after_reboot,
    )
    assert daemon.stop_reason == "test: awaited events seen", daemon.stop_reason
    assert not events(journal, "task_error")
    reboot = events(journal, "reboot", vehicle="1")
    assert reboot and reboot[0]["t"] >= 40.0
    t_reboot = reboot[0]["t"]
    # the built-in vehicle comes back flying its stored mission (a timed loiter, not an
    # unlimited one): it is parked, joins again and gets a new verified mission
    rejoined = after(events(journal, "vehicle_joined", vehicle="1"), t_reboot)
    assert rejoined and rejoined[0]["how"] == "parked"
    assert after(
        events(journal, "upload", vehicle="1", ok=True, purpose="target"), rejoined[0]["t"]
    )
    assert all(
        "1" not in p["routes"]
        for p in events(journal, "plan")
        if t_reboot < p["t"] < rejoined[0]["t"]
    )
