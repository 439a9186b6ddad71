"""The issue's wind benchmark: wind-aware against wind-blind planning on the same seeds.

    nice -n 10 python benchmarks/wind_study.py --json benchmarks/wind_study.json

runs the whole grid: scenarios ``paper-boat`` and ``svalbard-2015`` (the field test), 3
and 5 UAVs, a mean wind of 0, 5, 10 and 15 m/s from 0, 90, 180 and 270 deg (calm: one
direction), wind-aware and wind-blind planning (scenario ``planner.wind_aware``), seeds
0-9. Every run goes through ``groundstation.runners.simulate.simulator.run_simulation`` in virtual
time, exactly as ``gcs simulate --wind SPEED,FROM`` (the vehicles report their WIND to the
core at 1 Hz). The aware and the blind run of a (scenario, fleet, wind, seed) see the same
icebergs, the same air and the same detection noise until their plans differ (paired
runs). ``--quick``: seeds 0-2, directions 90 and 270, winds 0 and 10 m/s. ``--gust G``
adds Gauss-Markov gusts of G m/s (``gust_tau_s`` of the scenario's spec, 5 s default).

Per (scenario, fleet size, wind speed) it prints:

* the arrival error (metrics.json ``arrival_error_s``: |predicted - flown| arrival at the
  aim point, s), aware | blind: the median and 90th percentile of every counted arrival of
  every run pooled, and the median of the per-run medians; the median signed error (bias,
  > 0: late); arrivals counted and superseded (summed over runs);
* the run-average uncertainty (metrics.json ``mean_uncertainty``), the mean over runs aware
  | blind, and paired per (seed, direction): the geometric mean of ``aware / blind``, as
  a change in %, with its 95 % t interval (``ratio_interval``), and wins/losses (runs
  where aware is lower/higher);
* detections per visit (accepted measurements / visits), a measure of how long a loiter
  keeps its target in the camera's view;
* "no route %": the share of (plan, vehicle) slots after t = 1 s in which the plan gave the
  vehicle no route (the idle rule then sends it somewhere), aware | blind: the symptom of
  the wind's credit (docs/wind.md, "The wind's credit").

``--aware-part costs|intercept`` makes the aware run of each pair use the wind in its
planning costs only, or in its intercept (aim points) only (``wind_parts.py``): which half
of wind-awareness costs what (docs/wind.md, "Measured").

``--json FILE`` writes every run's figures (the arrival errors of every run included);
``--report FILE...`` prints the tables again from such files (their runs pooled: seeds
0-9 of one file and 10-29 of another make 30-seed rows). ``--directions`` prints the
10 m/s rows per wind direction too; ``--fields`` the paired visits, accepted detections
and largest uncertainty (aware / blind, as the mean uncertainty). The machine is shared:
use ``nice -n 10``. On 2 cores the full grid (1040 runs) took 4 min (14 min with other
work on the machine); ``--quick`` (72 runs) well under a minute.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from typing import Any

from paper_study import paired
from wind_parts import AWARE_PARTS, core_class

from groundstation.core.arrivals import percentile

Job = tuple[str, int, float, float, float, bool, int, float | None, str | None, str]

SCENARIOS = ("paper-boat", "svalbard-2015")


def _one(job: Job) -> dict[str, Any]:
    """One run; the arrival errors come from the run's own ArrivalTracker."""
    import groundstation.runners.simulate.simulator as simulate
    from groundstation.core.metrics import MetricsRecorder
    from groundstation.runners.simulate.simulator import SimulationOptions, run_simulation
    from world.scenario import load_scenario
    from world.wind import WindSpec

    scenario_name, uavs, speed, from_deg, gust, aware, seed, duration, objective, part = job
    kept: list[Any] = []

    class Recorder(MetricsRecorder):
        """Keeps the run's recorder so the raw arrival errors can be read back."""

        def __init__(self) -> None:
            super().__init__()
            self.accepted = 0
            kept.append(self)

        def seen(self, t_s: float, vehicle: str | None, target: str) -> None:
            self.accepted += 1
            super().seen(t_s, vehicle, target)

    scenario = load_scenario(scenario_name)
    base = scenario.wind
    wind = WindSpec(speed, from_deg if speed > 0 else 0.0, gust if speed > 0 else 0.0,
                    base.gust_tau_s)
    planner = replace(scenario.planner, wind_aware=aware)
    if objective is not None:
        planner = replace(planner, objective=objective)
    scenario = replace(scenario, wind=wind, planner=planner)
    original, original_core = simulate.MetricsRecorder, simulate.DecisionCore
    simulate.MetricsRecorder = Recorder  # type: ignore[misc, assignment]
    simulate.DecisionCore = core_class(part) if aware else original_core  # type: ignore[misc]
    try:
        run = run_simulation(scenario, SimulationOptions(
            seed=seed, uavs=uavs, duration_s=duration, snapshot_times_s=(1.0,), journal=True))
        m = run.metrics
    finally:
        simulate.MetricsRecorder = original  # type: ignore[misc]
        simulate.DecisionCore = original_core  # type: ignore[misc]
    recorder = kept[-1]
    return {
        "scenario": scenario_name, "uavs": uavs, "wind_m_s": speed, "from_deg": from_deg,
        "gust_m_s": gust, "aware": aware, "seed": seed, "objective": planner.objective,
        "aware_part": part,
        "duration_s": m["duration_s"], "mean": m["mean_uncertainty"],
        "max": m["max_uncertainty"], "visits": len(m["visits"]),
        "accepted": recorder.accepted,
        "arrival_errors_s": [round(e, 4) for e in recorder.arrivals.errors_s],
        "arrival_error_s": m["arrival_error_s"], "arrival_bias_s": m["arrival_bias_s"],
        "arrivals": m["arrivals"], "rtf": m["realtime_factor"],
        "no_route": _no_route(run.journal),
    }


