"""What a SiK radio link costs floe's traffic, in the built-in simulator (simulated time).

    python benchmarks/sim_radio.py [--radio sik] [--duration 600] [--uploads 40]
        [--items 3 6] [--daemon]

1. **Telemetry.** Three airborne vehicles, each on its own radio pair (``--radio``, default
   ``sik``: 57 600 baud, 64 kbit/s air, 1 % loss in bursts of 3), streaming ArduPlane's
   default telemetry (every stream at 1 Hz), a ground station on each link sending a
   HEARTBEAT a second (as floe does), for ``--duration`` simulated seconds. Per link: air
   time used (% of the elapsed time: every packet of both radios, and the share carrying
   data), serial capacity used (% of 5 760 B/s each way), latency serial in -> serial out
   p50/p95 each way, drops and lost packets.
2. **A target upload**, through floe's own sans-IO machines with the daemon's settings on a
   constrained link (``_Upload``): ``--uploads`` of them at random times on link 1 while its
   telemetry runs, for each mission length of ``--items`` (3: paper-boat's target mission;
   6: a discovery pass through 3 more cells), each with three of floe's upload rules:
   ``before`` issue 28's resends, ``resend`` (a lost item resent after one timeout, a lost
   final ACK probed for: one item per request) and ``now`` (the same, pipelined: item 0 with
   MISSION_COUNT and the rest once the vehicle's first request shows the upload open,
   ``MissionUpload``'s ``window``): frames each way and seconds from MISSION_COUNT to the
   verified read-back (p50/p95/max).
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
from groundstation.mavlink.link_budget import (
    PIPELINE_ITEMS,
    SIK_DOWNLINK_BPS,
    LinkBudget,
    ack_retries,
)
from groundstation.mavlink.mission_download import MissionDownload
from groundstation.mavlink.mission_items import LoiterUnlimited, Waypoint, build_mission_items
from groundstation.mavlink.mission_transfer import Send
from groundstation.mavlink.mission_upload import MissionUpload
from groundstation.mavlink.mission_verify import compare_missions
from sitl.loopback import MemoryClient
from sitl.radio import RadioEnd
from sitl.server import ServerOptions, SitlServer
from sitl.vehicle import SimVehicle, VehicleConfig

M = mavlink2
STEP_S = 0.02
RULES = (("before", False, 1), ("resend", True, 1), ("now", True, PIPELINE_ITEMS))
"""floe's upload rules compared: (name, resend_items, window)."""
ORIGIN = GeoOrigin(78.93, 11.92)


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
    """floe's upload and verifying download of an ``items``-item mission, through its own
    sans-IO machines (:class:`MissionUpload`, :class:`MissionDownload`) with the settings the
    daemon uses on a constrained link (``daemon/vehicle_port.py``): timeouts from the link's
    RTT estimate (:class:`LinkBudget`), ``ack_retries`` for 1.5 s, the pipelined download of
    the count just uploaded, and, unless ``resend`` is False (floe before issue 28's
    resends), a lost item resent after one timeout and a lost final ACK probed for. A
    failed round is tried again after floe's retry pause, as the session does."""

    RETRY_PAUSE_S = 0.5

    def __init__(self, enc: MavlinkEncoder, budget: LinkBudget, t_s: float, count: int,
                 resend: bool, window: int = 1) -> None:
        self.enc, self.budget, self.resend, self.window = enc, budget, resend, window
        self.t0_s = t_s
        self.items = _mission(count)
        self.sent = self.received = 0
        self.done_s: float | None = None
        self.machine: Any = None
        self.wait_until_s: float | None = None
        self.out: list[bytes] = []

    def _run(self, machine: Any, t_s: float) -> None:
        self.machine = machine
        self._act(machine.start(t_s), t_s)

    def start(self, t_s: float) -> None:
        timeout_s = self.budget.transfer_timeout_s()
        self._run(MissionUpload(1, 1, self.items, timeout_s=timeout_s, own_system=245,
                                own_component=190, resend_items=self.resend,
                                ack_retries=ack_retries(timeout_s), window=self.window),
                  t_s)

    def _act(self, actions: list[Any], t_s: float) -> None:
        for action in actions:
            if isinstance(action, Send):
                self.sent += 1
                self.out.append(self.enc.encode(action.msg))
        machine = self.machine
        if machine is None or not machine.done:
            return
        for rtt_s in machine.rtt_samples_s:
            self.budget.rtt.sample(rtt_s)
        machine.rtt_samples_s.clear()
        result = machine.result
        if isinstance(machine, MissionUpload):
            if result.ok or result.maybe_stored:
                self._run(MissionDownload(1, 1, window=PIPELINE_ITEMS,
                                          expect_count=len(self.items),
                                          timeout_s=self.budget.transfer_timeout_s(),
                                          own_system=245, own_component=190), t_s)
                return
        elif result.ok and result.items is not None and not compare_missions(
                self.items, result.items):
            self.done_s, self.machine = t_s, None
            return
        self.machine, self.wait_until_s = None, t_s + self.RETRY_PAUSE_S

    def on(self, msg: Any, t_s: float) -> None:
        """One frame from the vehicle."""
        if self.machine is not None:
            before = self.sent
            self._act(self.machine.receive(msg, t_s), t_s)
            if msg.get_type().startswith("MISSION") or self.sent != before:
                self.received += 1

    def tick(self, t_s: float) -> list[bytes]:
        if self.machine is not None:
            self._act(self.machine.poll(t_s), t_s)
        elif self.done_s is None and self.wait_until_s is not None and t_s >= self.wait_until_s:
            self.wait_until_s = None
            self.start(t_s)
        out, self.out = self.out, []
        return out


