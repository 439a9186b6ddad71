"""Supervision by error class: expected faults restart within a limit, bugs stop the daemon."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import pytest
from daemon_run import events, run_gcs

from domain.errors import (
    ConfigError,
    DataError,
    FloeError,
    LinkError,
    LocalProtocolError,
    PlanningError,
    UsageError,
)
from groundstation.core import events as ev
from groundstation.core.decision import DecisionCore
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.session import VehicleSession
from groundstation.daemon.supervision import RestartPolicy, Supervisor


class FakeTime:
    def __init__(self) -> None:
        self.t_s = 0.0

    def __call__(self) -> float:
        return self.t_s


def make(policy: RestartPolicy | None = None) -> tuple[Supervisor, list[Any], list[Any], FakeTime]:
    lines: list[Any] = []
    bugs: list[Any] = []
    now = FakeTime()
    sup = Supervisor(
        now,
        lambda event, **fields: lines.append((event, fields)),
        lambda task, exc: bugs.append((task, exc)),
        policy or RestartPolicy(max_restarts=3, window_s=60.0, pause_step_s=0.0),
    )
    return sup, lines, bugs, now


def test_every_error_floe_raises_has_one_root() -> None:
    from domain.fault_spec import FaultError
    from domain.yaml_fields import FieldError
    from groundstation.core.records import RecordError
    from groundstation.daemon.control.bodies import RequestError
    from groundstation.daemon.startup import StartError
    from groundstation.link.detection_feed import FeedError
    from groundstation.link.url import LinkUrlError
    from groundstation.runners.replay.journal import JournalError
    from groundstation.runners.replay.tlog import TlogError
    from groundstation.runners.report.data import ReportError
    from planner.problem import ProblemError
    from world.scenario import ScenarioError

    expected = {
        RequestError: UsageError, StartError: UsageError,
        LinkUrlError: ConfigError, FaultError: ConfigError,
        ScenarioError: ConfigError, FieldError: ConfigError,
        RecordError: DataError, FeedError: DataError, JournalError: DataError,
        TlogError: DataError, ReportError: DataError,
        ProblemError: PlanningError,
    }  # fmt: skip
    for cls, parent in expected.items():
        assert issubclass(cls, parent), cls
        assert issubclass(cls, FloeError), cls
    # the root's classes are declared once: the link package re-exports its LinkError
    import groundstation.link

    assert groundstation.link.LinkError is LinkError
    # user mistakes stay ValueErrors, so input validation can catch either
    assert issubclass(ConfigError, ValueError) and issubclass(DataError, ValueError)


def test_expected_errors_restart_then_give_up_past_the_limit() -> None:
    sup, lines, bugs, now = make()
    calls: list[int] = []
    gave_up: list[bool] = []

    async def flaky() -> None:
        calls.append(1)
        now.t_s += 1.0
        raise LinkError("serial port vanished")

    asyncio.run(sup.supervise("vehicle 1", flaky, lambda: gave_up.append(True)))
    assert len(calls) == 4  # the first run and three restarts
    assert [e for e, _ in lines] == ["task_error"] * 3 + ["task_gave_up"]
    assert all(f["expected"] for e, f in lines if e == "task_error")
    assert gave_up == [True] and not bugs and sup.given_up == ["vehicle 1"]


def test_restarts_spread_beyond_the_window_never_give_up() -> None:
    sup, lines, bugs, now = make()
    runs = 0

    async def sometimes() -> None:
        nonlocal runs
        runs += 1
        now.t_s += 100.0  # one failure per 100 mission s: never 4 within 60 s
        if runs < 8:
            raise OSError("connection reset")

    asyncio.run(sup.supervise("link", sometimes))
    assert runs == 8
    assert not [e for e, _ in lines if e == "task_gave_up"] and not bugs


@pytest.mark.parametrize(
    "bug", [ZeroDivisionError("division by zero"), LocalProtocolError("receive() after end"),
            KeyError("x"), AssertionError("invariant")],
)
def test_a_bug_is_not_restarted_and_stops_the_daemon(bug: Exception) -> None:
    sup, lines, bugs, _ = make()
    calls = 0

    async def buggy() -> None:
        nonlocal calls
        calls += 1
        raise bug

    asyncio.run(sup.supervise("ticker", buggy))
    assert calls == 1
    assert bugs == [("ticker", bug)]
    assert lines[0][0] == "task_error" and lines[0][1]["bug"] is True
    assert any(type(bug).__name__ in line for line in lines[0][1]["traceback"])


def test_cancellation_is_not_an_error() -> None:
    sup, lines, bugs, _ = make()

    async def main() -> None:
        task = asyncio.create_task(sup.supervise("forever", lambda: asyncio.sleep(3600)))
        await asyncio.sleep(0.01)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task

    asyncio.run(main())
    assert not lines and not bugs


def _raise_from(cls: type, name: str, message: str, when: Any) -> Any:
    """``cls.name`` that raises ZeroDivisionError(message) once ``when(self, *args)``."""
    original = getattr(cls, name)

    def patched(self: Any, *args: Any) -> Any:
        if when(self, *args):
            raise ZeroDivisionError(message)
        return original(self, *args)

    return patched


BUGS = {  # where the bug is -> (class, method, when, the task_error's task)
    "ticker": (Daemon, "tick", lambda self, now: now >= 60.0, "ticker"),
    # the decision core and the vehicle controller run in callbacks, not tasks: their bugs
    # take the same path (Supervisor.bug), named after where they happened
    "core": (DecisionCore, "handle", lambda self, event: event.t_s >= 60.0
             and isinstance(event, ev.Tick), "core (Tick)"),
    "controller": (VehicleSession, "on_message", lambda self, msg: self.clock.now_s() >= 60.0
                   and self.system_id == 1, "vehicle 1 controller"),
}  # fmt: skip


@pytest.mark.timeout(90)
@pytest.mark.parametrize("where", list(BUGS))
def test_a_bug_in_the_daemon_stops_it_cleanly_and_the_vehicles_keep_their_missions(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, where: str
) -> None:
    cls, name, when, task = BUGS[where]
    monkeypatch.setattr(cls, name, _raise_from(cls, name, f"a bug in the {where}", when))
    daemon, journal = run_gcs(
        tmp_path, "--vehicles", "sim:2", "--scenario", "paper-boat", "--duration", "300",
        "--on-exit", "rtl",
    )  # fmt: skip
    assert daemon.internal_error is not None and "ZeroDivisionError" in daemon.internal_error
    bug = events(journal, "task_error", task=task)
    assert len(bug) == 1 and bug[0]["bug"] is True, events(journal, "task_error")
    assert any("ZeroDivisionError" in line for line in bug[0]["traceback"])
    stop = events(journal, "stop")
    assert stop and stop[0]["reason"] == "internal error" and stop[0]["t"] < 120.0
    # a bug is no reason to send the vehicles home: no on-exit RTL, nothing more commanded
    assert not events(journal, "rtl")
    assert not [e for e in journal if e["event"] in ("fly", "upload", "release")
                and e["t"] > bug[0]["t"]]
    assert events(journal, "upload", ok=True, purpose="target")  # they had missions to keep
