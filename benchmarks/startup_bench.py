"""Start-up and simulation-loop benchmark: today's code beside what it replaced.

    nice -n 10 python benchmarks/startup_bench.py [--rounds 7] [--bytecode cached|none]
        [--json benchmarks/startup_bench.json]
    git archive <commit> | tar -x -C /tmp/old
    nice -n 10 python benchmarks/startup_bench.py --rounds 5 --against-tree /tmp/old

Every section runs its alternatives interleaved, round by round, so a busy host slows them
alike; figures are medians over the rounds, CPU (user + system) and wall side by side.

1. Process start-up (fresh interpreters; CPU from ``resource.getrusage(RUSAGE_CHILDREN)``,
   wall around the child): ``gcs plan`` on a 3x10 problem and ``gcs simulate --no-plots``
   (paper-boat, 3 UAVs, its 200 s; with and without its journal). The "before" cases
   re-create the old imports in the same process first: ``ortools.sat`` (which the
   planner imported at start-up), matplotlib (which ``gcs simulate`` imported even without
   plots), filterpy's ``KalmanFilter`` (scipy.stats) and ``scipy.optimize`` (GOSPA's,
   through the discovery module) that every paper-boat run imported until issue 30, and
   numpy loaded before ``gcs`` could set OPENBLAS_NUM_THREADS. ``--bytecode cached``
   (default) runs with a bytecode cache in a temporary folder, as an installed package
   does; ``none`` compiles floe's modules at every start (a checkout with
   PYTHONDONTWRITEBYTECODE=1).
2. Observer prediction, one 0.1 s grid step of 10 and of 50 tracks (in this process, CPU):
   per-track ``predict`` (before), the closed form on Python floats per track (the
   alternative not taken), and today's batched product. Each is checked against filterpy's
   own ``KalmanFilter.predict`` over random states and steps: largest relative difference
   and whether every number is bit-for-bit equal.
3. The simulation loop in this process: paper-boat, 3 UAVs, 200 mission s, seed 0, with
   the observer predicting per track (before) and batched (now); CPU and wall seconds and
   the real time factors (200 s / CPU s, and / wall s). ``--against-tree DIR`` runs only
   this loop, in fresh interpreters alternating between the source tree in DIR and this
   one (CPU and wall of the loop, and of the whole process, imports included).
``--quick`` runs one round of sections 1 and 3 only (a smoke run, seconds).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
import timeit
from collections.abc import Callable
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np
from filterpy.kalman import KalmanFilter  # the reference (the test extra), not floe's path

from groundstation.runners.simulate.simulator import SimulationOptions, run_simulation
from observer import Observer, ObserverConfig
from observer.kalman_track import (
    KalmanBatch,
    KalmanTrack,
    process_noise,
    transition,
)
from world.scenario import load_scenario

SIM_ARGS = "['simulate', '--scenario', 'paper-boat', '--uavs', '3', '--no-plots', " \
    "'--quiet', '--out', OUT]"
OLD_KALMAN = "import filterpy.kalman\nimport scipy.optimize\n"
"""What every Kalman run imported before issue 30 (filterpy's filter, GOSPA's scipy)."""
MAIN = "from groundstation.cli import main\n"


def _problem_3x10(path: Path) -> None:
    uavs = [{"id": f"u{k}", "x": 1500.0, "y": 0.0, "heading": h}
            for k, h in enumerate((0.0, math.pi / 2, math.pi))]
    targets = [{"id": f"t{k}", "x": 150.0 * k, "y": 1400.0 - 130.0 * k, "sigma": 5.0 + 3.0 * k}
               for k in range(10)]
    path.write_text(json.dumps({"uavs": uavs, "targets": targets, "turn_radius": 105.0}))


def _startup_cases(problem: Path, out: Path) -> dict[str, str]:
    plan = MAIN + f"main(['plan', {str(problem)!r}])\n"
    sim = MAIN + f"OUT = {str(out)!r}\nmain({SIM_ARGS})\n"
    sim_no_journal = sim.replace("'--quiet',", "'--quiet', '--no-journal',")
    return {
        "interpreter only (python -c pass)": "pass\n",
        "import numpy": "import numpy\n",
        "import numpy, filterpy.kalman": "import numpy\nimport filterpy.kalman\n",
        "gcs plan 3x10, before": "import ortools.sat.python.cp_model\n" + plan,
        "gcs plan 3x10, lazy CP-SAT only": "import numpy\n" + plan,
        "gcs plan 3x10, now": plan,
        "gcs simulate --no-plots --no-journal, before": (
            "import ortools.sat.python.cp_model\n"
            "import groundstation.runners.simulate.plots\n" + OLD_KALMAN + sim_no_journal
        ),
        "gcs simulate --no-plots --no-journal, with filterpy": OLD_KALMAN + sim_no_journal,
        "gcs simulate --no-plots --no-journal, now": sim_no_journal,
        "gcs simulate --no-plots, with filterpy": OLD_KALMAN + sim,
        "gcs simulate --no-plots, now": sim,
    }


def _child(code: str, env: dict[str, str]) -> tuple[float, float]:
    """CPU (user + system) and wall seconds of a fresh interpreter running ``code``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    w0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], env=env, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, timeout=300)
    wall_s = time.perf_counter() - w0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall_s


