"""Every operator action answers with what happened (issue 29, items 1 and 5).

Unit level: an operator's target fix re-seats the track (not a gated measurement) and
replays; the vehicle controller's release, RTL and resume say what they did, journal
``released`` (not ``override``) and never a refusal before a success. End to end (``gcs
run`` against the built-in ArduPlane vehicles, actions through the API's controller): the
fix, release-all, RTL-all and resume-all, each answered per vehicle, a released vehicle
showing no route, and the run replaying to the same decisions.
"""

from __future__ import annotations

import asyncio
import contextlib
import io
from pathlib import Path
from typing import Any

import pytest
from daemon_run import events
from test_daemon_pilot_modes import run_watching
from test_vehicle_controller import active_rig

from domain.modes import ArduPlaneMode
from groundstation.cli import main
from groundstation.core import events as ev
from groundstation.core.commands import Note
from groundstation.core.config import CoreConfig
from groundstation.core.decision import DecisionCore
from groundstation.core.records import event_to_record, record_to_event
from groundstation.daemon.control.controller import DaemonController
from groundstation.daemon.daemon import Daemon
from groundstation.vehicle import controller_io as vio
from groundstation.vehicle.controller import VehicleState
from observer import ObserverConfig
from sitl.server import SitlServer

S = VehicleState


# ------------------------------------------------------------------ the target fix
@pytest.mark.parametrize("model", ["kalman", "linear"])
def test_an_operators_fix_far_from_the_estimate_reseats_the_track(model: str) -> None:
    """Issue 29: ``gcs target move`` 300 m from the estimate went through the measurement
    gate and was refused while the CLI said "moved". A ``TargetFixed`` is no measurement:
    the track is where the operator says, with the sigma given, and counts as seen."""
    inputs: list[dict[str, Any]] = []
    core = DecisionCore(CoreConfig(observer=ObserverConfig(model=model)))
    core.on_input = lambda e: inputs.append(event_to_record(e))
    core.handle(ev.TargetAdded(0.0, "B7", 100.0, 200.0, 0.3, -0.1, sigma0=4.0))
    core.handle(ev.Tick(10.0))
    gated = core.handle(ev.Detection(10.0, None, "B7", 400.0, 200.0))
    if model == "kalman":  # (the linear model has no gate)
        assert gated.verdicts[0].accepted is False  # what a "move" did before
    core.handle(ev.TargetFixed(12.0, "B7", 400.0, 200.0, 50.0))
    (track,) = core.view().tracks
    assert (track.x_m, track.y_m) == (400.0, 200.0)
    assert track.sigma == pytest.approx(50.0)
    assert track.last_seen_s == 12.0 and track.status == "confirmed"
    assert (track.vx_m_s, track.vy_m_s) == pytest.approx((0.3, -0.1))  # its drift is kept
    # the journal's input lines replay it exactly (docs/replay.md)
    again = DecisionCore(CoreConfig(observer=ObserverConfig(model=model)))
    for record in inputs:
        again.handle(record_to_event(record))
    assert again.view().tracks == core.view().tracks


def test_a_fix_of_an_unknown_target_is_a_note_not_a_crash() -> None:
    core = DecisionCore(CoreConfig())
    out = core.handle(ev.TargetFixed(1.0, "nope", 0.0, 0.0, 5.0))
    assert [c.kind for c in out if isinstance(c, Note)] == ["unknown_target"]


