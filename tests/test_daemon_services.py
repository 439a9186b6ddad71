"""The daemon runs the services it is given: built with fake services on an event loop whose
clock is virtual (:class:`tests.test_vehicle_port.VirtualTimeLoop`: a wait advances time
instead of sleeping), with the mission clock on that loop's time. So the stop at
``--duration`` and a bug at mission time t are exact, and no wall time passes."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import pytest
from test_vehicle_port import run

from groundstation.core.config import CoreConfig
from groundstation.daemon.clock import MissionClock
from groundstation.daemon.config_parse import parse_config
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.journal import Journal, read_journal


class FakeService:
    """Waits ``every_s`` mission s at a time (``ticks`` counts), raises ``bug`` at
    ``bug_at_s``; records when it started and ended (cancelled or returned)."""

    def __init__(self, name: str, clock: MissionClock, every_s: float = 1.0,
                 bug_at_s: float | None = None, returns_at_s: float | None = None) -> None:
        self.name = name
        self.clock = clock
        self.every_s = every_s
        self.bug_at_s = bug_at_s
        self.returns_at_s = returns_at_s
        self.started_s: float | None = None
        self.ended_s: float | None = None
        self.cancelled = False
        self.ticks = 0

    async def run(self) -> None:
        self.started_s = self.clock.now_s()
        try:
            while True:
                now = self.clock.now_s() + 1e-6  # the sum of the waits, give or take
                if self.bug_at_s is not None and now >= self.bug_at_s:
                    raise ZeroDivisionError(f"a bug in {self.name}")
                if self.returns_at_s is not None and now >= self.returns_at_s:
                    return
                self.ticks += 1
                await asyncio.sleep(self.every_s)
        except asyncio.CancelledError:
            self.cancelled = True
            raise
        finally:
            self.ended_s = self.clock.now_s()


def _daemon(tmp_path: Path, duration_s: float) -> Daemon:
    """A daemon with no link, its mission clock on the running (virtual) loop's time."""
    clock = MissionClock(1.0, source=lambda: asyncio.get_running_loop().time())
    config = parse_config({"vehicles": ["udpin:127.0.0.1:0"], "duration": duration_s}, {})
    journal = Journal(tmp_path / "journal.jsonl", clock.now_s, clock.unix_s)
    return Daemon(config, CoreConfig(), clock, tmp_path, None, journal, None)


def _run(tmp_path: Path, duration_s: float, *specs: dict[str, Any]
         ) -> tuple[Daemon, list[FakeService], list[dict[str, Any]]]:
    async def main() -> tuple[Daemon, list[FakeService]]:
        daemon = _daemon(tmp_path, duration_s)
        services = [FakeService(clock=daemon.clock, **spec) for spec in specs]
        await daemon.run(services)
        daemon.journal_file.close()
        return daemon, services

    daemon, services = run(main())
    return daemon, services, read_journal(tmp_path / "journal.jsonl")


def test_services_start_and_stop_ends_every_one_of_them(tmp_path: Path) -> None:
    daemon, services, journal = _run(tmp_path, 30.0, {"name": "a"},
                                     {"name": "b", "every_s": 7.0})
    for service in services:
        assert service.started_s == 0.0, service.name
        assert service.cancelled and service.ended_s is not None
        assert 30.0 <= service.ended_s < 30.5, service.ended_s  # ended by the stop
    assert 30 <= services[0].ticks <= 31 and services[1].ticks == 5
    stop = [e for e in journal if e["event"] == "stop"]
    assert len(stop) == 1 and stop[0]["reason"] == "duration"
    assert daemon.internal_error is None
    assert not [e for e in journal if e["event"] == "task_error"]


def test_a_service_that_returns_is_done_and_the_daemon_runs_on(tmp_path: Path) -> None:
    daemon, services, _ = _run(tmp_path, 20.0, {"name": "once", "returns_at_s": 3.0},
                               {"name": "steady"})
    once, steady = services
    assert once.ended_s == pytest.approx(3.0) and not once.cancelled
    assert steady.cancelled and steady.ended_s is not None and steady.ended_s >= 20.0
    assert daemon.stop_reason == "duration"


def test_a_bug_in_a_service_stops_the_daemon_cleanly_with_a_journal_line(
    tmp_path: Path,
) -> None:
    daemon, services, journal = _run(tmp_path, 300.0, {"name": "buggy", "bug_at_s": 12.0},
                                     {"name": "bystander"})
    buggy, bystander = services
    assert buggy.ended_s == pytest.approx(12.0) and not buggy.cancelled
    bug = [e for e in journal if e["event"] == "task_error"]
    assert len(bug) == 1 and bug[0]["task"] == "buggy" and bug[0]["bug"] is True
    assert any("ZeroDivisionError" in line for line in bug[0]["traceback"])
    assert daemon.internal_error is not None and "buggy" in daemon.internal_error
    stop = [e for e in journal if e["event"] == "stop"]
    assert len(stop) == 1 and stop[0]["reason"] == "internal error"
    assert 11.99 <= stop[0]["t"] < 12.5  # at once, not at --duration
    assert bystander.cancelled and bystander.ended_s is not None and bystander.ended_s < 12.5
