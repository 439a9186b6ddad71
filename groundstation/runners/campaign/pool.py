"""The local executor of ``gcs campaign``: a process pool on this machine.

Workers are reused: each is forked from a *forkserver* that has already imported the
simulator (``set_forkserver_preload``), then :func:`.run.init_worker` sets one
BLAS/OpenMP thread and ignores SIGINT, so no run pays for imports and a rebuilt pool starts
at once. Forkserver rather than fork: the driver holds pyarrow's threads, and forking a
threaded process can deadlock the child.

At most ``2 x workers`` runs are in flight, so results stream back as runs finish (the
driver stores each one at once) and an interruption loses only those.

A worker that dies mid-run (killed, out of memory) breaks a ``ProcessPoolExecutor``: every
run in flight fails with ``BrokenProcessPool`` and nothing tells which one killed it. The
pool is rebuilt and those runs are retried one at a time (*solo*): an innocent run then
finishes, and a run that breaks the pool while alone is the culprit. A culprit is retried
solo up to ``max_solo_failures`` times in all, then reported as failed and skipped. An
exception raised by a run is not retried (the simulation is deterministic: it would raise
again); it is reported and the campaign goes on.
"""

from __future__ import annotations

import multiprocessing
import os
from collections import deque
from collections.abc import Iterable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Protocol

from groundstation.runners.campaign.grid import RunTask
from groundstation.runners.campaign.run import THREAD_ENV, RunOutcome, execute_run, init_worker

__all__ = ["LocalPool", "RunSink"]

PRELOAD = ["groundstation.runners.campaign.run"]
"""Imported once by the forkserver; every worker is forked with them loaded."""


class RunSink(Protocol):
    """Where an executor reports each run as it ends (called in the driver's thread)."""

    def done(self, outcome: RunOutcome) -> None: ...

    def failed(self, task: RunTask, reason: str) -> None: ...


class LocalPool:
    """Runs tasks on ``workers`` local processes (module docstring)."""

    def __init__(self, workers: int, *, max_solo_failures: int = 2) -> None:
        if workers < 1:
            raise ValueError("workers must be >= 1")
        self.workers = workers
        self.max_solo_failures = max_solo_failures
        self.rebuilds = 0
        self._pool: ProcessPoolExecutor | None = None

    def describe(self) -> str:
        return f"local pool, {self.workers} worker{'s' if self.workers != 1 else ''}"

    def __enter__(self) -> LocalPool:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._kill()

    def _new_pool(self) -> ProcessPoolExecutor:
        for key, value in THREAD_ENV.items():  # inherited by the forkserver, then workers
            os.environ.setdefault(key, value)
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(PRELOAD)
        environ = {k: v for k, v in os.environ.items() if k.startswith("FLOE_CAMPAIGN_")}
        return ProcessPoolExecutor(
            max_workers=self.workers, mp_context=context, initializer=init_worker,
            initargs=(environ, os.getpid()),
        )

    def run(self, tasks: Iterable[RunTask], sink: RunSink) -> None:
        """Run every task, reporting each to ``sink``; KeyboardInterrupt stops the workers
        at once (runs in flight are lost) and propagates."""
        source = iter(tasks)
        solo: deque[RunTask] = deque()
        solo_failures: dict[str, int] = {}
        in_flight: dict[Future[RunOutcome], RunTask] = {}
        solo_running = False
        window = 2 * self.workers
        self._pool = self._new_pool()
        try:
            while True:
                lost: list[RunTask] = []
                try:
                    if solo:
                        if not in_flight:
                            task = solo.popleft()
                            in_flight[self._pool.submit(execute_run, task)] = task
                            solo_running = True
                    else:
                        solo_running = False
                        while len(in_flight) < window:
                            next_task = next(source, None)
                            if next_task is None:
                                break
                            in_flight[self._pool.submit(execute_run, next_task)] = next_task
                except BrokenProcessPool:
                    lost = list(in_flight.values())
                if not lost:
                    if not in_flight:
                        return
                    finished, _ = wait(list(in_flight), return_when=FIRST_COMPLETED)
                    for future in finished:
                        task = in_flight.pop(future)
                        try:
                            outcome = future.result()
                        except BrokenProcessPool:
                            lost.append(task)
                        except Exception as exc:  # a run's own error: reported, not retried
                            sink.failed(task, f"{type(exc).__name__}: {exc}")
                        else:
                            sink.done(outcome)
                if lost:
                    lost.extend(t for t in in_flight.values() if t not in lost)
                    in_flight.clear()
                    self._rebuild()
                    if solo_running and len(lost) == 1:
                        culprit = lost[0]
                        solo_failures[culprit.run_id] = solo_failures.get(culprit.run_id, 0) + 1
                        if solo_failures[culprit.run_id] >= self.max_solo_failures:
                            sink.failed(culprit, "its worker process died "
                                        f"{solo_failures[culprit.run_id] + 1} times")
                            continue
                    solo.extend(lost)
        except BaseException:
            self._kill()
            raise
        finally:
            self._close()

    def _rebuild(self) -> None:
        self.rebuilds += 1
        self._kill()
        self._pool = self._new_pool()

    def _kill(self) -> None:
        """Stop the pool now: cancel what is queued, terminate the workers (ours)."""
        pool = self._pool
        if pool is None:
            return
        processes = list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            if process.is_alive():
                process.terminate()
        for process in processes:
            process.join(timeout=5)
        self._pool = None

    def _close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None
