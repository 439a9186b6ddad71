"""End-to-end: a pilot's mode change is final (issue 25), through real MAVLink.

``gcs run`` against the built-in ArduPlane vehicles. A pilot switches a vehicle out of AUTO
at a chosen phase of floe's mission (flying to its target, loitering over it, on the last
item), exactly as ``--sim-fault N:mode:at=T,mode=M`` does, but at the moment the phase is
reached; the test then checks what the simulated vehicle *received* after that moment (no
upload started, no set-current, no mode change, no arming), and that the journal calls it an
override, never a mission end. ``gcs vehicle resume`` (the API's action, as the CLI sends it)
then gives the vehicle back. A plane that glided into the ground while the pilot had it is
never launched again on floe's own, even with launch on; ``gcs vehicle launch`` launches it.
Times are mission times; the wall clock only bounds the runs. A run whose checks of "nothing
commanded" end at a stated moment (the resume, the operator's launch) stops once that moment
and the events asserted after it are in; ``--duration`` only bounds it.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import pytest
from daemon_run import Journal, events, stop_when
from test_daemon_trust import KeptSim, changes_vehicle, from_gcs, is_set_mode

from domain.modes import ArduPlaneMode
from groundstation.commands.run import build_config
from groundstation.daemon.control.controller import DaemonController
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.journal import read_journal
from groundstation.daemon.startup import run_daemon
from sitl.faults import FaultEvent
from sitl.server import SitlServer
from sitl.vehicle import SimVehicle

AUTO = int(ArduPlaneMode.AUTO)
Watch = Callable[[Daemon, SitlServer, float], None]
Done = Callable[[SitlServer, Journal], bool]


def run_watching(tmp_path: Path, args: list[str], watch: Watch, timeout_s: float = 90.0,
                 until: Done | None = None) -> tuple[Daemon, SitlServer, Journal]:  # fmt: skip
    """Run the daemon until ``--duration``, calling ``watch(daemon, server, t_s)`` every
    few wall milliseconds on its event loop; with ``until``, stop it as soon as
    ``until(server, journal)`` holds (:func:`daemon_run.stop_when`: ``--duration`` is then
    only the upper bound)."""
    config = build_config([*args, "--run-dir", str(tmp_path), "--http", "off",
                           "--detections", "off", "--status", "quiet"])  # fmt: skip

    async def main() -> tuple[Daemon, SitlServer]:
        loop = asyncio.get_running_loop()
        started: asyncio.Future[Daemon] = loop.create_future()
        kept = KeptSim()
        task = asyncio.create_task(run_daemon(
            config, print_fn=lambda _: None, install_signals=False,
            on_started=started.set_result, embedded=kept,
        ))  # fmt: skip
        daemon = await started
        server = kept.server
        stopper = None
        if until is not None:
            stopper = asyncio.create_task(stop_when(daemon, partial(until, server)))
        try:
            while not task.done():
                watch(daemon, server, daemon.clock.now_s())
                await asyncio.sleep(0.002)
            await task
        finally:
            if stopper is not None:
                stopper.cancel()
        return daemon, server

    daemon, server = asyncio.run(asyncio.wait_for(main(), timeout_s))
    return daemon, server, read_journal(daemon.run_dir / "journal.jsonl")


def sim(server: SitlServer, sysid: int) -> SimVehicle:
    return next(v for v in server.vehicles() if v.system_id == sysid)


def switch(server: SitlServer, sysid: int, mode: str, t_s: float) -> None:
    """The pilot's switch, as the simulator's ``mode`` fault makes it."""
    slot = next(s for s in server.slots if s.vehicle is not None and s.vehicle.system_id == sysid)
    slot.faults.add_event(FaultEvent(t_s, "mode", mode=int(ArduPlaneMode[mode])))


def phase(daemon: Daemon, v: SimVehicle) -> str | None:
    """Where vehicle ``v`` is in floe's target mission [home, timed loiter, unlimited
    loiter], by the simulator's own state (None: not in one yet)."""
    session = daemon.sessions.get(v.system_id)
    fly = session.fly if session is not None else None
    nav = v.autopilot.nav
    if session is None or session.status != "active" or fly is None or fly.verified_t_s is None:
        return None
    if v.autopilot.mode != AUTO or nav is None:
        return None
    last = len(v.store) - 1
    if nav.kind == "loiter_unlim" and v.autopilot.current_seq == last == 2:
        return "last item"
    if nav.kind != "loiter_time" or v.autopilot.current_seq != 1:
        return None
    if nav.on_circle_t_s is not None:
        return "loitering" if v.t_s - nav.on_circle_t_s >= 2.0 else None
    far = math.hypot(v.airframe.x_m - nav.x_m, v.airframe.y_m - nav.y_m) > nav.radius_m + 300
    return "flying to a target" if far else None


