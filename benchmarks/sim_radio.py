"""What a SiK radio link costs floe's traffic, in the built-in simulator (simulated time).

    python benchmarks/sim_radio.py [--radio sik] [--duration 600] [--uploads 40] [--daemon]

1. **Telemetry.** Three airborne vehicles, each on its own radio pair (``--radio``, default
   ``sik``: 57 600 baud, 64 kbit/s air, 1 % loss in bursts of 3), streaming ArduPlane's
   default telemetry (every stream at 1 Hz), a ground station on each link sending a
   HEARTBEAT a second (as floe does), for ``--duration`` simulated seconds. Per link: air
   time used (% of the elapsed time: every packet of both radios, and the share carrying
   data), serial capacity used (% of 5 760 B/s each way), latency serial in -> serial out
   p50/p95 each way, drops and lost packets.
2. **A target upload**, as floe sends one (MISSION_COUNT 3, the items on request, the ACK,
   then the verifying download: REQUEST_LIST, COUNT, each item, ACK) on one of those
   links while its telemetry runs: ``--uploads`` of them at random times; frames each way
   and seconds from MISSION_COUNT to the last ACK (p50/p95), a request repeated after
   1.5 s of silence (floe's ``transfer_timeout_s``).
3. With ``--daemon``: ``gcs run --vehicles sim:3 --scenario paper-boat --sim-radio RADIO
   --speedup 20 --duration 300`` in this process; the radios' figures from
   ``SitlServer.radio_stats()`` and the run's uploads.

Everything runs on the simulated clock (no sockets in parts 1 and 2), so the figures do not
depend on the host. Prints a table.
"""

from __future__ import annotations

import argparse
import random
import statistics
from typing import Any

from domain.geodesy import GeoOrigin
from domain.radio_spec import parse_radio_spec
from groundstation.mavlink.codec import MavlinkEncoder, mavlink2
from sitl.loopback import MemoryClient
from sitl.radio import RadioEnd
from sitl.server import ServerOptions, SitlServer
from sitl.vehicle import SimVehicle, VehicleConfig

M = mavlink2
STEP_S = 0.02
RETRY_S = 1.5


def _server(count: int, radio: str) -> tuple[SitlServer, list[MemoryClient]]:
    _, spec = parse_radio_spec(radio, count)
    assert spec is not None, "a radio is needed"
    origin = GeoOrigin(78.93, 11.92)
    configs = [VehicleConfig(system_id=i + 1, origin=origin, home_lat_deg=78.93,
                             home_lon_deg=11.92, airborne=True, fast_boot=True,
                             launch_heading_rad=i * 2.0) for i in range(count)]
    server = SitlServer(configs, ServerOptions(base_port=0, radios={
        c.system_id: spec for c in configs}))
    grounds = []
    for slot in server.slots:
        slot.vehicle = SimVehicle(slot.config, 0.0)
        ground = MemoryClient()
        slot.clients.add(ground)  # type: ignore[arg-type]
        grounds.append(ground)
    return server, grounds


class _Upload:
    """floe's target upload and verifying download, scripted (3 items)."""

    def __init__(self, enc: MavlinkEncoder, t_s: float) -> None:
        self.enc = enc
        self.t0_s = self.last_s = t_s
        self.phase = "upload"
        self.sent = 0
        self.received = 0
        self.done_s: float | None = None
        self.count = 3
        self.last: bytes = b""

    def _send(self, msg: Any, t_s: float) -> bytes:
        self.sent += 1
        self.last_s = t_s
        self.last = self.enc.encode(msg)
        return self.last

    def start(self, t_s: float) -> bytes:
        return self._send(M.MAVLink_mission_count_message(1, 1, self.count, 0), t_s)

    def item(self, seq: int) -> Any:
        if seq == 0:
            return M.MAVLink_mission_item_int_message(1, 1, 0, 0, 16, 0, 1, 0, 0, 0, 0,
                                                      789300000, 119200000, 0.0, 0)
        return M.MAVLink_mission_item_int_message(1, 1, seq, 3, 19 if seq == 1 else 16, 0, 1,
                                                  60.0 if seq == 1 else 0.0, 0, 120.0, 0,
                                                  789300000 + 9000 * seq, 119200000, 100.0, 0)

    def on(self, msg: Any, t_s: float) -> list[bytes]:
        """Answer one frame from the vehicle."""
        kind = msg.get_type()
        if kind not in ("MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK",
                        "MISSION_COUNT", "MISSION_ITEM_INT"):
            return []
        self.received += 1
        if self.phase == "upload":
            if kind in ("MISSION_REQUEST", "MISSION_REQUEST_INT"):
                return [self._send(self.item(int(msg.seq)), t_s)]
            if kind == "MISSION_ACK":
                self.phase = "download"
                return [self._send(M.MAVLink_mission_request_list_message(1, 1, 0), t_s)]
        elif self.phase == "download":
            if kind == "MISSION_COUNT":
                return [self._send(M.MAVLink_mission_request_int_message(1, 1, 0, 0), t_s)]
            if kind == "MISSION_ITEM_INT":
                seq = int(msg.seq)
                if seq + 1 < self.count:
                    return [self._send(M.MAVLink_mission_request_int_message(1, 1, seq + 1, 0),
                                       t_s)]
                self.phase = "done"
                self.done_s = t_s
                return [self._send(M.MAVLink_mission_ack_message(1, 1, 0, 0), t_s)]
        return []

    def retry(self, t_s: float) -> list[bytes]:
        if self.phase != "done" and t_s - self.last_s > RETRY_S:
            self.sent += 1
            self.last_s = t_s
            return [self.last]
        return []


