"""Issue 10.5 benchmark: a flood on one link next to a normal 10 Hz vehicle on another.

For UDP and TCP floods, runs the fair receive path (per-link inbox, drain with a budget per
loop turn) and the old one (``LinkOptions(fair=False)``: decode and deliver inside the
transport callback) side by side, interleaved, and prints the normal vehicle's worst
delivery latency and worst gap (in wall time, then in the time the receiving loop ran:
what the tests assert on), and what each link received and dropped.

The last column holds the throughput floors the tests kept until issue 30 (a loaded host
cannot always reach them, so tests/test_link_flood.py asserts correctness only): a UDP
flood offers at least ``FLOOR_FRAMES_PER_S`` frames/s, and a fair TCP flood delivers at
least that rate times the duration (it is served, not shut out). "ok" or "BELOW".

    .venv/bin/python benchmarks/link_flood.py [--repeats N] [--duration S] [--json FILE]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from link_flood_harness import FloodResult, run_flood

FLOOR_FRAMES_PER_S = 20_000  # offered by the UDP flood; delivered by a fair TCP flood


def floor_met(r: FloodResult, duration_s: float) -> bool:
    """The throughput floor of ``r``'s case (see the module docstring)."""
    if r.transport == "tcp":
        return not r.fair or r.flood_delivered >= FLOOR_FRAMES_PER_S * duration_s
    return r.flood_frames_per_s >= FLOOR_FRAMES_PER_S


def main() -> int:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--duration", type=float, default=3.0)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    results: list[FloodResult] = []
    print(
        f"{'transport':<10}{'path':<6}{'offered f/s':>12}{'worst lat ms':>13}{'worst gap ms':>13}"
        f"{'lat run ms':>11}{'gap run ms':>11}"
        f"{'normal':>8}{'flood rx':>10}{'flood drop':>11}{'prio drop':>10}{'floor':>7}"
    )
    for _ in range(args.repeats):
        for transport in ("udp", "tcp"):
            for fair in (True, False):
                r = asyncio.run(run_flood(fair=fair, transport=transport, duration_s=args.duration))
                results.append(r)
                print(
                    f"{transport:<10}{'fair' if fair else 'old':<6}{r.flood_frames_per_s:>12.0f}"
                    f"{r.worst_latency_ms:>13.1f}{r.worst_gap_ms:>13.1f}"
                    f"{r.worst_latency_run_ms:>11.1f}{r.worst_gap_run_ms:>11.1f}"
                    f"{r.normal_delivered:>4}/{r.normal_sent:<3}{r.flood_link['received']:>10}"
                    f"{r.flood_link['dropped']:>11}{r.flood_link['dropped_priority']:>10}"
                    f"{'ok' if floor_met(r, args.duration) else 'BELOW':>7}",
                    flush=True,
                )
    if args.json is not None:
        args.json.write_text(json.dumps([r.as_dict() for r in results], indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
