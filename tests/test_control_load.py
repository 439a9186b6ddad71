"""The control surface under bursts of clients keeps the daemon's event loop free: the
mechanisms, not wall-clock luck (issue 28; the figures are benchmarks/control_load.py's).

* a loop turn runs at most ``TurnBudget.per_turn`` requests (counted in loop turns, with an
  event loop that numbers its turns);
* a burst of readers builds and serialises the state document once, not once per reader;
* a burst of live pages serialises the state once per push, not once per page;
* a burst of refusals is two log lines: the first, then one summary with the count;
* the loop-lag monitor sees a stall.

Servers and clients on 127.0.0.1, ephemeral ports, bounded time.
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from collections import Counter
from collections.abc import Awaitable, Callable
from typing import Any

import aiohttp
import pytest
from test_control_fake import FakeControl

from groundstation.daemon.control import server as server_module
from groundstation.daemon.control.guard import ControlLimits, RejectLog
from groundstation.daemon.control.pacing import STATE_MAX_AGE_S, TurnBudget
from groundstation.daemon.control.server import ControlServer
from groundstation.daemon.loop_monitor import LoopMonitor

BURST = 200


class TurnCountingLoop(asyncio.SelectorEventLoop):
    """An event loop that numbers its turns (``turn``: one per pass over the ready
    callbacks), so a test can say in which turn something ran."""

    turn = 0

    def _run_once(self) -> None:
        self.turn += 1
        super()._run_once()  # type: ignore[misc]


def run_counting(main: Callable[[], Awaitable[Any]]) -> Any:
    with asyncio.Runner(loop_factory=TurnCountingLoop) as runner:
        return runner.run(asyncio.wait_for(main(), 60.0))


class CountingControl(FakeControl):
    """The fake daemon, counting how often its state document is built."""

    def __init__(self) -> None:
        super().__init__()
        self.state_calls = 0

    def state(self) -> dict[str, Any]:
        self.state_calls += 1
        return super().state()


async def get_raw(port: int, path: str) -> int:
    """One request on its own connection; the answer's status (0: no answer)."""
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    try:
        writer.write(f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n"
                     .encode())
        data = await reader.read()
        return int(data.split(b" ", 2)[1]) if data.startswith(b"HTTP/1.1 ") else 0
    finally:
        writer.close()


# ------------------------------------------------------------------ the turn budget

def test_turn_budget_wakes_at_most_k_per_turn_in_arrival_order() -> None:
    ran: list[tuple[int, int]] = []

    async def main() -> None:
        loop = asyncio.get_running_loop()
        assert isinstance(loop, TurnCountingLoop)
        budget = TurnBudget(per_turn=4)

        async def worker(i: int) -> None:
            await budget.take()
            ran.append((loop.turn, i))

        tasks = [asyncio.create_task(worker(i)) for i in range(50)]
        await asyncio.sleep(0)  # all 50 queued
        tasks[7].cancel()  # its client went away: it costs no unit
        await asyncio.gather(*tasks, return_exceptions=True)
        assert budget.waiting == 0 and budget.max_waiting == 50 and budget.taken == 49

    run_counting(main)
    per_turn = Counter(turn for turn, _ in ran)
    assert len(ran) == 49 and max(per_turn.values()) == 4
    assert [i for _, i in ran] == [i for i in range(50) if i != 7]  # first come, first served
    with pytest.raises(ValueError):
        TurnBudget(per_turn=0)