def bench_startup(rounds: int, bytecode: str, tmp: Path) -> dict[str, dict[str, float]]:
    """Median CPU and wall seconds per case (``cpu_s``, ``wall_s``)."""
    problem = tmp / "p3x10.json"
    _problem_3x10(problem)
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    env["PYTHONPATH"] = str(Path(__file__).resolve().parent.parent)
    if bytecode == "cached":
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = str(tmp / "pycache")
    else:
        env["PYTHONDONTWRITEBYTECODE"] = "1"
    cases = _startup_cases(problem, tmp / "sim")
    for code in cases.values():  # warm the bytecode cache and the file cache
        _child(code, env)
    cpu: dict[str, list[float]] = {name: [] for name in cases}
    wall: dict[str, list[float]] = {name: [] for name in cases}
    for _ in range(rounds):
        for name, code in cases.items():
            c, w = _child(code, env)
            cpu[name].append(c)
            wall[name].append(w)
    return {name: {"cpu_s": statistics.median(cpu[name]), "wall_s": statistics.median(wall[name])}
            for name in cases}


# --- 2. observer prediction -------------------------------------------------------------
def _tracks(n: int, seed: int, h: float = 0.1) -> list[KalmanTrack]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        tr = KalmanTrack(0.0, rng.normal(0, 500, 4).tolist(), [1.0] * 4, 0.1, h)
        m = rng.normal(size=(4, 4)) * 10.0
        tr.kf.P = m @ m.T
        tr.x_view, tr.p_view = tr.kf.x, tr.kf.P
        out.append(tr)
    return out


def _closed_form(p: list[float], h: float, q: float) -> list[float]:
    """One CV step on a row-major 4x4 list: blocks A, B, C, D of (pos, vel) per axis pair,
    P' = [[A + h(B + C) + h^2 D, B + h D], [C + h D, D]] + Q(h), written as F P F'."""
    g = p[:]  # G = F P: rows 0, 1 gain h * rows 2, 3
    for j in range(4):
        g[j] = p[j] + h * p[8 + j]
        g[4 + j] = p[4 + j] + h * p[12 + j]
    r = g[:]  # R = G F': columns 0, 1 gain h * columns 2, 3
    for i in range(4):
        r[4 * i] = g[4 * i] + h * g[4 * i + 2]
        r[4 * i + 1] = g[4 * i + 1] + h * g[4 * i + 3]
    r[10] += q * h  # Q(h) = diag(0, 0, q h, q h) for one step
    r[15] += q * h
    return r


class _ClosedFormTracks:
    """The alternative not taken: the covariance as 16 Python floats per track."""

    def __init__(self, tracks: list[KalmanTrack]) -> None:
        self.p = [tr.kf.P.ravel().tolist() for tr in tracks]
        self.x = [tr.kf.x.ravel().tolist() for tr in tracks]
        self.sigma = [0.0] * len(tracks)

    def step(self, h: float, q: float) -> None:
        for k, p in enumerate(self.p):
            self.p[k] = p = _closed_form(p, h, q)
            x = self.x[k]
            self.x[k] = [x[0] + h * x[2], x[1] + h * x[3], x[2], x[3]]
            self.sigma[k] = p[0] + p[5]


def _per_track(obs: Observer) -> Callable[[float], None]:
    """The observer's predict as it was: each track on its own (filterpy predict)."""
    def predict_to(t_s: float) -> None:
        for target_id, track in obs._tracks.items():
            if t_s > track.t_s:
                track.predict_to(t_s)
                obs._check_lost(target_id)
    return predict_to


def _observer(n: int) -> Observer:
    obs = Observer(ObserverConfig())
    for k in range(n):
        obs.add_target(f"T{k}", 0.0, 100.0 * k, 50.0, vx_m_s=1.0, vy_m_s=-0.5, sigma0=20.0)
    return obs


