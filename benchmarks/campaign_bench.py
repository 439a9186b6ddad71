"""Throughput of ``gcs campaign``: the local pool, Dask, and the old paper_study way.

    nice -n 10 python benchmarks/campaign_bench.py [--runs 1000] [--rounds 1]
        [--configs old,pool,dask2,dask1] [--json benchmarks/campaign_bench.json]

Every configuration computes the same runs: paper-boat, 3 UAVs, sequence objective, tau
0.5, seeds 0..RUNS-1, 200 mission s, each as its real command in a fresh process, into a
fresh folder:

* ``old``: ``benchmarks/paper_study.py --uavs 3 --variants sequence:0.5 --seeds RUNS``
  (a process pool of 2, every row kept in memory until the end);
* ``pool``: ``gcs campaign FILE --out DIR`` (the default executor, os.cpu_count() workers);
* ``dask2`` / ``dask1``: ``gcs campaign FILE --out DIR --dask local:2`` / ``local:1``.

Configurations alternate within each round (the order rotates from round to round) so a
shared machine's load weighs on all of them alike; the load average is recorded before
each. Figures per configuration: wall time, runs per second, CPU (user + system of the
command and every process it waited for; for the campaign configurations at least the sum
of the runs' own CPU, as forkserver workers are not reaped by the command), the cores
that CPU occupied on average (CPU / wall: 2 is the whole machine; less means the runs
waited, for other users' processes or for the executor), and for the campaign
configurations the mean
per-run wall and CPU time measured inside the workers (``runs.parquet``), from which the
per-task overhead is ``wall x workers / runs - mean run wall``: what a run costs beyond
its own simulation (scheduling, transport, storing, idle workers at start and end).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = {
    "old": "paper_study.py, process pool of 2",
    "pool": "gcs campaign, local pool (default)",
    "dask2": "gcs campaign --dask local:2",
    "dask1": "gcs campaign --dask local:1",
}
WORKERS = {"old": 2, "pool": os.cpu_count() or 1, "dask2": 2, "dask1": 1}


def _campaign_file(folder: Path, runs: int) -> Path:
    path = folder / "bench.yaml"
    path.write_text(
        "name: bench\n"
        "grid:\n"
        "  scenario: [paper-boat]\n"
        "  uavs: [3]\n"
        "  objective: [sequence]\n"
        "  tau: [0.5]\n"
        f"  seed: {{from: 0, to: {runs - 1}}}\n",
        encoding="utf-8",
    )
    return path


def _command(config: str, campaign: Path, out: Path, runs: int) -> list[str]:
    if config == "old":
        return [sys.executable, str(ROOT / "benchmarks" / "paper_study.py"), "--uavs", "3",
                "--variants", "sequence:0.5", "--seeds", str(runs), "--jobs", "2"]
    command = [sys.executable, "-m", "groundstation.cli", "campaign", str(campaign),
               "--out", str(out), "--quiet"]
    if config.startswith("dask"):
        command += ["--dask", f"local:{config[len('dask'):]}"]
    return command


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _measure(config: str, campaign: Path, scratch: Path, runs: int) -> dict[str, Any]:
    out = scratch / f"out-{config}"
    shutil.rmtree(out, ignore_errors=True)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    load_before = os.getloadavg()[0]
    cpu_start, wall_start = _children_cpu_s(), time.perf_counter()
    done = subprocess.run(_command(config, campaign, out, runs), env=env, cwd=ROOT / "benchmarks",
                          capture_output=True, text=True, check=False)
    wall_s = time.perf_counter() - wall_start
    cpu_s = _children_cpu_s() - cpu_start
    if done.returncode != 0:
        raise SystemExit(f"{config} failed ({done.returncode}): {done.stderr[-2000:]}")
    figures: dict[str, Any] = {
        "wall_s": wall_s, "runs_per_s": runs / wall_s, "cpu_s": cpu_s,
        "load_average_before": load_before, "workers": WORKERS[config],
    }
    if config != "old":
        import pyarrow.parquet as pq

        table = pq.read_table(out / "runs.parquet", columns=["run_id", "wall_s", "cpu_s"])
        assert table.num_rows == runs, (config, table.num_rows)
        run_wall = statistics.fmean(table.column("wall_s").to_pylist())
        figures["run_wall_s_mean"] = run_wall
        figures["run_cpu_s_mean"] = statistics.fmean(table.column("cpu_s").to_pylist())
        figures["overhead_per_task_s"] = wall_s * WORKERS[config] / runs - run_wall
        # forkserver workers are not reaped by the command: count the runs' own CPU
        figures["cpu_s"] = max(cpu_s, sum(table.column("cpu_s").to_pylist()))
    figures["cores_used"] = figures["cpu_s"] / wall_s
    shutil.rmtree(out, ignore_errors=True)
    return figures


def _median(rounds: list[dict[str, Any]], key: str) -> float | None:
    values = [r[key] for r in rounds if key in r]
    return statistics.median(values) if values else None


def main() -> int:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--configs", default=",".join(CONFIGS))
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    configs = args.configs.split(",")
    results: dict[str, list[dict[str, Any]]] = {c: [] for c in configs}
    with tempfile.TemporaryDirectory(prefix="campaign-bench-") as folder:
        scratch = Path(folder)
        campaign = _campaign_file(scratch, args.runs)
        for round_index in range(args.rounds):
            order = configs[round_index % len(configs):] + configs[:round_index % len(configs)]
            for config in order:
                figures = _measure(config, campaign, scratch, args.runs)
                results[config].append(figures)
                load = figures["load_average_before"]
                print(f"round {round_index + 1} {config:>5}: {figures['wall_s']:7.1f} s wall, "
                      f"{figures['runs_per_s']:5.2f} runs/s, load {load:.1f}",
                      file=sys.stderr, flush=True)
    summary = {c: {k: _median(results[c], k) for k in (
        "wall_s", "runs_per_s", "cpu_s", "run_wall_s_mean", "run_cpu_s_mean",
        "overhead_per_task_s", "load_average_before", "cores_used")} for c in configs}
    print(f"\n{args.runs} paper-boat runs (3 UAVs, 200 s), median of {args.rounds} round(s):")
    print(f"{'configuration':<40} {'wall s':>8} {'runs/s':>7} {'CPU s':>8} {'cores':>6}"
          f" {'run CPU s':>9} {'overhead/task s':>15}")
    for config in configs:
        s = summary[config]
        run_cpu = f"{s['run_cpu_s_mean']:.3f}" if s["run_cpu_s_mean"] is not None else "-"
        overhead = f"{s['overhead_per_task_s']:.3f}" if s["overhead_per_task_s"] is not None \
            else "-"
        print(f"{CONFIGS[config]:<40} {s['wall_s']:>8.1f} {s['runs_per_s']:>7.2f}"
              f" {s['cpu_s']:>8.1f} {s['cores_used']:>6.2f} {run_cpu:>9} {overhead:>15}")
    ratios: dict[str, float] = {}
    if "pool" in summary and "old" in summary:
        ratios["pool_vs_old_throughput"] = summary["pool"]["runs_per_s"] / summary["old"][
            "runs_per_s"]
    if "dask2" in summary and "pool" in summary:
        ratios["dask2_vs_pool_throughput"] = summary["dask2"]["runs_per_s"] / summary["pool"][
            "runs_per_s"]
    if "dask2" in summary and "dask1" in summary:
        ratios["dask_strong_scaling_2_over_1"] = summary["dask2"]["runs_per_s"] / summary[
            "dask1"]["runs_per_s"]
    for name, value in ratios.items():
        print(f"{name}: {value:.2f}")
    if args.json is not None:
        args.json.write_text(json.dumps({
            "runs": args.runs, "rounds": args.rounds, "cpu_count": os.cpu_count(),
            "configurations": CONFIGS, "summary": summary, "ratios": ratios,
            "rounds_detail": results,
        }, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