def test_a_burst_of_requests_is_answered_a_few_per_loop_turn(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """200 clients at once: at most 8 answers built in any one loop turn (before: all the
    requests that arrived together were answered in the same turn)."""
    answered_in: list[int] = []
    real_json = server_module._json

    def spy(data: Any, status: int = 200, **headers: str) -> Any:
        answered_in.append(asyncio.get_running_loop().turn)  # type: ignore[attr-defined]
        return real_json(data, status, **headers)

    monkeypatch.setattr(server_module, "_json", spy)

    async def main() -> list[int]:
        control = FakeControl()
        server = ControlServer(control, "127.0.0.1", 0, "tok")
        await server.start()
        try:
            return await asyncio.gather(*(get_raw(server.port, "/api/session")
                                          for _ in range(BURST)))
        finally:
            control.close()
            await server.stop()

    statuses = run_counting(main)
    assert statuses == [200] * BURST and len(answered_in) == BURST
    assert max(Counter(answered_in).values()) <= 8


# ------------------------------------------------------------------ one state document

def test_a_burst_of_state_reads_builds_the_state_once() -> None:
    """200 concurrent GET /api/state: the state is built at most once per 0.1 s of the
    burst (before: once per request, 200 times)."""
    async def main() -> tuple[int, float, list[int], str]:
        control = CountingControl()
        server = ControlServer(control, "127.0.0.1", 0, "tok")
        await server.start()
        try:
            started_s = time.monotonic()
            statuses = await asyncio.gather(*(get_raw(server.port, "/api/state")
                                              for _ in range(BURST)))
            elapsed_s = time.monotonic() - started_s
            async with aiohttp.ClientSession() as http:  # a write makes it stale at once
                control.advance(1.0)
                async with http.post(f"{server.url}/api/targets", json={"x_m": 1, "y_m": 2},
                                     headers={"Authorization": "Bearer tok"}) as resp:
                    assert resp.status == 201
                    added = (await resp.json())["target"]
                async with http.get(f"{server.url}/api/state") as resp:
                    ids = [t["id"] for t in (await resp.json())["targets"]]
            return control.state_calls, elapsed_s, statuses, str(added in ids)
        finally:
            control.close()
            await server.stop()

    calls, elapsed_s, statuses, read_own_write = asyncio.run(asyncio.wait_for(main(), 60.0))
    assert statuses == [200] * BURST and read_own_write == "True"
    assert calls <= 3 + math.ceil(elapsed_s / STATE_MAX_AGE_S), (calls, elapsed_s)


def test_a_burst_of_pages_serialises_the_state_once_per_push() -> None:
    """16 pages connecting at once and 40 more refused: the state document is built once
    for all the pages' first states and once per push (before: once per page, too)."""
    pages = 16

    async def main() -> tuple[int, float, Counter[int]]:
        control = CountingControl()
        server = ControlServer(control, "127.0.0.1", 0, "tok", push_hz=2.0,
                               limits=ControlLimits(max_ws_clients=pages))
        await server.start()
        refused: Counter[int] = Counter()
        try:
            async with aiohttp.ClientSession(
                    connector=aiohttp.TCPConnector(limit=0)) as http:
                started_s = time.monotonic()

                async def page() -> None:
                    try:
                        async with http.ws_connect(f"{server.url}/ws") as ws:
                            kinds = []
                            while len(kinds) < 4:  # hello, state, events, then a push
                                kinds.append((await ws.receive_json())["type"])
                            assert kinds[:3] == ["hello", "state", "events"]
                            assert kinds[3] == "state"
                    except aiohttp.WSServerHandshakeError as exc:
                        refused[exc.status] += 1

                await asyncio.gather(*(page() for _ in range(pages + 40)))
                elapsed_s = time.monotonic() - started_s
            return control.state_calls, elapsed_s, refused
        finally:
            control.close()
            await server.stop()

    calls, elapsed_s, refused = asyncio.run(asyncio.wait_for(main(), 60.0))
    assert refused == Counter({503: 40})
    # the buffer seeded at start, one build for the first states per 0.1 s of the burst,
    # one per push (2 Hz)
    assert calls <= 3 + math.ceil(elapsed_s / STATE_MAX_AGE_S) + math.ceil(elapsed_s * 2.0), (
        calls, elapsed_s)
    assert calls < pages


# ------------------------------------------------------------------ refusals, monitor

def test_a_refusal_burst_logs_its_first_line_and_one_summary(
        caplog: pytest.LogCaptureFixture) -> None:
    log = RejectLog(logging.getLogger("test.burst"), every_s=10.0)
    with caplog.at_level(logging.WARNING, logger="test.burst"):
        for i in range(BURST):
            log.note("ws_clients_full", "16 pages connected", i * 0.001)
        log.flush(5.0)  # the window is still open: nothing yet
        assert len(caplog.records) == 1
        log.flush(10.5)
        log.flush(30.0)  # nothing more to say
    lines = [r.getMessage() for r in caplog.records]
    assert lines == ["control API refused (ws_clients_full): 16 pages connected",
                     "control API refused (ws_clients_full): 199 more in the last 10 s"]
    assert log.counts == {"ws_clients_full": BURST}


def test_loop_monitor_sees_a_stall() -> None:
    monitor = LoopMonitor(interval_s=0.01)

    async def main() -> None:
        task = asyncio.create_task(monitor.run())
        await asyncio.sleep(0.05)
        time.sleep(0.15)  # a callback holding the loop: at least 140 ms late
        await asyncio.sleep(0.05)
        task.cancel()

    asyncio.run(main())
    assert monitor.max_ms >= 100.0 and monitor.over_threshold >= 1 and monitor.samples >= 2
    figures = monitor.to_dict()
    assert figures["loop_stall_max_ms"] == round(monitor.max_ms, 1)
    assert figures["loop_stalls_over_100ms"] == monitor.over_threshold
