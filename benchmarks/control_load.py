"""Benchmark: how long ``gcs run``'s event loop stalls under bursts of HTTP and WebSocket
clients, before and after the control surface's pacing (``daemon/control/pacing.py``).

Two daemons run side by side, each ``gcs run --vehicles sim:3 --scenario discovery
--speedup 1`` with its control API on 127.0.0.1 (ephemeral port): one from this tree
("after"), one from ``--baseline REV`` ("before", extracted with ``git archive`` into a
temporary folder). Each runs a loop-lag monitor of its own inside its event loop (a task
sleeping 5 ms; how late it wakes is the stall; the same in both trees, so the baseline
needs no monitor of its own). The loads, from this process, one daemon at a time and
interleaved (round 1: load A on before, A on after, B on before, ...):

* ``slow-read``: 200 clients connect at once, each sends ``GET /api/state`` and reads the
  answer 64 bytes every 0.2 s for 6 s;
* ``slowloris``: 200 clients connect at once and send their headers one byte every 0.5 s
  (the server cuts them off after its 5 s header timeout);
* ``ws``: 200 WebSocket pages (with permessage-deflate, as browsers ask) connect at once
  and read for 4 s: 16 are served, 184 refused (503);
* ``idle``: no client for 6 s, the floor: what the machine and the daemon's own work give.

Printed: the worst stall of each daemon's loop during each load (wall ms), per round, and
the worst over the rounds. A stall also counts what the machine did to the process (other
programs on the cores): run it on a quiet machine.

    python benchmarks/control_load.py [--baseline 3e03a37] [--rounds 3] [--clients 200]
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Awaitable, Callable
from pathlib import Path

import aiohttp

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("groundstation", "domain", "planner", "observer", "world", "sitl")
#: The commit before the pacing (issue 28): the "before" of the figures in docs/control.md.
DEFAULT_BASELINE = "3e03a37"

CHILD = r"""
import asyncio, sys, time
from groundstation.commands.run import build_config, run_daemon

config = build_config(sys.argv[1:])
worst = [0.0]

async def monitor():
    while True:
        start = time.perf_counter()
        await asyncio.sleep(0.005)
        worst[0] = max(worst[0], (time.perf_counter() - start - 0.005) * 1000.0)

async def commands(daemon):
    loop = asyncio.get_running_loop()
    reader = asyncio.StreamReader()
    await loop.connect_read_pipe(lambda: asyncio.StreamReaderProtocol(reader), sys.stdin)
    while True:
        line = (await reader.readline()).decode().strip()
        if line == "reset":
            worst[0] = 0.0
        elif line == "report":
            print(f"WORST {worst[0]:.1f}", flush=True)
        else:
            daemon.request_stop("benchmark done")
            return

def started(daemon):
    loop = asyncio.get_running_loop()
    loop.create_task(monitor())
    loop.create_task(commands(daemon))
    print(f"URL {daemon.control_url}", flush=True)

asyncio.run(run_daemon(config, print_fn=lambda _: None, install_signals=False,
                       on_started=started))