def _no_route(journal: list[dict[str, Any]]) -> list[int]:
    """[vehicle slots without a route, vehicle slots] over the run's plans after t = 1 s
    (at t = 0 every sigma is 0 and one UAV gets every target by design)."""
    slots = [not route for r in journal if r["event"] == "plan" and r["t"] > 1.0
             for route in r["routes"].values()]
    return [sum(slots), len(slots)]


def _arrival(group: list[dict[str, Any]]) -> tuple[str, str, str, str]:
    """(pooled median | p90, median of run medians, bias, counted/superseded)."""
    errors = [e for r in group for e in r["arrival_errors_s"]]
    if not errors:
        return "-", "-", "-", "0/" + str(sum(r["arrivals"]["superseded"] for r in group))
    absolute = [abs(e) for e in errors]
    medians = [r["arrival_error_s"]["median"] for r in group if r["arrival_error_s"]]
    return (f"{statistics.median(absolute):.2f} / {percentile(absolute, 0.9):.1f}",
            f"{statistics.median(medians):.2f}", f"{statistics.median(errors):+.2f}",
            f"{len(errors)}/{sum(r['arrivals']['superseded'] for r in group)}")


def _keys(rows: list[dict[str, Any]], by_direction: bool) -> list[tuple[Any, ...]]:
    keys = {(r["scenario"], r["uavs"], r["wind_m_s"]) + ((r["from_deg"],) if by_direction
                                                         else ()) for r in rows}
    order = {name: k for k, name in enumerate(SCENARIOS)}
    return sorted(keys, key=lambda k: (order.get(k[0], 99), k[0], *k[1:]))


