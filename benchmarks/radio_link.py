"""floe over SiK-class telemetry radios, side by side with the same runs on loopback
(issue 28, docs/links.md "Over a telemetry radio").

    python benchmarks/radio_link.py [--scenarios paper-boat discovery] [--radio sik,loss=0.05]
        [--duration 1800] [--speedup 20] [--seeds 1] [--first-seed 0] [--json FILE]
    python benchmarks/radio_link.py --report FILE [FILE ...]   # the tables of saved runs

Every run is ``gcs run --vehicles sim:3 --scenario S --speedup K --duration D --seed N``
in this process, through real MAVLink on 127.0.0.1 with the built-in simulator, once with
each vehicle on its own simulated radio (``--sim-radio RADIO``: 57 600 baud, 64 kbit/s air,
half-duplex TDM, here 5 % loss in bursts) and once on plain loopback sockets. The runs are
interleaved (for each seed, each scenario: radio, then loopback), so a slower stretch of
the shared machine hits both alike.

Per run and per vehicle link it prints the run's ``metrics.json`` ``links`` entry:

* air time used (% of the elapsed time: the simulated radios' own figure, every packet of
  both radios; on loopback there is no air and no figure);
* uploads per vehicle per hour and the share verified;
* upload latency p50/p95 (mission s from an upload's first frame to its verdict);
* telemetry age p95 (the age of the vehicle's newest position, sampled each mission
  second, against its own clock);

and per run the mean uncertainty, with the radio run's against its loopback twin. The
last lines check the issue's bounds: at least 99 % of uploads verified, p95 upload latency
at most 3 s, p95 telemetry age at most 2 s, air time at most 60 % on every link, mean
uncertainty within 10 % of loopback (the worst seed's ratio).

A single pair cannot judge the uncertainty on ``paper-boat``: a ``gcs run`` is not
repeatable (its plans race the wall clock), and over 1 800 s two loopback runs of one seed
differ by 2-3x. With several seeds (``--seeds``, or ``--report`` over the JSON files of
runs made in parallel, one seed each) the last lines also give the **paired ensemble**: the
ratio of the radio runs' mean to their loopback twins' mean over the seeds, with a 95 %
bootstrap interval (seeds resampled in pairs, 4 000 times), and the geometric mean of the
per-seed ratios.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import random
import tempfile
import time
from pathlib import Path
from typing import Any

BOOTSTRAP_ROUNDS = 4000
BOUNDS = {"upload_ok_pct": 99.0, "upload_p95_s": 3.0, "age_p95_s": 2.0, "airtime_pct": 60.0,
          "uncertainty_ratio": 1.10}


def run_once(scenario: str, radio: str | None, seed: int, duration_s: float,
             speedup: float) -> dict[str, Any]:
    """One ``gcs run`` with three built-in vehicles; its metrics.json and wall time."""
    from groundstation.commands.embedded_sim import build_embedded_sim
    from groundstation.commands.run import build_config
    from groundstation.daemon.startup import run_daemon

    with tempfile.TemporaryDirectory() as run_dir:
        argv = ["--vehicles", "sim:3", "--scenario", scenario, "--seed", str(seed),
                "--speedup", str(speedup), "--duration", str(duration_s), "--run-dir",
                run_dir, "--http", "off", "--status", "quiet"]
        argv += ["--sim-radio", radio] if radio else []
        wall0 = time.perf_counter()
        asyncio.run(run_daemon(build_config(argv), embedded=build_embedded_sim,
                               print_fn=lambda _: None, install_signals=False))
        wall_s = time.perf_counter() - wall0
        metrics = json.loads(next(Path(run_dir).rglob("metrics.json")).read_text())
    return {"scenario": scenario, "radio": radio or "loopback", "seed": seed,
            "wall_s": wall_s, "mission_s": metrics["summary"]["mission_s"],
            "mean_uncertainty": metrics["mean_uncertainty"], "links": metrics["links"]}


def _f(value: float | None, fmt: str = ".1f") -> str:
    return "-" if value is None else format(value, fmt)


def print_runs(rows: list[dict[str, Any]]) -> None:
    print(f"{'scenario':<11}{'link':<16}{'seed':>4} {'veh':>3} {'air %':>6} {'upl/h':>6} "
          f"{'ok %':>6} {'lat p50':>7} {'lat p95':>7} {'age p95':>7}  mean uncertainty")
    for r in rows:
        for i, e in enumerate(r["links"]):
            lat, age = e["upload_latency_s"], e["telemetry_age_s"]
            tail = f"  {r['mean_uncertainty']:.1f}" if i == 0 else ""
            print(f"{r['scenario']:<11}{r['radio']:<16}{r['seed']:>4} {e['vehicle']:>3} "
                  f"{_f(e['airtime_pct']):>6} {_f(e['uploads_per_hour'], '.0f'):>6} "
                  f"{_f(e['upload_ok_pct']):>6} {_f(lat['p50'], '.2f'):>7} "
                  f"{_f(lat['p95'], '.2f'):>7} {_f(age['p95'], '.2f'):>7}{tail}")


def paired_ensemble(pairs: list[tuple[float, float]], rounds: int = BOOTSTRAP_ROUNDS,
                    seed: int = 0) -> dict[str, float]:
    """Radio against loopback over seeds: R = sum(radio) / sum(loopback) (the ratio of the
    ensemble means), its 95 % percentile bootstrap interval (the seeds' pairs resampled with
    replacement ``rounds`` times), and the geometric mean of the per-seed ratios,
    exp(mean(ln(radio_i / loopback_i)))."""
    def ratio(sample: list[tuple[float, float]]) -> float:
        return sum(r for r, _ in sample) / sum(lo for _, lo in sample)

    rng = random.Random(seed)
    boots = sorted(ratio([rng.choice(pairs) for _ in pairs]) for _ in range(rounds))
    return {"n": len(pairs), "ratio": ratio(pairs), "low": boots[int(0.025 * rounds)],
            "high": boots[min(rounds - 1, int(0.975 * rounds))],
            "geomean": math.exp(sum(math.log(r / lo) for r, lo in pairs) / len(pairs))}


def ensemble_lines(rows: list[dict[str, Any]]) -> list[str]:
    """The paired ensemble of every scenario with at least two seeds run both ways."""
    lines = []
    for scenario in dict.fromkeys(r["scenario"] for r in rows):
        loop = {r["seed"]: r["mean_uncertainty"] for r in rows
                if r["scenario"] == scenario and r["radio"] == "loopback"}
        pairs = [(r["mean_uncertainty"], loop[r["seed"]]) for r in rows
                 if r["scenario"] == scenario and r["radio"] != "loopback"
                 and loop.get(r["seed"])]
        if len(pairs) < 2:
            continue
        e = paired_ensemble(pairs)
        lines.append(
            f"{scenario}, paired ensemble of {e['n']} seeds: mean uncertainty radio/loopback "
            f"{e['ratio']:.3f} [95 % {e['low']:.3f}, {e['high']:.3f}], geometric mean of the "
            f"seeds' ratios {e['geomean']:.3f}")
    return lines


def check(rows: list[dict[str, Any]]) -> list[str]:
    """The issue's bounds, per scenario over the radio runs (each paired with its loopback
    run of the same seed for the uncertainty)."""
    lines = []
    for scenario in dict.fromkeys(r["scenario"] for r in rows):
        radio = [r for r in rows if r["scenario"] == scenario and r["radio"] != "loopback"]
        loop = {r["seed"]: r for r in rows if r["scenario"] == scenario
                and r["radio"] == "loopback"}
        links = [e for r in radio for e in r["links"]]
        uploads = sum(e["uploads"] for e in links)
        ok = sum(round(e["uploads"] * (e["upload_ok_pct"] or 0.0) / 100.0) for e in links)
        ok_pct = 100.0 * ok / uploads if uploads else None
        lat95 = max((e["upload_latency_s"]["p95"] or 0.0 for e in links), default=None)
        age95 = max((e["telemetry_age_s"]["p95"] or 0.0 for e in links), default=None)
        air = max((e["airtime_pct"] or 0.0 for e in links), default=None)
        ratios = [r["mean_uncertainty"] / loop[r["seed"]]["mean_uncertainty"]
                  for r in radio if r["seed"] in loop and loop[r["seed"]]["mean_uncertainty"]]
        worst = max(ratios, default=None)
        verdict = {
            "verified": ok_pct is not None and ok_pct >= BOUNDS["upload_ok_pct"],
            "latency": lat95 is not None and lat95 <= BOUNDS["upload_p95_s"],
            "age": age95 is not None and age95 <= BOUNDS["age_p95_s"],
            "air": air is not None and air <= BOUNDS["airtime_pct"],
            "uncertainty": worst is not None and worst <= BOUNDS["uncertainty_ratio"],
        }
        lines.append(
            f"{scenario}: verified {_f(ok_pct, '.2f')} % ({ok}/{uploads}), worst link's "
            f"upload p95 {_f(lat95, '.2f')} s, telemetry age p95 {_f(age95, '.2f')} s, air "
            f"{_f(air)} %, uncertainty radio/loopback {_f(worst, '.3f')}: "
            + ", ".join(f"{k} {'ok' if v else 'MISSED'}" for k, v in verdict.items()))
    return lines


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    p.add_argument("--scenarios", nargs="+", default=["paper-boat", "discovery"])
    p.add_argument("--radio", default="sik,loss=0.05")
    p.add_argument("--duration", type=float, default=1800.0)
    p.add_argument("--speedup", type=float, default=20.0)
    p.add_argument("--seeds", type=int, default=1)
    p.add_argument("--first-seed", type=int, default=0)
    p.add_argument("--json", help="also write the runs to this file")
    p.add_argument("--report", nargs="+", metavar="FILE",
                   help="only print the tables of runs saved with --json (several files: "
                        "one ensemble)")
    args = p.parse_args()
    rows: list[dict[str, Any]] = []
    if args.report:
        for name in args.report:
            try:
                rows += json.loads(Path(name).read_text())
            except (OSError, ValueError) as exc:
                p.error(f"{name}: not a file of saved runs ({exc})")
        print_runs(rows)
        for line in check(rows) + ensemble_lines(rows):
            print(line)
        return
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        for scenario in args.scenarios:
            for radio in (args.radio, None):
                row = run_once(scenario, radio, seed, args.duration, args.speedup)
                print(f"... {scenario} {row['radio']} seed {seed}: {row['mission_s']:.0f} "
                      f"mission s in {row['wall_s']:.0f} s", flush=True)
                rows.append(row)
    print_runs(rows)
    for line in check(rows) + ensemble_lines(rows):
        print(line)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
