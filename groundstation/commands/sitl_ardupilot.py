"""``gcs sitl --ardupilot`` and ``--camera-of``: the argument side of real ArduPilot SITL.

The launcher itself (command lines, supervision, the camera that reads each instance's
position) is ``sitl.ardupilot``; this module turns ``gcs sitl``'s arguments into its calls.
"""

from __future__ import annotations

import asyncio
from pathlib import Path

from domain.errors import UsageError
from groundstation.commands.sitl_args import DEFAULT_HOME, SitlOptions
from sitl.ardupilot import (
    ArduPilotLaunch,
    CameraLink,
    ardupilot_commands,
    default_defaults_file,
    launch,
    supervise,
)
from sitl.sitl_setup import scenario_setup
from world.scenario import load_scenario
from world.wind import WindSpec

__all__ = ["ardupilot_launches", "run_ardupilot", "run_camera_only"]


def run_ardupilot(options: SitlOptions) -> int:
    """``gcs sitl --ardupilot PATH``: start, supervise and stop N SITL instances."""
    assert options.ardupilot is not None
    binary = Path(options.ardupilot)
    if not binary.is_file():
        raise UsageError(f"--ardupilot: no such file {binary}")
    defaults = (
        Path(options.ardupilot_defaults)
        if options.ardupilot_defaults
        else (default_defaults_file(binary))
    )
    if not defaults.is_file():
        raise UsageError(
            f"--ardupilot-defaults: no such file {defaults} (give the plane "
            "defaults file, Tools/autotest/models/plane.parm)"
        )
    scenario = None
    if options.scenario is not None:
        scenario = load_scenario(options.scenario)
    count = options.count or (scenario.fleet.count if scenario is not None else 1)
    home = options.home
    setup = scenario_setup(scenario, count, home or DEFAULT_HOME, home is not None)
    wind = options.wind  # given, even calm, it is set; else a windy scenario's
    if wind is None and not setup.wind.calm:
        wind = setup.wind
    launches = ardupilot_launches(options, binary, defaults, count, setup.home, wind)
    feed = setup.make_feed(options.seed, options.anonymous_detections)
    return asyncio.run(
        launch(
            launches, feed, options.detections, setup.origin, options.speedup, options.duration_s
        )
    )


def ardupilot_launches(
    options: SitlOptions,
    binary: Path,
    defaults: Path,
    count: int,
    home: tuple[float, float],
    wind: WindSpec | None = None,
) -> list[ArduPilotLaunch]:
    """The SITL command lines for ``gcs sitl --ardupilot``: instance i serves TCP
    ``--base-port`` + 10 i (ArduPilot's 5760 by default); port 0 (ephemeral, for the
    built-in vehicles) is refused since SITL cannot report the port it took. ``wind``
    (``--wind``, else a windy scenario's) becomes SIM_WIND_* in a second defaults file;
    None leaves SITL's wind parameters alone."""
    if options.base_port == 0:
        raise UsageError(
            "--base-port: 0 (ephemeral) is for the built-in vehicles; "
            "ArduPilot SITL needs a port (default 5760)"
        )
    try:
        return ardupilot_commands(
            binary,
            count,
            options.speedup,
            home,
            defaults,
            Path("sitl-ardupilot").resolve(),
            base_port=options.base_port,
            wind=wind,
        )
    except ValueError as exc:
        raise UsageError(f"--base-port: {exc}") from None


def run_camera_only(options: SitlOptions) -> int:
    """``gcs sitl --camera-of HOST:PORT,...``: only the world and its camera, reading the
    positions of vehicles served elsewhere (e.g. the SITL containers of docker-compose.yml);
    the k-th endpoint is taken to be system id k."""
    if options.scenario is None:
        raise UsageError("--camera-of needs --scenario (the world to play)")
    scenario = load_scenario(options.scenario)
    endpoints = options.camera_of or ()
    setup = scenario_setup(scenario, len(endpoints), DEFAULT_HOME, False)
    cameras = [CameraLink(i + 1, h, p, setup.origin) for i, (h, p) in enumerate(endpoints)]
    feed = setup.make_feed(options.seed, options.anonymous_detections)
    feed_address = options.detections
    for cam in cameras:
        print(f"camera of system id {cam.system_id}: tcp:{cam.host}:{cam.port}", flush=True)
    return asyncio.run(
        supervise([], cameras, feed, feed_address, options.speedup, options.duration_s)
    )
