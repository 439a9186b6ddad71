"""``gcs sitl``: built-in ArduPlane-like MAVLink vehicles (or real ArduPilot SITL).

    gcs sitl --count 3 --speedup 20 --out udp:127.0.0.1:14550
    gcs sitl --count 2 --scenario default --airborne --alt 120 --fault 2:drop:at=60,for=30
    gcs sitl --ardupilot ~/ardupilot/build/sitl/bin/arduplane --count 3 --speedup 10

Vehicle i (0-based) serves TCP 127.0.0.1:(base + 10 i) with system id i + 1 (base 5760,
like ArduPilot SITL instance i). Ctrl-C stops everything cleanly.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import signal
import sys
import time
from typing import Any

from groundstation.commands.async_main import run_async
from groundstation.commands.sitl_args import (
    DEFAULT_HOME,
    UsageError,
    _check,
    parse_latlon,
    parse_udp_url,
)

__all__ = ["run"]

def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="gcs sitl",
        description="Start N simulated ArduPlane vehicles speaking MAVLink 2 (TCP per vehicle,"
        " optional UDP out) plus the world's detection feed, or N real ArduPilot SITL "
        "instances with --ardupilot.",
    )
    p.add_argument(
        "--count",
        type=int,
        default=None,
        help="number of vehicles (default: the scenario's fleet, else 1)",
    )
    p.add_argument(
        "--speedup", type=float, default=1.0, help="simulated seconds per wall second (default 1)"
    )
    p.add_argument("--seed", type=int, default=0, help="random seed (faults, world)")
    p.add_argument(
        "--scenario",
        default=None,
        help="scenario name or YAML file: origin, fleet, icebergs, boat, events",
    )
    p.add_argument(
        "--base-port",
        type=int,
        default=5760,
        help="TCP port of vehicle 0; vehicle i uses base + 10 i (0: ephemeral)",
    )
    p.add_argument("--host", default="127.0.0.1", help="address the TCP ports bind to")
    p.add_argument(
        "--out",
        default=None,
        metavar="udp:HOST:PORT",
        help="also send every vehicle's MAVLink to this UDP address",
    )
    p.add_argument(
        "--detections",
        default="udp:127.0.0.1:14600",
        metavar="udp:HOST:PORT",
        help="detection feed address (default udp:127.0.0.1:14600; 'none': off)",
    )
    p.add_argument(
        "--anonymous-detections",
        action="store_true",
        help="send detections with target null (the observer associates them)",
    )
    p.add_argument(
        "--wait-for-client",
        action="store_true",
        help="boot each vehicle only when a TCP client connects (like SITL)",
    )
    p.add_argument(
        "--airborne", action="store_true", help="start flying, armed, in AUTO, loitering over home"
    )
    p.add_argument("--alt", type=float, default=100.0, help="altitude for --airborne (m)")
    p.add_argument(
        "--home",
        default=None,
        metavar="LAT,LON",
        help="home (default: the scenario's launch point, else 78.93,11.92)",
    )
    p.add_argument(
        "--fast-boot", action="store_true", help="GPS/EKF settle in 1-2 s instead of 10-20 s"
    )
    p.add_argument(
        "--duration", type=float, default=None, help="stop after this many simulated seconds"
    )
    p.add_argument(
        "--fault",
        action="append",
        default=[],
        metavar="SPEC",
        help="VEHICLES:KIND[:key=value,...], e.g. 1:loss:p=0.2,dir=up, "
        "all:delay:s=0.2,jitter=0.1, 2:drop:at=60,for=20, 2:kill:at=60,for=30, 1:reboot:at=90, "
        "3:mode:at=120,mode=FBWA, 2:battery:at=100,pct=10 (repeatable)",
    )
    p.add_argument("--loss", type=float, default=None, help="packet loss, all links (0-1)")
    p.add_argument("--dup", type=float, default=None, help="duplication, all links (0-1)")
    p.add_argument("--reorder", type=float, default=None, help="reordering, all links (0-1)")
    p.add_argument("--delay-ms", type=float, default=None, help="delay, all links (ms)")
    p.add_argument(
        "--ardupilot",
        default=None,
        metavar="PATH",
        help="run real ArduPlane SITL binaries instead of the built-in vehicles",
    )
    p.add_argument(
        "--camera-of",
        default=None,
        metavar="HOST:PORT,...",
        help="run only the world and its camera, reading vehicle k's position "
        "from the k-th MAVLink TCP endpoint (e.g. SITL containers' SERIAL1)",
    )
    p.add_argument(
        "--ardupilot-defaults",
        default=None,
        metavar="FILE",
        help="defaults file for --ardupilot (default: "
        "Tools/autotest/models/plane.parm of the ArduPilot tree)",
    )
    p.add_argument(
        "--signing-key",
        default=None,
        metavar="FILE",
        help="vehicles start with this MAVLink 2 signing key (32 raw bytes or 64 hex digits); "
        "without a key they accept SETUP_SIGNING from a ground station",
    )
    p.add_argument(
        "--signing-passphrase-file",
        default=None,
        metavar="FILE",
        help="vehicles start with key SHA-256(first line of FILE), as MAVProxy's "
        "`signing setup PASSPHRASE` (or set FLOE_SIGNING_PASSPHRASE)",
    )
    return p


def signing_key(args: argparse.Namespace, environ: dict[str, str] | None = None) -> bytes | None:
    """The key the vehicles start with (``--signing-key``, ``--signing-passphrase-file``,
    else ``FLOE_SIGNING_PASSPHRASE``), None for none. Errors never quote the content."""
    import os
    from pathlib import Path

    from groundstation.mavlink.signing import (
        SigningKeyError,
        key_from_passphrase,
        parse_key_file_bytes,
        parse_passphrase_file_bytes,
    )

    env = os.environ if environ is None else environ
    key_file = getattr(args, "signing_key", None)
    pass_file = getattr(args, "signing_passphrase_file", None)
    if key_file and pass_file:
        raise UsageError("--signing-key and --signing-passphrase-file: give one, not both")
    option, path = ("--signing-key", key_file) if key_file else (
        "--signing-passphrase-file", pass_file)
    try:
        if path:
            try:
                data = Path(path).expanduser().read_bytes()
            except OSError as exc:
                raise UsageError(f"{option}: cannot read {path}: {exc.strerror or exc}") from None
            return parse_key_file_bytes(data) if key_file else parse_passphrase_file_bytes(data)
        if env.get("FLOE_SIGNING_PASSPHRASE"):
            return key_from_passphrase(env["FLOE_SIGNING_PASSPHRASE"])
    except SigningKeyError as exc:
        raise UsageError(f"{option}: {path}: {exc}") from None
    return None


def build(args: argparse.Namespace) -> tuple[Any, ...]:
    """(configs, faults, feed, options) for the built-in simulator from parsed arguments."""
    from sitl.faults import FaultError, VehicleFaults, apply_fault, parse_fault_spec
    from sitl.server import ServerOptions
    from sitl.sitl_setup import scenario_setup

    _check(args)
    scenario = None
    if args.scenario is not None:
        from world.scenario import load_scenario

        scenario = load_scenario(args.scenario)
    count = args.count or (scenario.fleet.count if scenario is not None else 1)
    home = parse_latlon(args.home) if args.home else None
    setup = scenario_setup(scenario, count, home or DEFAULT_HOME, home is not None)
    configs = [
        setup.vehicle_config(i, airborne=args.airborne, airborne_alt_m=args.alt,
                             fast_boot=args.fast_boot, unix_time_at_zero_s=time.time())
        for i in range(count)
    ]
    faults = {c.system_id: VehicleFaults(args.seed * 1000 + c.system_id) for c in configs}
    specs = list(args.fault)
    for name, kind, key in (
        ("loss", "loss", "p"),
        ("dup", "dup", "p"),
        ("reorder", "reorder", "p"),
    ):
        if getattr(args, name) is not None:
            specs.append(f"all:{kind}:{key}={getattr(args, name)}")
    if args.delay_ms is not None:
        specs.append(f"all:delay:s={args.delay_ms / 1000.0}")
    specs += setup.fault_specs
    try:
        for spec in specs:
            for sysid, kind, fault_options in parse_fault_spec(spec, count):
                apply_fault(faults[sysid], kind, fault_options)
    except FaultError as exc:
        raise UsageError(f"--fault: {exc}") from None
    feed = None
    feed_address = None
    if args.detections != "none":
        feed_address = parse_udp_url(args.detections, "--detections")
        feed = setup.make_feed(args.seed, args.anonymous_detections)
    out = parse_udp_url(args.out, "--out") if args.out else None
    options = ServerOptions(
        speedup=args.speedup,
        host=args.host,
        base_port=args.base_port,
        out=out,
        wait_for_client=args.wait_for_client,
        feed_address=feed_address,
    )
    start_key = signing_key(args)
    if start_key is not None:
        options.signing_keys = {c.system_id: start_key for c in configs}
    return configs, faults, feed, options


async def _serve(args: argparse.Namespace) -> int:
    from sitl.server import SitlServer

    configs, faults, feed, options = build(args)
    server = SitlServer(configs, options, faults, feed)
    try:
        await server.start()
    except OSError as exc:
        print(f"gcs sitl: error: cannot open a port: {exc} (try --base-port)", file=sys.stderr)
        await server.close()
        return 1
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, server.stop)
    for line in server.describe():
        print(line, flush=True)
    if options.signing_keys:
        print("signing: vehicles start with a key (MAVLink 2 signing on)", flush=True)
    try:
        await server.run(args.duration)
    finally:
        await server.close()
    for sysid, counts in server.signing_rejected().items():
        if counts:
            print(f"gcs sitl: vehicle {sysid} refused frames failing the signature check: "
                  + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())), flush=True)
    print(
        f"gcs sitl: stopped after {server.t_s:.1f} simulated s "
        f"(real-time factor {server.realtime_factor:.1f})",
        flush=True,
    )
    return 0


def run(argv: list[str]) -> int:
    """Entry point of ``gcs sitl``; returns the exit status."""
    args = _parser().parse_args(argv)
    try:
        if args.camera_of is not None:
            from groundstation.commands.sitl_ardupilot import run_camera_only

            return run_camera_only(args)
        if args.ardupilot is not None:
            from groundstation.commands.sitl_ardupilot import run_ardupilot
            if args.signing_key or args.signing_passphrase_file:
                raise UsageError("--signing-*: real ArduPilot SITL keeps its own key; "
                                 "give it one with `gcs run --signing-setup`")

            return run_ardupilot(args)
        return run_async(lambda: _serve(args))
    except KeyboardInterrupt:
        return 130
    except UsageError as exc:
        print(f"gcs sitl: error: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:  # ScenarioError and other bad input: the message names the field
        print(f"gcs sitl: error: {exc}", file=sys.stderr)
        return 2
