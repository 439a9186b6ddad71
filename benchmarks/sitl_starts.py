"""``gcs run`` against ``gcs sitl``: does a start warn of a silent link that is not?

Issue 29: every start at 5x/10x warned "no vehicle heard in 17 s ... connected but silent"
(the silence was counted on the mission clock from its start). For each speed-up, N times:
start ``gcs sitl --count 3 --speedup K --base-port 0`` (free ports, read from its output),
then ``gcs run`` on those ports at the same speed-up for ``--wall`` seconds of wall time
(log mode, no API, no feed), and count the warnings about silent links; report the wall
seconds until the last vehicle was bound. Then one ``gcs run`` on a closed port: the wall
seconds until its "no vehicle heard" warning (it must still come, within 20 s).

    python benchmarks/sitl_starts.py [--speedups 5,10] [--runs 10] [--wall 15]
"""

from __future__ import annotations

import argparse
import re
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

GCS = [sys.executable, "-m", "groundstation.cli"]
SILENT = re.compile(r"no vehicle heard|connected but silent")


def _sitl(speedup: float) -> tuple[subprocess.Popen[str], list[int]]:
    proc = subprocess.Popen([*GCS, "sitl", "--count", "3", "--speedup", f"{speedup:g}",
                             "--base-port", "0", "--detections", "none"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert proc.stdout is not None
    ports: list[int] = []
    deadline = time.monotonic() + 60.0
    while len(ports) < 3 and time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        if m := re.search(r"system id \d+\): tcp:127\.0\.0\.1:(\d+)", line):
            ports.append(int(m.group(1)))
    if len(ports) < 3:
        proc.kill()
        raise RuntimeError("gcs sitl did not print its ports")
    return proc, ports


def _run(ports: list[int], speedup: float, wall_s: float, run_dir: Path) -> tuple[str, float]:
    """``gcs run`` for ``wall_s`` wall seconds; its output with each line's wall time."""
    urls = [f"tcp:127.0.0.1:{p}" for p in ports]
    start = time.monotonic()
    proc = subprocess.Popen([*GCS, "run", "--vehicles", *urls, "--speedup", f"{speedup:g}",
                             "--duration", f"{wall_s * speedup * 4:g}", "--http", "off",
                             "--detections", "off", "--status", "log", "--run-dir",
                             str(run_dir)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    assert proc.stdout is not None
    lines: list[str] = []
    started: float | None = None
    import selectors

    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    while True:
        now = time.monotonic()
        if started is not None and now - started >= wall_s:
            break
        if now - start > wall_s + 60.0:
            break
        if sel.select(timeout=0.2):
            line = proc.stdout.readline()
            if not line:
                break
            if started is None and "link vehicles0 started" in line:
                started = time.monotonic()
            lines.append(f"{time.monotonic() - (started or start):7.2f} {line}")
    proc.terminate()
    try:
        proc.communicate(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
    return "".join(lines), time.monotonic() - start


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def main() -> int:
    p = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.split("\n\n")[0])
    p.add_argument("--speedups", default="5,10")
    p.add_argument("--runs", type=int, default=10)
    p.add_argument("--wall", type=float, default=15.0, help="wall seconds of each run")
    p.add_argument("--keep", type=Path, default=None, help="keep each run's output here")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for speedup in (float(k) for k in args.speedups.split(",")):
            clean, bound = 0, []
            for i in range(args.runs):
                sitl, ports = _sitl(speedup)
                try:
                    out, _ = _run(ports, speedup, args.wall, Path(tmp))
                finally:
                    sitl.terminate()
                    sitl.wait(20)
                warnings = [line for line in out.splitlines() if SILENT.search(line)]
                times = [float(line.split()[0]) for line in out.splitlines()
                         if re.search(r"system \d+ bound to link", line)]
                if args.keep:
                    args.keep.mkdir(parents=True, exist_ok=True)
                    (args.keep / f"run-{speedup:g}x-{i + 1}.log").write_text(out)
                clean += not warnings
                if len(times) == 3:
                    bound.append(max(times))
                print(f"{speedup:g}x run {i + 1}: {len(warnings)} silent-link warnings; "
                      f"3 vehicles bound {max(times):.1f} wall s after the link started"
                      if len(times) == 3 else f"{speedup:g}x run {i + 1}: "
                      f"{len(warnings)} warnings, {len(times)} of 3 bound", flush=True)
                for w in warnings:
                    print("   ", w.strip())
            spread = f"{min(bound):.1f}-{max(bound):.1f}" if bound else "-"
            print(f"{speedup:g}x: {clean} of {args.runs} starts without a silent-link warning; "
                  f"all 3 bound after {spread} wall s", flush=True)
        out, _ = _run([_closed_port()], 5.0, 25.0, Path(tmp))
        first = next((line for line in out.splitlines() if SILENT.search(line)), None)
        print("unreachable port at 5x: " + (f"warned {float(first.split()[0]):.1f} wall s "
              "after the link started" if first else "NO WARNING in 25 s"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
