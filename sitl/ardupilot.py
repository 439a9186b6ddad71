"""Launcher for N real ArduPlane SITL instances (``gcs sitl --ardupilot PATH``).

Instance i is started as sim_vehicle.py would (ArduPilot's SITL_cmdline.cpp options)::

    PATH -S --model plane --speedup K -I i --base-port B+10i --home LAT,LON,ALT,HDG \
         --defaults <tree>/Tools/autotest/models/plane.parm --sysid i+1

in its own working directory (``DIR/I<i>``: SITL keeps eeprom.bin and logs in the current
directory). Instance i serves TCP B + 10 i (SERIAL0, for the ground station; it waits
for that client before it boots) and B + 2 + 10 i (SERIAL1), where the launcher itself reads
positions to play the camera; B is ``base_port`` (5760, ArduPilot's default).

Wind: with ``wind`` given, instance i also reads ``DIR/I<i>/floe-wind.parm`` (SIM_WIND_SPD,
SIM_WIND_DIR, SIM_WIND_TURB; :func:`wind_defaults_text`) after the plane defaults: SITL's
``--defaults`` takes a comma-separated list of files, later ones overriding earlier ones
(AP_Param::load_defaults_file). A defaults file does not override a value already saved in
the instance's eeprom.bin (an earlier ``param set``): ``param set`` it again, or remove
``DIR/I<i>/eeprom.bin``. SITL reads its
options in order, and ``-I i`` adds 10 i to the base port only if the base port is still the
default at that moment (``if (_base_port == BASE_PORT) _base_port += _instance*10``). So
``-I i`` comes first and the explicit ``--base-port B+10i`` after it overrides whatever it
did: the other order breaks when B + 10 i happens to be 5760 for some i > 0 (``--base-port
5750 --count 2``: instance 1 would be told 5760, then moved to 5770 by ``-I 1``). SITL exits
when its parent goes away, so the launcher stays alive until Ctrl-C (or ``--duration``) and
then terminates its children.
"""

from __future__ import annotations

import asyncio
import contextlib
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, mavlink2
from sitl.sim_wind import WIND_PARAMS, wind_param_values
from world.wind import WindSpec

__all__ = [
    "DEFAULT_BASE_PORT",
    "ArduPilotLaunch",
    "CameraLink",
    "ardupilot_commands",
    "default_defaults_file",
    "launch",
    "supervise",
    "wind_defaults_text",
]

DEFAULT_BASE_PORT = 5760
"""ArduPilot SITL's own base port (instance i: 5760 + 10 i)."""
CAMERA_SYSID = 250
CAMERA_COMPID = 191
WIND_DEFAULTS_NAME = "floe-wind.parm"


@dataclass(frozen=True)
class ArduPilotLaunch:
    """One SITL instance: its command line, working directory and ports."""

    instance: int
    system_id: int
    argv: list[str]
    cwd: Path
    gcs_port: int
    camera_port: int
    wind_defaults: str = ""
    """Content of ``cwd / WIND_DEFAULTS_NAME`` to write before starting ('' for none)."""


def default_defaults_file(binary: Path) -> Path:
    """``<tree>/Tools/autotest/models/plane.parm`` for ``<tree>/build/sitl/bin/arduplane``."""
    tree = binary.resolve().parent.parent.parent.parent
    return tree / "Tools" / "autotest" / "models" / "plane.parm"


def wind_defaults_text(wind: WindSpec) -> str:
    """An ArduPilot parameter file setting SITL's wind to ``wind`` (SIM_WIND_DIR: the true
    direction it comes from; SIM_WIND_TURB: the gust standard deviation)."""
    values = wind_param_values(wind)
    lines = [f"# floe: {wind.describe()}"]
    lines += [f"{name} {values[name]:g}" for name in WIND_PARAMS]
    return "\n".join(lines) + "\n"


def ardupilot_commands(
    binary: Path,
    count: int,
    speedup: float,
    home: tuple[float, float],
    defaults: Path,
    workdir: Path,
    home_alt_m: float = 0.0,
    home_heading_deg: float = 0.0,
    base_port: int = DEFAULT_BASE_PORT,
    wind: WindSpec | None = None,
) -> list[ArduPilotLaunch]:
    """The command lines of ``count`` ArduPlane SITL instances; instance i serves the
    ground station on TCP ``base_port + 10 i``; ``wind`` (None: SITL's own parameters)
    is added as a second defaults file."""
    if not 1 <= base_port <= 65535 - 10 * count:
        raise ValueError(f"base port {base_port} leaves no room for {count} instance(s)")
    out = []
    wind_text = wind_defaults_text(wind) if wind is not None else ""
    for i in range(count):
        port = base_port + 10 * i
        cwd = workdir / f"I{i}"
        defaults_arg = str(defaults)
        if wind_text:
            defaults_arg += f",{cwd / WIND_DEFAULTS_NAME}"
        argv = [
            str(binary),
            "-S",
            "--model",
            "plane",
            "--speedup",
            f"{speedup:g}",
            "-I",
            str(i),
            "--base-port",
            str(port),
            "--home",
            f"{home[0]:.7f},{home[1]:.7f},{home_alt_m:g},{home_heading_deg:g}",
            "--defaults",
            defaults_arg,
            "--sysid",
            str(i + 1),
        ]
        out.append(ArduPilotLaunch(i, i + 1, argv, cwd, port, port + 2, wind_text))
    return out


