"""``gcs simulate``: run a scenario in virtual time and write metrics and plots.

    gcs simulate --scenario paper-boat --uavs 1,3 --seed 0 --out out/paper

writes ``out/paper/uavs-1/metrics.json``, ``journal.jsonl`` and plots, the same for 3 UAVs,
and ``out/paper/comparison.png``; with a single fleet size, ``out/paper/metrics.json``
directly. ``--wind 10,270`` flies the run in 10 m/s of wind from the west (the scenario's
``wind`` otherwise; a third number adds gusts of that standard deviation).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from domain.errors import ConfigError
from domain.extras import extra_hint, module_missing
from domain.limits import MAX_FLEET
from groundstation.commands.argtypes import positive_float
from groundstation.commands.progress_bars import ProgressBars, TaskUpdate
from groundstation.storage import (
    StorageError,
    atomic_write_bytes,
    atomic_write_text,
    describe_os_error,
)
from planner import Objective
from world.scenario import ScenarioError, bundled_scenarios, load_scenario
from world.wind import parse_wind_text

__all__ = ["run"]


def _fleet_sizes(text: str) -> list[int]:
    sizes: list[int] = []
    for part in text.split(","):
        part = part.strip()
        if not part.isdigit() or int(part) < 1:
            raise argparse.ArgumentTypeError(
                f"--uavs takes positive integers separated by commas, got {text!r}"
            )
        if int(part) > MAX_FLEET:
            raise argparse.ArgumentTypeError(
                f"{part} UAVs is above floe's limit of {MAX_FLEET}"
            )
        sizes.append(int(part))
    if len(set(sizes)) != len(sizes):
        raise argparse.ArgumentTypeError(f"--uavs lists a size twice: {text!r}")
    return sizes


MAX_SEEDS = 10_000


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        allow_abbrev=False,
        prog="gcs simulate",
        description="Run a scenario in virtual time: the decision core against the world "
        "model. Writes metrics.json and PNG plots.",
    )
    parser.add_argument(
        "--scenario",
        default="paper-boat",
        help=f"bundled name ({', '.join(bundled_scenarios())}) or a YAML file"
        " (default: paper-boat)",
    )
    parser.add_argument(
        "--uavs",
        type=_fleet_sizes,
        default=None,
        help="fleet size, or a comma list (1,3) to compare sizes (default: the scenario's)",
    )
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument(
        "--seeds",
        type=int,
        default=1,
        metavar="K",
        help="run K seeds (seed, seed+1, ...) per fleet size, each in DIR[/uavs-N]/seed-S, and "
        "print each size's growth over the second half of the mean curve with its 95 %% "
        "bootstrap interval over the seeds (default 1: one run, no interval)",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("out/simulate"),
        help="output folder (default out/simulate)",
    )
    parser.add_argument(
        "--duration",
        type=positive_float,
        default=None,
        help="mission seconds to simulate (default: the scenario's)",
    )
    parser.add_argument(
        "--objective",
        choices=[m.value for m in Objective],
        default=None,
        help="planner objective (default: the scenario's)",
    )
    parser.add_argument(
        "--workers",
        type=int,
        default=1,
        help="CP-SAT worker threads (default 1: deterministic runs)",
    )
    parser.add_argument(
        "--wind",
        metavar="SPEED_M_S,FROM_DEG[,GUST_M_S]",
        default=None,
        help="fly in this wind instead of the scenario's: mean speed (m/s), the compass "
        "direction it blows from (deg), optional gust standard deviation (m/s); "
        "e.g. 10,270 is 10 m/s from the west",
    )
    parser.add_argument("--no-plots", action="store_true", help="write metrics only")
    parser.add_argument(
        "--no-journal",
        action="store_true",
        help="do not write journal.jsonl (every core input and decision)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress output")
    return parser


def run(argv: list[str]) -> int:
    args = _parser().parse_args(argv)
    if args.workers < 1:
        print("gcs simulate: error: --workers must be >= 1", file=sys.stderr)
        return 2
    if not args.no_plots and module_missing("matplotlib"):  # before the run, not after it
        print(f"gcs simulate: error: plots need matplotlib, not installed here: "
              f"{extra_hint('plot')}, or --no-plots", file=sys.stderr)
        return 2
    if not 1 <= args.seeds <= MAX_SEEDS:
        print(f"gcs simulate: error: --seeds must be in [1, {MAX_SEEDS}]", file=sys.stderr)
        return 2
    try:
        scenario = load_scenario(args.scenario)
    except ScenarioError as exc:
        print(f"gcs simulate: error: {exc}", file=sys.stderr)
        return 2
    if args.wind is not None:
        try:
            scenario = dataclasses.replace(scenario, wind=parse_wind_text(args.wind))
        except ConfigError as exc:
            print(f"gcs simulate: error: {exc}", file=sys.stderr)
            return 2
    if scenario.wind.speed_m_s >= scenario.fleet.speed_m_s:
        source = "--wind" if args.wind is not None else f"scenario {scenario.name}'s wind"
        print(f"gcs simulate: error: {source}: a wind of {scenario.wind.speed_m_s:g} m/s is "
              f"not below the airspeed {scenario.fleet.speed_m_s:g} m/s: legs into it "
              "cannot be flown", file=sys.stderr)
        return 2
    sizes: list[int] = args.uavs or [scenario.fleet.count]
    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        print(f"gcs simulate: error: cannot create {args.out}: {exc}", file=sys.stderr)
        return 2
    try:
        rows = _run_sizes(args, scenario, sizes)
    except StorageError as exc:  # a full disk, an unwritable folder: one line
        print(f"gcs simulate: error: {exc}", file=sys.stderr)
        return 2
    except Interrupted as stop:
        kept = "metrics.json" + (", journal.jsonl" if not args.no_journal else "")
        print(f"gcs simulate: interrupted at t={stop.t_s:.1f} s: the partial run's {kept} "
              f"kept in {stop.out_dir} (no plots)", file=sys.stderr)
        return 130
    _print_summary(rows)
    _print_growth(rows, sizes, args.seeds)
    if not scenario.wind.calm:
        print(f"wind: {scenario.wind.describe()}")
    for row in rows:
        for line in row.get("fallbacks", ()):
            print(f"uavs={row['uavs']}: {line}")
    return 0


def journal_lines(records: list[dict[str, Any]]) -> Iterator[bytes]:
    """Each journal record as one UTF-8 JSON line."""
    return ((json.dumps(record) + "\n").encode("utf-8") for record in records)


def _run_sizes(args: argparse.Namespace, scenario: Any, sizes: list[int]) -> list[dict[str, Any]]:
    """Simulate each fleet size; every file is written atomically (StorageError on failure).
    The heavy imports happen only here, once the arguments are known to be good, and
    matplotlib (~0.3 s of CPU) only when plots are drawn. Progress: one task per fleet
    size (:mod:`groundstation.commands.progress_bars`)."""
    with ProgressBars(quiet=args.quiet) as bars:
        duration_s = args.duration or scenario.duration_s
        wind = "" if scenario.wind.calm else f" wind {scenario.wind.describe()}"
        updates = {  # one task per fleet size and seed, all shown from the start
            (uavs, seed): bars.task(f"{scenario.name} uavs={uavs} seed={seed}{wind}",
                                    duration_s, " s")
            for uavs in sizes
            for seed in _seeds(args)
        }
        return _simulate_sizes(args, scenario, sizes, updates)


def _simulate_sizes(
    args: argparse.Namespace,
    scenario: Any,
    sizes: list[int],
    updates: dict[tuple[int, int], TaskUpdate],
) -> list[dict[str, Any]]:
    from groundstation.runners.simulate.simulator import SimulationOptions, run_simulation

    curves: dict[int, list[list[float]]] = {}
    rows: list[dict[str, Any]] = []
    for uavs, seed in ((u, s) for u in sizes for s in _seeds(args)):
        update = updates[(uavs, seed)]
        out_dir = args.out / f"uavs-{uavs}" if len(sizes) > 1 else args.out
        if args.seeds > 1:
            out_dir = out_dir / f"seed-{seed}"
        try:
            out_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise StorageError(f"cannot create {out_dir}: {describe_os_error(exc)}") from None
        options = SimulationOptions(
            seed=seed,
            uavs=uavs,
            duration_s=args.duration,
            num_workers=args.workers,
            deterministic=args.workers == 1,
            objective=args.objective,
            progress=_mission_progress(update),
            journal=not args.no_journal,
        )
        result = run_simulation(scenario, options)
        metrics = result.metrics
        atomic_write_text(out_dir / "metrics.json", json.dumps(metrics, indent=1) + "\n")
        if result.journal:
            atomic_write_bytes(out_dir / "journal.jsonl", b"".join(journal_lines(result.journal)))
        if result.interrupted_at_s is not None:
            raise Interrupted(result.interrupted_at_s, out_dir)
        if not args.no_plots:
            from groundstation.runners.simulate.plots import write_plots

            write_plots(result, out_dir)
        if seed == args.seed:
            curves[uavs] = metrics["uncertainty_series"]
        rows.append({"uavs": uavs, "seed": seed, "dir": str(out_dir), **metrics,
                     "fallbacks": fallback_lines(result.journal or [])})
    if len(sizes) > 1 and not args.no_plots:
        from groundstation.runners.simulate.plots import plot_comparison

        plot_comparison(
            curves,
            f"{scenario.name}, seed {args.seed}: mean uncertainty",
            args.out / "comparison.png",
        )
    return rows


class Interrupted(Exception):
    """Ctrl-C stopped a simulation at mission time ``t_s``; its partial metrics and journal
    are written in ``out_dir``."""

    def __init__(self, t_s: float, out_dir: Path) -> None:
        super().__init__(f"interrupted at t={t_s:.1f} s")
        self.t_s = t_s
        self.out_dir = out_dir


FALLBACK_NOTES = ("wind_refused", "wind_fallback")
"""The core's notes of a fallback that changes the result (planning in still air, or in
the configured wind instead of the vehicles'): said on the console, not only journalled."""


