"""Planning costs in wind: the first leg's accuracy against a brute force, and the cost
matrix's build time with and without wind.

    nice -n 10 python benchmarks/wind_costs.py                  # both parts, ~40 s
    nice -n 10 python benchmarks/wind_costs.py --only accuracy  # or: --only timing
    python benchmarks/wind_costs.py --only accuracy --plot first_leg.png   # and a figure

Accuracy: random first legs (UAV at the origin, heading uniform; target uniform in a ring
around it: "near" 0-210 m = 2 turn radii, "far" 210-3000 m, the two regimes of
planner.wind; half of them drifting at up to 3 m/s per axis) in winds of 5, 10 and 15 m/s
from a uniform direction, V = 22 m/s, R = 105 m. Reference: tests/wind_reference.py, the
fastest of the turn-straight flights (20 000-step grid of the turn, bisected) and, near,
the turn-turn-straight flights (400 x 400 grid, refined), all flown in the wind over the
ground: an upper bound on the true minimum time, exact to its grid. Printed per class:
error = floe's time - reference (s), median |error|, 99th percentile and extremes, and for
comparison two cheap estimates floe does not use: the still-air time D/V (what a
wind-blind planner uses) and D over the ground speed along the straight line to the
target; and floe's time per call. Case k of class c is seeded random.Random(f"{c}-{wind}-{k}").

The figure (--plot) shows |error| against the distance to the target for floe and the two
cheap estimates (errors below 1e-12 s drawn at 1e-12).

Timing: build_instance (10 % rule, cost matrix, mu) for 3x10, 5x25 and 10x60 problems as in
planner_bench.py, still air against a 10 m/s wind from a random direction, median and max
over the seeds, one thread, whatever the machine's load.
"""

from __future__ import annotations

import argparse
import math
import random
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from planner_bench import make_problem  # noqa: E402
from wind_reference import reference_time_s  # noqa: E402

from domain.wind_triangle import ground_speed_along_m_s  # noqa: E402
from planner.dubins import dubins_distance_to_point  # noqa: E402
from planner.instance import build_instance  # noqa: E402
from planner.wind import time_in_wind_s  # noqa: E402

V_M_S = 22.0
R_M = 105.0
WINDS_M_S = (5.0, 10.0, 15.0)
CLASSES = {"near": (0.0, 2.0 * R_M), "far": (2.0 * R_M, 3000.0)}
SIZES = ((3, 10), (5, 25), (10, 60))


def case(cls: str, wind_m_s: float, k: int) -> tuple[float, float, float, tuple[float, float],
                                                      tuple[float, float]]:
    """(heading, px, py, wind, target velocity) of case k."""
    rng = random.Random(f"{cls}-{wind_m_s:g}-{k}")
    lo, hi = CLASSES[cls]
    radius = rng.uniform(lo, hi)
    bearing = rng.uniform(0.0, 2.0 * math.pi)
    heading = rng.uniform(-math.pi, math.pi)
    towards = rng.uniform(0.0, 2.0 * math.pi)
    wind = (wind_m_s * math.cos(towards), wind_m_s * math.sin(towards))
    drift = (rng.uniform(-3, 3), rng.uniform(-3, 3)) if k % 2 else (0.0, 0.0)
    return heading, radius * math.cos(bearing), radius * math.sin(bearing), wind, drift


def cheap_estimates(heading: float, px: float, py: float, wind: tuple[float, float]) -> tuple[
        float, float]:
    """(D / V, D / ground speed along the bearing): estimates floe does not use."""
    d = dubins_distance_to_point(0.0, 0.0, heading, px, py, R_M)
    along = ground_speed_along_m_s(math.atan2(py, px), wind, V_M_S) or math.nan
    return d / V_M_S, d / along