"""


class Daemon:
    """One ``gcs run`` child with its loop monitor, commanded over stdin."""

    def __init__(self, name: str, source: Path, run_dir: Path) -> None:
        self.name = name
        self.source = source
        self.run_dir = run_dir
        self.proc: asyncio.subprocess.Process | None = None
        self.url = ""

    async def start(self) -> None:
        env = {**os.environ, "PYTHONPATH": str(self.source)}
        self.proc = await asyncio.create_subprocess_exec(
            sys.executable, "-c", CHILD, "--vehicles", "sim:3", "--scenario", "discovery",
            "--speedup", "1", "--duration", "100000", "--http", "127.0.0.1:0",
            "--status", "quiet", "--detections", "off", "--run-dir", str(self.run_dir),
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
            cwd=self.source, env=env)
        assert self.proc.stdout is not None
        while not self.url:
            line = (await asyncio.wait_for(self.proc.stdout.readline(), 60.0)).decode()
            if not line:
                raise RuntimeError(f"{self.name}: the daemon exited")
            if line.startswith("URL "):
                self.url = line.split()[1]

    async def ask(self, command: str) -> str:
        assert self.proc is not None and self.proc.stdin and self.proc.stdout
        self.proc.stdin.write(command.encode() + b"\n")
        await self.proc.stdin.drain()
        if command != "report":
            return ""
        line = (await asyncio.wait_for(self.proc.stdout.readline(), 30.0)).decode()
        return line.split()[1]

    async def stop(self) -> None:
        if self.proc is None or self.proc.returncode is not None:
            return
        with contextlib.suppress(Exception):
            await self.ask("stop")
        try:
            await asyncio.wait_for(self.proc.wait(), 30.0)
        except TimeoutError:
            self.proc.kill()
            await self.proc.wait()


def host_port(url: str) -> tuple[str, int]:
    host, port = url.removeprefix("http://").rsplit(":", 1)
    return host, int(port)


async def slow_read(url: str, clients: int) -> None:
    host, port = host_port(url)

    async def one() -> None:
        try:
            reader, writer = await asyncio.open_connection(host, port, limit=256)
        except OSError:
            return
        try:
            writer.write(f"GET /api/state HTTP/1.1\r\nHost: {host}\r\n\r\n".encode())
            end_s = time.monotonic() + 6.0
            while time.monotonic() < end_s and await reader.read(64):
                await asyncio.sleep(0.2)
        except OSError:
            pass
        finally:
            writer.close()

    await asyncio.gather(*(one() for _ in range(clients)))


async def slowloris(url: str, clients: int) -> None:
    host, port = host_port(url)

    async def one() -> None:
        try:
            reader, writer = await asyncio.open_connection(host, port)
        except OSError:
            return
        try:
            writer.write(f"GET /api/state HTTP/1.1\r\nHost: {host}\r\n".encode())
            end_s = time.monotonic() + 7.0
            while time.monotonic() < end_s and not reader.at_eof():
                await asyncio.sleep(0.5)
                writer.write(b"X")
                await writer.drain()
        except OSError:
            pass
        finally:
            writer.close()

    await asyncio.gather(*(one() for _ in range(clients)))


async def websockets(url: str, clients: int) -> None:
    connector = aiohttp.TCPConnector(limit=0)
    async with aiohttp.ClientSession(connector=connector) as http:
        async def one() -> None:
            with contextlib.suppress(Exception):
                async with http.ws_connect(url + "/ws", compress=15) as ws:
                    end_s = time.monotonic() + 4.0
                    while time.monotonic() < end_s:
                        with contextlib.suppress(TimeoutError):
                            await asyncio.wait_for(ws.receive(), end_s - time.monotonic())

        await asyncio.gather(*(one() for _ in range(clients)))


async def idle(url: str, clients: int) -> None:
    """No client for 6 s: the machine's own noise (other programs, the daemon's work)."""
    await asyncio.sleep(6.0)


LOADS: dict[str, Callable[[str, int], Awaitable[None]]] = {
    "idle": idle, "slow-read": slow_read, "slowloris": slowloris, "ws": websockets}


def extract(revision: str, into: Path) -> Path:
    """The packages of ``revision`` (``git archive``) in ``into``."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", revision, *PACKAGES],
                             check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    return into


async def main() -> None:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", default=DEFAULT_BASELINE,
                        help="git revision measured as 'before' (default %(default)s)")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--clients", type=int, default=200)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="floe-control-load-") as tmp:
        before_src = Path(tmp) / "before"
        before_src.mkdir()
        extract(args.baseline, before_src)
        daemons = [Daemon("before", before_src, Path(tmp) / "runs-before"),
                   Daemon("after", ROOT, Path(tmp) / "runs-after")]
        try:
            await asyncio.gather(*(d.start() for d in daemons))
            await asyncio.sleep(5.0)  # past the start-up (first plans, solver warm-up)
            results: dict[tuple[str, str], list[float]] = {}
            for round_ in range(1, args.rounds + 1):
                for load_name, load in LOADS.items():
                    for daemon in daemons:
                        await daemon.ask("reset")
                        await load(daemon.url, args.clients)
                        await asyncio.sleep(1.0)  # connections closing
                        worst_ms = float(await daemon.ask("report"))
                        results.setdefault((load_name, daemon.name), []).append(worst_ms)
                        print(f"round {round_} {load_name:9s} {daemon.name:6s} worst loop "
                              f"stall {worst_ms:7.1f} ms", flush=True)
            print(f"\n{args.clients} clients at once, gcs run --vehicles sim:3 --scenario "
                  f"discovery --speedup 1; worst loop stall over {args.rounds} rounds (ms)")
            print(f"{'load':10s} {'before ' + args.baseline:>16s} {'after':>10s}")
            for load_name in LOADS:
                before = max(results[(load_name, 'before')])
                after = max(results[(load_name, 'after')])
                print(f"{load_name:10s} {before:16.1f} {after:10.1f}")
        finally:
            await asyncio.gather(*(d.stop() for d in daemons))


if __name__ == "__main__":
    asyncio.run(main())
