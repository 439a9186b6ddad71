"""The Dask executor of ``gcs campaign --dask ADDRESS`` (``dask[distributed]``, the
``campaign`` extra; imported only when ``--dask`` is given).

* ``--dask local:N``: a ``LocalCluster`` that floe starts and closes: N worker processes
  with one thread each, listening on 127.0.0.1 only, no dashboard, and so no statistical
  profiler in the workers (``distributed.worker.profile.enabled``).
* ``--dask tcp://HOST:PORT`` (or any address ``distributed.Client`` takes): an existing
  scheduler, e.g. one that dask-jobqueue runs on Slurm or dask-kubernetes on Kubernetes
  (docs/campaigns.md). Its workers must import floe: the same environment as the driver.

Each run is one task, ``run.execute_run(task)``, keyed ``floe-run-<run_id>``;
results come back to the driver, which alone writes the results folder. At most
``4 x threads`` runs (at least 8) are submitted at a time, so a million-run grid does not
flood the scheduler. A worker lost mid-run is handled by the scheduler: its tasks are
rescheduled on other workers, up to ``distributed.scheduler.allowed-failures`` (default
3) times, then the run fails with ``KilledWorker`` and is reported and skipped. A run that
raises is retried once (``retries=1``: a remote worker may hit a passing fault).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from typing import Any

from domain.errors import FloeError
from domain.extras import extra_hint
from groundstation.runners.campaign.grid import RunTask
from groundstation.runners.campaign.pool import RunSink
from groundstation.runners.campaign.run import execute_run

__all__ = ["DaskError", "DaskExecutor", "parse_local"]

CONNECT_TIMEOUT_S = 10.0


class DaskError(FloeError):
    """Dask is missing, or the scheduler cannot be reached (one line)."""


def parse_local(address: str) -> int | None:
    """N of ``local:N``; None for any other address; ValueError for a bad N."""
    if not address.startswith("local:"):
        return None
    text = address[len("local:"):]
    if not text.isdigit() or int(text) < 1:
        raise ValueError(f"--dask local:N needs N >= 1, got {address!r}")
    return int(text)


class DaskExecutor:
    """Runs tasks on a Dask cluster (module docstring); use as a context manager."""

    def __init__(self, address: str) -> None:
        self.address = address
        self.local_workers = parse_local(address)
        self._client: Any = None
        self._cluster: Any = None

    def describe(self) -> str:
        if self.local_workers is not None:
            n = self.local_workers
            return f"Dask LocalCluster, {n} worker{'s' if n != 1 else ''}"
        return f"Dask scheduler {self.address}"

    def __enter__(self) -> DaskExecutor:
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise DaskError(f"--dask needs dask[distributed]: {extra_hint('campaign')}") \
                from None
        try:
            if self.local_workers is not None:
                import dask.config

                # no dashboard, so nobody reads the workers' statistical profiler: off (it
                # samples every thread's stack every 10 ms, ~0.07 of a run's 0.6 CPU-s)
                with dask.config.set({"distributed.worker.profile.enabled": False}):
                    self._cluster = LocalCluster(
                        n_workers=self.local_workers, threads_per_worker=1, processes=True,
                        host="127.0.0.1", dashboard_address=None, silence_logs=logging.ERROR,
                    )
                self._client = Client(self._cluster, timeout=CONNECT_TIMEOUT_S)
            else:
                self._client = Client(self.address, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as exc:
            self.close()
            text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise DaskError(f"cannot reach the Dask scheduler at {self.address}: {text}") \
                from None
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def threads(self) -> int:
        """Worker threads the cluster has now (at least 1)."""
        info = self._client.scheduler_info()
        return max(1, sum(w.get("nthreads", 1) for w in info.get("workers", {}).values()))

    def run(self, tasks: Iterable[RunTask], sink: RunSink) -> None:
        """Run every task, reporting each to ``sink``; on KeyboardInterrupt cancel what is
        submitted and propagate."""
        from distributed import as_completed

        client = self._client
        window = max(8, 4 * self.threads())
        source = iter(tasks)
        submitted: dict[str, RunTask] = {}

        def submit() -> Any:
            task = next(source, None)
            if task is None:
                return None
            key = f"floe-run-{task.run_id}"
            submitted[key] = task
            return client.submit(execute_run, task, key=key, pure=False, retries=1)

        first = [f for f in (submit() for _ in range(window)) if f is not None]
        pending = as_completed(first)
        try:
            for future in pending:
                task = submitted.pop(future.key)
                try:
                    outcome = future.result()
                except Exception as exc:  # the run's error, KilledWorker, a cancellation
                    sink.failed(task, f"{type(exc).__name__}: {exc}")
                else:
                    sink.done(outcome)
                future.release()
                replacement = submit()
                if replacement is not None:
                    pending.add(replacement)
        except BaseException:
            client.cancel(list(pending.futures))
            raise

    def close(self) -> None:
        if self._client is not None:
            try:
                self._client.close()
            finally:
                self._client = None
        if self._cluster is not None:
            try:
                self._cluster.close()
            finally:
                self._cluster = None
