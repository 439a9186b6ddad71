"""Fuzz benchmark of ``gcs run``: hostile MAVLink on one vehicle's link and from another link.

Processes (all on 127.0.0.1, ephemeral ports): ``gcs sitl --airborne`` with N vehicles; a
proxy in front of vehicle 1 (``python -m sitl.flood_proxy --mix fuzz``) that, for
``--seconds``, writes ``--rate`` frames per second into that vehicle's link: random bytes,
wrong-length frames with a valid CRC, valid frames with random field values and forged
battery / boot time / mode / item reached / current frames from another component; and
``gcs run`` connected to the proxy and to the other vehicles, with an ``--out udpin:``
link on which this script sends ``--udp-rate`` frames per second of forged frames with
vehicle 1's own system and component ids plus random valid frames (the other link).

Printed (and written as JSON with ``--json FILE``):

* frames sent (link fuzz, other link);
* task errors in the journal (``task_error``, ``core_error``): must be 0;
* false state changes: journal lines ``reboot``, ``battery_low``, ``override``,
  ``link_lost`` and ``loiter_end`` that the simulated vehicles' real events do not
  explain: must be 0. The truth is a **tap**: this script connects its own TCP client to
  every simulated vehicle (not through the fuzzing proxy, sending nothing) and records
  what each vehicle really said. A ``loiter_end`` is explained by the vehicle's own
  "Loiter time complete" STATUSTEXT or MISSION_ITEM_REACHED on the tap in the 3 mission
  seconds (plus 0.5 wall seconds for the host) before it; a ``battery_low`` by its own
  "Battery" STATUSTEXT in the 10 mission seconds before; a ``reboot`` by its
  ``time_boot_ms`` going back on the tap; ``override`` and ``link_lost`` by nothing (no
  fault is scheduled). (The daemon's journal alone is not the truth: the fuzz on vehicle
  1's link destroys some of its real frames, e.g. a "Loiter time complete" text, as noise
  on a radio does; the daemon then sees the end from MISSION_CURRENT.) A ``loiter_end``
  that the tap saw earlier than that, but within the 30 mission seconds before (a loiter
  lasts far longer, so it is the same end), is **late**, not false: the fuzz destroyed the
  end's own frames and the daemon found it later. Late ends are counted apart, with how
  late (mission s), and are no failure.
* the worst gap between frames the daemon received (tlog reception times) from each of
  the other vehicles during the fuzz window, and in the same length of time before it;
* the daemon's resident memory (VmRSS) just before the fuzz and at the end;
* the system ids the daemon journalled that the simulator never served (phantom vehicles
  made up from fuzzed frames; their lines count among the false state changes).

Exit status 1 if task errors or false state changes were found.

    python benchmarks/fuzz_daemon.py                 # 3 vehicles, 20 000 frames/s for 10 s
                                                     # (writes benchmarks/fuzz_daemon.json)
    python benchmarks/fuzz_daemon.py --quick         # 2 vehicles, 2 s: a smoke test
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import random
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from groundstation.daemon.journal import read_journal
from groundstation.link.tlog import TlogReader
from groundstation.mavlink.codec import MavlinkDecoder
from sitl.forge import forged_frames, random_valid_frame

FALSE_EVENTS = ("reboot", "battery_low", "override", "link_lost")
GCS = str(Path(sys.executable).parent / "gcs")
RESULTS = Path(__file__).with_suffix(".json")


def _start(cmd: list[str], pattern: str, count: int, timeout_s: float) -> tuple[Any, list[str]]:
    proc = subprocess.Popen(
        cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True
    )
    lines: list[str] = []
    end = time.monotonic() + timeout_s
    assert proc.stdout is not None
    while sum(pattern in x for x in lines) < count and time.monotonic() < end:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line.strip())
    if sum(pattern in x for x in lines) < count:
        proc.kill()
        raise SystemExit(f"fuzz_daemon: {cmd[1]} did not start: {lines}")
    return proc, lines


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _rss_kib(pid: int) -> int | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        return None
    return None


def _send_other_link(port: int, rate: float, seconds: float, seed: int) -> int:
    """Forged frames with vehicle 1's ids plus random valid frames, to the daemon's
    ``udpin`` link, ``rate`` per second for ``seconds``; returns how many were sent."""
    rng = random.Random(seed)
    pool = forged_frames(1, 1, seed=seed) * 10
    pool += [random_valid_frame(rng, rng.choice((1, 2, 3, 77)), 1) for _ in range(400)]
    sent = 0
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        start = time.monotonic()
        burst = max(1, round(rate * 0.01))
        next_t = start
        while time.monotonic() - start < seconds:
            for _ in range(burst):
                sock.sendto(pool[sent % len(pool)], ("127.0.0.1", port))
                sent += 1
            next_t += 0.01
            time.sleep(max(0.0, next_t - time.monotonic()))
    return sent


class Tap:
    """A passive TCP client of one simulated vehicle: what it really said, with the wall
    time (Unix) it arrived. Records loiter ends, battery texts and reboots."""

    def __init__(self, port: int) -> None:
        self.port = port
        self.events: list[tuple[float, str]] = []  # (unix s, "loiter_end"|"battery"|"reboot")
        self.frames = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5.0)

    def _run(self) -> None:
        decoder = MavlinkDecoder()
        last_boot_ms: int | None = None
        with socket.create_connection(("127.0.0.1", self.port), timeout=10.0) as sock:
            sock.settimeout(0.2)
            while not self._stop.is_set():
                try:
                    data = sock.recv(65536)
                except TimeoutError:
                    continue
                except OSError:
                    return
                if not data:
                    return
                now = time.time()
                for msg in decoder.feed(data):
                    self.frames += 1
                    kind = msg.get_type()
                    if kind == "MISSION_ITEM_REACHED":
                        self.events.append((now, "loiter_end"))
                    elif kind == "STATUSTEXT":
                        text = str(msg.text)
                        if "Loiter time complete" in text:
                            self.events.append((now, "loiter_end"))
                        elif "Battery" in text:
                            self.events.append((now, "battery"))
                    boot_ms = getattr(msg, "time_boot_ms", None)
                    if isinstance(boot_ms, int) and msg.get_srcComponent() == 1:
                        if last_boot_ms is not None and boot_ms < last_boot_ms - 3000:
                            self.events.append((now, "reboot"))
                        last_boot_ms = boot_ms

    def said(self, kind: str, unix_s: float, before_s: float) -> bool:
        return any(unix_s - before_s <= t <= unix_s + 0.2 and k == kind for t, k in self.events)


LATE_WINDOW_MISSION_S = 30.0
"""A loiter end the tap saw up to this long before the daemon's is the same end, found late."""


