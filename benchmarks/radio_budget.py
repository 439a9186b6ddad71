"""floe over simulated SiK radios against the same run on loopback: the issue's "Done when".

    python benchmarks/radio_budget.py [--scenario paper-boat] [--radio sik,loss=0.05]
        [--duration 1800] [--speedup 20] [--vehicles 3] [--no-loopback]

Runs ``gcs run --vehicles sim:N --scenario S --sim-radio RADIO --speedup K --duration D``
in this process (and the same without ``--sim-radio``), then prints one row per run:

* uploads: verified / all (``upload`` journal lines), per vehicle per hour;
* upload latency p50/p95: mission seconds from the first MISSION_COUNT to the verdict of
  the verified upload (the journal's ``took_s``), retries (timeouts that led to a resend
  or a new attempt) per upload;
* per radio link: air time carrying data and all air time (% of the elapsed time,
  ``SitlServer.radio_stats``), downlink latency p95 (serial in -> serial out: the age of a
  telemetry frame when floe reads it), bytes the radios dropped;
* the GCS heartbeat rate per mission second (RADIO_STATUS the ground radio injected);
* mean uncertainty (``metrics.json``).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import tempfile
from pathlib import Path
from typing import Any


def _pct(q: float, values: list[float]) -> float | None:
    if not values:
        return None
    values = sorted(values)
    return values[min(len(values) - 1, int(q * len(values)))]


def run_once(scenario: str, radio: str | None, duration_s: float, speedup: float,
             vehicles: int, extra: list[str]) -> dict[str, Any]:
    """One daemon run with the built-in simulator; its figures."""
    from groundstation.commands.embedded_sim import build_embedded_sim
    from groundstation.commands.run import build_config
    from groundstation.daemon.startup import run_daemon

    sims: list[Any] = []

    def factory(*args: Any) -> Any:
        sim = build_embedded_sim(*args)
        sims.append(sim)
        return sim

    with tempfile.TemporaryDirectory() as run_dir:
        argv = ["--vehicles", f"sim:{vehicles}", "--scenario", scenario, "--speedup",
                str(speedup), "--duration", str(duration_s), "--run-dir", run_dir, "--http",
                "off", "--detections", "off", "--status", "quiet", *extra]
        if radio:
            argv += ["--sim-radio", radio]
        config = build_config(argv)
        daemon = asyncio.run(run_daemon(config, embedded=factory, print_fn=lambda _: None,
                                        install_signals=False))
        summary = daemon.summary()
        journal = next(Path(run_dir).rglob("journal.jsonl"))
        lines = [json.loads(x) for x in journal.read_text().splitlines() if x.strip()]
    uploads = [x for x in lines if x.get("event") == "upload"]
    took = [float(x["took_s"]) for x in uploads if x.get("took_s") is not None and x["ok"]]
    mission_s = float(summary["mission_s"])
    links = sims[0].radio_stats() if sims else {}
    return {
        "scenario": scenario, "radio": radio or "loopback", "mission_s": mission_s,
        "uploads": len(uploads), "uploads_ok": sum(1 for x in uploads if x["ok"]),
        "retries": sum(int(x.get("retries") or 0) for x in uploads),
        "upload_p50_s": _pct(0.5, took), "upload_p95_s": _pct(0.95, took),
        "upload_max_s": max(took) if took else None,
        "mean_uncertainty": summary["mean_uncertainty"],
        "links": {sysid: {
            "data_air_pct": s["data_air_pct"], "air_pct": s["air_pct"],
            "down_latency_p95_s": s["down"]["latency_p95_s"],
            "dropped_bytes": s["down"]["bytes_dropped"] + s["up"]["bytes_dropped"],
            "heartbeat_hz": s["ground_radio"]["sent"] / max(s["elapsed_s"], 1e-9),
            "up_bytes_s": s["up"]["bytes_offered"] / max(s["elapsed_s"], 1e-9),
            "down_bytes_s": s["down"]["bytes_offered"] / max(s["elapsed_s"], 1e-9),
        } for sysid, s in sorted(links.items())},
    }


def _f(value: float | None, fmt: str = ".2f") -> str:
    return "-" if value is None else format(value, fmt)


def print_row(r: dict[str, Any], vehicles: int) -> None:
    hours = max(r["mission_s"], 1e-9) / 3600.0
    ok_pct = 100.0 * r["uploads_ok"] / r["uploads"] if r["uploads"] else None
    print(f"{r['scenario']:<10} {r['radio']:<16} uploads {r['uploads_ok']}/{r['uploads']} "
          f"({_f(ok_pct, '.1f')} %, {r['uploads'] / vehicles / hours:.0f}/vehicle/h, "
          f"{r['retries']} retries)  latency p50/p95/max {_f(r['upload_p50_s'])} / "
          f"{_f(r['upload_p95_s'])} / {_f(r['upload_max_s'])} s  mean uncertainty "
          f"{_f(r['mean_uncertainty'], '.1f')}")
    for sysid, s in r["links"].items():
        print(f"    link {sysid}: air data {s['data_air_pct']:.1f} % (all {s['air_pct']:.1f} "
              f"%), down {s['down_bytes_s']:.0f} B/s, up {s['up_bytes_s']:.0f} B/s, "
              f"telemetry age p95 {_f(s['down_latency_p95_s'], '.3f')} s, dropped "
              f"{s['dropped_bytes']} B, GCS heartbeat {s['heartbeat_hz']:.2f} Hz")


def main() -> None:
    p = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="paper-boat")
    p.add_argument("--radio", default="sik,loss=0.05")
    p.add_argument("--duration", type=float, default=1800.0)
    p.add_argument("--speedup", type=float, default=20.0)
    p.add_argument("--vehicles", type=int, default=3)
    p.add_argument("--no-loopback", action="store_true")
    p.add_argument("--json", help="also write the rows to this file")
    p.add_argument("extra", nargs="*", help="more gcs run flags (after --)")
    args = p.parse_args()
    rows = [run_once(args.scenario, args.radio, args.duration, args.speedup, args.vehicles,
                     args.extra)]
    if not args.no_loopback:
        rows.append(run_once(args.scenario, None, args.duration, args.speedup,
                             args.vehicles, args.extra))
    for row in rows:
        print_row(row, args.vehicles)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
