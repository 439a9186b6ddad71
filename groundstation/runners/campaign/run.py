"""One run of a campaign, in a worker process: a :class:`RunTask` in, its rows out.

:func:`execute_run` is the function every executor calls (the local process pool, a Dask
worker, or in-process for tests). It parses the task's scenario mapping, runs the offline
simulator (deterministic: one CP-SAT worker, no wall-clock limits) and turns the metrics
into one flat row (``runs.parquet``) and, when asked, one row per adopted plan
(``plans.parquet``). Columns are listed in :mod:`groundstation.runners.campaign.schema`.

:func:`init_worker` prepares a worker process once: one BLAS/OpenMP thread, SIGINT
ignored (the driver decides when to stop); the simulator's imports are this module's own, so
no run pays them.
"""

from __future__ import annotations

import functools
import os
import signal
import socket
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from domain.extras import DISTRIBUTION
from groundstation.runners.campaign.grid import RunTask
from groundstation.runners.campaign.schema import ARRIVAL_SUMMARIES, metrics_columns
from groundstation.runners.simulate.simulator import PlanRecord, SimulationOptions, run_simulation
from world.scenario import parse_scenario

__all__ = [
    "KILL_HOOK_ENV",
    "THREAD_ENV",
    "RunOutcome",
    "execute_run",
    "floe_version",
    "init_worker",
]

THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
"""Set in every worker before numpy loads: one run is single-threaded maths on small
matrices; a thread pool per worker would only compete with the other workers."""

KILL_HOOK_ENV = "FLOE_CAMPAIGN_TEST_KILL"
"""Test-only fault injection: ``RUN_ID:MARKER_PATH``. The worker that starts run RUN_ID
while MARKER_PATH does not exist creates it and kills itself with SIGKILL (a worker lost
mid-run, the first time only). ``tests/test_campaign_exec.py`` uses it to check that the
run is retried; nothing else sets it."""


@dataclass(frozen=True)
class RunOutcome:
    """The rows of one finished run."""

    run_id: str
    run_row: dict[str, Any]
    plan_rows: list[dict[str, Any]]


def init_worker(environ: Mapping[str, str] | None = None, driver_pid: int | None = None) -> None:
    """Prepare a local-pool worker process (module docstring); ``environ`` carries the
    driver's ``FLOE_CAMPAIGN_*`` variables into a worker forked from an older server, and
    the worker ends by itself once ``driver_pid`` is gone."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for key, value in THREAD_ENV.items():
        os.environ.setdefault(key, value)
    if environ is not None:
        os.environ.update(environ)
    if driver_pid is not None:
        _exit_with_driver(driver_pid)


def _process_alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, killed but not yet reaped, does not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as handle:
            state = handle.read().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return True  # no /proc: trust kill(pid, 0)
    return state not in ("Z", "X")


def _exit_with_driver(driver_pid: int, poll_s: float = 0.5) -> None:
    """End this worker when the driver is gone. A pool worker waits for work on a queue
    that a dead driver never closes (the worker holds its write end too), and while a
    worker lives the forkserver does too: a driver killed with SIGKILL would leave both
    behind, holding memory and the terminal's pipes."""

    def watch() -> None:
        while _process_alive(driver_pid):
            time.sleep(poll_s)
        os._exit(0)

    threading.Thread(target=watch, name="floe-driver-watch", daemon=True).start()