def _late_loiter_ends(
    false: list[dict[str, Any]], taps: dict[str, Tap], speedup: float
) -> tuple[list[dict[str, Any]], list[float]]:
    """Split ``false``: the loiter ends a tap saw in the :data:`LATE_WINDOW_MISSION_S`
    before are late (their delays, mission s); the rest stay false."""
    still: list[dict[str, Any]] = []
    late_s: list[float] = []
    window_s = LATE_WINDOW_MISSION_S / speedup
    for e in false:
        tap = taps.get(str(e.get("vehicle")))
        seen = [t for t, kind in (tap.events if tap else []) if kind == "loiter_end"
                and e["unix_s"] - window_s <= t < e["unix_s"]]
        if e["event"] == "loiter_end" and seen:
            late_s.append(round((e["unix_s"] - max(seen)) * speedup, 1))
        else:
            still.append(e)
    return still, late_s


def _false_changes(
    journal: list[dict[str, Any]], taps: dict[str, Tap], speedup: float
) -> list[dict[str, Any]]:
    """State changes that the vehicles' real events (the taps) do not explain."""
    explained = {
        "loiter_end": ("loiter_end", 3.0 / speedup + 0.5),
        "battery_low": ("battery", 10.0 / speedup + 0.5),
        "reboot": ("reboot", 3.0 / speedup + 0.5),
    }
    out = []
    for e in journal:
        name, vehicle = e["event"], str(e.get("vehicle"))
        if name not in (*FALSE_EVENTS, "loiter_end"):
            continue
        tap = taps.get(vehicle)
        kind, before_s = explained.get(name, ("", 0.0))
        if tap is None or not kind or not tap.said(kind, e["unix_s"], before_s):
            out.append(e)
    return out