def run(radio: str, duration_s: float, uploads: int, seed: int) -> dict[str, Any]:
    server, grounds = _server(3, radio)
    encoders = [MavlinkEncoder(245, 190) for _ in grounds]
    rng = random.Random(seed)
    starts = sorted(rng.uniform(30.0, duration_s - 20.0) for _ in range(uploads))
    upload: _Upload | None = None
    done: list[_Upload] = []
    t = 0.0
    while t < duration_s - 1e-9:
        t = round(t + STEP_S, 6)
        for slot, ground, enc in zip(server.slots, grounds, encoders, strict=True):
            assert slot.radio is not None
            frames: list[bytes] = []
            if t % 1.0 < STEP_S - 1e-9:
                frames.append(enc.encode(M.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3)))
            if slot.index == 0:
                if upload is None and starts and t >= starts[0]:
                    starts.pop(0)
                    upload = _Upload(enc, t)
                    frames.append(upload.start(t))
                if upload is not None:
                    for msg in ground.msgs:
                        frames += upload.on(msg, t)
                    frames += upload.retry(t)
                    if upload.done_s is not None:
                        done.append(upload)
                        upload = None
            ground.msgs.clear()
            for data in frames:
                slot.radio.write(RadioEnd.GROUND, data, server.t_s)
        server.advance(t)
    return {"links": server.radio_stats(), "uploads": done}


def _pct(q: float, values: list[float]) -> float:
    values = sorted(values)
    return values[min(len(values) - 1, int(q * len(values)))]


def _print_links(links: dict[int, dict[str, Any]]) -> None:
    print("link  air used %  (data %)  serial down/up %  latency down p50/p95 ms  "
          "up p50/p95 ms  lost pkts  dropped B")
    for sysid, s in sorted(links.items()):
        down, up = s["down"], s["up"]
        print(f"{sysid:>4}  {s['air_pct']:10.1f}  ({s['data_air_pct']:5.1f})  "
              f"{down['serial_pct']:7.1f} / {up['serial_pct']:4.1f}  "
              f"{_ms(down['latency_p50_s']):>14} / {_ms(down['latency_p95_s']):<6}  "
              f"{_ms(up['latency_p50_s']):>5} / {_ms(up['latency_p95_s']):<5}  "
              f"{down['packets_lost'] + up['packets_lost']:9d}  "
              f"{down['bytes_dropped'] + up['bytes_dropped']:9d}")


def _ms(value: float | None) -> str:
    return "-" if value is None else f"{value * 1000:.0f}"


def _daemon(radio: str) -> None:
    import asyncio
    import tempfile

    from groundstation.commands.embedded_sim import build_embedded_sim
    from groundstation.commands.run import build_config
    from groundstation.daemon.startup import run_daemon

    sims: list[Any] = []

    def factory(*args: Any) -> Any:
        sim = build_embedded_sim(*args)
        sims.append(sim)
        return sim

    with tempfile.TemporaryDirectory() as run_dir:
        config = build_config(["--vehicles", "sim:3", "--scenario", "paper-boat", "--sim-radio",
                               radio, "--speedup", "20", "--duration", "300", "--run-dir",
                               run_dir, "--http", "off", "--detections", "off", "--status",
                               "quiet"])
        daemon = asyncio.run(run_daemon(config, embedded=factory, print_fn=lambda _: None,
                                        install_signals=False))
        summary = daemon.summary()
    print(f"\ngcs run --vehicles sim:3 --scenario paper-boat --sim-radio {radio} "
          f"--speedup 20 --duration 300: uploads {summary['uploads_ok']} ok / "
          f"{summary['uploads_failed']} failed")
    _print_links(sims[0].radio_stats())


def main() -> None:
    p = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    p.add_argument("--radio", default="sik")
    p.add_argument("--duration", type=float, default=600.0)
    p.add_argument("--uploads", type=int, default=40)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--daemon", action="store_true")
    args = p.parse_args()
    result = run(args.radio, args.duration, args.uploads, args.seed)
    print(f"radio {args.radio}: 3 airborne vehicles, default telemetry, {args.duration:g} "
          "simulated s")
    _print_links(result["links"])
    done: list[_Upload] = result["uploads"]
    seconds = [u.done_s - u.t0_s for u in done if u.done_s is not None]
    print(f"\ntarget upload + verifying download (3 items), link 1, {len(done)} of "
          f"{args.uploads}: frames up {statistics.mean(u.sent for u in done):.1f}, down "
          f"{statistics.mean(u.received for u in done):.1f} (mean); seconds p50 "
          f"{_pct(0.5, seconds):.2f}, p95 {_pct(0.95, seconds):.2f}, max {max(seconds):.2f}")
    if args.daemon:
        _daemon(args.radio)


if __name__ == "__main__":
    main()
