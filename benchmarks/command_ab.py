"""A ``gcs`` command's whole cost in fresh processes: this tree, another, and the floor.

    git archive <rev> | tar -x -C /tmp/old
    python benchmarks/command_ab.py --against-tree /tmp/old --rounds 10 --floor \\
        --mission-s 200 -- simulate --scenario paper-boat --uavs 3 --quiet --out OUT

Each round runs every case once, in an order that rotates from round to round so a shared
machine's load weighs on all alike. A tree's case is ``python -m groundstation.cli ARGS`` in
a fresh interpreter with ``PYTHONPATH`` set to the tree, so what a user waits for is all
counted: the interpreter's start, every import, the run and its output files. The token
``OUT`` in ARGS becomes a fresh folder per run. With ``--floor``, two more cases show what
no change to floe can remove: the interpreter alone (``python -c pass``) and the
interpreter with numpy (one BLAS thread, as ``gcs`` sets it). One unmeasured warm-up run of
each case first writes the trees' bytecode, as an installed package has it.

Figures per case: the median and minimum CPU (user + system of the child,
``getrusage(RUSAGE_CHILDREN)``) and wall; with ``--mission-s S`` also the mission seconds
per CPU second of the median (issue 30 asks a 200 s paper-boat ``gcs simulate`` for
1000x: 0.20 CPU-s), and the ratio of the trees' medians.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
"""This tree."""

FLOOR_CASES = {
    "floor: python -c pass": ["-c", "pass"],
    "floor: python -c 'import numpy'": ["-c", "import numpy"],
}


def _run(argv: list[str], env: dict[str, str], cwd: Path) -> tuple[float, float]:
    """(CPU s, wall s) of one child run to its end; a failing run stops the benchmark."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(argv, env=env, cwd=cwd, stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True, check=False)
    wall_s = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"command_ab: {' '.join(argv)} exited {done.returncode}: "
                         f"{done.stderr[-1500:]}")
    return (after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime, wall_s)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against-tree", type=Path, default=None, metavar="DIR",
                        help="another floe source tree to run the same command from")
    parser.add_argument("--rounds", type=int, default=10)
    parser.add_argument("--floor", action="store_true",
                        help="also time the interpreter alone and with numpy")
    parser.add_argument("--mission-s", type=float, default=None,
                        help="the run's mission seconds: print x real time in CPU")
    parser.add_argument("args", nargs=argparse.REMAINDER,
                        help="-- then the gcs arguments (OUT: a fresh output folder)")
    ns = parser.parse_args()
    args = ns.args[1:] if ns.args[:1] == ["--"] else ns.args
    if not args:
        parser.error("give the gcs command after --, e.g. -- plan problem.json")
    if ns.rounds < 1:
        parser.error("--rounds must be at least 1")
    trees = {"this tree": ROOT}
    if ns.against_tree is not None:
        if not (ns.against_tree / "groundstation" / "cli.py").is_file():
            parser.error(f"{ns.against_tree} is not a floe source tree")
        trees = {"other tree": ns.against_tree.resolve(), **trees}
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONDONTWRITEBYTECODE", "OPENBLAS_NUM_THREADS", "PYTHONPATH")}
    with tempfile.TemporaryDirectory(prefix="command-ab-") as scratch:
        cases: dict[str, tuple[list[str], dict[str, str], Path]] = {}
        for name, tree in trees.items():
            cases[name] = ([sys.executable, "-m", "groundstation.cli", *args],
                           {**env, "PYTHONPATH": str(tree)}, tree)
        if ns.floor:
            for name, argv in FLOOR_CASES.items():
                cases[name] = ([sys.executable, *argv], {**env, "OPENBLAS_NUM_THREADS": "1"},
                               Path(scratch))
        figures: dict[str, list[tuple[float, float]]] = {name: [] for name in cases}
        names = list(cases)
        count = 0
        for round_index in range(ns.rounds + 1):  # round 0: the unmeasured warm-up
            shift = round_index % len(names)
            for name in names[shift:] + names[:shift]:
                argv, case_env, cwd = cases[name]
                count += 1
                out = str(Path(scratch) / f"out-{count}")
                result = _run([out if a == "OUT" else a for a in argv], case_env, cwd)
                if round_index > 0:
                    figures[name].append(result)
            print(f"round {round_index}/{ns.rounds} done, load {os.getloadavg()[0]:.1f}"
                  if round_index else "warm-up done", file=sys.stderr, flush=True)
    print(f"gcs {' '.join(args)}: {ns.rounds} rounds, fresh processes, bytecode cached")
    print(f"{'case':<34} {'CPU med s':>9} {'CPU min s':>9} {'wall med s':>10}"
          + (f" {'x real time (CPU)':>17}" if ns.mission_s else ""))
    medians: dict[str, float] = {}
    for name, rows in figures.items():
        cpu = [c for c, _ in rows]
        medians[name] = statistics.median(cpu)
        line = (f"{name:<34} {medians[name]:9.3f} {min(cpu):9.3f} "
                f"{statistics.median([w for _, w in rows]):10.3f}")
        if ns.mission_s and not name.startswith("floor"):
            line += f" {ns.mission_s / medians[name]:16.0f}x"
        print(line)
    if "other tree" in medians:
        print(f"this tree / other tree, CPU medians: "
              f"{medians['this tree'] / medians['other tree']:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
