"""A UDP flood on one vehicle link next to a normal 10 Hz vehicle on another (issue 10.5).

Used by ``tests/test_link_flood.py`` and ``benchmarks/link_flood.py``. The senders run in
another process (stdlib only, bounded in time), so the receiving event loop competes with
them only for cores. Latency is measured per frame of the normal vehicle: the time its
frame reached the router's callback minus the time the sender sent it, both
``time.monotonic()`` (CLOCK_MONOTONIC, one clock for every process on Linux).

Each latency and gap is also counted in the time the receiving loop actually ran (the CPU
time of its thread over the same interval, sampled every 2 ms): the delay the flood can
cause, since the flood's work is done on that thread. On a quiet host the two agree; on a
loaded one the wall figures also hold the time the host did not run the loop at all, which
is no flood's doing (tests assert on the run figures; benchmarks/link_flood.py prints both).
"""

from __future__ import annotations

import asyncio
import bisect
import itertools
import json
import sys
import time
from dataclasses import dataclass, field
from typing import Any

from groundstation.link import LinkOptions, Received, Router, open_link
from groundstation.link.tcp import TcpServerLink
from groundstation.link.udp import UdpInLink
from groundstation.mavlink.codec import MavlinkEncoder, mavlink2

FLOOD_SYSID = 1
NORMAL_SYSID = 2

_SENDER = r"""
import json, socket, sys, time
cfg = json.load(sys.stdin)
flood = [bytes.fromhex(h) for h in cfg["flood"]]
normal = [bytes.fromhex(h) for h in cfg["normal"]]
fa, na = tuple(cfg["flood_addr"]), tuple(cfg["normal_addr"])
rate, duration, period = cfg["datagrams_per_s"], cfg["duration_s"], cfg["period_s"]
tcp = cfg["transport"] == "tcp"
if tcp:
    fs = socket.create_connection(fa)
    fs.setblocking(False)
else:
    fs = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
ns = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
sent, k, sent_at, errors, pending = 0, 0, [], 0, b""
t0 = time.monotonic()
while True:
    elapsed = time.monotonic() - t0
    if elapsed >= duration:
        break
    while k < len(normal) and k * period <= elapsed:
        ns.sendto(normal[k], na)
        sent_at.append(time.monotonic())
        k += 1
    target, n = int(rate * elapsed), 0
    while sent < target and n < 256:
        try:
            if tcp:  # never block: a full socket buffer skips the chunk (and counts it)
                pending = pending or flood[sent % len(flood)]
                pending = pending[fs.send(pending):]
            else:
                fs.sendto(flood[sent % len(flood)], fa)
        except OSError:
            errors += 1
        sent += 1
        n += 1
    if sent >= target:
        time.sleep(0.0005)
print(json.dumps({"flood_datagrams": sent, "sent_at": sent_at, "errors": errors,
                  "elapsed_s": time.monotonic() - t0}))
"""


@dataclass
class FloodResult:
    """What the normal vehicle and the two links saw during one flood."""

    fair: bool
    transport: str
    flood_frames_per_s: float
    normal_sent: int
    normal_delivered: int
    worst_latency_ms: float
    worst_gap_ms: float
    worst_latency_run_ms: float
    worst_gap_run_ms: float
    flood_delivered: int
    flood_heartbeats_delivered: int
    flood_link: dict[str, int] = field(default_factory=dict)
    normal_link: dict[str, int] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """Plain dict (for JSON)."""
        return dict(self.__dict__)


def _ran_between(cpu: list[tuple[float, float]], lo: float, hi: float) -> float:
    """CPU seconds the sampled thread ran between monotonic times ``lo`` and ``hi``, from
    ``cpu`` = [(monotonic, thread CPU)], interpolated linearly between samples."""

    def at(t: float) -> float:
        i = bisect.bisect_left(cpu, (t, -float("inf")))
        if i <= 0:
            return cpu[0][1]
        if i >= len(cpu):
            return cpu[-1][1]
        (t0, c0), (t1, c1) = cpu[i - 1], cpu[i]
        return c0 + (c1 - c0) * min(1.0, (t - t0) / (t1 - t0)) if t1 > t0 else c1

    return max(0.0, at(hi) - at(lo)) if cpu else hi - lo


async def _sample_cpu(cpu: list[tuple[float, float]]) -> None:
    """Every 2 ms of the event loop: (monotonic time, CPU time of the loop's thread)."""
    while True:
        cpu.append((time.monotonic(), time.thread_time()))
        await asyncio.sleep(0.002)


