"""The first leg in the real wind (issue 25, part 2): how late each vehicle's first leg
arrives, and which of two first-wind strategies does better.

    nice -n 10 python benchmarks/first_leg.py --json benchmarks/first_leg.json
    python benchmarks/first_leg.py --report benchmarks/first_leg.json

Every run is ``gcs run --vehicles sim:3 --scenario paper-boat`` in this process, through
real MAVLink with the built-in simulator (launched from the ground: the climb-out, the
join, the first plan before the vehicles' first WIND estimate, as docs/wind.md "The first
leg" tells), at a steady wind of ``--wind`` m/s from each of ``--directions``, seeds
``--first-seed``.. ``--first-seed + --seeds - 1``. The wind is

* ``known``: given to floe as ``--wind`` (its fallback is right from the start), or
* ``unknown``: flown by the vehicles, but floe's fallback is still air until their
  estimates arrive (the built-in simulator is given the wind directly).

Strategies (``--strategies``, interleaved: every strategy runs each (seed, direction) in
turn, so a slower stretch of the shared machine hits them alike):

* ``none``: no wind replan (``planner.wind_replan: false``);
* ``replan``: floe's rule (docs/wind.md, "The first leg"): when the first estimate arrives
  or the wind moves by more than ``wind_replan_m_s``, legs whose predicted arrival moves
  by more than ``wind_replan_margin_s`` are replanned even under commitment;
* ``join-after-wind``: a prototype of the alternative, not kept in floe: a vehicle joins
  the plan (its ``VehicleJoined``) only with its first ``WindReport`` (wind replan off).
  It is patched into the vehicle controller in this process only.

``before`` is not a strategy of this code: it labels (``--label before``) the runs of a
checkout of the code before the change, whose only behaviour runs under ``replan``'s
configuration (docs/wind.md, "The first leg", has the commands).

``--policy commit`` (default: ``--replan event --commit``, the issue's setting; paper-boat's
5 s period stays, and with commitment it plans only idle vehicles) or ``scenario``
(paper-boat's own: every 5 s, no commitment).

Per (wind knowledge, strategy) it prints, pooled over seeds and directions: the first
legs' |arrival error| (median / p90 / max, counted / runs x 3), the later legs' (median /
p90), the mean uncertainty (mean over runs; metrics.json ``mean_uncertainty``) and, paired
per (seed, direction) against the first strategy, the geometric mean of the ratio with
its 95 % t interval; the first visit of each vehicle (median mission time) and the uploads.
``--json FILE`` keeps every run's figures; ``--report FILE...`` prints them again.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import statistics
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from groundstation.core.arrivals import percentile

STRATEGIES = ("before", "none", "replan", "join-after-wind")


@contextmanager
def join_after_wind() -> Iterator[None]:
    """Prototype: hold a vehicle's ``VehicleJoined`` until its first ``WindReport`` (then
    send both, in that order, so the core's estimate counts it before the next plan)."""
    from groundstation.core import events as ev
    from groundstation.vehicle import controller_io
    from groundstation.vehicle.controller import VehicleController

    joined, core = VehicleController.joined, VehicleController._core

    def held_joined(self: Any, how: str) -> None:
        self._held_join = True
        joined(self, how)

    def held_core(self: Any, event: ev.Event) -> None:
        if getattr(self, "_held_join", False):
            if isinstance(event, ev.VehicleJoined | ev.Telemetry):
                return
            if isinstance(event, ev.WindReport):
                self._held_join = False
                pose = self._pose(joined=True)
                if pose is not None:
                    self._out.append(controller_io.CoreEvent(pose))
        core(self, event)

    VehicleController.joined = held_joined  # type: ignore[method-assign]
    VehicleController._core = held_core  # type: ignore[method-assign]
    try:
        yield
    finally:
        VehicleController.joined = joined  # type: ignore[method-assign]
        VehicleController._core = core  # type: ignore[method-assign]


