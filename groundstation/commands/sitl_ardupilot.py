"""``gcs sitl --ardupilot`` and ``--camera-of``: the argument side of real ArduPilot SITL.

The launcher itself (command lines, supervision, the camera that reads each instance's
position) is ``sitl.ardupilot``; this module turns ``gcs sitl``'s arguments into its calls.
"""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

from groundstation.commands.sitl_args import (
    DEFAULT_HOME,
    UsageError,
    _check,
    parse_latlon,
    parse_udp_url,
)
from sitl.ardupilot import (
    CameraLink,
    ardupilot_commands,
    default_defaults_file,
    launch,
    supervise,
)
from sitl.sitl_setup import scenario_setup
from world.scenario import load_scenario

__all__ = ["run_ardupilot", "run_camera_only"]


def run_ardupilot(args: Any) -> int:
    """``gcs sitl --ardupilot PATH``: start, supervise and stop N SITL instances."""
    _check(args)
    binary = Path(args.ardupilot)
    if not binary.is_file():
        raise UsageError(f"--ardupilot: no such file {binary}")
    defaults = (
        Path(args.ardupilot_defaults)
        if args.ardupilot_defaults
        else (default_defaults_file(binary))
    )
    if not defaults.is_file():
        raise UsageError(
            f"--ardupilot-defaults: no such file {defaults} (give the plane "
            "defaults file, Tools/autotest/models/plane.parm)"
        )
    scenario = None
    if args.scenario is not None:
        scenario = load_scenario(args.scenario)
    count = args.count or (scenario.fleet.count if scenario is not None else 1)
    home = parse_latlon(args.home) if args.home else None
    setup = scenario_setup(scenario, count, home or DEFAULT_HOME, home is not None)
    launches = ardupilot_commands(
        binary, count, args.speedup, setup.home, defaults, Path("sitl-ardupilot").resolve()
    )
    feed_address = (
        None if args.detections == "none" else parse_udp_url(args.detections, "--detections")
    )
    feed = setup.make_feed(args.seed, args.anonymous_detections)
    return asyncio.run(
        launch(launches, feed, feed_address, setup.origin, args.speedup, args.duration)
    )


def run_camera_only(args: Any) -> int:
    """``gcs sitl --camera-of HOST:PORT,...``: only the world and its camera, reading the
    positions of vehicles served elsewhere (e.g. the SITL containers of docker-compose.yml);
    the k-th endpoint is taken to be system id k."""
    _check(args)
    if args.scenario is None:
        raise UsageError("--camera-of needs --scenario (the world to play)")
    scenario = load_scenario(args.scenario)
    endpoints = []
    for part in args.camera_of.split(","):
        host, sep, port = part.strip().removeprefix("tcp:").rpartition(":")
        if not sep or not host or not port.isdigit():
            raise UsageError(f"--camera-of: expected HOST:PORT[,HOST:PORT...], got {part!r}")
        endpoints.append((host, int(port)))
    setup = scenario_setup(scenario, len(endpoints), DEFAULT_HOME, False)
    cameras = [CameraLink(i + 1, h, p, setup.origin) for i, (h, p) in enumerate(endpoints)]
    feed = setup.make_feed(args.seed, args.anonymous_detections)
    feed_address = (
        None if args.detections == "none" else parse_udp_url(args.detections, "--detections")
    )
    for cam in cameras:
        print(f"camera of system id {cam.system_id}: tcp:{cam.host}:{cam.port}", flush=True)
    return asyncio.run(
        supervise([], cameras, feed, feed_address, args.speedup, args.duration)
    )
