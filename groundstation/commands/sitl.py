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

from domain.errors import UsageError
from groundstation.commands.async_main import run_async
from groundstation.commands.sitl_args import (
    DEFAULT_HOME,
    SitlOptions,
    sitl_options,
)

__all__ = ["build", "parse_options", "run", "signing_key"]


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        allow_abbrev=False,
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
        "--wind",
        default=None,
        metavar="SPEED_M_S,FROM_DEG[,GUST_M_S]",
        help="wind the vehicles fly in, e.g. 10,270 (10 m/s from the west); default: the "
        "scenario's, else calm. Sets SIM_WIND_SPD/SIM_WIND_DIR/SIM_WIND_TURB (also with "
        "--ardupilot)",
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
        "3:mode:at=120,mode=FBWA, 2:battery:at=100,pct=10, 1:airspeed:at=120,for=60 "
        "(repeatable)",
    )
    p.add_argument("--loss", type=float, default=None, help="packet loss, all links (0-1)")
    p.add_argument("--dup", type=float, default=None, help="duplication, all links (0-1)")
    p.add_argument("--reorder", type=float, default=None, help="reordering, all links (0-1)")
    p.add_argument("--delay-ms", type=float, default=None, help="delay, all links (ms)")
    p.add_argument(
        "--sim-radio",
        action="append",
        default=[],
        metavar="SPEC",
        help="links through a simulated SiK telemetry radio pair: sik[,baud=57600,air=64,"
        "loss=0.01,burst=3,ecc=0,window=131,buffer=1850,seed=N]; VEHICLES:sik,... for some "
        "vehicles; none (repeatable, after the scenario's radio:; docs/sitl.md)",
    )
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


def parse_options(argv: list[str]) -> SitlOptions:
    """``argv`` -> the checked, frozen options (raises UsageError naming the option)."""
    return sitl_options(_parser().parse_args(argv))


def signing_key(options: SitlOptions, environ: dict[str, str] | None = None) -> bytes | None:
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
    key_file, pass_file = options.signing_key_file, options.signing_passphrase_file
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
            option, path = "FLOE_SIGNING_PASSPHRASE", "(environment)"
            return key_from_passphrase(env["FLOE_SIGNING_PASSPHRASE"])
    except SigningKeyError as exc:
        raise UsageError(f"{option}: {path}: {exc}") from None
    return None


def build(options: SitlOptions) -> tuple[Any, ...]:
    """(configs, faults, feed, server options) for the built-in simulator."""
    from domain.radio_spec import RadioSpecError, radio_assignments
    from sitl.faults import FaultError, build_faults, fault_specs
    from sitl.server import ServerOptions
    from sitl.sitl_setup import scenario_setup

    scenario = None
    if options.scenario is not None:
        from world.scenario import load_scenario

        scenario = load_scenario(options.scenario)
    count = options.count or (scenario.fleet.count if scenario is not None else 1)
    home = options.home
    setup = scenario_setup(scenario, count, home or DEFAULT_HOME, home is not None)
    configs = [
        setup.vehicle_config(i, airborne=options.airborne, airborne_alt_m=options.alt_m,
                             fast_boot=options.fast_boot, unix_time_at_zero_s=time.time(),
                             wind=options.wind, wind_seed=options.seed)
        for i in range(count)
    ]
    specs = fault_specs(
        options.faults, loss=options.loss, dup=options.dup, reorder=options.reorder,
        delay_s=options.delay_s, scripted=setup.fault_specs,
    )
    try:
        faults = build_faults(specs, [c.system_id for c in configs], options.seed)
    except FaultError as exc:
        raise UsageError(f"--fault: {exc}") from None
    try:
        radios = radio_assignments([*setup.radio_specs, *options.radio],
                                   [c.system_id for c in configs])
    except RadioSpecError as exc:
        raise UsageError(f"--sim-radio: {exc}") from None
    feed = None
    if options.detections is not None:
        feed = setup.make_feed(options.seed, options.anonymous_detections)
    server_options = ServerOptions(
        speedup=options.speedup,
        host=options.host,
        base_port=options.base_port,
        out=options.out,
        wait_for_client=options.wait_for_client,
        feed_address=options.detections,
        radios=radios,
        radio_seed=options.seed,
    )
    start_key = signing_key(options)
    if start_key is not None:
        server_options.signing_keys = {c.system_id: start_key for c in configs}
    return configs, faults, feed, server_options


async def _serve(options: SitlOptions) -> int:
    from sitl.server import SitlServer

    configs, faults, feed, server_options = build(options)
    server = SitlServer(configs, server_options, faults, feed)
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
    wind = configs[0].wind if configs else None
    if wind is not None and not wind.calm:
        print(f"wind: {wind.describe()} (SIM_WIND_SPD, SIM_WIND_DIR, SIM_WIND_TURB)", flush=True)
    if server_options.signing_keys:
        print("signing: vehicles start with a key (MAVLink 2 signing on)", flush=True)
    try:
        await server.run(options.duration_s)
    finally:
        await server.close()
    for sysid, link in server.radio_stats().items():
        down, up = link["down"], link["up"]
        print(f"gcs sitl: vehicle {sysid}'s radio: air busy {link['air_pct']:.1f} % (data "
              f"{link['data_air_pct']:.1f} %), packets lost {down['packets_lost']} of "
              f"{down['packets']} down, {up['packets_lost']} of {up['packets']} up, bytes "
              f"dropped {down['bytes_dropped']} down, {up['bytes_dropped']} up", flush=True)
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
        options = sitl_options(args)
        if options.camera_of is not None:
            from groundstation.commands.sitl_ardupilot import run_camera_only

            return run_camera_only(options)
        if options.ardupilot is not None:
            from groundstation.commands.sitl_ardupilot import run_ardupilot

            return run_ardupilot(options)
        return run_async(lambda: _serve(options))
    except KeyboardInterrupt:
        return 130
    except UsageError as exc:
        print(f"gcs sitl: error: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:  # ScenarioError and other bad input: the message names the field
        print(f"gcs sitl: error: {exc}", file=sys.stderr)
        return 2
