"""Where a simulation run's CPU goes: named functions timed inclusively, in-process.

    python benchmarks/sim_parts.py [--runs 10] [--scenario paper-boat]
        [module:Qual.name ...]

e.g. ``python benchmarks/sim_parts.py 10 observer.observer:Observer.measure
groundstation.core.decision:DecisionCore.view``. One warm-up run (seed 999), then
``--runs`` runs (3 UAVs, seeds 0..N-1, the scenario's duration, no journal, no plots: what a
campaign worker computes after its imports). Each named function is wrapped (outermost call
only, ``time.perf_counter``), so its line gives the mean time per run and per call, its
share of the runs' wall time and its calls a run; the wrappers' own cost is in the figures,
so compare them between trees (run each tree in turn, ``PYTHONPATH`` set to it), not with
other benchmarks. Without names it prints the CPU per run only, and is also what to run
under a sampling profiler::

    py-spy record -r 250 -f raw -o out.txt -- python benchmarks/sim_parts.py --runs 30
"""

from __future__ import annotations

import argparse
import functools
import importlib
import time
from collections.abc import Callable
from typing import Any


def _wrap(spec: str, totals: dict[str, list[float]]) -> None:
    module_name, _, qualname = spec.partition(":")
    if not qualname:
        raise SystemExit(f"sim_parts: {spec!r} is not module:Qual.name")
    owner: Any = importlib.import_module(module_name)
    parts = qualname.split(".")
    for part in parts[:-1]:
        owner = getattr(owner, part)
    function: Callable[..., Any] = getattr(owner, parts[-1])
    totals[qualname] = [0.0, 0.0]
    depth = [0]

    @functools.wraps(function)
    def timed(*args: Any, **kwargs: Any) -> Any:
        if depth[0]:
            return function(*args, **kwargs)
        depth[0] += 1
        start_s = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            entry = totals[qualname]
            entry[0] += time.perf_counter() - start_s
            entry[1] += 1
            depth[0] -= 1

    setattr(owner, parts[-1], timed)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--scenario", default="paper-boat")
    parser.add_argument("functions", nargs="*", help="module:Qual.name to time")
    args = parser.parse_args()
    totals: dict[str, list[float]] = {}
    for spec in args.functions:
        _wrap(spec, totals)
    from groundstation.runners.simulate.simulator import SimulationOptions, run_simulation
    from world.scenario import load_scenario

    scenario = load_scenario(args.scenario)
    run_simulation(scenario, SimulationOptions(seed=999, uavs=3, snapshot_times_s=(0.0,)))
    for entry in totals.values():
        entry[0] = entry[1] = 0.0
    runs = max(1, args.runs)
    wall_start_s, cpu_start_s = time.perf_counter(), time.process_time()
    for seed in range(runs):
        run_simulation(scenario, SimulationOptions(seed=seed, uavs=3, snapshot_times_s=(0.0,)))
    wall_s = (time.perf_counter() - wall_start_s) / runs
    cpu_s = (time.process_time() - cpu_start_s) / runs
    print(f"{args.scenario}, 3 UAVs, {runs} runs: {cpu_s:.4f} CPU-s a run, "
          f"{wall_s * 1e3:.1f} ms of wall a run")
    for name, (spent_s, calls) in totals.items():
        per_call_us = spent_s / calls * 1e6 if calls else 0.0
        share = 100 * spent_s / runs / wall_s
        print(f"  {name:45s} {spent_s / runs * 1e3:7.1f} ms a run {share:5.1f} %"
              f" {calls / runs:8.0f} calls a run {per_call_us:7.1f} us a call")


if __name__ == "__main__":
    main()