def run_once(seed: int, from_deg: float, speed_m_s: float, known: bool, strategy: str,
             duration_s: float, policy: str, scenario: str) -> dict[str, Any]:
    """One ``gcs run`` in this process; its figures."""
    from groundstation.commands.embedded_sim import build_embedded_sim
    from groundstation.commands.run import build_config
    from groundstation.daemon.startup import run_daemon
    from world.wind import WindSpec

    flown = WindSpec(speed_m_s, from_deg)
    with tempfile.TemporaryDirectory(prefix="first_leg_") as tmp:
        config_file = Path(tmp) / "config.yaml"
        lines = ["planner:"]
        if strategy != "replan":
            lines.append("  wind_replan: false")
        config_file.write_text("\n".join(lines) + "\n" if len(lines) > 1 else "{}\n")
        args = ["--config", str(config_file), "--vehicles", "sim:3", "--scenario", scenario,
                "--duration", str(duration_s), "--seed", str(seed), "--run-dir", tmp,
                "--http", "off", "--detections", "off", "--status", "quiet"]
        if known:
            args += ["--wind", f"{speed_m_s:g},{from_deg:g}"]
        if policy == "commit":
            args += ["--replan", "event", "--commit"]
        config = build_config(args)

        def embedded(c: Any, s: Any, keys: Any, wind: Any) -> Any:
            return build_embedded_sim(c, s, keys, flown)

        wall = time.perf_counter()
        patch = join_after_wind() if strategy == "join-after-wind" else _nothing()
        with patch:
            daemon = asyncio.run(run_daemon(config, embedded=embedded,
                                            print_fn=lambda _: None, install_signals=False))
        wall = time.perf_counter() - wall
        metrics = json.loads((daemon.run_dir / "metrics.json").read_text())
        journal = [json.loads(line) for line in (daemon.run_dir / "journal.jsonl").open()]
    arrivals = daemon.metrics.arrivals
    first_visit: dict[str, float] = {}
    for visit in metrics["visits"]:
        first_visit.setdefault(str(visit["vehicle"]), visit["t_s"])
    return {
        "seed": seed, "from_deg": from_deg, "speed_m_s": speed_m_s, "known": known,
        "strategy": strategy, "policy": policy, "duration_s": duration_s,
        "first_errors_s": [round(e, 3) for e in arrivals.first_errors_s],
        "later_errors_s": [round(e, 3) for e in arrivals.later_errors_s],
        "arrivals": metrics["arrivals"],
        "mean_uncertainty": metrics["mean_uncertainty"],
        "visits": len(metrics["visits"]),
        "first_visit_s": sorted(first_visit.values()),
        "uploads": sum(1 for e in journal if e["event"] == "upload" and e.get("ok")
                       and e.get("purpose") == "target"),
        "wind_replans": sum(1 for e in journal if e["event"] == "wind_replan"),
        "joined_s": sorted(e["t"] for e in journal if e["event"] == "input"
                           and e.get("kind") == "VehicleJoined"),
        "cruise": sorted({(e.get("source"), e.get("speed_m_s")) for e in journal
                          if e["event"] == "cruise_speed"}),
        "wall_s": round(wall, 1),
    }


@contextmanager
def _nothing() -> Iterator[None]:
    yield


def _errors(values: Sequence[float]) -> str:
    if not values:
        return "-"
    a = [abs(v) for v in values]
    return f"{statistics.median(a):.1f} / {percentile(a, 0.9):.1f} / {max(a):.1f}"


def ratio_interval(ratios: Sequence[float]) -> str:
    """Geometric mean of paired ratios as a change in %, with its 95 % t interval."""
    logs = [math.log(r) for r in ratios if r > 0]
    if len(logs) < 2:
        return "-"
    from scipy import stats

    mean = statistics.fmean(logs)
    half = stats.t.ppf(0.975, len(logs) - 1) * statistics.stdev(logs) / math.sqrt(len(logs))
    f: Callable[[float], float] = lambda x: (math.exp(x) - 1) * 100  # noqa: E731
    return f"{f(mean):+.1f} % [{f(mean - half):+.1f}, {f(mean + half):+.1f}]"


