"""The simulation loop's CPU, this tree against another, in two warm interpreters in turn.

    git archive <commit> | tar -x -C /tmp/old
    python benchmarks/sim_loop_ab.py --against-tree /tmp/old [--scenario paper-boat]
        [--duration SECONDS] [--rounds 15]

Each tree gets one long-lived interpreter (``PYTHONPATH`` set to it) that has imported the
simulator and run the scenario once (3 UAVs, seed 0, its duration unless ``--duration``);
then they are asked for one run each, in turn (the order alternates every round), so a
shared machine's load weighs on both alike. Prints the minimum and the median of each
tree's CPU seconds per run (``time.process_time`` around ``run_simulation``, no journal,
no plots: what a campaign worker spends after its imports) and their ratios.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

from tree_ab import ROOT, interleaved_rounds, ratio_line, tree_children

_CHILD = """
import sys, time
from world.scenario import load_scenario
from groundstation.runners.simulate.simulator import SimulationOptions, run_simulation
name, seconds = sys.argv[1], sys.argv[2]
scenario = load_scenario(name)
options = SimulationOptions(seed=0, uavs=3, duration_s=float(seconds) if seconds else None)
run_simulation(scenario, options)
print("ready", flush=True)
for _ in sys.stdin:
    c0 = time.process_time()
    run_simulation(scenario, options)
    print(time.process_time() - c0, flush=True)
"""


def main() -> int:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.split("\n\n")[0])
    parser.add_argument("--against-tree", type=Path, required=True, metavar="DIR")
    parser.add_argument("--scenario", default="paper-boat")
    parser.add_argument("--duration", default="", help="mission seconds (default: its own)")
    parser.add_argument("--rounds", type=int, default=15)
    args = parser.parse_args()
    trees = {"other tree": args.against_tree.resolve(), "this tree": ROOT}
    child_args = {name: [args.scenario, args.duration] for name in trees}
    with tree_children(trees, _CHILD, child_args) as procs:
        cpu = interleaved_rounds(procs, args.rounds)
    span = f"{args.duration} s" if args.duration else "its duration"
    print(f"{args.scenario}, 3 UAVs, {span}, seed 0: loop CPU per run, {args.rounds} rounds")
    for name, values in cpu.items():
        print(f"   {name:<12} min {min(values):.3f} s, median {statistics.median(values):.3f} s")
    print(ratio_line(cpu["other tree"], cpu["this tree"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