def _accuracy(seed: int = 11, cases: int = 300) -> dict[str, tuple[float, bool]]:
    """Largest relative difference from filterpy's predict, and bit-for-bit equality."""
    rng = np.random.default_rng(seed)
    worst = {"closed form (Python floats)": 0.0, "batched (now)": 0.0}
    equal = dict.fromkeys(worst, True)
    for _ in range(cases):
        h = float(rng.choice([0.1, rng.uniform(0.01, 5.0)]))
        tracks = _tracks(int(rng.integers(1, 12)), int(rng.integers(1 << 30)), h)
        ref = []
        for tr in tracks:  # filterpy's own filter, the reference
            kf = KalmanFilter(dim_x=4, dim_z=2)
            kf.x, kf.P = tr.kf.x.copy(), tr.kf.P.copy()
            kf.predict(F=transition(h), Q=process_noise(tr.q_per_s, h))
            ref.append((kf.x, kf.P))
        cf = _ClosedFormTracks(tracks)
        cf.step(h, tracks[0].q_per_s)
        KalmanBatch(h).predict_to(tracks, h)
        for k, (x, p) in enumerate(ref):
            pairs = {
                "closed form (Python floats)": (np.array(cf.p[k]).reshape(4, 4),
                                                np.array(cf.x[k]).reshape(4, 1), p, x),
                "batched (now)": (tracks[k].kf.P, tracks[k].kf.x, p, x),
            }
            for name, (got_p, got_x, want_p, want_x) in pairs.items():
                scale = float(np.max(np.abs(want_p)))  # relative to the matrix's largest
                worst[name] = max(worst[name], float(np.max(np.abs(got_p - want_p))) / scale)
                equal[name] = (equal[name] and bool(np.array_equal(got_p, want_p))
                               and bool(np.array_equal(got_x, want_x)))
    return {name: (worst[name], equal[name]) for name in worst}


def bench_observer(rounds: int, n: int = 10) -> dict[str, float]:
    """Microseconds per 0.1 s step of n tracks."""
    before, now = _observer(n), _observer(n)
    old_predict = _per_track(before)
    cf = _ClosedFormTracks(_tracks(n, 1))
    clock = {"before": 0, "now": 0}

    def run_before() -> None:
        clock["before"] += 1
        old_predict(clock["before"] * 0.1)

    def run_now() -> None:
        clock["now"] += 1
        now.predict_to(clock["now"] * 0.1)

    cases: dict[str, Callable[[], None]] = {
        "per-track predict (before)": run_before,
        "closed form, Python floats per track": lambda: cf.step(0.1, 0.1),
        "batched product (now)": run_now,
    }
    samples: dict[str, list[float]] = {name: [] for name in cases}
    number = 2000
    for _ in range(rounds):
        for name, fn in cases.items():
            samples[name].append(timeit.timeit(fn, timer=time.process_time, number=number)
                                 / number * 1e6)
    return {name: statistics.median(v) for name, v in samples.items()}


# --- 3. the simulation loop -------------------------------------------------------------
def bench_loop(rounds: int) -> dict[str, dict[str, float]]:
    scenario = load_scenario("paper-boat")
    options = SimulationOptions(seed=0, uavs=3)
    new_predict = Observer.predict_to

    def old_predict(self: Observer, t_s: float) -> None:
        _per_track(self)(t_s)

    variants: dict[str, Callable[[Observer, float], None]] = {
        "per-track predict (before)": old_predict,
        "batched predict (now)": new_predict,
    }
    cpu: dict[str, list[float]] = {name: [] for name in variants}
    wall: dict[str, list[float]] = {name: [] for name in variants}
    journals: dict[str, Any] = {}
    run_simulation(scenario, options)  # warm-up
    try:
        for _ in range(rounds):
            for name, predict in variants.items():
                setattr(Observer, "predict_to", predict)  # noqa: B010
                c0, w0 = time.process_time(), time.perf_counter()
                result = run_simulation(scenario, options)
                cpu[name].append(time.process_time() - c0)
                wall[name].append(time.perf_counter() - w0)
                journals[name] = result.metrics["uncertainty_series"]
    finally:
        setattr(Observer, "predict_to", new_predict)  # noqa: B010
    same = len({json.dumps(v) for v in journals.values()}) == 1
    duration = scenario.duration_s
    out = {}
    for name in variants:
        c, w = statistics.median(cpu[name]), statistics.median(wall[name])
        out[name] = {"cpu_s": c, "wall_s": w, "x_realtime_cpu": duration / c,
                     "x_realtime_wall": duration / w, "same_uncertainty_series": same}
    return out


_LOOP_CODE = """
import resource, time
t0 = time.perf_counter()
from world.scenario import load_scenario
from groundstation.runners.simulate.simulator import SimulationOptions, run_simulation
scenario, options = load_scenario("paper-boat"), SimulationOptions(seed=0, uavs=3)
run_simulation(scenario, options)
u = resource.getrusage(resource.RUSAGE_SELF)
first_cpu_s, first_wall_s = u.ru_utime + u.ru_stime, time.perf_counter() - t0
c0, w0 = time.process_time(), time.perf_counter()
run_simulation(scenario, options)
print(time.process_time() - c0, time.perf_counter() - w0, first_cpu_s, first_wall_s)
"""