def report(rows: list[dict[str, Any]], by_direction: bool = False,
           speeds: Sequence[float] | None = None) -> str:
    """Markdown table: aware | blind per (scenario, UAVs, wind[, direction])."""
    head = "| scenario | UAVs | wind m/s " + ("| from " if by_direction else "")
    lines = [
        head + "| arrival err med / p90 s (aware \\| blind) | run medians | bias s |"
        " counted/superseded | mean sigma aware \\| blind |"
        " aware / blind, geometric mean (95 % CI) | wins/losses | det./visit | no route % |",
        "|---|---|---|" + ("---|" if by_direction else "") + "---|---|---|---|---|---|---|---|---|",
    ]
    for key in _keys(rows, by_direction):
        if speeds is not None and key[2] not in speeds:
            continue
        group = [r for r in rows if (r["scenario"], r["uavs"], r["wind_m_s"])
                 + ((r["from_deg"],) if by_direction else ()) == key]
        aware = [r for r in group if r["aware"]]
        blind = [r for r in group if not r["aware"]]
        if not aware or not blind:
            continue
        a, b = _arrival(aware), _arrival(blind)
        pairs = [(x["mean"], y["mean"]) for x, y in _pairs(group)]
        ci = ratio_interval(pairs)
        det = "{:.1f} \\| {:.1f}".format(*(
            sum(r["accepted"] for r in g) / max(1, sum(r["visits"] for r in g))
            for g in (aware, blind)))
        lines.append(
            f"| {key[0]} | {key[1]} | {key[2]:g} "
            + (f"| {key[3]:g} " if by_direction else "")
            + f"| {a[0]} \\| {b[0]} | {a[1]} \\| {b[1]} | {a[2]} \\| {b[2]} |"
            f" {a[3]} \\| {b[3]} |"
            f" {statistics.fmean(r['mean'] for r in aware):,.0f} \\|"
            f" {statistics.fmean(r['mean'] for r in blind):,.0f} | {ci} |"
            f" {sum(x < y for x, y in pairs)}/{sum(x > y for x, y in pairs)} | {det} |"
            f" {_no_route_share(aware)} \\| {_no_route_share(blind)} |"
        )
    return "\n".join(lines)


def _pairs(group: list[dict[str, Any]]) -> list[tuple[dict[str, Any], dict[str, Any]]]:
    """(aware run, blind run) of every (scenario, UAVs, wind, direction, seed) in `group`
    that has both."""
    blind = {(r["scenario"], r["uavs"], r["wind_m_s"], r["from_deg"], r["seed"]): r
             for r in group if not r["aware"]}
    return [(r, blind[k]) for r in group if r["aware"] and (k := (
        r["scenario"], r["uavs"], r["wind_m_s"], r["from_deg"], r["seed"])) in blind]


def field_report(rows: list[dict[str, Any]]) -> str:
    """Markdown table: aware / blind (``ratio_interval``) of the visits, the accepted
    detections and the run's largest uncertainty (metrics.json ``max_uncertainty``) per
    (scenario, UAVs, wind)."""
    fields = ("visits", "accepted", "max")
    lines = ["| scenario | UAVs | wind m/s | pairs | " + " | ".join(
                 f"{f}: aware / blind" for f in fields) + " |",
             "|---|---|---|---|" + "---|" * len(fields)]
    for key in _keys(rows, False):
        pairs = _pairs([r for r in rows if (r["scenario"], r["uavs"], r["wind_m_s"]) == key])
        if key[2] == 0 or not pairs:
            continue
        lines.append(f"| {key[0]} | {key[1]} | {key[2]:g} | {len(pairs)} | " + " | ".join(
            ratio_interval([(a[f], b[f]) for a, b in pairs]) for f in fields) + " |")
    return "\n".join(lines)


def ratio_interval(pairs: Sequence[tuple[float, float]]) -> str:
    """aware against blind as the geometric mean of the paired ratios, in %, with its 95 %
    t interval: with ``l_k = ln(aware_k / blind_k)``,

        exp(mean l) - 1    [exp(mean l - h) - 1, exp(mean l + h) - 1],
        h = t_975(n - 1) s_l / sqrt(n).

    Unlike the mean of ``aware / blind - 1`` it is symmetric: swapping aware and blind
    gives the reciprocal ratio. The mean of the ratios is not: for paired runs whose
    ratio spreads by e^(+-0.25), as these chaotic runs do, it is about s_l^2 / 2 = 3 %
    above 0 when neither side is better, and above 0 the other way round too."""
    logs = [math.log(x / y) for x, y in pairs if x > 0 and y > 0]
    if not logs:
        return "-"
    avg, half = paired(logs)
    if len(logs) < 2:
        return f"{100.0 * math.expm1(avg):+.1f} %"
    return (f"{100.0 * math.expm1(avg):+.1f} % [{100.0 * math.expm1(avg - half):+.1f},"
            f" {100.0 * math.expm1(avg + half):+.1f}]")


