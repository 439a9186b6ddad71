"""Same results, bit for bit: ``gcs simulate`` of this tree against another source tree.

    git archive <commit> | tar -x -C /tmp/old
    python benchmarks/sim_identity.py --against-tree /tmp/old [--extended]
        [--run NAME[:SECONDS[:WIND]] ...] [--work DIR [--reuse]]

For each run (default: paper-boat and paper-boat-clutter for their 200 s, discovery and
ship-watch for 150 s; ``--extended`` adds paper-boat in a gusty wind of 10 m/s from the
west, the linear-model svalbard-2015 with its scripted events, the default scenario's event
replanning and loiters, and 1800 s of ship-watch with its launches and recoveries; 3 UAVs,
seed 0) both trees run ``gcs simulate --scenario S --uavs 3 --seed 0 --no-plots
[--duration D] [--wind W]`` in fresh interpreters (``PYTHONPATH`` set to the tree), and the
two ``journal.jsonl`` and
``metrics.json`` are compared record by record: every line parsed as JSON and written back
with sorted keys, so each float is compared through its shortest exact representation
(``repr``), that is bit for bit. The only fields left out are the measured times, which no
two runs share: ``solve_time_s`` (anywhere, a plan's or the metrics' summary of them),
``wall_time_s`` and ``realtime_factor``. Prints one line per scenario and file, the first
difference if any, and exits 1 when anything differs.

``--work DIR`` keeps the outputs (``DIR/reference/<run>``, ``DIR/this-tree/<run>``); with
``--reuse`` a reference tree's outputs already there are not computed again.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_RUNS = ("paper-boat", "paper-boat-clutter", "discovery:150", "ship-watch:150")
EXTENDED_RUNS = ("paper-boat:200:10,270,2", "svalbard-2015", "default", "ship-watch:1800")
VOLATILE = frozenset({"solve_time_s", "wall_time_s", "realtime_factor"})
"""Measured times: the only fields two runs of the same code do not share."""

_MAIN = (
    "import sys\n"
    "from groundstation.cli import main\n"
    "sys.exit(main(sys.argv[1:]))\n"
)


def masked(value: Any) -> Any:
    """``value`` with every VOLATILE key removed, at any depth."""
    if isinstance(value, dict):
        return {k: masked(v) for k, v in value.items() if k not in VOLATILE}
    if isinstance(value, list):
        return [masked(v) for v in value]
    return value


def canonical(line: str) -> str:
    """One JSON record, volatile fields removed, keys sorted, floats as ``repr``."""
    return json.dumps(masked(json.loads(line)), sort_keys=True)


def simulate(tree: Path, run: str, out: Path) -> None:
    """``gcs simulate`` of ``tree`` in a fresh interpreter for ``run``
    (``NAME[:SECONDS[:WIND]]``), into ``out``."""
    scenario, _, rest = run.partition(":")
    seconds, _, wind = rest.partition(":")
    args = ["simulate", "--scenario", scenario, "--uavs", "3", "--seed", "0", "--no-plots",
            "--quiet", "--out", str(out)]
    if seconds:
        args += ["--duration", seconds]
    if wind:
        args += ["--wind", wind]
    env = dict(os.environ, PYTHONPATH=str(tree))
    subprocess.run([sys.executable, "-c", _MAIN, *args], env=env, cwd=tree, check=True,
                   stdout=subprocess.DEVNULL, timeout=1800)


def first_difference(a: Path, b: Path) -> tuple[int, str, str] | None:
    """The first differing record of two JSON-lines files (1-based line, both texts), or
    None when every record is the same; a missing line compares as ``<end of file>``."""
    with a.open(encoding="utf-8") as fa, b.open(encoding="utf-8") as fb:
        line = 0
        while True:
            la, lb = fa.readline(), fb.readline()
            line += 1
            if not la and not lb:
                return None
            ca = canonical(la) if la else "<end of file>"
            cb = canonical(lb) if lb else "<end of file>"
            if ca != cb:
                return line, ca, cb


def compare(ref: Path, new: Path) -> list[str]:
    """Differences between two run folders (empty: identical)."""
    problems = []
    diff = first_difference(ref / "journal.jsonl", new / "journal.jsonl")
    if diff is not None:
        line, a, b = diff
        problems.append(f"journal.jsonl line {line}:\n  ref {a[:400]}\n  new {b[:400]}")
    m_ref = masked(json.loads((ref / "metrics.json").read_text(encoding="utf-8")))
    m_new = masked(json.loads((new / "metrics.json").read_text(encoding="utf-8")))
    if json.dumps(m_ref, sort_keys=True) != json.dumps(m_new, sort_keys=True):
        keys = sorted(k for k in set(m_ref) | set(m_new) if m_ref.get(k) != m_new.get(k))
        problems.append(f"metrics.json differs in {keys}")
    return problems


def main() -> int:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.split("\n\n")[0])
    parser.add_argument("--against-tree", type=Path, required=True, metavar="DIR")
    parser.add_argument("--run", action="append", default=None, metavar="NAME[:S[:WIND]]",
                        help="a scenario, its mission seconds and a --wind value (repeat; "
                        f"default: {' '.join(DEFAULT_RUNS)})")
    parser.add_argument("--extended", action="store_true",
                        help=f"also: {' '.join(EXTENDED_RUNS)}")
    parser.add_argument("--work", type=Path, default=None, help="keep the outputs here")
    parser.add_argument("--reuse", action="store_true",
                        help="reuse the reference tree's outputs already in --work")
    args = parser.parse_args()
    runs = list(args.run or DEFAULT_RUNS) + (list(EXTENDED_RUNS) if args.extended else [])
    ref_tree = args.against_tree.resolve()
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work.resolve() if args.work is not None else Path(tmp)
        failed = False
        for run in runs:
            folder = run.replace(":", "_").replace(",", "-")
            ref = work / "reference" / folder
            new = work / "this-tree" / folder
            if not (args.reuse and (ref / "metrics.json").exists()):
                simulate(ref_tree, run, ref)
            simulate(ROOT, run, new)
            problems = compare(ref, new)
            records = sum(1 for _ in (new / "journal.jsonl").open(encoding="utf-8"))
            if problems:
                failed = True
                print(f"{run}: DIFFERENT")
                for p in problems:
                    print("  " + p)
            else:
                print(f"{run}: identical ({records} journal records, metrics.json)",
                      flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
