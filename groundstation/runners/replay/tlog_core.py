"""The decision core on a bare tlog plus a detections file (``gcs replay X.tlog
--detections FILE``).

A tlog of another tool holds the vehicles but no targets and no decisions, so nothing can
be compared; this runs today's core on what the vehicles did and what the cameras saw, and
returns the decisions it makes (which target each vehicle would have been sent to, when).

Inputs, in the mission time of the tlog (``replay/mission_timeline.py``: the run's journal
beside it, else the first vehicle's ``time_boot_ms``, the autopilot's clock, which is the
built-in simulator's mission time and the clock of ``gcs sitl --detections``), taken at each
frame's reception; one clock for every vehicle, whatever each one's own boot time, a reboot
or a stray frame's clock:

* ``VehicleJoined`` at a vehicle's first valid position, then ``Telemetry`` for each
  GLOBAL_POSITION_INT (local ENU around the first position; heading
  ``psi = pi/2 - hdg``; ground speed ``hypot(vx, vy)``);
* ``Detection`` for each ``"kind": "detection"`` line of the file (design.md detection
  feed format; malformed lines are counted and skipped; ``r = sigma_m^2``);
* ``Tick`` every 0.1 s; plans are solved inline (one worker, seed 0, deterministic).

No loiter ends can be known from a foreign tlog, so the default policy is the paper's:
replan every 5 s without commitment (``--set`` changes it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pymap3d

from domain.geodesy import enu_rad_from_compass_deg
from groundstation.core.commands import Command, SolveRequest
from groundstation.core.config import CoreConfig, ReplanPolicy
from groundstation.core.decision import DecisionCore
from groundstation.core.events import Detection, Event, PlanSolved, Telemetry, Tick, VehicleJoined
from groundstation.core.records import command_to_record
from groundstation.link.detection_feed import FeedError, parse_line
from groundstation.link.tlog import TlogReader
from groundstation.runners.replay.mission_timeline import mission_timeline
from groundstation.runners.replay.tlog import TlogError, read_tlog, tlog_of
from planner import solve_plan

__all__ = ["TLOG_DEFAULT_CONFIG", "TlogCoreRun", "run_core_on_tlog"]

TLOG_DEFAULT_CONFIG = CoreConfig(policy=ReplanPolicy(on_events=True, period_s=5.0, commit=False))


@dataclass
class TlogCoreRun:
    """The decisions today's core makes on a tlog and detections."""

    decisions: list[dict[str, Any]] = field(default_factory=list)
    inputs: int = 0
    detections_used: int = 0
    detections_skipped: list[str] = field(default_factory=list)
    skipped_ranges: list[tuple[int, int]] = field(default_factory=list)
    origin: tuple[float, float] | None = None


def _positions(
    path: Path,
) -> tuple[list[tuple[float, Event]], list[tuple[int, int]], tuple[float, float] | None]:
    summary = read_tlog(tlog_of(path))
    vehicles = set(summary.vehicles)
    clock = mission_timeline(summary.path, sorted(vehicles)).at
    reader = TlogReader(summary.path)
    events: list[tuple[float, Event]] = []
    origin: tuple[float, float] | None = None
    joined: set[str] = set()
    for record in reader:
        msg = record.message
        if (msg.get_type() != "GLOBAL_POSITION_INT" or (msg.lat == 0 and msg.lon == 0)
                or int(msg.get_srcSystem()) not in vehicles):
            continue
        lat, lon = msg.lat / 1e7, msg.lon / 1e7
        if origin is None:
            origin = (lat, lon)
        e, n, _u = pymap3d.geodetic2enu(lat, lon, 0.0, origin[0], origin[1], 0.0)
        t_s = clock(record.t_unix_s)
        heading = enu_rad_from_compass_deg(msg.hdg / 100.0) if msg.hdg != 65535 else 0.0
        speed = math.hypot(msg.vx, msg.vy) / 100.0
        vehicle = str(msg.get_srcSystem())
        if vehicle not in joined:
            joined.add(vehicle)
            events.append((t_s, VehicleJoined(t_s, vehicle, float(e), float(n), heading, speed)))
        events.append((t_s, Telemetry(t_s, vehicle, float(e), float(n), heading, speed)))
    return events, list(reader.skipped), origin


def run_core_on_tlog(
    tlog: Path, detections: Path, config: CoreConfig = TLOG_DEFAULT_CONFIG
) -> TlogCoreRun:
    """See the module docstring. Raises TlogError / OSError for unusable files."""
    events, skipped, origin = _positions(tlog)
    if origin is None:
        raise TlogError(f"{tlog}: no vehicle position (GLOBAL_POSITION_INT) in the tlog")
    run = TlogCoreRun(skipped_ranges=skipped, origin=origin)
    for number, line in enumerate(detections.read_bytes().splitlines(), start=1):
        if not line.strip():
            continue
        try:
            d = parse_line(line)
        except FeedError as exc:
            run.detections_skipped.append(f"line {number}: {exc}")
            continue
        if d.kind != "detection":
            continue
        e, n, _u = pymap3d.geodetic2enu(d.lat_deg, d.lon_deg, 0.0, origin[0], origin[1], 0.0)
        vehicle = str(d.vehicle) if d.vehicle is not None else None
        events.append(
            (
                d.time_s,
                Detection(
                    d.time_s,
                    vehicle,
                    d.target,
                    float(e),
                    float(n),
                    d.sigma_m**2 if d.sigma_m > 0 else None,
                ),
            )
        )
        run.detections_used += 1
    events.sort(key=lambda item: item[0])
    core = DecisionCore(config)
    t_first, t_last = events[0][0], events[-1][0]
    tick_s = config.tick_s
    ticks = [t_first + k * tick_s for k in range(int((t_last - t_first) / tick_s) + 1)]
    k = 0
    for t_tick in ticks:
        while k < len(events) and events[k][0] <= t_tick + 1e-9:
            _feed(core, events[k][1], run)
            k += 1
        _feed(core, Tick(t_tick), run)
    return run


def _feed(core: DecisionCore, event: Event, run: TlogCoreRun) -> None:
    run.inputs += 1
    pending: list[Command] = list(core.handle(event))
    while pending:
        command = pending.pop(0)
        record = command_to_record(command)
        if record["event"] in ("fly", "release", "send_home", "plan"):
            if record["event"] == "plan":
                record = {
                    k: record[k]
                    for k in (
                        "event",
                        "t",
                        "request_id",
                        "assignments",
                        "objective",
                        "status",
                        "solve_time_s",
                    )
                }
            run.decisions.append(record)
        if isinstance(command, SolveRequest):
            result = solve_plan(
                command.problem, command.hint, num_workers=1, random_seed=0, deterministic=True
            )
            pending.extend(core.handle(PlanSolved(command.t_s, command.request_id, result)))