class CameraLink:
    """Reads one vehicle's position on a MAVLink TCP port (SITL's SERIAL1), reconnecting."""

    def __init__(self, system_id: int, host: str, port: int, origin: Any) -> None:
        self.system_id = system_id
        self.host = host
        self.port = port
        self.origin = origin
        self.position: tuple[float, float] | None = None
        self.airborne = False

    async def run(self) -> None:
        """Connect, ask for positions at 4 Hz, keep the latest (forever; cancel to stop)."""
        enc = MavlinkEncoder(CAMERA_SYSID, CAMERA_COMPID)
        while True:
            try:
                reader, writer = await asyncio.open_connection(self.host, self.port)
            except OSError:
                await asyncio.sleep(1.0)
                continue
            dec = MavlinkDecoder()
            writer.write(
                enc.encode(
                    mavlink2.MAVLink_request_data_stream_message(
                        self.system_id, 1, mavlink2.MAV_DATA_STREAM_POSITION, 4, 1
                    )
                )
            )
            try:
                while data := await reader.read(4096):
                    msgs: list[Any] = dec.feed(data)
                    for msg in msgs:
                        if (
                            msg.get_type() == "GLOBAL_POSITION_INT"
                            and msg.lat != 0
                            and (msg.get_srcSystem() == self.system_id)
                        ):
                            x, y, _ = self.origin.to_local(msg.lat * 1e-7, msg.lon * 1e-7)
                            self.position = (x, y)
                            self.airborne = msg.relative_alt > 5000
            except OSError:
                pass
            writer.close()
            await asyncio.sleep(1.0)


async def launch(
    launches: list[ArduPilotLaunch],
    feed: Any,
    feed_address: tuple[str, int] | None,
    origin: Any,
    speedup: float,
    duration_s: float | None,
) -> int:
    """Start every SITL instance, then :func:`supervise` them with their cameras."""
    procs = []
    for launch in launches:
        launch.cwd.mkdir(parents=True, exist_ok=True)
        if launch.wind_defaults:
            (launch.cwd / WIND_DEFAULTS_NAME).write_text(launch.wind_defaults, encoding="ascii")
        procs.append(
            await asyncio.create_subprocess_exec(
                *launch.argv,
                cwd=str(launch.cwd),
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
        )
        print(
            f"ArduPlane SITL {launch.instance} (system id {launch.system_id}, pid "
            f"{procs[-1].pid}): tcp:127.0.0.1:{launch.gcs_port} (camera reads "
            f"{launch.camera_port})",
            flush=True,
        )
    cameras = [CameraLink(x.system_id, "127.0.0.1", x.camera_port, origin) for x in launches]
    return await supervise(procs, cameras, feed, feed_address, speedup, duration_s)


async def supervise(
    procs: list[Any],
    cameras: list[CameraLink],
    feed: Any,
    feed_address: tuple[str, int] | None,
    speedup: float,
    duration_s: float | None,
) -> int:
    """Play the camera from the cameras' positions until Ctrl-C, ``--duration`` or a child's
    exit; then terminate the children (SIGTERM, then SIGKILL after 5 s)."""
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, stop.set)
    tasks = [asyncio.create_task(c.run()) for c in cameras]
    transport = None
    if feed is not None and feed_address is not None:
        transport, _ = await loop.create_datagram_endpoint(
            asyncio.DatagramProtocol, remote_addr=feed_address
        )
    wall0 = time.monotonic()
    status = 0
    try:
        while not stop.is_set():
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(stop.wait(), 0.05)
            t_s = (time.monotonic() - wall0) * speedup
            if feed is not None:
                positions = {
                    c.system_id: c.position
                    for c in cameras
                    if c.position is not None and c.airborne
                }
                for datagram in feed.step(t_s, positions):
                    if transport is not None:
                        transport.sendto(datagram)
            if duration_s is not None and t_s >= duration_s:
                break
            dead = [p for p in procs if p.returncode is not None]
            if dead:
                print(
                    f"gcs sitl: ArduPilot SITL exited (status {dead[0].returncode})",
                    file=sys.stderr,
                )
                status = 1
                break
    finally:
        for task in tasks:
            task.cancel()
        for proc in procs:
            if proc.returncode is None:
                proc.terminate()
        for proc in procs:
            try:
                await asyncio.wait_for(proc.wait(), 5.0)
            except TimeoutError:
                proc.kill()
                await proc.wait()
        if transport is not None:
            transport.close()
    return status
