"""The paper's simulation study, over many seeds: fleet sizes, objectives, speed.

    python benchmarks/paper_study.py --seeds 20 --uavs 1,3,5 --objectives sequence,arrival

For every (objective, fleet size) it runs ``paper-boat`` for each seed in virtual time and
prints how many runs are *bounded* (design.md: the maximum of the average uncertainty over
the second half is at most 1.5 times its maximum over the first half), the mean and median
of the run-average uncertainty, visits, lost targets, and the real-time factor (simulated
seconds per wall second, planning included). Runs go to a process pool (one per core).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
from concurrent.futures import ProcessPoolExecutor
from typing import Any

from groundstation.runners.simulate import SimulationOptions, run_simulation
from world.scenario import load_scenario


def _one(job: tuple[str, str, int, int, float | None]) -> dict[str, Any]:
    scenario_name, objective, uavs, seed, duration = job
    scenario = load_scenario(scenario_name)
    options = SimulationOptions(seed=seed, uavs=uavs, objective=objective,
                                duration_s=duration, snapshot_times_s=(1.0,))
    m = run_simulation(scenario, options).metrics
    return {
        "objective": objective, "uavs": uavs, "seed": seed, "bounded": m["bounded"],
        "ratio": m["boundedness_ratio"], "mean": m["mean_uncertainty"],
        "max": m["max_uncertainty"], "visits": len(m["visits"]),
        "lost": len(m["lost_targets"]), "rtf": m["realtime_factor"],
        "solve_median_s": m["solve_time_s"]["median"], "solve_max_s": m["solve_time_s"]["max"],
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="paper-boat")
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--uavs", default="1,3")
    parser.add_argument("--objectives", default="sequence,arrival")
    parser.add_argument("--duration", type=float, default=None)
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--json", help="also write every run's figures to this file")
    args = parser.parse_args()
    jobs = [
        (args.scenario, objective, int(uavs), seed, args.duration)
        for objective in args.objectives.split(",")
        for uavs in args.uavs.split(",")
        for seed in range(args.seeds)
    ]
    print(f"{len(jobs)} runs of {args.scenario} on {args.jobs} process(es)...", file=sys.stderr)
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        rows = list(pool.map(_one, jobs))
    print(f"{'objective':>9} {'uavs':>4} {'bounded':>9} {'mean sigma':>11} {'median':>9}"
          f" {'max sigma':>10} {'visits':>6} {'lost':>5} {'x realtime':>10}"
          f" {'solve med/max ms':>17}")
    for objective in args.objectives.split(","):
        for uavs in (int(u) for u in args.uavs.split(",")):
            group = [r for r in rows if r["objective"] == objective and r["uavs"] == uavs]
            means = [r["mean"] for r in group]
            print(
                f"{objective:>9} {uavs:>4} {sum(r['bounded'] for r in group):>4}/{len(group):<4}"
                f" {statistics.fmean(means):>11.0f} {statistics.median(means):>9.0f}"
                f" {statistics.fmean(r['max'] for r in group):>10.0f}"
                f" {statistics.fmean(r['visits'] for r in group):>6.1f}"
                f" {statistics.fmean(r['lost'] for r in group):>5.1f}"
                f" {statistics.median(r['rtf'] for r in group):>10.0f}"
                f" {1000 * statistics.median(r['solve_median_s'] for r in group):>8.1f}"
                f"/{1000 * max(r['solve_max_s'] for r in group):<8.1f}"
            )
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(rows, handle, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
