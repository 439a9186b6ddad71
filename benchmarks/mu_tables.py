"""docs/planner.md's Section 4.5 tables from a finished ``campaigns/mu-rules.yaml`` folder.

    python benchmarks/mu_tables.py out/mu-rules

1. Per cell (UAVs x ``planner.mu``): runs, the mean mu of the adopted plans, mu / (F1/F2)
   (``f2 / f1`` of each plan with F1 > 0 and mu > 0; mean +- sd over the plans), the 95 %
   t interval over the runs' own ``mu_ratio`` means, and the mean sigma with its 95 % t
   interval over the runs.
2. Paired over the seeds, per fleet size: ``100 (mean sigma of the rule / floe's - 1)``,
   mean with its 95 % t interval, and how many runs are identical to floe's (the same
   mean uncertainty to 1e-9, relative).

Reads ``runs.parquet`` and ``plans.parquet`` (pyarrow, the ``campaign`` extra).
"""

from __future__ import annotations

import argparse
import math
import statistics
from pathlib import Path
from typing import Any

import pyarrow.parquet as pq
from scipy import stats

RULES = ("floe", "paper", "unconstrained")


def t_interval(values: list[float]) -> tuple[float, float, float]:
    """Mean and its 95 % t interval."""
    mean = statistics.fmean(values)
    half = stats.t.ppf(0.975, len(values) - 1) * statistics.stdev(values) / math.sqrt(len(values))
    return mean, mean - half, mean + half


def cell_table(runs: list[dict[str, Any]], plans: list[dict[str, Any]]) -> list[str]:
    out = ["| UAVs | `mu` | runs | mean mu | mu / (F1/F2): mean +- sd over the plans (plans) "
           "| 95 % CI (over the runs' means) | mean sigma (m^2) [95 % CI] |",
           "|---|---|---|---|---|---|---|"]
    for uavs in sorted({r["uavs"] for r in runs}):
        for rule in RULES:
            rs = [r for r in runs if r["uavs"] == uavs and r["planner.mu"] == rule]
            ps = [p for p in plans if p["uavs"] == uavs and p["planner.mu"] == rule
                  and (p["f1"] or 0.0) > 0.0 and (p["mu"] or 0.0) > 0.0]
            if len(rs) < 2 or len(ps) < 2:
                continue
            ratios = [p["f2"] / p["f1"] for p in ps]
            _, lo, hi = t_interval([r["mu_ratio_mean"] for r in rs
                                    if r["mu_ratio_mean"] is not None])
            sigma, s_lo, s_hi = t_interval([r["mean_uncertainty"] for r in rs])
            out.append(
                f"| {uavs} | {rule} | {len(rs)} | {statistics.fmean(p['mu'] for p in ps):.1f} "
                f"| {statistics.fmean(ratios):.2f} +- {statistics.stdev(ratios):.2f} "
                f"({len(ratios):,}) | {lo:.2f} - {hi:.2f} | {sigma:,.0f} [{s_lo:,.0f} - "
                f"{s_hi:,.0f}] |")
    return out


def paired_table(runs: list[dict[str, Any]]) -> list[str]:
    sigma = {(r["uavs"], r["planner.mu"], r["seed"]): r["mean_uncertainty"] for r in runs}
    out = ["| UAVs | seeds | `paper` vs `floe`: mean sigma, % [95 % CI] | identical runs "
           "| `unconstrained` vs `floe` | identical runs |", "|---|---|---|---|---|---|"]
    for uavs in sorted({r["uavs"] for r in runs}):
        cells, seeds_n = [], []
        for rule in RULES[1:]:
            seeds = sorted(s for (u, m, s) in sigma
                           if u == uavs and m == "floe" and (uavs, rule, s) in sigma)
            if len(seeds) < 2:
                break
            base = [sigma[(uavs, "floe", s)] for s in seeds]
            other = [sigma[(uavs, rule, s)] for s in seeds]
            diff = [100.0 * (o / b - 1.0) for o, b in zip(other, base, strict=True)]
            same = sum(1 for o, b in zip(other, base, strict=True) if abs(o - b) <= 1e-9 * b)
            mean, lo, hi = t_interval(diff)
            cells.append(f"{mean:+.1f} [{lo:+.1f}, {hi:+.1f}] | {same}/{len(seeds)}")
            seeds_n.append(len(seeds))
        if len(cells) == 2:
            out.append(f"| {uavs} | {min(seeds_n)} | " + " | ".join(cells) + " |")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    parser.add_argument("folder", type=Path, help="a mu-rules campaign's --out folder")
    args = parser.parse_args()
    try:
        runs = pq.read_table(args.folder / "runs.parquet", columns=[
            "uavs", "seed", "planner.mu", "mean_uncertainty", "mu_ratio_mean"]).to_pylist()
        plans = pq.read_table(args.folder / "plans.parquet", columns=[
            "uavs", "planner.mu", "mu", "f1", "f2"]).to_pylist()
    except (OSError, KeyError, ValueError) as exc:
        parser.error(f"{args.folder}: not a mu-rules campaign folder ({exc})")
    print("\n".join(cell_table(runs, plans)))
    print()
    print("\n".join(paired_table(runs)))


if __name__ == "__main__":
    main()
