"""The camera's detection feed: the world (icebergs, boat) advanced in simulated time and
its measurements sent as JSON lines over UDP (design.md, "Detection feed";
groundstation/link/detection_feed.py reads them)::

    {"v": 1, "kind": "frame", "time_s": 12.5, "vehicle": 2, "target": null,
     "lat_deg": 78.93, "lon_deg": 11.95, "sigma_m": 0.0, "radius_m": 150.0}
    {"v": 1, "kind": "detection", "time_s": 12.5, "vehicle": 2, "target": "A",
     "lat_deg": 78.93, "lon_deg": 11.95, "sigma_m": 2.236}
    {"v": 1, "kind": "boat", "time_s": 13.0, "vehicle": null, "target": null, ...}

``time_s`` is simulated seconds since the simulator started (the vehicles' clock);
``vehicle`` is the seeing vehicle's system id; ``target`` the iceberg id if the scenario's
camera is labelled (``camera: {labelled: true}``), else null, and always null when the feed
is ``anonymous`` (then the observer associates it); ``sigma_m`` the camera's noise standard
deviation per axis, sqrt(r). The camera is the scenario's (world/model.py): per camera
tick (2 Hz by default) each flying vehicle's frame detects each iceberg in its FOV with
probability ``camera.pd`` and adds Poisson(``camera.clutter_per_frame``) false alarms. The
boat's position goes out once per simulated second, in a datagram of its own.

With ``frames`` (what ``gcs sitl`` does unless the scenario's camera is the paper's:
labelled, pd 1, no clutter), every frame is one datagram: its ``frame`` line (the
vehicle's position and the footprint radius) first, then its detections. Without, every
detection is a datagram of its own and no frame line is sent: the paper's scenarios feed
exactly what they always fed.

The icebergs are drawn as ``gcs simulate`` and the daemon draw them (same seed, same
icebergs) and join or leave the world at their ``appear_s`` or at scripted
``target_added``/``target_removed`` times; the world steps by at most 0.1 s.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from domain.geodesy import GeoOrigin
from world.model import Iceberg, World

__all__ = ["DetectionSource", "scenario_targets", "world_from_scenario"]

WORLD_STEP_S = 0.1
BOAT_PERIOD_S = 1.0

Script = list[tuple[float, str, Any]]
"""[(t_s, "add" | "remove", TargetSpec | target id)], sorted by time."""


def scenario_targets(scenario: Any, rng: np.random.Generator) -> list[Any]:
    """The scenario's targets as every frontend draws them (see ``resolve_targets``)."""
    from world.scenario import resolve_targets

    return resolve_targets(scenario, rng)


def world_from_scenario(scenario: Any, rng: np.random.Generator) -> tuple[World, Script]:
    """An empty world (boat, camera) on ``rng`` and its script of target additions and
    removals: the icebergs join the world when their time comes."""
    targets = scenario_targets(scenario, rng)
    boat = None
    if scenario.boat is not None:
        b = scenario.boat
        boat = b.build()
    from world.discovery_spec import scenario_camera

    camera = scenario_camera(scenario)
    script: Script = [(t.appear_s, "add", t) for t in targets]
    for ev in scenario.events:
        if ev.kind == "target_added" and ev.target is not None:
            script.append((ev.t_s, "add", ev.target))
        elif ev.kind == "target_removed" and ev.target_id is not None:
            script.append((ev.t_s, "remove", ev.target_id))
    script.sort(key=lambda item: item[0])
    return World([], boat, camera, rng), script


class DetectionSource:
    """Sans-IO: ``step(t_s, positions)`` returns the datagrams (one JSON line each, or with
    ``frames`` a frame's lines per datagram; see the module docstring)."""

    def __init__(
        self,
        world: World,
        origin: GeoOrigin,
        anonymous: bool = False,
        script: Script | None = None,
        iceberg_q_per_s: float = 0.0,
        *,
        frames: bool = False,
    ) -> None:
        self.world = world
        self.origin = origin
        self.anonymous = anonymous
        self.frames = frames
        self.sigma_m = math.sqrt(world.camera.r_m2)
        self.iceberg_q_per_s = iceberg_q_per_s
        self._script: Script = list(script or [])
        self._next_boat_s = world.t_s
        self.sent = 0

    @classmethod
    def for_scenario(
        cls, scenario: Any, seed: int, origin: GeoOrigin, anonymous: bool = False,
        *, frames: bool = False,
    ) -> DetectionSource:
        """The feed of a scenario's world, seeded as ``gcs simulate`` seeds it."""
        world, script = world_from_scenario(scenario, np.random.default_rng(seed))
        q = float(scenario.observer.iceberg_q_per_s)
        return cls(world, origin, anonymous, script, q, frames=frames)

    def _line(
        self,
        kind: str,
        t_s: float,
        vehicle: int | None,
        target: str | None,
        x_m: float,
        y_m: float,
        sigma_m: float,
        radius_m: float | None = None,
    ) -> bytes:
        lat, lon, _ = self.origin.to_geodetic(x_m, y_m)
        self.sent += 1
        line: dict[str, Any] = {
            "v": 1,
            "kind": kind,
            "time_s": round(t_s, 3),
            "vehicle": vehicle,
            "target": target,
            "lat_deg": lat,
            "lon_deg": lon,
            "sigma_m": sigma_m,
        }
        if radius_m is not None:
            line["radius_m"] = radius_m
        return (json.dumps(line) + "\n").encode("utf-8")

    def _world_events(self) -> None:
        world = self.world
        while self._script and self._script[0][0] <= world.t_s + 1e-9:
            _, action, payload = self._script.pop(0)
            if action == "add":
                if payload.id not in world.icebergs:
                    world.add_iceberg(
                        Iceberg(
                            payload.id,
                            payload.x_m,
                            payload.y_m,
                            payload.vx_m_s,
                            payload.vy_m_s,
                            self.iceberg_q_per_s,
                        )
                    )
            elif payload in world.icebergs:
                world.remove_iceberg(payload)

    def step(self, t_s: float, positions: dict[int, tuple[float, float]]) -> list[bytes]:
        """Advance the world to ``t_s`` (steps <= 0.1 s) and emit what the camera saw."""
        out: list[bytes] = []
        world = self.world
        named = {str(sysid): pos for sysid, pos in positions.items()}
        while world.t_s < t_s - 1e-9:
            self._world_events()
            world.step(min(WORLD_STEP_S, t_s - world.t_s))
            out += self._camera(named)
            if world.boat is not None and world.t_s >= self._next_boat_s:
                self._next_boat_s += BOAT_PERIOD_S
                out.append(
                    self._line("boat", world.t_s, None, None, world.boat.x_m, world.boat.y_m, 0.0)
                )
        return out

    def _camera(self, named: dict[str, tuple[float, float]]) -> list[bytes]:
        """The datagrams of the camera tick due now (none between ticks)."""
        out: list[bytes] = []
        for frame in self.world.observe_frames(named):
            vehicle = int(frame.vehicle)
            lines = [
                self._line("detection", m.t_s, vehicle, None if self.anonymous else m.target,
                           m.x_m, m.y_m, self.sigma_m)
                for m in frame.detections
            ]
            if not self.frames:
                out += lines
                continue
            head = self._line("frame", frame.t_s, vehicle, None, frame.x_m, frame.y_m, 0.0,
                              frame.radius_m)
            out.append(b"".join([head, *lines]))
        return out