def _store(reply: dict[str, Any], done: asyncio.Task[dict[str, Any]]) -> None:
    reply.update(done.result())


class Pilots:
    """Switch vehicle ``sysid`` to ``mode`` when it reaches ``when``; give each back through
    the API ``resume_after_s`` later."""

    def __init__(self, plan: dict[int, tuple[str, str]], resume_after_s: float) -> None:
        self.plan = plan
        self.resume_after_s = resume_after_s
        self.switched: dict[int, float] = {}
        self.resumed: dict[int, tuple[float, dict[str, Any]]] = {}
        self.tasks: list[asyncio.Task[dict[str, Any]]] = []

    def __call__(self, daemon: Daemon, server: SitlServer, t_s: float) -> None:
        for sysid, (when, mode) in self.plan.items():
            v = sim(server, sysid)
            if sysid not in self.switched and phase(daemon, v) == when:
                switch(server, sysid, mode, v.t_s)
                self.switched[sysid] = v.t_s
            at = self.switched.get(sysid)
            if at is not None and sysid not in self.resumed and t_s >= at + self.resume_after_s:
                control = DaemonController(daemon)
                reply: dict[str, Any] = {}
                self.resumed[sysid] = (t_s, reply)
                task = asyncio.ensure_future(control.vehicle_action(str(sysid), "resume"))
                self.tasks.append(task)
                task.add_done_callback(partial(_store, reply))

    def given_back(self, server: SitlServer, journal: Journal) -> bool:
        """Every vehicle of the plan was switched, overridden, and given back: the API
        answered its resume, the journal took it, and after it came a verified target
        upload and floe's AUTO at the vehicle. That is the last thing the test asserts on
        (its spans of "nothing commanded", "no fly" end at the resume; the journal calls the
        switch an override, not a mission end, within 6 s of it), at ~85 of the 240
        mission s (measured); the rest of the run only flies on."""
        for sysid in self.plan:
            if sysid not in self.resumed or not self.resumed[sysid][1]:
                return False
            name = str(sysid)
            if not [e for e in events(journal, "override", vehicle=name)
                    if e["t"] >= self.switched[sysid]]:  # fmt: skip
                return False
            t_asked = self.resumed[sysid][0]
            resumed = [e for e in events(journal, "resume", vehicle=name, reason="api")
                       if e["t"] >= t_asked - 0.5]  # fmt: skip
            if not resumed:
                return False
            t_resume = resumed[0]["t"]
            if not [e for e in events(journal, "upload", vehicle=name, ok=True,
                                      purpose="target") if e["t"] >= t_resume]:  # fmt: skip
                return False
            if not [c for c in from_gcs(server, sysid, t_resume - 0.5) if is_set_mode(c, AUTO)]:
                return False
        return True


CASES = {
    "rtl": {1: ("flying to a target", "RTL"), 2: ("loitering", "RTL"), 3: ("last item", "RTL")},
    "pilot modes": {
        1: ("flying to a target", "FBWA"), 2: ("loitering", "MANUAL"), 3: ("last item", "LOITER"),
    },
}  # fmt: skip


