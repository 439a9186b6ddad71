"""gcs campaign: executors give identical rows; kills, lost workers and Ctrl-C lose nothing
that was stored, and running again completes every run exactly once."""

from __future__ import annotations

import importlib.util
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from environment import need

from groundstation.runners.campaign.driver import open_campaign, run_campaign
from groundstation.runners.campaign.pool import LocalPool
from groundstation.runners.campaign.run import KILL_HOOK_ENV, execute_run
from groundstation.runners.campaign.schema import WALL_CLOCK_COLUMNS
from groundstation.runners.campaign.store import PLANS_DIR, RUNS_DIR, read_results

ROOT = Path(__file__).resolve().parents[1]
TINY = """\
name: tiny
grid:
  scenario: [paper-boat]
  uavs: [1, 3]
  seed: [0, 7]
set: {duration_s: 20}
per_plan: true
"""


def campaign_file(tmp_path: Path, text: str = TINY) -> Path:
    path = tmp_path / "c.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def comparable(rows: list[dict[str, Any]]) -> dict[tuple[Any, ...], dict[str, Any]]:
    """Rows by (run_id, plan_index) without the columns that measure the machine."""
    return {(r["run_id"], r.get("plan_index")): {k: v for k, v in r.items()
                                                 if k not in WALL_CLOCK_COLUMNS}
            for r in rows}


def _worker_profiles() -> bool:
    """In a Dask worker: whether its statistical profiler samples the running tasks."""
    import dask.config

    return bool(dask.config.get("distributed.worker.profile.enabled"))


def test_local_pool_dask_and_in_process_runs_give_identical_rows(tmp_path: Path) -> None:
    need(importlib.util.find_spec("distributed") is not None,
         "dask[distributed] is not installed (pip install '.[test,plot,campaign]')")
    from groundstation.runners.campaign.dask_executor import DaskExecutor

    path = campaign_file(tmp_path)
    serial = [execute_run(task) for task in open_campaign(path, tmp_path / "serial").spec.tasks()]
    results: dict[str, tuple[Any, Any]] = {}
    for name, executor in (("pool", LocalPool(2)), ("dask", DaskExecutor("local:2"))):
        plan = open_campaign(path, tmp_path / name)
        with executor as engine:
            outcome = run_campaign(plan, engine)
            if isinstance(engine, DaskExecutor):  # no dashboard: no profiler sampling runs
                assert set(engine._client.run(_worker_profiles).values()) == {False}
        assert outcome.finished == 4 and not outcome.failures
        results[name] = (read_results(tmp_path / name).to_pylist(),
                         read_results(tmp_path / name, PLANS_DIR).to_pylist())
    runs, plans = results["pool"]
    assert len(runs) == 4 and len(plans) == sum(r["plans"] for r in runs)
    assert comparable(runs) == comparable(results["dask"][0])
    assert comparable(plans) == comparable(results["dask"][1])
    assert comparable(runs) == comparable([o.run_row for o in serial])
    assert comparable(plans) == comparable([p for o in serial for p in o.plan_rows])
    workers = {r["worker"] for r in runs} | {r["worker"] for r in results["dask"][0]}
    assert str(os.getpid()) not in {w.rsplit("/", 1)[1] for w in workers}  # other processes
    table = pq.read_table(tmp_path / "dask" / RUNS_DIR)  # a bare read: compacted, once each
    assert table.num_rows == 4 and table.column("seed").type == "int64"
    series = table.column("series_mean_sigma").type
    assert pa.types.is_list(series) and series.value_type == pa.float64()


