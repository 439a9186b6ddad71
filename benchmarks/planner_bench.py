"""Planner benchmark: floe's solvers against the paper's MTZ model in HiGHS and SCIP.

    python benchmarks/planner_bench.py --sizes 1x10,3x10,5x20,10x50 --seeds 10 \
        --solvers floe,cpsat,mtz-highs,mtz-scip --time-limit 5 --time-limit-large 1

Instances: UAVs and targets uniform in [0, 1500]^2, UAV headings uniform, sigma uniform in
[10, 100] (so the 10 % rule drops nothing and the size is exact), turn radius 105 m,
tau 0.5, sequence objective. Seed s of size MxN is random.Random(f"{M}x{N}-{s}").

Solvers (each in its own subprocess: highspy and OR-Tools both bundle HiGHS):
  floe       solve_plan as shipped (DP <= 11-13 targets, else ILS + CP-SAT)
  cpsat      the CP-SAT model alone (position model <= 30 targets, circuit above), hinted
             by a short ILS, as PlanSolver(method=...)
  mtz-highs  the paper's MTZ MIP in HiGHS (1 thread, mip_rel_gap 1e-6)
  mtz-scip   the paper's MTZ MIP in SCIP (1 thread, default gap 0)
  reference  floe with --reference-time seconds, only for sizes above 30 targets: a
             longer run that sets the best known plan
Printed per size and solver: proven (count within the time limit), median wall time to the
proven optimum (unproven instances count as infinite), gap of the solver's plan to the
best known objective over all solvers ((J - J_best) / |J_best|, median and max), and the
number of plans within 1 % of the best known.
"""

from __future__ import annotations

import argparse
import json
import math
import random
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))


if TYPE_CHECKING or "--worker" not in sys.argv or "mtz" not in " ".join(sys.argv):
    # not in the MTZ workers: OR-Tools (loaded by planner) and highspy clash
    from planner import PlanningProblem, PlanSolver, TargetEstimate, UavPose
    from planner.instance import build_instance

SOLVERS = ("floe", "cpsat", "mtz-highs", "mtz-scip", "reference")


def make_problem(m: int, n: int, seed: int, time_limit_s: float) -> PlanningProblem:
    rng = random.Random(f"{m}x{n}-{seed}")
    uavs = tuple(
        UavPose(f"u{k}", rng.uniform(0, 1500), rng.uniform(0, 1500), rng.uniform(-math.pi, math.pi))
        for k in range(m)
    )
    targets = tuple(
        TargetEstimate(f"t{k}", rng.uniform(0, 1500), rng.uniform(0, 1500), rng.uniform(10, 100))
        for k in range(n)
    )
    return PlanningProblem(uavs, targets, 105.0, time_limit_s=time_limit_s)


def parse_sizes(text: str) -> list[tuple[int, int]]:
    out = []
    for part in text.split(","):
        m, n = part.lower().split("x")
        out.append((int(m), int(n)))
    return out


def limit_for(n: int, args: argparse.Namespace) -> float:
    return float(args.time_limit_large if n > 30 else args.time_limit)


def run_one(solver: str, p: PlanningProblem, args: argparse.Namespace) -> dict[str, Any]:
    if solver in ("floe", "cpsat", "reference"):
        method = "auto"
        if solver == "cpsat":
            method = "position" if len(p.targets) <= 30 else "circuit"
        t0 = time.perf_counter()
        r = PlanSolver(p, num_workers=args.workers, method=method).solve()
        wall = time.perf_counter() - t0
        return {
            "proven": r.status == "optimal",
            "objective": r.objective,
            "time_s": wall,
            "detail": r.solver,
        }
    raise ValueError(solver)


def mtz_data(p: PlanningProblem) -> dict[str, Any]:
    inst = build_instance(p)
    return {
        "m": inst.m,
        "n": inst.n,
        "tau": inst.tau,
        "mu": inst.mu,
        "d": inst.d.tolist(),
        "sigma": inst.sigma.tolist(),
    }


def mtz_worker(args: argparse.Namespace) -> None:
    """HiGHS / SCIP worker: reads the instances' numbers, never imports OR-Tools."""
    from planner_mtz import MtzData, solve_highs, solve_scip

    fn = solve_highs if args.worker == "mtz-highs" else solve_scip
    for line in Path(args.data).read_text().splitlines():
        row = json.loads(line)
        proven, objective, wall = fn(MtzData.from_dict(row["data"]), row["limit_s"])
        out = {"proven": proven, "objective": objective, "time_s": wall, "detail": args.worker}
        out.update(solver=args.worker, size=row["size"], seed=row["seed"], limit_s=row["limit_s"])
        print(json.dumps(out), flush=True)


