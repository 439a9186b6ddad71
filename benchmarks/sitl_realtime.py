"""Real-time factor and CPU of the built-in simulator for 1, 3 and 10 vehicles.

    /work/venv/bin/python benchmarks/sitl_realtime.py [--counts 1,3,10] [--wall-s 4]

For each fleet size, runs of ``--wall-s`` wall seconds, every vehicle airborne and
streaming its default telemetry over the shared UDP ``--out`` link to a local sink (a
stand-in ground station in its own process), plus its TCP listener, as ``gcs sitl`` serves
them. For each speed-up in ``--speedups`` (default 20, 50, 100, 200; 20 is the issue's
target): the real-time factor reached and the CPU used in % of one core (CPU time of the
simulator process / wall time). Escalation stops at the first speed-up not kept (real-time
factor below 90 % of it): the last kept one is the highest this host sustains with full
1 Hz telemetry per vehicle (the simulated clock slows down rather than skips when
overloaded). On a shared host, other processes' load lowers the factors: CPU below 100 %
with a factor below the speed-up means the process was waiting for a core.

Prints a table and writes ``benchmarks/sitl_realtime.json`` unless ``--no-json``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import platform
import subprocess
import sys
import time
from pathlib import Path

from domain.geodesy import GeoOrigin
from sitl.server import ServerOptions, SitlServer
from sitl.vehicle import VehicleConfig


async def measure(count: int, speedup: float, wall_s: float, sink_port: int) -> dict[str, float]:
    origin = GeoOrigin(78.93, 11.92)
    configs = [
        VehicleConfig(
            system_id=i + 1,
            origin=origin,
            home_lat_deg=78.93,
            home_lon_deg=11.92,
            airborne=True,
            launch_x_m=105.0 * (i % 5),
            launch_y_m=0.0,
        )
        for i in range(count)
    ]
    server = SitlServer(
        configs, ServerOptions(speedup=speedup, base_port=0, out=("127.0.0.1", sink_port))
    )
    await server.start()
    cpu0, wall0 = time.process_time(), time.monotonic()
    task = asyncio.create_task(server.run())
    await asyncio.sleep(wall_s)
    server.stop()
    await task
    wall = time.monotonic() - wall0
    cpu = time.process_time() - cpu0
    sim = server.t_s
    await server.close()
    return {
        "vehicles": count,
        "speedup_requested": speedup,
        "simulated_s": round(sim, 1),
        "wall_s": round(wall, 2),
        "realtime_factor": round(sim / wall, 1),
        "cpu_percent_of_one_core": round(100.0 * cpu / wall, 1),
        "mavlink_bytes_per_wall_s": round(server.bytes_out / wall),
    }


_SINK = (
    "import socket\n"
    "s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)\n"
    "s.bind(('127.0.0.1', 0))\n"
    "print(s.getsockname()[1], flush=True)\n"
    "while True:\n"
    "    s.recv(65536)\n"
)


def main() -> None:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.split("\n\n")[0])
    parser.add_argument("--counts", default="1,3,10")
    parser.add_argument("--speedups", default="20,50,100,200")
    parser.add_argument("--wall-s", type=float, default=4.0)
    parser.add_argument("--no-json", action="store_true")
    args = parser.parse_args()
    # the stand-in ground station: a separate process that reads and discards everything
    # (a thread here would compete for the GIL and its CPU would count as the simulator's)
    sink = subprocess.Popen([sys.executable, "-c", _SINK], stdout=subprocess.PIPE, text=True)
    assert sink.stdout is not None
    sink_port = int(sink.stdout.readline())
    rows = []
    for count in (int(c) for c in args.counts.split(",")):
        for speedup in (float(k) for k in args.speedups.split(",")):
            row = asyncio.run(measure(count, speedup, args.wall_s, sink_port))
            rows.append(row)
            print(
                f"{count:>3} vehicles  speed-up {speedup:>7g}: real-time factor "
                f"{row['realtime_factor']:>7.1f}, CPU {row['cpu_percent_of_one_core']:>5.1f} %"
                f" of a core, {row['mavlink_bytes_per_wall_s'] / 1000:.0f} kB/s MAVLink",
                flush=True,
            )
            if row["realtime_factor"] < 0.9 * speedup:
                break
    sink.kill()
    sink.wait()
    if not args.no_json:
        out = Path(__file__).with_name("sitl_realtime.json")
        out.write_text(
            json.dumps(
                {"host": platform.platform(), "python": platform.python_version(), "runs": rows},
                indent=2,
            )
            + "\n",
            encoding="utf-8",
        )
        print(f"wrote {out}")


if __name__ == "__main__":
    main()