@pytest.mark.timeout(150)
@pytest.mark.parametrize("case", list(CASES))
def test_pilots_switch_is_final_until_given_back(tmp_path: Path, case: str) -> None:
    pilots = Pilots(CASES[case], resume_after_s=12.0)
    daemon, server, journal = run_watching(
        tmp_path,
        ["--vehicles", "sim:3", "--scenario", "default", "--loiter", "15",
         "--speedup", "25", "--duration", "240"],
        pilots, until=pilots.given_back,
    )  # fmt: skip
    assert daemon.stop_reason == "test: awaited events seen", daemon.stop_reason
    assert not events(journal, "task_error")
    for sysid, (when, mode) in CASES[case].items():
        assert sysid in pilots.switched, f"vehicle {sysid} never reached {when!r}"
        t_switch = pilots.switched[sysid]
        t_asked, reply = pilots.resumed[sysid]
        name = str(sysid)
        resumed = [e for e in events(journal, "resume", vehicle=name, reason="api")
                   if e["t"] >= t_asked - 0.5]  # fmt: skip
        assert resumed, f"vehicle {sysid}: the API's resume was not taken"
        t_resume = resumed[0]["t"]
        # the journal: an override of the pilot's mode, never a mission end or a failsafe
        overrides = [e for e in events(journal, "override", vehicle=name) if e["t"] >= t_switch]
        assert overrides and overrides[0]["reason"] == f"mode {mode}", (when, overrides)
        assert overrides[0]["mode"] == mode and overrides[0]["t"] < t_switch + 6.0
        assert not [e for e in events(journal, "autopilot_mode", vehicle=name)
                    if e["t"] >= t_switch]  # fmt: skip
        # the vehicle: nothing changed it between the switch and the resume
        # (the simulator's clock and the daemon's differ by a fraction of a second)
        between = [c for c in from_gcs(server, sysid, t_switch) if c.t_s < t_resume - 1.0]
        assert not [c for c in between if changes_vehicle(c)], (when, between)
        # (the core may still decide for it until the override is known; never after)
        assert not [e for e in events(journal, "fly", vehicle=name)
                    if overrides[0]["t"] <= e["t"] < t_resume]  # fmt: skip
        # given back: the API's resume took it, a verified target, AUTO set by floe
        assert reply == {"ok": True, "error": None, "vehicle": name, "status": "active",
                         "what": f"vehicle {name} resumed: floe flies it again "
                                 "(was overridden)"}
        uploads = [e for e in events(journal, "upload", vehicle=name, ok=True, purpose="target")
                   if e["t"] >= t_resume]  # fmt: skip
        assert uploads, f"vehicle {sysid} was not given back"
        assert [c for c in from_gcs(server, sysid, t_resume - 0.5) if is_set_mode(c, AUTO)]


@pytest.mark.timeout(150)
def test_sim_fault_rtl_on_the_first_target_is_the_operators(tmp_path: Path) -> None:
    """The issue's own command: before the fix this RTL was journalled as a mission end and
    floe uploaded a new target and set AUTO 4 s later."""
    config = build_config([
        "--vehicles", "sim:1", "--scenario", "default", "--sim-fault", "1:mode:at=60,mode=RTL",
        "--duration", "120", "--run-dir", str(tmp_path), "--http", "off",
        "--detections", "off", "--status", "quiet",
    ])  # fmt: skip
    kept = KeptSim()
    daemon = asyncio.run(asyncio.wait_for(
        run_daemon(config, print_fn=lambda _: None, install_signals=False, embedded=kept), 90.0
    ))  # fmt: skip
    journal = read_journal(daemon.run_dir / "journal.jsonl")
    server = kept.server
    # at t=60 it flew its first target item (launched, joined, sent to its target)
    fly = [e for e in events(journal, "upload", vehicle="1", purpose="target") if e["t"] < 60]
    assert fly and fly[0]["ok"] is True
    (override,) = events(journal, "override", vehicle="1")
    assert override["reason"] == "mode RTL" and 60.0 <= override["t"] < 66.0
    assert not events(journal, "autopilot_mode")
    assert not [c for c in from_gcs(server, 1, 60.0) if changes_vehicle(c)]
    assert sim(server, 1).autopilot.mode == int(ArduPlaneMode.RTL)