def fallback_lines(journal: list[dict[str, Any]]) -> list[str]:
    """One console line per kind of fallback note in the journal: its first time and
    detail, and how many there were."""
    seen: dict[str, list[dict[str, Any]]] = {}
    for record in journal:
        if record.get("event") in FALLBACK_NOTES:
            seen.setdefault(str(record["event"]), []).append(record)
    lines = []
    for kind, records in seen.items():
        first = records[0]
        more = f" ({len(records)} times)" if len(records) > 1 else ""
        lines.append(f"fallback: {kind} at t={float(first.get('t', 0.0)):.1f} s: "
                     f"{first.get('detail') or ''}{more}".rstrip())
    return lines


def _seeds(args: argparse.Namespace) -> range:
    return range(args.seed, args.seed + args.seeds)


def _mission_progress(update: TaskUpdate) -> Callable[[float, float], None]:
    """The runner's ``progress(t_s, duration_s)`` -> the task's update."""

    def progress(t_s: float, _duration_s: float) -> None:
        update(t_s)

    return progress


def _print_summary(rows: list[dict[str, Any]]) -> None:
    header = (
        f"{'uavs':>4} {'mean sigma':>11} {'max sigma':>11} {'final':>11} {'trend':>6}"
        f" {'lost':>4} {'visits':>6} {'plans':>5} {'x realtime':>10}  output"
    )
    print(header)
    for r in rows:
        print(
            f"{r['uavs']:>4} {r['mean_uncertainty']:>11.1f} {r['max_uncertainty']:>11.1f}"
            f" {r['final_uncertainty']:>11.1f} {_trend_text(r['trend']):>6}"
            f" {len(r['lost_targets']):>4} {len(r['visits']):>6} {r['plans']:>5}"
            f" {r['realtime_factor']:>10.0f}  {r['dir']}"
        )
    for r in rows:
        if "on_station_shortfall_s" in r:
            print(_watch_line(r))