def worker(args: argparse.Namespace) -> None:
    for m, n in parse_sizes(args.sizes):
        if args.worker == "reference" and n <= 30:
            continue
        for seed in range(args.seeds):
            limit = args.reference_time if args.worker == "reference" else limit_for(n, args)
            p = make_problem(m, n, seed, limit)
            row = run_one(args.worker, p, args)
            row.update(solver=args.worker, size=f"{m}x{n}", seed=seed, limit_s=limit)
            print(json.dumps(row), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", default="1x10,3x10,5x20,10x50")
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--solvers", default="floe,cpsat,mtz-highs,mtz-scip,reference")
    parser.add_argument("--time-limit", type=float, default=5.0, help="s, <= 30 targets")
    parser.add_argument("--time-limit-large", type=float, default=1.0, help="s, > 30 targets")
    parser.add_argument("--reference-time", type=float, default=30.0)
    parser.add_argument("--workers", type=int, default=1, help="CP-SAT workers")
    parser.add_argument("--json", help="also write all rows to this file")
    parser.add_argument("--worker", choices=SOLVERS, help=argparse.SUPPRESS)
    parser.add_argument("--data", help=argparse.SUPPRESS)
    parser.add_argument("--report", help="only print the table of rows saved with --json")
    args = parser.parse_args()
    if args.report:
        lines = Path(args.report).read_text().splitlines()
        report([json.loads(line) for line in lines if line.strip()], args)
        return
    if args.worker in ("mtz-highs", "mtz-scip"):
        mtz_worker(args)
        return
    if args.worker:
        worker(args)
        return
    with tempfile.NamedTemporaryFile("w", suffix=".planner-bench.jsonl", delete=False) as fh:
        data_path = Path(fh.name)
        for m, n in parse_sizes(args.sizes):
            for seed in range(args.seeds):
                limit = limit_for(n, args)
                row = {"size": f"{m}x{n}", "seed": seed, "limit_s": limit}
                row["data"] = mtz_data(make_problem(m, n, seed, limit))
                fh.write(json.dumps(row) + "\n")
    rows: list[dict[str, Any]] = []
    for solver in args.solvers.split(","):
        if solver not in SOLVERS:
            parser.error(f"unknown solver {solver}")
        cmd = [sys.executable, __file__, "--worker", solver]
        for flag in (
            "sizes",
            "seeds",
            "time_limit",
            "time_limit_large",
            "reference_time",
            "workers",
        ):
            cmd += [f"--{flag.replace('_', '-')}", str(getattr(args, flag))]
        cmd += ["--data", str(data_path)]
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        got = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
        if proc.returncode != 0:
            print(f"# {solver} failed: {proc.stderr.strip().splitlines()[-1:]}", file=sys.stderr)
        rows += got
        print(f"# {solver}: {len(got)} runs", file=sys.stderr, flush=True)
    data_path.unlink(missing_ok=True)
    if args.json:
        Path(args.json).write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    report(rows, args)


def report(rows: list[dict[str, Any]], args: argparse.Namespace) -> None:
    """Table per size and solver. gap: (J - J_best) / |J_best|; vgap: the same on the part
    of J that depends on the plan, J - C with C = -(1 - tau)(N - 1) sum(sigma) (a constant
    that dominates J; vgap is the stricter figure)."""
    best: dict[tuple[str, int], float] = {}
    for r in rows:
        if r["objective"] is not None:
            key = (r["size"], r["seed"])
            best[key] = min(best.get(key, math.inf), r["objective"])
    constant: dict[tuple[str, int], float] = {}
    for size, seed in best:
        m, n = parse_sizes(size)[0]
        inst = build_instance(make_problem(m, n, seed, 1.0))
        constant[(size, seed)] = inst.constant
    print(
        f"{'size':>6} {'solver':>10} {'limit_s':>7} {'proven':>7} {'med_t_opt_s':>11} "
        f"{'med_gap_%':>9} {'max_gap_%':>9} {'med_vgap_%':>10} {'max_vgap_%':>10} {'<=1%':>5}"
    )
    sizes = sorted({r["size"] for r in rows}, key=lambda t: parse_sizes(t)[0][::-1])
    solvers = list(dict.fromkeys(r["solver"] for r in rows))
    for size in sizes:
        for solver in solvers:
            mine = [r for r in rows if r["size"] == size and r["solver"] == solver]
            if not mine:
                continue
            times = sorted(r["time_s"] if r["proven"] else math.inf for r in mine)
            med = statistics.median(times)
            gaps, vgaps = [], []
            for r in mine:
                ref = best[(size, r["seed"])]
                var_ref = ref - constant[(size, r["seed"])]
                if r["objective"] is None:
                    gaps.append(math.inf)
                    vgaps.append(math.inf)
                else:
                    gaps.append(100.0 * (r["objective"] - ref) / max(abs(ref), 1e-12))
                    vgaps.append(100.0 * (r["objective"] - ref) / max(abs(var_ref), 1e-12))
            proven = sum(r["proven"] for r in mine)
            med_text = f"{med:.3f}" if math.isfinite(med) else ">limit"
            within = sum(g <= 1.0 for g in gaps)
            print(
                f"{size:>6} {solver:>10} {mine[0]['limit_s']:>7g} {proven:>3}/{len(mine):<3} "
                f"{med_text:>11} {statistics.median(gaps):>9.4f} {max(gaps):>9.4f} "
                f"{statistics.median(vgaps):>10.4f} {max(vgaps):>10.4f} {within:>2}/{len(mine)}"
            )


if __name__ == "__main__":
    main()