def _flood_datagrams(frames_per_datagram: int) -> list[bytes]:
    """99 datagrams of ATTITUDE frames, then one HEARTBEAT alone (a priority item)."""
    enc = MavlinkEncoder(FLOOD_SYSID, 1)
    out = []
    for d in range(99):
        out.append(
            b"".join(
                enc.encode(enc.mav.attitude_encode(d * 100 + i, 0.1, 0.2, 0.3, 0.0, 0.0, 0.0))
                for i in range(frames_per_datagram)
            )
        )
    out.append(
        enc.encode(
            enc.mav.heartbeat_encode(
                mavlink2.MAV_TYPE_FIXED_WING, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 10, 4
            )
        )
    )
    return out


def _normal_frames(count: int) -> list[bytes]:
    """ATTITUDE frames of the normal vehicle; ``time_boot_ms`` is the sequence number."""
    enc = MavlinkEncoder(NORMAL_SYSID, 1)
    return [
        enc.encode(enc.mav.attitude_encode(k, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)) for k in range(count)
    ]


async def run_flood(
    *,
    fair: bool = True,
    transport: str = "udp",
    duration_s: float = 3.0,
    datagrams_per_s: int = 4000,
    frames_per_datagram: int = 50,
    period_s: float = 0.1,
) -> FloodResult:
    """Flood one link (``udpin:``, or ``tcpin:`` for ``transport="tcp"``) for
    ``duration_s`` while a 10 Hz vehicle talks on another (``udpin:``). Over TCP the
    sender never blocks: what the socket does not take is skipped (``errors``)."""
    options = LinkOptions(fair=fair)
    delivered_at: dict[int, float] = {}
    flood_types: list[str] = []

    def on_frame(rx: Received) -> None:
        if rx.system_id == NORMAL_SYSID:
            delivered_at[int(rx.message.time_boot_ms)] = time.monotonic()
        else:
            flood_types.append(rx.message.get_type())

    router = Router(on_vehicle_frame=on_frame)
    url = "tcpin:127.0.0.1:0" if transport == "tcp" else "udpin:127.0.0.1:0"
    flooded = open_link(url, link_id="flooded", options=options)
    normal = open_link("udpin:127.0.0.1:0", link_id="normal", options=options)
    router.add_vehicle_link(flooded)
    router.add_vehicle_link(normal)
    count = int(duration_s / period_s)
    config = {
        "flood": [d.hex() for d in _flood_datagrams(frames_per_datagram)],
        "normal": [f.hex() for f in _normal_frames(count)],
        "datagrams_per_s": datagrams_per_s,
        "duration_s": duration_s,
        "period_s": period_s,
        "transport": transport,
    }
    cpu: list[tuple[float, float]] = []
    sampler = asyncio.create_task(_sample_cpu(cpu))
    async with router:
        assert isinstance(flooded, UdpInLink | TcpServerLink)
        assert isinstance(normal, UdpInLink)
        config["flood_addr"] = list(flooded.local_address)
        config["normal_addr"] = list(normal.local_address)
        proc = await asyncio.create_subprocess_exec(
            sys.executable,
            "-c",
            _SENDER,
            stdin=asyncio.subprocess.PIPE,
            stdout=asyncio.subprocess.PIPE,
        )
        out, _ = await asyncio.wait_for(
            proc.communicate(json.dumps(config).encode()), timeout=duration_s + 30.0
        )
        report = json.loads(out)
        # let the last frames through (bounded)
        deadline = time.monotonic() + 2.0
        while (flooded.pending or normal.pending) and time.monotonic() < deadline:
            await asyncio.sleep(0.01)
        await asyncio.sleep(0.05)
    sampler.cancel()
    sent_at: list[float] = report["sent_at"]
    spans = [(t, delivered_at[k]) for k, t in enumerate(sent_at) if k in delivered_at]
    latencies = [b - a for a, b in spans]
    times = [delivered_at[k] for k in sorted(delivered_at)]
    gaps = [b - a for a, b in itertools.pairwise(times)]
    latencies_run = [_ran_between(cpu, a, b) for a, b in spans]
    gaps_run = [_ran_between(cpu, a, b) for a, b in itertools.pairwise(times)]
    return FloodResult(
        fair=fair,
        transport=transport,
        flood_frames_per_s=round(
            report["flood_datagrams"] * (99 * frames_per_datagram + 1) / 100 / report["elapsed_s"]
        ),
        normal_sent=len(sent_at),
        normal_delivered=len(delivered_at),
        worst_latency_ms=round(1000 * max(latencies, default=float("inf")), 1),
        worst_gap_ms=round(1000 * max(gaps, default=float("inf")), 1),
        worst_latency_run_ms=round(1000 * max(latencies_run, default=float("inf")), 1),
        worst_gap_run_ms=round(1000 * max(gaps_run, default=float("inf")), 1),
        flood_delivered=len(flood_types),
        flood_heartbeats_delivered=flood_types.count("HEARTBEAT"),
        flood_link=flooded.counters.receive_summary()
        | {"dropped_priority": flooded.counters.rx_dropped_priority},
        normal_link=normal.counters.receive_summary()
        | {"dropped_priority": normal.counters.rx_dropped_priority},
    )