def _mission(count: int) -> list[Any]:
    """A target mission as floe uploads one: home, ``count - 2`` points to fly through (a
    discovery pass: the aim and the route's next cells), the hold over the last."""
    points = [Waypoint(900.0 + 300.0 * k, 400.0 * (k % 2), 100.0) for k in range(count - 2)]
    last = points[-1]
    return build_mission_items(
        [*points, LoiterUnlimited(last.x_m, last.y_m, 100.0, radius_m=120)], ORIGIN)


def run(radio: str, duration_s: float, uploads: int, seed: int, count: int = 3,
        resend: bool = True, window: int = 1) -> dict[str, Any]:
    server, grounds = _server(3, radio)
    encoders = [MavlinkEncoder(245, 190) for _ in grounds]
    budget = LinkBudget(configured_bps=SIK_DOWNLINK_BPS)
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
                    upload = _Upload(enc, budget, t, count, resend, window)
                    upload.start(t)
                if upload is not None:
                    for msg in ground.msgs:
                        upload.on(msg, t)
                    frames += upload.tick(t)
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
    p.add_argument("--items", type=int, nargs="+", default=[3, 6])
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--daemon", action="store_true")
    args = p.parse_args()
    print(f"radio {args.radio}: 3 airborne vehicles, default telemetry, {args.duration:g} "
          "simulated s")
    first = True
    rows = []
    for count in args.items:
        for rule, resend, window in RULES:
            result = run(args.radio, args.duration, args.uploads, args.seed, count, resend,
                         window)
            if first:
                _print_links(result["links"])
                first = False
            done: list[_Upload] = result["uploads"]
            seconds = [u.done_s - u.t0_s for u in done if u.done_s is not None]
            rows.append((count, rule, len(done), done, seconds))
    print(f"\ntarget upload + verifying download, link 1, {args.uploads} at random times "
          "(s from MISSION_COUNT to the verified read-back; floe's own machines):")
    print("items  upload rule  done   frames up/down   p50 s   p95 s   max s")
    for count, rule, n, done, seconds in rows:
        if not seconds:
            print(f"{count:5d}  {rule:<11}  {n:4d}   (none finished)")
            continue
        print(f"{count:5d}  {rule:<11}  {n:4d}   {statistics.mean(u.sent for u in done):5.1f} / "
              f"{statistics.mean(u.received for u in done):5.1f}    {_pct(0.5, seconds):5.2f}"
              f"   {_pct(0.95, seconds):5.2f}   {max(seconds):5.2f}")
    if args.daemon:
        _daemon(args.radio)


if __name__ == "__main__":
    main()