# ------------------------------------------------------------------ the vehicle's answers
def test_an_operators_release_reads_released_and_resume_takes_it_back() -> None:
    """Issue 29: a vehicle released through the API showed as ``overridden``."""
    rig = active_rig()
    ok, what = rig.c.operator_release(rig.t, "api")
    rig._collect(rig.c.take_outputs())
    assert ok and "released" in what
    assert rig.c.status == "released" and rig.c.state is S.OVERRIDDEN
    assert not rig.journal("override")
    (line,) = rig.journal("released")
    assert line.fields["by"] == "operator" and line.fields["reason"] == "api"
    assert len(rig.core(ev.OperatorOverride)) == 1
    rig.feed(vio.Release(rig.t, "operator override"))  # the core's answer: nothing new
    assert len(rig.journal("released")) == 1
    ok, what = rig.c.operator_release(rig.t, "api")
    assert not ok and "released, not active" in what
    ok, what = rig.c.operator_resume(rig.t, "api")
    rig._collect(rig.c.take_outputs())
    assert ok and "resumed" in what and rig.c.status == "active"
    ok, what = rig.c.operator_resume(rig.t, "api")
    assert not ok and "already active" in what


def test_a_resume_before_the_flight_evidence_settles_is_deferred_not_refused() -> None:
    """Issue 29: a red ``resume_refused ... not flying`` came 1.3 s before a good resume:
    the flight evidence was only unsettled (one slow frame), not a vehicle on the ground."""
    rig = active_rig()
    rig.run(5.0, mode=ArduPlaneMode.FBWA, mode_name="FBWA")
    assert rig.c.state is S.OVERRIDDEN
    rig.frame("GLOBAL_POSITION_INT", speed_m_s=3.0)  # high, slow for a frame: no verdict
    assert not rig.c.watch.flying.confirmed and not rig.c.watch.grounded.confirmed
    assert rig.c.resume(rig.t, "api") is False
    rig._collect(rig.c.take_outputs())
    assert not rig.journal("resume_refused") and rig.journal("resume_deferred")
    rig.run(6.0, speed_m_s=22.0, mode=ArduPlaneMode.AUTO, mode_name="AUTO")
    assert rig.c.state is S.ACTIVE and not rig.journal("resume_refused")


def test_an_operators_rtl_sends_it_home_but_never_takes_a_pilots_vehicle() -> None:
    rig = active_rig()
    ok, what = rig.c.operator_rtl(rig.t, "api rtl")
    rig._collect(rig.c.take_outputs())
    assert ok and "sent home" in what and rig.c.state is S.HOME
    rig.run(2.0)
    assert [r.mode for r in rig.requests(vio.SetMode)][-1] == ArduPlaneMode.RTL
    assert len(rig.core(ev.OperatorOverride)) == 1
    ok, what = rig.c.operator_resume(rig.t, "api")
    assert ok and rig.c.state is S.ACTIVE
    pilot = active_rig()
    pilot.run(5.0, mode=ArduPlaneMode.FBWA, mode_name="FBWA")
    asked = list(pilot.asked)
    ok, what = pilot.c.operator_rtl(pilot.t, "api rtl")
    pilot.run(2.0)
    assert not ok and "pilot" in what and pilot.asked == asked  # nothing sent


def test_a_pilot_who_takes_a_released_vehicle_keeps_it_from_an_operators_rtl() -> None:
    """Released through floe, then switched by its pilot to FBWA: the pilot's mode change
    is final, so an operator's RTL is refused and nothing is sent, as for any vehicle a
    pilot took."""
    rig = active_rig()
    ok, _ = rig.c.operator_release(rig.t, "api")
    rig._collect(rig.c.take_outputs())
    assert ok and rig.c.status == "released"
    rig.run(5.0, mode=ArduPlaneMode.FBWA, mode_name="FBWA")
    assert rig.c.status == "overridden", rig.c.status
    asked = list(rig.asked)
    ok, what = rig.c.operator_rtl(rig.t, "api rtl")
    rig.run(2.0)
    assert not ok and "pilot" in what and rig.asked == asked  # nothing sent