def _trend_text(trend: float | None) -> str:
    return "-" if trend is None else f"{trend:.2f}"


def _print_growth(rows: list[dict[str, Any]], sizes: list[int], seeds: int) -> None:
    """Per fleet size, the growth over the second half of the mean curve over its seeds
    with the 95 % bootstrap interval (groundstation/core/metrics.py, ensemble_growth)."""
    from groundstation.core.metrics import ensemble_growth, third_means

    for uavs in sizes:
        thirds = []
        for r in rows:
            if r["uavs"] != uavs:
                continue
            series = r["uncertainty_series"]
            pair = third_means([t for t, _ in series], [v for _, v in series])
            if pair is not None:
                thirds.append(pair)
        growth = ensemble_growth(thirds)
        hint = "" if seeds > 1 else "; --seeds K for an interval over K seeds"
        print(f"uavs {uavs}: growth over the second half (mean curve, last third / middle "
              f"third, {growth.runs} seed(s)): {growth.text()}{hint}")


def _watch_line(r: dict[str, Any]) -> str:
    """A watch run's figures (core/watch_metrics.py), one line per fleet size."""
    hours = " ".join(f"{v:.0f}" for v in r["hourly_mean_uncertainty"])
    ends = r["rtl_end_distance_to_ship_m"]
    end = ("no return" if ends["median"] is None
           else f"returns ended {ends['median']:.0f} m (median), {ends['max']:.0f} m (max) "
                "from the ship")
    landing = r["min_landing_battery_pct"]
    lowest = "none recovered" if landing is None else f"lowest landing charge {landing:.1f} %"
    share = 100.0 * r["on_station_shortfall_s"] / max(r["duration_s"], 1e-9)
    return (f"watch, {r['uavs']} uavs: {r['vehicles_lost']} lost, {r['reliefs']} reliefs,"
            f" {r['launches']} launches; {lowest}; {end}; short on station"
            f" {r['on_station_shortfall_s']:.0f} s ({share:.1f} %); mean sigma by hour {hours}")