def _stop_summary(journal: list[dict[str, Any]]) -> dict[str, Any]:
    stops = [e for e in journal if e["event"] == "stop"]
    return stops[-1] if stops else {}


def run(args: argparse.Namespace) -> dict[str, Any]:
    """Run the benchmark; returns the measurements."""
    k = args.speedup
    mission_s = (args.at + args.seconds + 4.0) * k
    sim, lines = _start(
        [GCS, "sitl", "--count", str(args.vehicles), "--base-port", "0", "--scenario",
         "default", "--airborne", "--speedup", f"{k:g}", "--detections", "none",
         "--duration", f"{mission_s * 3:g}"],
        "system id", args.vehicles, 60.0,
    )  # fmt: skip
    ports = [int(x.rsplit(":", 1)[1]) for x in lines if "system id" in x]
    taps = {str(i + 1): Tap(port) for i, port in enumerate(ports)}
    for tap in taps.values():
        tap.start()
    proxy, plines = _start(
        [sys.executable, "-m", "sitl.flood_proxy", "--upstream", str(ports[0]), "--mix",
         "fuzz", "--rate", f"{args.rate:g}", "--at", f"{args.at:g}", "--for",
         f"{args.seconds:g}", "--sysid", "1", "--compid", "191", "--seed", str(args.seed)],
        "listening", 1, 30.0,
    )  # fmt: skip
    proxy_port = int(plines[-1].split()[1])
    out_port = _free_udp_port()
    run_dir = Path(tempfile.mkdtemp(prefix="fuzz-daemon-"))
    vehicles = [f"tcp:127.0.0.1:{proxy_port}"] + [f"tcp:127.0.0.1:{p}" for p in ports[1:]]
    daemon = subprocess.Popen(
        [GCS, "run", "--vehicles", *vehicles, "--out", f"udpin:127.0.0.1:{out_port}",
         "--scenario", "default", "--speedup", f"{k:g}", "--duration", f"{mission_s:g}",
         "--run-dir", str(run_dir), "--http", "off", "--detections", "off",
         "--status", "quiet"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    rss: list[int] = []
    rss_before = None
    udp_sent = 0
    try:
        t0 = time.monotonic()
        while time.monotonic() - t0 < args.at:
            value = _rss_kib(daemon.pid)
            if value is not None:
                rss.append(value)
            time.sleep(0.2)
        rss_before = rss[-1] if rss else None
        udp_sent = _send_other_link(out_port, args.udp_rate, args.seconds, args.seed)
        while daemon.poll() is None:
            value = _rss_kib(daemon.pid)
            if value is not None:
                rss.append(value)
            time.sleep(0.2)
            if time.monotonic() - t0 > mission_s / k + 60.0:
                daemon.terminate()
                break
        daemon.wait(timeout=30)
    finally:
        out, _ = proxy.communicate(input="", timeout=30)
        for tap in taps.values():
            tap.stop()
        sim.kill()
        sim.wait(timeout=10)
    flood = [x for x in out.splitlines() if x.startswith("flood")]
    _, link_sent, span, start_unix, end_unix = (flood[-1] if flood else "flood 0 0 0 0").split()
    journals = sorted(run_dir.rglob("journal.jsonl"))
    journal = read_journal(journals[0]) if journals else []
    start, end = float(start_unix), float(end_unix)
    windows = {"fuzz": (start, end), "before": (start - (end - start), start)}
    times: dict[tuple[str, int], list[float]] = {
        (w, v): [] for w in windows for v in range(2, args.vehicles + 1)
    }
    tlogs = sorted(run_dir.rglob("flight.tlog"))
    for record in TlogReader(tlogs[0]) if tlogs else []:
        sysid = record.message.get_srcSystem()
        for w, (lo, hi) in windows.items():
            if (w, sysid) in times and lo <= record.t_unix_s <= hi:
                times[(w, sysid)].append(record.t_unix_s)
    gaps_ms = {
        f"{w} vehicle {v}": round(
            1000 * max((b - a for a, b in itertools.pairwise(ts)), default=math.inf), 1
        )
        for (w, v), ts in times.items()
    }
    false, late_s = _late_loiter_ends(_false_changes(journal, taps, k), taps, k)
    served = {str(v) for v in range(1, args.vehicles + 1)}
    by_kind: dict[str, int] = {}
    for e in false:
        by_kind[e["event"]] = by_kind.get(e["event"], 0) + 1
    return {
        "frames_sent": int(link_sent) + udp_sent,
        "frames_on_link": int(link_sent),
        "frames_other_link": udp_sent,
        # the rate the proxy reached (tests/test_daemon_trust.py's flood asked 22 000/s and
        # asserted >= 20 000 until issue 30: a figure of a quiet host, kept here)
        "frames_on_link_per_s": round(int(link_sent) / float(span)) if float(span) > 0 else 0,
        "task_errors": len([e for e in journal if e["event"] in ("task_error", "core_error")]),
        "false_state_changes": len(false),
        "false_state_changes_by_event": by_kind,
        "late_loiter_ends_mission_s": late_s,
        "false_on_served_vehicles": [
            {k2: e.get(k2) for k2 in ("t", "event", "vehicle")}
            for e in false
            if str(e.get("vehicle")) in served
        ],
        "phantom_vehicles": sorted(
            {str(e["vehicle"]) for e in journal if e.get("vehicle") is not None} - served,
            key=lambda v: int(v) if v.isdigit() else 0,
        ),
        "worst_telemetry_gap_ms": gaps_ms,
        "tap_frames": {v: tap.frames for v, tap in taps.items()},
        "unknown_systems": _stop_summary(journal).get("unknown_systems"),
        "daemon_rss_kib": {"before_fuzz": rss_before, "end": rss[-1] if rss else None},
        "daemon_exit": daemon.returncode,
        "run_dir": str(run_dir),
    }


def main(argv: list[str] | None = None) -> int:
    """Parse options, run, print; exit status 1 on task errors or false state changes."""
    p = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.split("\n\n")[0])
    p.add_argument("--vehicles", type=int, default=3, help="simulated vehicles (>= 2)")
    p.add_argument("--rate", type=float, default=20_000.0, help="fuzz frames/s on vehicle 1")
    p.add_argument("--udp-rate", type=float, default=1_000.0, help="frames/s, other link")
    p.add_argument("--seconds", type=float, default=10.0, help="fuzz duration (wall s)")
    p.add_argument("--at", type=float, default=6.0, help="fuzz start after connect (wall s)")
    p.add_argument("--speedup", type=float, default=10.0)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--quick", action="store_true", help="2 vehicles, 5000 frames/s for 2 s")
    p.add_argument(
        "--json", type=Path,
        help=f"also write the results to this file (default, without --quick: {RESULTS})",
    )  # fmt: skip
    args = p.parse_args(argv)
    if args.json is None and not args.quick:
        args.json = RESULTS
    if args.quick:
        args.vehicles, args.rate, args.udp_rate, args.seconds, args.at = 2, 5000.0, 500.0, 2.0, 3.0
    if args.vehicles < 2 or args.rate <= 0 or args.seconds <= 0:
        p.error("need --vehicles >= 2, --rate > 0 and --seconds > 0")
    result = run(args)
    for key, value in result.items():
        print(f"{key}: {value}")
    if args.json is not None:
        args.json.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    return 1 if result["task_errors"] or result["false_state_changes"] else 0


if __name__ == "__main__":
    raise SystemExit(main())
