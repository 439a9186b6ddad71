"""The paper's simulation study over many seeds: planner variants against a baseline, paired.

    nice -n 10 python benchmarks/paper_study.py --uavs 1-6 --seeds 20 \\
        --variants sequence:0.5,arrival:0.5,arrival:0,latency --base sequence:0.5

Every run is ``paper-boat`` (or ``--scenario``) in virtual time through the same code as
``gcs simulate``; variant k and the base see the same icebergs for a seed (paired runs). A
variant is ``objective[:tau][+option...]``; options: ``old-idle`` (the idle-UAV rule before
issue 12: nearest target even if another UAV flies there), ``point30`` (the planner sees
every sigma predicted 30 s ahead) and ``growth`` (time-integrated uncertainty with each
track's growth, linearised; both in growth_weights.py, for the latency objective).
``--still``: icebergs that do not drift (a level control for the bounded statistic);
``--commit-loiter S``: the daemon's policy (event-based, committed, S-second loiters)
instead of the scenario's.

For each (fleet size, variant) it prints the run-average uncertainty (mean over seeds), the
paired difference to the base in % (mean of the per-seed ratio - 1, with a 95 % t interval)
and wins/losses (seeds where the variant is lower/higher), then the bounded rates over
seeds with 95 % Wilson intervals: ``trend`` (metrics.json ``bounded_trend``: the robust
trend of the second half, relative to its level, at most 0.5) and ``ratio`` (the first
definition, ``bounded``); a table of how many runs each trend bound would pass; and the
revisits (a target visited again: share within 40 s, median and 90th percentile gap).
``--json`` writes every run's figures; ``--report FILE`` prints the tables again from such
a file (``--base`` may name another of its variants). The commands and figures of
docs/planner.md ("Choosing the objective", "Bounded") came from here; use ``nice -n 10``.

``campaigns/*.yaml`` (``gcs campaign``, ``gcs campaign report``) now reproduce the runs
that need no patch of floe: the objectives and tau, fleet sizes, durations, ``--still``
and ``--commit-loiter`` (scenario overrides). Only here: the ``old-idle``, ``point30`` and
``growth`` variants (they replace planner functions) and the revisit-gap table.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from typing import Any

Job = tuple[str, str, int, int, float | None, bool, float | None]


def _old_idle_assignment(inst: Any, routes: Sequence[Sequence[int]]) -> dict[str, str]:
    """The idle-UAV rule before issue 12: nearest kept target by Dubins distance, shared or not."""
    out: dict[str, str] = {}
    if inst.n == 0:
        return out
    for u, route in enumerate(routes):
        if not route:
            out[inst.problem.uavs[u].id] = inst.target_id(int(inst.d[u, inst.m :].argmin()))
    return out


def parse_variant(text: str) -> tuple[str, float | None, set[str]]:
    """``objective[:tau][+option...]`` -> (objective, tau or None, options)."""
    head, *options = text.split("+")
    objective, _, tau = head.partition(":")
    return objective, (float(tau) if tau else None), set(options)


def _one(job: Job) -> dict[str, Any]:
    from growth_weights import growth_solver, point_solver

    import groundstation.runners.simulate.simulator as simulate
    import planner.solve
    from groundstation.runners.simulate.simulator import SimulationOptions, run_simulation
    from world.scenario import load_scenario

    scenario_name, variant, uavs, seed, duration, still, loiter_s = job
    objective, tau, options = parse_variant(variant)
    original_idle, original_solve = planner.solve.idle_assignment, simulate.solve_plan
    scenario = load_scenario(scenario_name)
    if "old-idle" in options:
        planner.solve.idle_assignment = _old_idle_assignment
    if "point30" in options:
        simulate.solve_plan = point_solver(scenario.observer.q_per_s, 30.0)
    if "growth" in options:
        simulate.solve_plan = growth_solver(scenario.observer.q_per_s)
    try:
        spec = replace(scenario.planner, objective=objective,
                       tau=scenario.planner.tau if tau is None else tau)
        scenario = replace(scenario, planner=spec)
        if loiter_s is not None:  # the daemon's policy: event-based, committed, loiters
            scenario = replace(
                scenario, policy=replace(scenario.policy, replan="event", period_s=None,
                                         commit=True),
                fleet=replace(scenario.fleet, loiter_s=loiter_s))
        if still and scenario.random_targets is not None:
            scenario = replace(scenario, random_targets=replace(
                scenario.random_targets, vx_m_s=(0.0, 0.0), vy_m_s=(0.0, 0.0)))
        m = run_simulation(scenario, SimulationOptions(
            seed=seed, uavs=uavs, duration_s=duration, snapshot_times_s=(1.0,))).metrics
    finally:
        planner.solve.idle_assignment, simulate.solve_plan = original_idle, original_solve
    last_seen: dict[str, float] = {}
    gaps: list[float] = []
    for visit in m["visits"]:
        if visit["target"] in last_seen:
            gaps.append(visit["t_s"] - last_seen[visit["target"]])
        last_seen[visit["target"]] = visit["t_s"]
    return {
        "variant": variant, "uavs": uavs, "seed": seed, "duration_s": m["duration_s"],
        "revisit_gaps_s": gaps,
        "mean": m["mean_uncertainty"], "max": m["max_uncertainty"],
        "bounded": m["bounded"], "ratio": m["boundedness_ratio"],
        "bounded_trend": m["bounded_trend"], "trend": m["trend"],
        "visits": len(m["visits"]), "lost": len(m["lost_targets"]), "rtf": m["realtime_factor"],
        "solve_median_s": m["solve_time_s"]["median"], "solve_max_s": m["solve_time_s"]["max"],
    }


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Wilson score interval of a proportion k / n."""
    if n == 0:
        return 0.0, 1.0
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def t_quantile_975(df: int) -> float:
    """Student's t 97.5 % quantile: exact for df <= 30 (table), Cornish-Fisher above."""
    table = (12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201,
             2.179, 2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074,
             2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042)
    if df <= len(table):
        return table[df - 1]
    z = 1.959964
    return z + (z**3 + z) / (4 * df) + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * df**2)