_TREE_FIGURES = ("loop_cpu_s", "loop_wall_s", "process_cpu_s", "process_wall_s")


def bench_against_tree(rounds: int, tree: Path) -> dict[str, dict[str, float]]:
    """Section 3 against another source tree (``git archive <commit> | tar -x -C DIR``):
    fresh interpreters alternate between DIR and this tree; medians of the loop's CPU and
    wall seconds (a second run, warm) and of the process up to the end of its first run
    (interpreter, imports and one run: what a ``gcs simulate`` pays)."""
    here = Path(__file__).resolve().parent.parent
    samples: dict[str, list[list[float]]] = {str(tree): [], "this tree": []}
    for _ in range(rounds):
        for name, root in ((str(tree), tree), ("this tree", here)):
            env = dict(os.environ, PYTHONPATH=str(root))
            done = subprocess.run([sys.executable, "-c", _LOOP_CODE], env=env, cwd=root,
                                  capture_output=True, text=True, check=True, timeout=300)
            samples[name].append([float(v) for v in done.stdout.split()[-4:]])
    return {name: {key: statistics.median(row[k] for row in v)
                   for k, key in enumerate(_TREE_FIGURES)} for name, v in samples.items()}


def main() -> int:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--bytecode", choices=("cached", "none"), default="cached")
    parser.add_argument("--json", type=Path, default=None, help="also write the figures here")
    parser.add_argument("--against-tree", type=Path, default=None, metavar="DIR",
                        help="only: the simulation loop of the tree in DIR against this one")
    parser.add_argument("--quick", action="store_true",
                        help="one round of sections 1 and 3 only (a smoke run)")
    args = parser.parse_args()
    if args.quick:
        args.rounds = 1
    if args.against_tree is not None:
        figures = bench_against_tree(args.rounds, args.against_tree.resolve())
        print("gcs simulate in fresh interpreters: paper-boat, 3 UAVs, 200 s, seed 0 "
              f"(median of {args.rounds})")
        for name, f in figures.items():
            print(f"   {name:<32} loop CPU {f['loop_cpu_s']:.3f} s "
                  f"({200.0 / f['loop_cpu_s']:5.0f}x), wall {f['loop_wall_s']:.3f} s; "
                  f"process to the end of a first run CPU {f['process_cpu_s']:.3f} s "
                  f"({200.0 / f['process_cpu_s']:5.0f}x), wall {f['process_wall_s']:.3f} s")
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        startup = bench_startup(args.rounds, args.bytecode, Path(tmp))
    print(f"1. process start-up, median of {args.rounds} rounds, bytecode {args.bytecode}")
    print(f"   {'':<52} {'CPU':>8} {'wall':>8}")
    for name, f in startup.items():
        print(f"   {name:<52} {f['cpu_s'] * 1000:5.0f} ms {f['wall_s'] * 1000:5.0f} ms")
    if args.quick:
        loop = bench_loop(1)
        for name, r in loop.items():
            print(f"3. {name:<40} CPU {r['cpu_s']:.3f} s, wall {r['wall_s']:.3f} s")
        return 0
    accuracy = _accuracy()
    observer = {n: bench_observer(args.rounds, n) for n in (10, 50)}
    labels = {"closed form, Python floats per track": "closed form (Python floats)",
              "batched product (now)": "batched (now)"}
    for n, figures in observer.items():
        print(f"2. observer prediction, {n} tracks, one 0.1 s grid step (CPU per step; "
              "wall: a step is pure computation, the same)")
        for name, us in figures.items():
            acc = accuracy.get(labels.get(name, ""))
            note = "(the reference)" if acc is None else (
                f"max rel. diff. from filterpy {acc[0]:.1e}, bit-identical: "
                f"{'yes' if acc[1] else 'no'}")
            print(f"   {name:<40} {us:7.1f} us  {note}")
    loop = bench_loop(args.rounds)
    print("3. gcs simulate loop in-process: paper-boat, 3 UAVs, 200 s, seed 0 (median)")
    for name, r in loop.items():
        print(f"   {name:<40} CPU {r['cpu_s']:.3f} s = {r['x_realtime_cpu']:5.0f}x real time"
              f" (wall {r['wall_s']:.3f} s = {r['x_realtime_wall']:5.0f}x)")
    same = next(iter(loop.values()))["same_uncertainty_series"]
    print(f"   same uncertainty series both ways: {same}")
    if args.json is not None:
        args.json.write_text(json.dumps({
            "rounds": args.rounds, "bytecode": args.bytecode, "startup": startup,
            "observer_step_us": {f"{n} tracks": v for n, v in observer.items()},
            "observer_accuracy": {k: {"max_rel_diff": v[0], "bit_identical": v[1]}
                                  for k, v in accuracy.items()},
            "simulation_loop": loop,
        }, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
