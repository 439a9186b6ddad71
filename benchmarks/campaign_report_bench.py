"""How long ``gcs campaign report`` takes on a large synthetic campaign.

    nice -n 10 python benchmarks/campaign_report_bench.py --runs 10000 --plans 40

Writes a campaign folder (default: a temporary one) the way ``gcs campaign`` does:
``runs.parquet`` with ``--runs`` runs over fleet sizes 1-5 x 4 objectives x seeds, each
with a ``--duration``-second mean-uncertainty series, and ``plans.parquet`` with
``--plans`` plans per run; then times :func:`write_campaign_report` (import excluded) and
prints the seconds and the page's size. The values are random, shaped like paper-boat's.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

OBJECTIVES = ("sequence", "arrival", "latency", "sequence-tau")


def write_campaign(folder: Path, runs: int, plans_per_run: int, duration_s: int) -> None:
    """A synthetic campaign folder of ``runs`` runs (see the module docstring)."""
    rng = np.random.default_rng(0)
    cells = 5 * len(OBJECTIVES)
    seeds = max(1, runs // cells)
    n = cells * seeds
    uavs = np.repeat(np.arange(1, 6), len(OBJECTIVES) * seeds)
    objective = np.tile(np.repeat(np.array(OBJECTIVES), seeds), 5)
    seed = np.tile(np.arange(seeds), cells)
    level = 50_000.0 / uavs**1.5 * rng.lognormal(0.0, 0.3, n)
    t_s = np.arange(duration_s + 1, dtype=np.float64)
    sigma = level[:, None] * (1 - np.exp(-t_s[None, :] / 40.0))
    points = duration_s + 1
    offsets = pa.array(np.arange(n + 1, dtype=np.int32) * points)
    run_id = pa.array([f"r{k:06d}" for k in range(n)])
    runs_table = pa.table(
        {
            "run_id": run_id,
            "scenario": pa.array(["paper-boat"] * n),
            "uavs": pa.array(uavs),
            "objective": pa.array(objective.tolist()),
            "tau": pa.array(np.full(n, 0.5)),
            "seed": pa.array(seed),
            "campaign": pa.array(["bench"] * n),
            "mean_uncertainty": pa.array(sigma.mean(axis=1)),
            "bounded": pa.array(rng.random(n) < uavs / 6),
            "bounded_trend": pa.array(rng.random(n) < uavs / 6),
            "trend": pa.array(rng.normal(0.5, 0.5, n)),
            "solve_time_median_s": pa.array(0.002 * uavs * rng.lognormal(0, 0.3, n)),
            "solve_time_max_s": pa.array(0.01 * uavs * rng.lognormal(0, 0.3, n)),
            "series_t_s": pa.ListArray.from_arrays(offsets, pa.array(np.tile(t_s, n))),
            "series_mean_sigma": pa.ListArray.from_arrays(offsets, pa.array(sigma.ravel())),
            "floe_version": pa.array(["0.1.0"] * n),
            "wall_s": pa.array(np.full(n, 0.5)),
            "cpu_s": pa.array(np.full(n, 0.5)),
            "worker": pa.array(["bench/1"] * n),
        }
    )
    m = n * plans_per_run
    latency = np.repeat(objective == "latency", plans_per_run)
    f1 = rng.uniform(1e4, 1e5, m)
    plans_table = pa.table(
        {
            "run_id": pa.array(np.repeat(np.array([f"r{k:06d}" for k in range(n)]), plans_per_run)),
            "plan_index": pa.array(np.tile(np.arange(plans_per_run), n)),
            "mu": pa.array(np.where(latency, 0.0, rng.uniform(0.05, 0.5, m))),
            "f1": pa.array(f1),
            "f2": pa.array(np.where(latency, 0.0, f1 * rng.lognormal(-0.7, 0.2, m))),
            "objective": pa.array(np.repeat(objective, plans_per_run).tolist()),
            "solve_time_s": pa.array(rng.lognormal(np.log(0.002), 0.6, m)),
        }
    )
    folder.mkdir(parents=True, exist_ok=True)
    pq.write_table(runs_table, folder / "runs.parquet")
    pq.write_table(plans_table, folder / "plans.parquet")
    (folder / "campaign.yaml").write_text(
        "name: bench\ngrid:\n  scenario: [paper-boat]\n  uavs: [1, 2, 3, 4, 5]\n"
        f"  objective: {list(OBJECTIVES)}\n  tau: [0.5]\n  seed: {{from: 0, to: {seeds - 1}}}\n"
        "set: {}\nper_plan: true\n"
    )


def main() -> int:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10_000)
    parser.add_argument("--plans", type=int, default=40, help="plans per run")
    parser.add_argument("--duration", type=int, default=200, help="mission seconds per run")
    parser.add_argument("--folder", type=Path, default=None, help="default: a temporary one")
    args = parser.parse_args()
    from groundstation.runners.campaign.report import write_campaign_report

    with tempfile.TemporaryDirectory() as tmp:
        folder = args.folder or Path(tmp) / "campaign"
        write_campaign(folder, args.runs, args.plans, args.duration)
        start = time.perf_counter()
        page = write_campaign_report(folder)
        took_s = time.perf_counter() - start
        print(
            f"{args.runs} runs x {args.duration + 1} points, {args.runs * args.plans} plans: "
            f"report in {took_s:.2f} s ({page.stat().st_size / 1e6:.2f} MB page)"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