@pytest.mark.timeout(150)
def test_plane_that_came_down_while_the_pilot_had_it_is_never_relaunched(
    tmp_path: Path,
) -> None:
    """sim:N launches vehicles on the ground by default. Vehicle 1 is taken in FBWA, glides
    into the ground and is switched back to AUTO there: floe refuses the resume, holds the
    launch and says why; only the operator's launch (``gcs vehicle launch 1``) arms it."""
    launch: dict[str, Any] = {}

    def operator(daemon: Daemon, server: SitlServer, t_s: float) -> None:
        if t_s >= 200.0 and not launch:
            launch["t"] = t_s
            control = DaemonController(daemon)
            launch["state"] = next(v for v in control.state()["vehicles"] if v["id"] == "1")
            task = asyncio.ensure_future(control.vehicle_action("1", "launch"))
            reply: dict[str, Any] = {}
            launch["reply"] = reply
            task.add_done_callback(partial(_store, reply))

    def relaunched(server: SitlServer, journal: Journal) -> bool:
        """The operator's launch answered, and after its request floe's launch and a
        verified takeoff mission: the last thing asserted on (~0.3 s after the request at
        200 of the 300 mission s, measured). The spans of "nothing armed, uploaded or
        launched" and of vehicle 2's plans end at that request."""
        requests = events(journal, "launch_request", vehicle="1")
        if not launch.get("reply") or not requests:
            return False
        t_request = requests[0]["t"]
        return bool(
            [e for e in events(journal, "launch", vehicle="1") if e["t"] >= t_request]
            and [e for e in events(journal, "upload", vehicle="1", purpose="takeoff", ok=True)
                 if e["t"] >= t_request]
        )  # fmt: skip

    daemon, server, journal = run_watching(
        tmp_path,
        ["--vehicles", "sim:2", "--scenario", "default",
         "--sim-fault", "1:mode:at=60,mode=FBWA", "--sim-fault", "1:mode:at=140,mode=AUTO",
         "--speedup", "25", "--duration", "300"],
        operator, until=relaunched,
    )  # fmt: skip
    assert daemon.stop_reason == "test: awaited events seen", daemon.stop_reason
    assert not events(journal, "task_error")
    hit = [e for e in events(journal, "statustext", vehicle="1") if "Hit ground" in e["text"]]
    (override,) = [e for e in events(journal, "override", vehicle="1")]
    assert hit and override["t"] < hit[0]["t"] < 140.0
    refused = events(journal, "resume_refused", vehicle="1")
    assert refused and refused[0]["t"] >= 140.0
    (held,) = events(journal, "launch_held", vehicle="1")
    assert "while the operator had it" in held["reason"] and held["t"] >= 140.0
    # nothing armed, uploaded or launched between the override and the operator's launch
    (request,) = events(journal, "launch_request", vehicle="1")
    assert request["by"] == "operator" and request["t"] >= launch["t"] - 0.01  # (rounded)
    t_launch = request["t"]
    # (the simulator's clock and the daemon's differ by a fraction of a second)
    before = [c for c in from_gcs(server, 1, override["t"]) if c.t_s < t_launch - 1.0]
    assert not [c for c in before if changes_vehicle(c)], before
    assert not [e for e in events(journal, "launch", vehicle="1") if e["t"] > override["t"]
                and e["t"] < t_launch]  # fmt: skip
    # the API (gcs vehicle list) says why it is held
    assert launch["state"]["launch_held"] == held["reason"]
    assert launch["state"]["status"] == "on_ground"
    # the operator's launch: accepted, and floe launches it (takeoff mission, armed, AUTO)
    answer = launch.get("reply") or {}
    assert (answer.get("ok"), answer.get("error"), answer.get("vehicle")) == (True, None, "1")
    assert str(answer.get("what")).startswith("vehicle 1: launch requested")
    relaunch = [e for e in events(journal, "launch", vehicle="1") if e["t"] >= t_launch]
    assert relaunch
    assert [e for e in events(journal, "upload", vehicle="1", purpose="takeoff", ok=True)
            if e["t"] >= t_launch]  # fmt: skip
    # vehicle 2 flew on: its plans never held vehicle 1 after the override
    later = [p for p in events(journal, "plan") if override["t"] < p["t"] < t_launch]
    assert later and all("1" not in p["routes"] for p in later)