def test_a_worker_killed_mid_run_is_retried(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    plan = open_campaign(campaign_file(tmp_path), tmp_path / "out")
    victim = list(plan.spec.run_ids())[1]
    marker = tmp_path / "killed-once"
    monkeypatch.setenv(KILL_HOOK_ENV, f"{victim}:{marker}")
    pool = LocalPool(2)
    with pool:
        outcome = run_campaign(plan, pool)
    assert marker.exists()  # the worker running `victim` did die (SIGKILL)
    assert pool.rebuilds >= 1
    assert outcome.finished == 4 and not outcome.failures
    assert sorted(r["run_id"] for r in read_results(tmp_path / "out").to_pylist()) == sorted(
        plan.spec.run_ids())


def _start(path: Path, out: Path) -> subprocess.Popen[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen(
        [sys.executable, "-m", "groundstation.cli", "campaign", str(path), "--out", str(out),
         "--workers", "1"],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True,
    )


def _wait_for_parts(out: Path, count: int, process: subprocess.Popen[str]) -> None:
    deadline = time.monotonic() + 60
    folder = out / RUNS_DIR
    while time.monotonic() < deadline:
        if folder.is_dir() and len(list(folder.glob("run-*.parquet"))) >= count:
            return
        assert process.poll() is None, process.communicate()
        time.sleep(0.01)
    raise AssertionError("no runs stored within 60 s")


SLOWER_RUNS = 64
SLOWER = TINY.replace("seed: [0, 7]", "seed: {from: 0, to: 31}").replace(
    "duration_s: 20", "duration_s: 40")  # 64 runs of 40 mission s: several seconds of work,
# so a Ctrl-C after the first parts lands mid-campaign even on a fast idle machine


def test_interrupted_campaigns_resume_and_end_with_every_run_once(tmp_path: Path) -> None:
    """Ctrl-C (exit 130, a line saying how to resume), then SIGKILL of the driver, then a
    run to the end: every run stored exactly once, the stored ones never recomputed."""
    path = campaign_file(tmp_path, SLOWER)
    out = tmp_path / "out"
    first = _start(path, out)
    _wait_for_parts(out, 2, first)
    os.killpg(first.pid, signal.SIGINT)  # what a terminal's Ctrl-C does (workers ignore it)
    _, err = first.communicate(timeout=30)
    assert first.returncode == 130, err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith("gcs campaign: interrupted: ")
    assert f" of {SLOWER_RUNS} runs stored in " in last
    assert last.endswith(f"resume with: gcs campaign {path} --out {out} --workers 1")
    after_ctrl_c = len(read_results(out).to_pylist())
    assert int(last.split("interrupted: ")[1].split(" of ")[0]) == after_ctrl_c >= 2

    second = _start(path, out)
    _wait_for_parts(out, after_ctrl_c + 2, second)
    os.kill(second.pid, signal.SIGKILL)  # the driver only; its workers see it gone and exit
    second.communicate(timeout=30)  # returns once every holder of its stderr (workers, the
    # forkserver) has exited: nothing is left behind
    stored = pq.read_table(out / RUNS_DIR).num_rows  # a bare read works after a kill
    assert after_ctrl_c + 2 <= stored < SLOWER_RUNS

    third = _start(path, out)
    _, err = third.communicate(timeout=120)
    assert third.returncode == 0, err
    assert f"{SLOWER_RUNS - stored} runs computed, {stored} reused" in err
    table = pq.read_table(out / RUNS_DIR)
    ids = table.column("run_id").to_pylist()
    assert len(ids) == len(set(ids)) == SLOWER_RUNS
    assert [p.name[:6] for p in (out / RUNS_DIR).iterdir()] == ["chunk-"]  # compacted
    plans = pq.read_table(out / PLANS_DIR)
    assert plans.num_rows == sum(table.column("plans").to_pylist())


def test_a_merge_takes_its_own_parts_from_memory_and_keeps_the_newest_row(tmp_path: Path) -> None:
    """The driver merges the parts it wrote from the tables it kept, the others (a killed
    driver's part, an earlier chunk) from disk: the same rows as a merge that reads every
    part back, one per run, the newest."""
    import shutil

    from groundstation.runners.campaign.run import RunOutcome
    from groundstation.runners.campaign.store import CampaignStore

    schema = pa.schema([("run_id", pa.string()), ("per_plan", pa.bool_()),
                        ("value", pa.float64())])

    def outcome(run: int, value: float) -> RunOutcome:
        return RunOutcome(f"r{run}", {"run_id": f"r{run}", "per_plan": False, "value": value}, [])

    out = tmp_path / "out"
    earlier = CampaignStore(out, schema, None)
    earlier.prepare()
    for run in range(5):
        earlier.write(outcome(run, 1.0))
    earlier.compact(final=False)  # one chunk of r0..r4
    earlier.write(outcome(5, 1.0))  # a part left by a driver killed before its merge
    later = CampaignStore(out, schema, None)
    later.prepare()
    for run in range(3, 8):
        later.write(outcome(run, 2.0))
    from_disk = tmp_path / "copy"
    shutil.copytree(out, from_disk)
    later.compact(final=True)
    CampaignStore(from_disk, schema, None).compact(final=True)  # knows no part: reads all

    rows = {r["run_id"]: r["value"] for r in read_results(out).to_pylist()}
    assert rows == {"r0": 1.0, "r1": 1.0, "r2": 1.0, "r3": 2.0, "r4": 2.0, "r5": 2.0,
                    "r6": 2.0, "r7": 2.0}
    assert pq.read_table(out / RUNS_DIR).equals(pq.read_table(from_disk / RUNS_DIR))
    assert [p.name[:6] for p in (out / RUNS_DIR).iterdir()] == ["chunk-"]
    assert later._written == {}  # nothing kept once merged