def _no_route_share(group: list[dict[str, Any]]) -> str:
    """Percentage of plan slots that left a vehicle without a route ("-": rows written
    before the count existed)."""
    counts = [r["no_route"] for r in group if "no_route" in r]
    total = sum(c[1] for c in counts)
    return f"{100.0 * sum(c[0] for c in counts) / total:.1f}" if total else "-"


def write_rows(path: str, rows: list[dict[str, Any]]) -> None:
    """A JSON list, one run per line (arrival errors to 0.1 ms)."""
    with open(path, "w", encoding="utf-8") as handle:
        handle.write("[\n" + ",\n".join(json.dumps(r) for r in rows) + "\n]\n")


def jobs_for(args: argparse.Namespace) -> list[Job]:
    """The grid: calm runs once (direction 0), windy runs in every direction."""
    out: list[Job] = []
    for scenario in args.scenarios.split(","):
        for uavs in (int(u) for u in args.uavs.split(",")):
            for speed in (float(s) for s in args.winds.split(",")):
                directions = [0.0] if speed == 0 else [float(d) for d in
                                                       args.from_deg.split(",")]
                for from_deg in directions:
                    for seed in range(args.first_seed, args.first_seed + args.seeds):
                        for aware in (True, False):
                            out.append((scenario, uavs, speed, from_deg, args.gust, aware,
                                        seed, args.duration, args.objective,
                                        args.aware_part))
    # the long runs first, so the pool's last minutes are not one svalbard run alone
    out.sort(key=lambda j: 0 if j[0] == "svalbard-2015" else 1)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", default=",".join(SCENARIOS))
    parser.add_argument("--uavs", default="3,5", help="fleet sizes, e.g. 3,5")
    parser.add_argument("--winds", default="0,5,10,15", help="mean wind speeds, m/s")
    parser.add_argument("--from-deg", default="0,90,180,270",
                        help="directions the wind blows from, deg")
    parser.add_argument("--gust", type=float, default=0.0, help="gust standard deviation, m/s")
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--duration", type=float, default=None)
    parser.add_argument("--objective", default=None, help="override the scenarios' objective")
    parser.add_argument("--aware-part", default="all", choices=sorted(AWARE_PARTS),
                        help="the aware run's use of the wind: all (the shipped core), costs "
                        "(planner costs only, still-air intercept) or intercept (aim points "
                        "only, still-air costs); benchmarks/wind_parts.py")
    parser.add_argument("--quick", action="store_true",
                        help="seeds 0-2, directions 90 and 270, winds 0 and 10 m/s")
    parser.add_argument("--directions", action="store_true",
                        help="also print the 10 m/s rows per direction")
    parser.add_argument("--fields", action="store_true",
                        help="also print aware / blind of the visits, detections and largest "
                        "uncertainty")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--json", help="also write every run's figures to this file")
    parser.add_argument("--report", nargs="+", metavar="JSON",
                        help="print the tables from --json files (their runs pooled) and exit")
    args = parser.parse_args()
    if args.report:
        rows = []
        for path in args.report:
            with open(path, encoding="utf-8") as handle:
                rows += json.load(handle)
    else:
        if args.quick:
            args.seeds, args.from_deg, args.winds = 3, "90,270", "0,10"
        jobs = jobs_for(args)
        print(f"{len(jobs)} runs on {args.jobs} process(es)...", file=sys.stderr)
        start = time.perf_counter()
        with ProcessPoolExecutor(max_workers=args.jobs) as pool:
            rows = list(pool.map(_one, jobs, chunksize=1))
        print(f"{time.perf_counter() - start:.0f} s wall", file=sys.stderr)
        if args.json:
            write_rows(args.json, rows)
    print(report(rows))
    if args.directions:
        print()
        print(report(rows, by_direction=True, speeds=(10.0,)))
    if args.fields:
        print()
        print(field_report(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
