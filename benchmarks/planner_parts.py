"""Planner parts, measured one by one: the subset DP's time per fleet size, and the lower
bounds (layered LP with P positions, in-arc) against the best plan floe finds.

    nice -n 10 python benchmarks/planner_parts.py            # about 2 minutes
    nice -n 10 python benchmarks/planner_parts.py --only dp  # or: --only lp

Instances as in planner_bench.py (seed s of size MxN is random.Random(f"{M}x{N}-{s}")).
DP rows: wall time of solve_dp per seed (the first of a size includes building the 3^n
table for 3+ UAVs), and dp_seconds, the estimate floe chooses the method by. LP rows: wall
time of lp_bound (scipy already imported) and its gap (J_ref - bound) / |J_ref|, J_ref the
plan of PlanSolver with a 5 s limit (the DP's optimum where the DP applies); the in-arc
bound's gap alike. All times with one thread on whatever load the machine has.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from planner_bench import make_problem

from planner.bound import in_arc_bound, lp_bound
from planner.exact_dp import _submask_pairs, dp_is_cheap, dp_seconds, solve_dp
from planner.instance import build_instance
from planner.solve import PlanSolver, warm_up

DP_SIZES = [(1, 13), (1, 14), (1, 15), (1, 16), (1, 17), (2, 14), (2, 16), (3, 12), (5, 12)]
LP_CASES = [
    ("sequence", 5, 20, [8, 20]),
    ("sequence", 10, 50, [6, 10, 50]),
    ("sequence", 20, 100, [4, 6, 10]),
    ("sequence", 30, 150, [3, 4]),
    ("arrival", 5, 20, [20]),
    ("arrival", 10, 50, [10]),
]


def dp_rows(seeds: int) -> None:
    print(f"{'size':>6} {'dp_s per seed':>28} {'estimate_s':>10} {'chosen@1s':>9}")
    for m, n in DP_SIZES:
        _submask_pairs.cache_clear()
        times = []
        for seed in range(seeds):
            inst = build_instance(make_problem(m, n, seed, 1.0))
            t0 = time.perf_counter()
            solve_dp(inst)
            times.append(time.perf_counter() - t0)
        text = " ".join(f"{t:.3f}" for t in times)
        print(f"{m}x{n:<4} {text:>28} {dp_seconds(m, n):>10.3f} {dp_is_cheap(m, n, 1.0)!s:>9}")


def lp_rows(seeds: int) -> None:
    warm_up()
    print(
        f"{'objective':>9} {'size':>6} {'P':>3} {'lp_s med':>8} {'lp_s max':>8} "
        f"{'lp_gap% med':>11} {'lp_gap% max':>11} {'in-arc gap% med':>15}"
    )
    for objective, m, n, layers in LP_CASES:
        refs, insts = [], []
        for seed in range(seeds):
            p = replace(make_problem(m, n, seed, 5.0), objective=objective)
            inst = build_instance(p)
            insts.append(inst)
            if dp_is_cheap(m, n, 5.0):
                refs.append(inst.evaluate(solve_dp(inst))[0])
            else:
                refs.append(PlanSolver(p).solve().objective)
        arc = [100 * (j - in_arc_bound(i)) / abs(j) for i, j in zip(insts, refs, strict=True)]
        for big_p in layers:
            times, gaps = [], []
            for inst, ref in zip(insts, refs, strict=True):
                t0 = time.perf_counter()
                lp = lp_bound(inst, big_p, 60.0)
                times.append(time.perf_counter() - t0)
                gaps.append(100 * (ref - lp.value) / abs(ref) if lp else float("inf"))
            print(
                f"{objective:>9} {m}x{n:<4} {big_p:>3} {statistics.median(times):>8.3f} "
                f"{max(times):>8.3f} {statistics.median(gaps):>11.2f} {max(gaps):>11.2f} "
                f"{statistics.median(arc):>15.2f}"
            )


def main() -> None:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=(__doc__ or "").split("\n")[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--only", choices=("dp", "lp"))
    args = parser.parse_args()
    if args.only in (None, "dp"):
        dp_rows(args.seeds)
    if args.only in (None, "lp"):
        lp_rows(args.seeds)


if __name__ == "__main__":
    main()
