"""Planner benchmark: floe against the paper's MTZ model in HiGHS, SCIP and CP-SAT.

    nice -n 10 python benchmarks/planner_bench.py --sizes 1x10,1x16,3x10,5x20,10x50 \
        --seeds 10 --solvers floe,mtz-highs,mtz-scip,mtz-cpsat --json rows.jsonl
    python benchmarks/planner_bench.py --sizes 10x50,20x100,50x250,50x500 --seeds 10 \
        --solvers floe,reflocal --busy 2 --json busy.jsonl     # issue 30: busy machine
    python benchmarks/planner_bench.py --report rows.jsonl     # the table again

Instances: UAVs and targets uniform in [0, 1500]^2, UAV headings uniform, sigma uniform in
[10, 100] (so the 10 % rule drops nothing and the size is exact), turn radius 105 m,
tau 0.5, sequence objective. Seed s of size MxN is random.Random(f"{M}x{N}-{s}").
Time limit: --time-limit (default 5 s) up to 30 targets, --time-limit-large (1 s) above.

Solvers, each in its own long-lived worker process (highspy and OR-Tools both bundle HiGHS
and cannot share a process), all with one thread and the same limit:
  floe       PlanSolver as shipped (DP where cheap, else ILS + LP bound + CP-SAT); the
             worker calls planner.solve.warm_up() first, so the one-time imports of scipy
             and OR-Tools (~0.3-0.5 s each) are not charged to the first instance
  cpsat      floe's CP-SAT model alone (position model <= 30 targets, circuit above)
  mtz-highs  the paper's MTZ MIP in HiGHS (mip_rel_gap 1e-6)
  mtz-scip   the paper's MTZ MIP in SCIP (gap 0)
  mtz-cpsat  the paper's MTZ model in CP-SAT
  reference  floe's local search alone for --reference-time s (sets the best known plan
             where nothing is proven)
  reflocal   a plain local search kept in benchmarks/reference_search.py (greedy insertion,
             relocate and exchange moves, kicks while time is left), independent of
             floe's planner code, given the same limit as floe
With --busy K, K busy loops (one Python process each, `while True: pass`) run beside the
solvers for half of the runs: every instance goes to every solver once with the loops
running and once with them stopped (SIGSTOP), interleaved, and the rows carry
`load: busy|quiet`. Times are measured in the worker process around the solve (wall, and
the CPU the solving thread obtained).
The runs are interleaved: every instance is handed to every solver in turn (one solver
busy at a time), so a change of machine load hits all solvers alike.

Printed per size and solver: proven (count), wall time median and max (s, including the
model build; `<=lim` counts runs within limit + 5 %), gap to the best known plan of any
solver ((J - J_best) / |J_best|, median and max, %), and the certified gap
((J - bound) / |J| with the solver's own proven lower bound, median and max, %; `-` when
the solver had no bound).
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import random
import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

if TYPE_CHECKING:
    from planner import PlanningProblem

SOLVERS = ("floe", "cpsat", "mtz-highs", "mtz-scip", "mtz-cpsat", "reference", "reflocal")
LOADS = ("quiet", "busy")


def make_problem(m: int, n: int, seed: int, time_limit_s: float) -> PlanningProblem:
    from planner import PlanningProblem, TargetEstimate, UavPose

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


def mtz_data(p: PlanningProblem) -> dict[str, Any]:
    from planner.instance import build_instance

    inst = build_instance(p)
    return {
        "m": inst.m,
        "n": inst.n,
        "tau": inst.tau,
        "mu": inst.mu,
        "d": inst.d.tolist(),
        "sigma": inst.sigma.tolist(),
    }


def floe_one(solver: str, task: dict[str, Any], args: argparse.Namespace) -> dict[str, Any]:
    from planner import PlanSolver
    from planner.solve import POSITION_MODEL_MAX_TARGETS

    m, n = parse_sizes(task["size"])[0]
    limit = args.reference_time if solver == "reference" else task["limit_s"]
    p = make_problem(m, n, task["seed"], limit)
    method = "auto"
    if solver == "cpsat":
        method = "position" if n <= POSITION_MODEL_MAX_TARGETS else "circuit"
    elif solver == "reference":
        method = "heuristic"
    if solver == "reflocal":
        return reflocal_one(p)
    t0 = time.perf_counter()
    c0 = time.thread_time()
    s = PlanSolver(p, num_workers=1, method=method)
    r = s.solve()
    wall = time.perf_counter() - t0
    cpu = time.thread_time() - c0
    return {
        "cpu_s": cpu,
        "lp_layers": s.lp.layers if s.lp is not None else None,
        "trace": s.trace,
        "proven": r.status == "optimal",
        "objective": r.objective,
        "bound": r.bound if solver != "reference" else None,
        "time_s": wall,
        "detail": r.solver,
        "limit_s": limit,
    }


def reflocal_one(p: PlanningProblem) -> dict[str, Any]:
    """The reference local search on the problem's numbers (benchmarks/reference_search.py);
    the plan's J by floe's evaluation of the objective."""
    from reference_search import ReferenceSearch

    from planner.instance import build_instance

    t0 = time.perf_counter()
    c0 = time.thread_time()
    inst = build_instance(p)  # the numbers: w, hop lengths, sigma (no search code)
    search = ReferenceSearch(
        inst.m,
        inst.arc_weight().tolist(),
        inst.hop.tolist(),
        inst.sigma.tolist(),
        1.0 - inst.tau,
    )
    routes = search.solve(p.time_limit_s - (time.perf_counter() - t0))
    wall = time.perf_counter() - t0
    cpu = time.thread_time() - c0
    return {
        "proven": False,
        "objective": inst.evaluate(routes)[0],
        "bound": None,
        "time_s": wall,
        "cpu_s": cpu,
        "detail": "reflocal",
        "limit_s": p.time_limit_s,
    }


def worker(args: argparse.Namespace) -> None:
    """Answer one JSON task per input line with one JSON row."""
    solve = None
    if args.worker.startswith("mtz-"):
        import planner_mtz

        solve = {
            "mtz-highs": planner_mtz.solve_highs,
            "mtz-scip": planner_mtz.solve_scip,
            "mtz-cpsat": planner_mtz.solve_cpsat,
        }[args.worker]
    else:
        from planner.solve import warm_up

        warm_up()
    print("ready", flush=True)
    for line in sys.stdin:
        task = json.loads(line)
        if solve is not None:
            from planner_mtz import MtzData

            proven, objective, bound, wall = solve(MtzData.from_dict(task["data"]), task["limit_s"])
            row = {"proven": proven, "objective": objective, "bound": bound, "time_s": wall}
            row.update(detail=args.worker, limit_s=task["limit_s"])
        else:
            row = floe_one(args.worker, task, args)
        row.update(solver=args.worker, size=task["size"], seed=task["seed"])
        print(json.dumps(row), flush=True)


def start_worker(solver: str, args: argparse.Namespace) -> subprocess.Popen[str]:
    cmd = [sys.executable, __file__, "--worker", solver]
    cmd += ["--reference-time", str(args.reference_time)]
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    if proc.stdout.readline().strip() != "ready":
        raise SystemExit(f"worker {solver} did not start")
    return proc


def ask(proc: subprocess.Popen[str], task: dict[str, Any]) -> dict[str, Any] | None:
    stdin: IO[str] | None = proc.stdin
    assert stdin is not None and proc.stdout is not None
    stdin.write(json.dumps(task) + "\n")
    stdin.flush()
    line = proc.stdout.readline()
    return json.loads(line) if line.startswith("{") else None


def main() -> None:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=(__doc__ or "").split("\n")[0])
    parser.add_argument("--sizes", default="1x10,1x16,3x10,5x20,10x50")
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--solvers", default="floe,mtz-highs,mtz-scip,mtz-cpsat")
    parser.add_argument("--time-limit", type=float, default=5.0, help="s, <= 30 targets")
    parser.add_argument("--time-limit-large", type=float, default=1.0, help="s, > 30 targets")
    parser.add_argument("--reference-time", type=float, default=30.0)
    parser.add_argument(
        "--mtz-max-targets",
        type=int,
        default=250,
        help="MTZ solvers skip larger sizes (their Python build alone exceeds the limit)",
    )
    parser.add_argument(
        "--mtz-seeds",
        type=int,
        default=None,
        help="MTZ solvers only on the first K seeds (they mostly run to the limit; default: all)",
    )
    parser.add_argument(
        "--busy",
        type=int,
        default=0,
        help="K busy loops beside the solvers for half of the runs (interleaved)",
    )
    parser.add_argument("--json", help="also write all rows to this file (JSON lines)")
    parser.add_argument("--worker", choices=SOLVERS, help=argparse.SUPPRESS)
    parser.add_argument("--report", help="only print the table of rows saved with --json")
    args = parser.parse_args()
    if args.report:
        lines = Path(args.report).read_text().splitlines()
        report([json.loads(line) for line in lines if line.strip()])
        return
    if args.worker:
        worker(args)
        return
    solvers = args.solvers.split(",")
    for solver in solvers:
        if solver not in SOLVERS:
            parser.error(f"unknown solver {solver}")
    procs = {s: start_worker(s, args) for s in solvers}
    rows: list[dict[str, Any]] = []
    out = open(args.json, "w") if args.json else None  # noqa: SIM115
    busy = [
        subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.busy)
    ]
    for loop in busy:
        os.kill(loop.pid, signal.SIGSTOP)
    loads = LOADS if busy else LOADS[:1]
    try:
        for m, n in parse_sizes(args.sizes):
            for seed in range(args.seeds):
                limit = limit_for(n, args)
                task: dict[str, Any] = {"size": f"{m}x{n}", "seed": seed, "limit_s": limit}
                if any(s.startswith("mtz-") for s in solvers) and n <= args.mtz_max_targets:
                    task["data"] = mtz_data(make_problem(m, n, seed, limit))
                for solver, load in itertools.product(solvers, loads):
                    signum = signal.SIGCONT if load == "busy" else signal.SIGSTOP
                    for loop in busy:
                        os.kill(loop.pid, signum)
                    if load == "busy":
                        time.sleep(0.2)  # the loops are running again
                    if solver.startswith("mtz-") and (
                        n > args.mtz_max_targets
                        or (args.mtz_seeds is not None and seed >= args.mtz_seeds)
                    ):
                        continue
                    if solver == "reference" and n <= 30:
                        continue
                    row = ask(procs[solver], task)
                    if row is None:
                        print(f"# {solver} gave no answer on {m}x{n} seed {seed}", file=sys.stderr)
                        procs[solver] = start_worker(solver, args)
                        continue
                    row["load"] = load
                    rows.append(row)
                    if out is not None:
                        out.write(json.dumps(row) + "\n")
                        out.flush()
            print(f"# {m}x{n} done", file=sys.stderr, flush=True)
    finally:
        for loop in busy:
            os.kill(loop.pid, signal.SIGCONT)
            loop.kill()
            loop.wait()
        for proc in procs.values():
            if proc.stdin is not None:
                proc.stdin.close()
            proc.wait(timeout=60)
        if out is not None:
            out.close()
    report(rows)


def _pct(values: list[float]) -> tuple[str, str]:
    """Median and max as text (an unknown value counts as inf); "-" if none is finite."""
    if not any(math.isfinite(v) for v in values):
        return "-", "-"
    med, top = (
        f"{v:.3f}" if math.isfinite(v) else "inf" for v in (statistics.median(values), max(values))
    )
    return med, top


def report(rows: list[dict[str, Any]]) -> None:
    """Table per size, solver and load (see the module docstring), then floe against the
    reference local search, instance by instance."""
    from planner.problem import plan_gap

    best: dict[tuple[str, int], float] = {}
    for r in rows:
        if r["objective"] is not None:
            key = (r["size"], r["seed"])
            best[key] = min(best.get(key, math.inf), r["objective"])
    print(
        f"{'size':>6} {'solver':>10} {'load':>5} {'limit_s':>7} {'proven':>7} {'med_s':>7} "
        f"{'max_s':>7} {'<=lim':>6} {'med_cpu':>7} {'med_gap%':>8} {'max_gap%':>8} "
        f"{'med_cert%':>9} {'max_cert%':>9}"
    )
    sizes = sorted({r["size"] for r in rows}, key=lambda t: parse_sizes(t)[0][::-1])
    solvers = list(dict.fromkeys(r["solver"] for r in rows))
    loads = [x for x in LOADS if any(r.get("load", "quiet") == x for r in rows)]
    for size, solver, load in itertools.product(sizes, solvers, loads):
        mine = [
            r for r in rows
            if r["size"] == size and r["solver"] == solver and r.get("load", "quiet") == load
        ]
        if not mine:
            continue
        times = [r["time_s"] for r in mine]
        cpus = [r["cpu_s"] for r in mine if r.get("cpu_s") is not None]
        within = sum(r["time_s"] <= 1.05 * r["limit_s"] for r in mine)
        gaps, certs = [], []
        for r in mine:
            ref = best.get((size, r["seed"]), math.nan)
            obj = r["objective"]
            if obj is None:
                gaps.append(math.inf)
                certs.append(math.inf)
                continue
            gaps.append(100.0 * (obj - ref) / max(abs(ref), 1e-12))
            cert = plan_gap(obj, r.get("bound"))
            certs.append(math.inf if cert is None else 100.0 * cert)
        proven = sum(bool(r["proven"]) for r in mine)
        g_med, g_max = _pct(gaps)
        c_med, c_max = _pct(certs)
        cpu = f"{statistics.median(cpus):.3f}" if cpus else "-"
        print(
            f"{size:>6} {solver:>10} {load:>5} {mine[0]['limit_s']:>7g} "
            f"{proven:>3}/{len(mine):<3} {statistics.median(times):>7.3f} {max(times):>7.3f} "
            f"{within:>3}/{len(mine):<2} {cpu:>7} {g_med:>8} {g_max:>8} {c_med:>9} {c_max:>9}"
        )
    pairs: dict[tuple[str, str], list[float]] = {}
    index = {(r["size"], r["seed"], r["solver"], r.get("load", "quiet")): r for r in rows}
    for (size, seed, solver, load), r in index.items():
        other = index.get((size, seed, "reflocal", load))
        if solver != "floe" or other is None or r["objective"] is None:
            continue
        j_ref = float(other["objective"])
        diff = 100.0 * (r["objective"] - j_ref) / max(abs(j_ref), 1e-12)
        pairs.setdefault((size, load), []).append(diff)
    if pairs:
        print("\nfloe against reflocal, same instance and load: (J_floe - J_ref) / |J_ref| in %"
              " (< 0: floe better)")
        print(f"{'size':>6} {'load':>5} {'n':>3} {'median':>8} {'max':>8} {'floe<=ref':>9}")
        for (size, load), diffs in sorted(
            pairs.items(), key=lambda kv: (parse_sizes(kv[0][0])[0][::-1], kv[0][1])
        ):
            ok = sum(d <= 1e-6 for d in diffs)
            print(
                f"{size:>6} {load:>5} {len(diffs):>3} {statistics.median(diffs):>8.3f} "
                f"{max(diffs):>8.3f} {ok:>5}/{len(diffs):<3}"
            )


if __name__ == "__main__":
    main()