def accuracy(cases: int, plot: str | None) -> None:
    print(f"first leg in wind: floe vs brute force, {cases} cases per row (seconds)")
    print(f"{'class':>5} {'wind':>5} {'ref med':>8} {'|err| med':>10} {'|err| p99':>10}"
          f" {'err min':>9} {'err max':>9} {'still-air med|max':>18} {'bearing med|max':>16}"
          f" {'floe ms':>8}")
    points: list[tuple[float, float, float, float]] = []
    for cls in CLASSES:
        for wind_m_s in WINDS_M_S:
            errors, blind, bearing, refs, cost = [], [], [], [], []
            for k in range(cases):
                heading, px, py, wind, drift = case(cls, wind_m_s, k)
                start = time.perf_counter()
                got = time_in_wind_s(0.0, 0.0, heading, px, py, wind, V_M_S, R_M, drift)
                cost.append(time.perf_counter() - start)
                ref = reference_time_s(0.0, 0.0, heading, px, py, wind, V_M_S, R_M, drift,
                                       n1=20000, n_cc=400 if cls == "near" else 0)
                refs.append(ref)
                errors.append(got - ref)
                a = b = math.nan  # the cheap estimates know no drift: still targets only
                if drift == (0.0, 0.0):
                    a, b = cheap_estimates(heading, px, py, wind)
                    blind.append(abs(a - ref))
                    bearing.append(abs(b - ref))
                points.append((math.hypot(px, py), got - ref, a - ref, b - ref))
            abs_err = sorted(abs(e) for e in errors)
            p99 = abs_err[min(len(abs_err) - 1, int(0.99 * len(abs_err)))]
            print(f"{cls:>5} {wind_m_s:5.0f} {statistics.median(refs):8.1f}"
                  f" {statistics.median(abs_err):10.2e} {p99:10.2e} {min(errors):+9.1e}"
                  f" {max(errors):+9.1e} {statistics.median(blind):8.2f}|{max(blind):8.2f}"
                  f" {statistics.median(bearing):7.2f}|{max(bearing):7.2f}"
                  f" {1e3 * statistics.median(cost):8.2f}")
    if plot:
        _plot(points, plot)


def _plot(points: list[tuple[float, float, float, float]], path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    dist = [p[0] for p in points]
    for column, label, marker in ((1, "floe (virtual target)", "o"), (2, "still air D/V", "x"),
                                  (3, "D / ground speed on the bearing", "+")):
        ax.scatter(dist, [max(abs(p[column]), 1e-12) for p in points], s=8, marker=marker,
                   label=label)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("distance to the target (m)")
    ax.set_ylabel("|time - brute force| (s)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"figure written to {path}")


def timing(seeds: int) -> None:
    print(f"cost matrix build (build_instance), {seeds} seeds, milliseconds")
    print(f"{'size':>6} {'still med':>10} {'still max':>10} {'wind med':>10} {'wind max':>10}")
    for m, n in SIZES:
        calm, windy = [], []
        for seed in range(seeds):
            problem = make_problem(m, n, seed, 1.0)
            towards = random.Random(f"wind-{m}x{n}-{seed}").uniform(0.0, 2.0 * math.pi)
            wind = (10.0 * math.cos(towards), 10.0 * math.sin(towards))
            for target, p in ((calm, problem), (windy, replace(problem, wind_m_s=wind))):
                start = time.perf_counter()
                build_instance(p)
                target.append(1e3 * (time.perf_counter() - start))
        print(f"{m}x{n:<4} {statistics.median(calm):10.2f} {max(calm):10.2f}"
              f" {statistics.median(windy):10.2f} {max(windy):10.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=("accuracy", "timing"))
    parser.add_argument("--cases", type=int, default=40, help="first legs per row")
    parser.add_argument("--seeds", type=int, default=10, help="problems per size")
    parser.add_argument("--plot", help="write the accuracy figure (PNG) here")
    args = parser.parse_args()
    if args.only in (None, "timing"):
        timing(args.seeds)
    if args.only in (None, "accuracy"):
        accuracy(args.cases, args.plot)


if __name__ == "__main__":
    main()