def report(runs: Sequence[dict[str, Any]]) -> None:
    """One table per (policy, wind, knowledge); a row per strategy."""
    keys = sorted({(r["policy"], r["speed_m_s"], r["known"]) for r in runs})
    for policy, speed, known in keys:
        group = [r for r in runs if (r["policy"], r["speed_m_s"], r["known"]) == (
            policy, speed, known)]
        strategies = [s for s in STRATEGIES if any(r["strategy"] == s for r in group)]
        cells = sorted({(r["seed"], r["from_deg"]) for r in group})
        print(f"\n{speed:g} m/s, wind {'known (--wind)' if known else 'unknown'}, policy "
              f"{policy}: {len(cells)} (seed, direction) cells, directions "
              f"{sorted({r['from_deg'] for r in group})}")
        print("| strategy | first legs: abs err median / p90 / max s | counted | bias s | "
              "later legs: median / p90 / max s | counted | mean sigma | vs "
              f"{strategies[0]} (geo. mean, 95 % CI) | first visit med s | uploads | "
              "wind replans |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        base = {(r["seed"], r["from_deg"]): r for r in group if r["strategy"] == strategies[0]}
        for strategy in strategies:
            rows = [r for r in group if r["strategy"] == strategy]
            first = [e for r in rows for e in r["first_errors_s"]]
            later = [e for r in rows for e in r["later_errors_s"]]
            ratios = [r["mean_uncertainty"] / base[(r["seed"], r["from_deg"])]["mean_uncertainty"]
                      for r in rows if (r["seed"], r["from_deg"]) in base]
            visits = [t for r in rows for t in r["first_visit_s"]]
            print(f"| {strategy} | {_errors(first)} | {len(first)}/{3 * len(rows)} | "
                  f"{statistics.median(first) if first else math.nan:+.1f} | "
                  f"{_errors(later)} | {len(later)} | "
                  f"{statistics.fmean(r['mean_uncertainty'] for r in rows):,.0f} | "
                  f"{'-' if strategy == strategies[0] else ratio_interval(ratios)} | "
                  f"{statistics.median(visits) if visits else math.nan:.0f} | "
                  f"{sum(r['uploads'] for r in rows)} | {sum(r['wind_replans'] for r in rows)} |")
        print("per direction, first legs abs err median / max s:")
        for from_deg in sorted({r["from_deg"] for r in group}):
            parts = []
            for strategy in strategies:
                first = [e for r in group if r["strategy"] == strategy
                         and r["from_deg"] == from_deg for e in r["first_errors_s"]]
                later = [e for r in group if r["strategy"] == strategy
                         and r["from_deg"] == from_deg for e in r["later_errors_s"]]
                parts.append(f"{strategy} first {_errors(first)} later {_errors(later)}")
            print(f"  from {from_deg:g}: " + " | ".join(parts))


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.split("\n\n")[0])
    parser.add_argument("--wind", type=float, default=15.0, help="m/s (default 15)")
    parser.add_argument("--directions", default="0,90,180,270", help="FROM degrees")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--knowledge", default="unknown,known",
                        help="unknown, known or both (default)")
    parser.add_argument("--strategies", default=",".join(STRATEGIES))
    parser.add_argument("--policy", choices=("commit", "scenario"), default="commit")
    parser.add_argument("--scenario", default="paper-boat")
    parser.add_argument("--duration", type=float, default=400.0, help="mission s per run")
    parser.add_argument("--label", help="name the runs' strategy so in the JSON (e.g. "
                        "'before' for a run of the old code, whose only strategy is 'replan')")
    parser.add_argument("--json", help="write every run's figures here")
    parser.add_argument("--report", nargs="+", metavar="FILE", help="print from JSON files")
    args = parser.parse_args(argv)
    if args.report:
        report([r for path in args.report for r in json.loads(Path(path).read_text())])
        return 0
    strategies = [s.strip() for s in args.strategies.split(",")]
    if unknown := set(strategies) - set(STRATEGIES) - {"before"}:
        parser.error(f"unknown strategy {sorted(unknown)[0]!r}")
    runs: list[dict[str, Any]] = []
    for known in [k.strip() == "known" for k in args.knowledge.split(",")]:
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            for from_deg in [float(d) for d in args.directions.split(",")]:
                for strategy in strategies:
                    run = run_once(seed, from_deg, args.wind, known, strategy, args.duration,
                                   args.policy, args.scenario)
                    if args.label:
                        run["strategy"] = args.label
                    runs.append(run)
                    print(f"seed {seed} from {from_deg:g} {'known' if known else 'unknown'} "
                          f"{strategy}: first {run['first_errors_s']} later "
                          f"{_errors(run['later_errors_s'])} sigma "
                          f"{run['mean_uncertainty']:,.0f} cruise {run['cruise']} "
                          f"({run['wall_s']} s)", file=sys.stderr, flush=True)
                    if args.json:
                        Path(args.json).write_text(json.dumps(runs, indent=1) + "\n")
    report(runs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