@functools.cache
def floe_version() -> str:
    """The installed floe's version, or ``unknown`` (a source tree without metadata)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(DISTRIBUTION)
    except PackageNotFoundError:
        return "unknown"


def execute_run(task: RunTask) -> RunOutcome:
    """Run one task and return its rows (module docstring)."""
    _maybe_kill_for_test(task.run_id)
    wall_start, cpu_start = time.perf_counter(), time.process_time()
    scenario = parse_scenario(task.scenario_data, source=task.scenario_source)
    result = run_simulation(scenario, SimulationOptions(
        seed=task.seed, uavs=task.uavs, snapshot_times_s=(0.0,),
    ))
    wall_s, cpu_s = time.perf_counter() - wall_start, time.process_time() - cpu_start
    metrics = result.metrics
    row: dict[str, Any] = {"run_id": task.run_id, **task.coords, "campaign": task.campaign}
    row.update(flatten_metrics(metrics))
    series = metrics["uncertainty_series"]
    row["series_t_s"] = [float(t) for t, _ in series]
    row["series_mean_sigma"] = [float(s) for _, s in series]
    row.update(floe_version=floe_version(), wall_s=wall_s, cpu_s=cpu_s,
               worker=f"{socket.gethostname()}/{os.getpid()}", per_plan=task.per_plan)
    plans = [_plan_row(task, index, record) for index, record in enumerate(result.plans)]
    return RunOutcome(task.run_id, row, plans if task.per_plan else [])


def flatten_metrics(metrics: Mapping[str, Any]) -> dict[str, Any]:
    """Every scalar of ``metrics.json`` as a column (schema.metrics_columns):
    lists become counts (``visits``, ``lost_targets``), ``hourly_mean_uncertainty`` its first
    and last hours (``first_hour_uncertainty``, ``last_hour_uncertainty``), ``solve_time_s`` becomes
    ``solve_time_median_s`` / ``solve_time_max_s``, ``max_estimation_error_m`` ({target:
    m}) its maximum over the targets, ``uploads`` ({vehicle: n}) their sum,
    ``uploads_per_hour`` its maximum over the vehicles (``uploads_per_hour_max``), other
    nested scalar mappings ``outer_inner``."""
    flat: dict[str, Any] = {}
    for key, value in metrics.items():
        if key == "solve_time_s":
            flat["solve_time_median_s"] = value["median"]
            flat["solve_time_max_s"] = value["max"]
        elif key == "max_estimation_error_m":
            flat[key] = max(value.values()) if value else None
        elif key == "uploads":  # {vehicle: n}: the fleet's total
            flat[key] = sum(value.values())
        elif key == "uploads_per_hour":  # {vehicle: per hour}: the busiest vehicle's
            flat["uploads_per_hour_max"] = max(value.values()) if value else None
        elif key in ("visits", "lost_targets"):
            flat[key] = len(value)
        elif key == "hourly_mean_uncertainty":
            flat["first_hour_uncertainty"] = value[0] if value else None
            flat["last_hour_uncertainty"] = value[-1] if value else None
        elif isinstance(value, Mapping):
            flat.update({f"{key}_{inner}": v for inner, v in value.items()})
        elif value is None and key in ARRIVAL_SUMMARIES:  # no arrival was counted
            flat.update({f"{key}_{inner}": None for inner in ARRIVAL_SUMMARIES[key]})
        elif not isinstance(value, list):
            flat[key] = value
    columns = metrics_columns()
    return {key: flat.get(key) for key in columns}


def _plan_row(task: RunTask, index: int, record: PlanRecord) -> dict[str, Any]:
    return {
        "run_id": task.run_id, **task.coords, "plan_index": index, "t_s": record.t_s,
        "mu": record.mu, "f1": record.f1, "f2": record.f2,
        "objective_value": record.objective_value, "objective": record.objective,
        "status": record.status, "solver": record.solver, "solve_time_s": record.solve_time_s,
        "bound": record.bound, "gap": record.gap, "targets": record.targets,
        "uavs_planned": record.uavs_planned,
    }


def _maybe_kill_for_test(run_id: str) -> None:
    hook = os.environ.get(KILL_HOOK_ENV)
    if not hook:
        return
    target, _, marker = hook.partition(":")
    if target != run_id or not marker:
        return
    try:
        fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        return
    os.close(fd)
    os.kill(os.getpid(), signal.SIGKILL)