def paired(diffs: Sequence[float]) -> tuple[float, float]:
    """Mean and half-width of the 95 % t interval."""
    if len(diffs) < 2:
        return (diffs[0] if diffs else 0.0), math.inf
    half = t_quantile_975(len(diffs) - 1) * statistics.stdev(diffs) / math.sqrt(len(diffs))
    return statistics.fmean(diffs), half


def _rate(rows: list[dict[str, Any]], key: str) -> str:
    values = [r[key] for r in rows if r[key] is not None]
    k = sum(bool(v) for v in values)
    lo, hi = wilson(k, len(values))
    return f"{k}/{len(values)} [{100 * lo:.0f}-{100 * hi:.0f} %]"


def report(rows: list[dict[str, Any]], base: str) -> str:
    """Markdown tables: paired differences to `base`, bounded rates."""
    variants = list(dict.fromkeys(r["variant"] for r in rows))
    sizes = sorted({r["uavs"] for r in rows})
    cell = {(r["variant"], r["uavs"], r["seed"]): r for r in rows}
    lines = [
        "| UAVs | variant | mean sigma (m^2) | vs " + base + " (95 % CI) | wins/losses |"
        " bounded: trend | bounded: ratio | visits |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for uavs in sizes:
        for variant in variants:
            group = [r for r in rows if r["variant"] == variant and r["uavs"] == uavs]
            if not group:
                continue
            mean = statistics.fmean(r["mean"] for r in group)
            compare = "-"
            wins = "-"
            if variant != base:
                pairs = [(r["mean"], cell[(base, uavs, r["seed"])]["mean"]) for r in group
                         if (base, uavs, r["seed"]) in cell]
                diffs = [100.0 * (v / b - 1.0) for v, b in pairs if b > 0]
                if diffs:
                    avg, half = paired(diffs)
                    compare = f"{avg:+.1f} % [{avg - half:+.1f}, {avg + half:+.1f}]"
                    wins = f"{sum(v < b for v, b in pairs)}/{sum(v > b for v, b in pairs)}"
            lines.append(
                f"| {uavs} | {variant} | {mean:,.0f} | {compare} | {wins} |"
                f" {_rate(group, 'bounded_trend')} | {_rate(group, 'bounded')} |"
                f" {statistics.fmean(r['visits'] for r in group):.1f} |"
            )
    return "\n".join(lines)


def threshold_table(rows: list[dict[str, Any]], bounds: Sequence[float]) -> str:
    """Runs whose trend is at most each bound (bounded), per (variant, fleet size)."""
    lines = ["| UAVs | variant | median trend | " + " | ".join(f"trend <= {b:g}" for b in bounds)
             + " |", "|---|---|---|" + "---|" * len(bounds)]
    for uavs in sorted({r["uavs"] for r in rows}):
        for variant in dict.fromkeys(r["variant"] for r in rows):
            trends = [r["trend"] for r in rows if r["variant"] == variant and r["uavs"] == uavs
                      and r["trend"] is not None]
            if not trends:
                continue
            counts = " | ".join(f"{sum(t <= b for t in trends)}/{len(trends)}" for b in bounds)
            lines.append(f"| {uavs} | {variant} | {statistics.median(trends):.2f} | {counts} |")
    return "\n".join(lines)


def revisit_table(rows: list[dict[str, Any]]) -> str:
    """Revisits (a target visited again): share within 40 s of the last visit, median and
    90th percentile of the gap, over every run of a (variant, fleet size)."""
    lines = ["| UAVs | variant | revisits | within 40 s | median gap (s) | 90th pct gap (s) |",
             "|---|---|---|---|---|---|"]
    for uavs in sorted({r["uavs"] for r in rows}):
        for variant in dict.fromkeys(r["variant"] for r in rows):
            gaps = sorted(g for r in rows if r["variant"] == variant and r["uavs"] == uavs
                          for g in r.get("revisit_gaps_s", []))
            if not gaps:
                continue
            q90 = gaps[min(len(gaps) - 1, int(0.9 * len(gaps)))]
            lines.append(f"| {uavs} | {variant} | {len(gaps)} |"
                         f" {100 * sum(g < 40.0 for g in gaps) / len(gaps):.0f} % |"
                         f" {statistics.median(gaps):.0f} | {q90:.0f} |")
    return "\n".join(lines)


def _sizes(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out.extend(range(int(lo), int(hi or lo) + 1))
    return out


def main() -> int:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="paper-boat")
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--uavs", default="1,3,5", help="fleet sizes: 1,3,5 or 1-6")
    parser.add_argument("--variants", default="sequence:0.5,latency")
    parser.add_argument("--base", default=None, help="variant the others are paired with "
                        "(default: the first)")
    parser.add_argument("--duration", type=float, default=None)
    parser.add_argument("--still", action="store_true", help="icebergs that do not drift "
                        "(a level control for the bounded statistic)")
    parser.add_argument("--commit-loiter", type=float, default=None, metavar="S",
                        help="the daemon's policy instead of the scenario's: event-based "
                        "replanning, commitment, loiters of S seconds")
    parser.add_argument("--thresholds", default="0.25,0.4,0.5,0.6",
                        help="trend bounds to count runs against (last table)")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--json", help="also write every run's figures to this file")
    parser.add_argument("--report", help="print the tables from a --json file and exit")
    args = parser.parse_args()
    variants = args.variants.split(",")
    base = args.base or variants[0]
    if args.report:
        with open(args.report, encoding="utf-8") as handle:
            rows = json.load(handle)
        print(report(rows, base))
        print()
        print(threshold_table(rows, [float(x) for x in args.thresholds.split(",")]))
        print()
        print(revisit_table(rows))
        return 0
    if base not in variants:
        variants.insert(0, base)
    jobs: list[Job] = [
        (args.scenario, variant, uavs, seed, args.duration, args.still, args.commit_loiter)
        for uavs in _sizes(args.uavs)
        for variant in variants
        for seed in range(args.first_seed, args.first_seed + args.seeds)
    ]
    print(f"{len(jobs)} runs of {args.scenario} on {args.jobs} process(es)...", file=sys.stderr)
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        rows = list(pool.map(_one, jobs, chunksize=4))
    print(report(rows, base))
    print()
    print(threshold_table(rows, [float(x) for x in args.thresholds.split(",")]))
    print()
    print(revisit_table(rows))
    rtf = statistics.median(r["rtf"] for r in rows)
    print(f"\nmedian real-time factor {rtf:.0f}x", file=sys.stderr)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(rows, handle, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