# ------------------------------------------------------------------ end to end
class Operator:
    """Acts through the API's controller at set mission times and keeps the answers."""

    def __init__(self) -> None:
        self.replies: dict[str, dict[str, Any]] = {}
        self.states: dict[str, dict[str, Any]] = {}
        self.tasks: list[asyncio.Future[dict[str, Any]]] = []
        self.fix: tuple[str, float, float] | None = None
        self.step_t: float | None = None

    def act(self, name: str, coro: Any, t_s: float) -> None:
        reply: dict[str, Any] = {}
        self.replies[name] = reply
        task = asyncio.ensure_future(coro)
        task.add_done_callback(lambda done: reply.update(done.result()))
        self.tasks.append(task)
        self.step_t = t_s

    def __call__(self, daemon: Daemon, server: SitlServer, t_s: float) -> None:
        control = DaemonController(daemon)
        done = [k for k, v in self.replies.items() if v and k not in self.states]
        for name in done:  # the state right after the action
            self.states[name] = control.state()
        if self.step_t is not None and t_s < self.step_t + 8.0:
            return
        if "resume" in self.states:  # all four answered, and 8 s of the resumed fleet
            daemon.request_stop("test: the operator's actions were answered")
            return
        state = control.state()
        if "fix" not in self.replies:
            flying = [v for v in state["vehicles"] if v["status"] == "active" and v["route"]]
            if len(flying) < 3 or not state["targets"]:
                return
            target = state["targets"][0]
            self.fix = (target["id"], target["x_m"] + 300.0, target["y_m"] - 200.0)
            self.act("fix", control.move_target(self.fix[0], x_m=self.fix[1],
                                                y_m=self.fix[2], sigma0=60.0), t_s)
        elif "release" not in self.replies:
            self.act("release", control.fleet_action("release"), t_s)
        elif "rtl" not in self.replies:
            self.act("rtl", control.fleet_action("rtl"), t_s)
        elif "resume" not in self.replies:
            self.act("resume", control.fleet_action("resume"), t_s)


@pytest.mark.timeout(150)
def test_fleet_actions_and_the_fix_answer_per_vehicle_and_replay(tmp_path: Path) -> None:
    """The run stops 8 mission s after the last action's answer (``--duration`` bounds
    it)."""
    op = Operator()
    daemon, _, journal = run_watching(
        tmp_path, ["--vehicles", "sim:3", "--scenario", "default", "--speedup", "25",
                   "--duration", "150"], op)  # fmt: skip
    assert not events(journal, "task_error")
    assert set(op.replies) == {"fix", "release", "rtl", "resume"}, op.replies
    # the fix: the track is where the operator put it, said in the answer
    assert op.fix is not None
    fix = op.replies["fix"]
    assert fix["ok"] and (fix["x_m"], fix["y_m"]) == pytest.approx(op.fix[1:])
    assert fix["sigma"] == pytest.approx(60.0)
    (line,) = events(journal, "target_fixed")
    assert line["target"] == op.fix[0] and line["sigma0"] == 60.0
    assert [e for e in journal if e.get("kind") == "TargetFixed"]
    # release all: every vehicle answers; none shows floe's route any more
    release = op.replies["release"]
    assert release["ok"] and release["done"] == 3 and release["refused"] == 0
    assert all("released" in r["what"] for r in release["results"])
    for v in op.states["release"]["vehicles"]:
        assert v["status"] == "released" and v["target"] is None and v["route"] == []
    assert len(events(journal, "released", by="operator")) == 3
    assert not events(journal, "override")
    # RTL all of released vehicles: the operator's own release, so sent home
    rtl = op.replies["rtl"]
    assert rtl["done"] == 3 and all(r["status"] == "home" for r in rtl["results"])
    # resume all: the same answer as one vehicle's resume, each
    resume = op.replies["resume"]
    assert resume["done"] == 3, resume
    assert all("resumed" in r["what"] for r in resume["results"])
    assert not events(journal, "resume_refused")
    # the run, the operator's fix included, replays to the same decisions
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(["replay", str(daemon.run_dir), "--no-resolve"])
    assert code == 0, out.getvalue()[-3000:]
