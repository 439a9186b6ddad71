"""A scenario's simulated world for the daemon: icebergs, boat and a virtual camera.

With ``--scenario`` the targets are simulated: the daemon adds them to the core when they
appear (``TargetAdded`` at their ``appear_s`` or scripted time), moves them and the boat in
0.1 s steps of mission time, and a virtual camera measures every iceberg within the FOV
radius of a flying vehicle at the camera rate (2 Hz), as ``Detection`` events. The vehicle
positions come from ``positions()``: the built-in simulator's true positions (``sim:N``) or
the vehicles' telemetry (real or ArduPilot SITL vehicles: the paper's 2015 field test).
The random targets are drawn as ``gcs simulate`` draws them (same seed, same icebergs).

**Discovery mode** (``world.discovery_spec.discovery_mode``: an unlabelled camera, a prior
or search, the rule the offline runner follows too): the scenario's icebergs are announced
only if ``targets.known``; the prior list (``world.discovery_spec.resolve_prior``, its own
generator) is announced at the first step as ``TargetAdded(prior=True)`` at the listed
position, velocity 0, ``sigma0 = 2 variance_m2`` (``PriorEntry.variance_m2`` per axis);
and the camera
(``scenario_camera``: ``pd``, clutter, labels) reports frames, each a ``CameraFrame`` then
its ``Detection`` events at the same mission time. Otherwise the camera measures as it
always did (no frame, no extra draw).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from groundstation.core import events as ev
from world.discovery_spec import PriorEntry, discovery_mode, resolve_prior, scenario_camera
from world.model import Iceberg, World
from world.scenario import Scenario, resolve_targets

__all__ = ["ScenarioWorld"]

STEP_S = 0.1


class ScenarioWorld:
    """The world of ``scenario``, advanced on the mission clock."""

    def __init__(
        self,
        scenario: Scenario,
        seed: int,
        positions: Callable[[], Mapping[str, tuple[float, float]]],
    ) -> None:
        self.scenario = scenario
        self.positions = positions
        rng = np.random.default_rng(seed)
        targets = resolve_targets(scenario, rng)
        boat = scenario.boat
        self.world = World(
            [],
            boat.build() if boat else None,
            scenario_camera(scenario),
            rng,
        )
        self.discovery = discovery_mode(scenario)
        self.prior: list[PriorEntry] = resolve_prior(scenario, targets, seed)
        self._prior_due = bool(self.prior)
        self._script: list[tuple[float, str, object]] = [(t.appear_s, "add", t) for t in targets]
        for event in scenario.events:
            if event.kind == "target_added" and event.target is not None:
                self._script.append((event.t_s, "add", event.target))
            elif event.kind == "target_removed" and event.target_id is not None:
                self._script.append((event.t_s, "remove", event.target_id))
        self._script.sort(key=lambda item: item[0])
        self.t_s = 0.0
        self.measurements = 0

    def step_to(self, t_s: float) -> list[ev.Event]:
        """Advance to ``t_s``; the core events that happened (targets, detections)."""
        out: list[ev.Event] = []
        if self._prior_due:
            self._prior_due = False
            out += [ev.TargetAdded.listed(self.t_s, p) for p in self.prior]
        positions = dict(self.positions())
        while self.t_s < t_s - 1e-9:
            dt = min(STEP_S, t_s - self.t_s)
            while self._script and self._script[0][0] <= self.t_s + 1e-9:
                _, action, payload = self._script.pop(0)
                out += self._apply(action, payload)
            self.world.step(dt)
            self.t_s += dt
            if self.discovery:
                out += self._frames(positions)
                continue
            for m in self.world.observe(positions):
                self.measurements += 1
                out.append(ev.Detection(self.t_s, m.vehicle, m.target, m.x_m, m.y_m, m.r_m2))
        return out

    def _frames(self, positions: Mapping[str, tuple[float, float]]) -> list[ev.Event]:
        """The camera's frames due now: each a ``CameraFrame`` and then its detections, all
        at this mission time (one scan for the core)."""
        out: list[ev.Event] = []
        for frame in self.world.observe_frames(positions):
            out.append(ev.CameraFrame(self.t_s, frame.vehicle, frame.x_m, frame.y_m,
                                      frame.radius_m))
            for m in frame.detections:
                self.measurements += 1
                out.append(ev.Detection(self.t_s, m.vehicle, m.target, m.x_m, m.y_m, m.r_m2))
        return out

    def _apply(self, action: str, payload: object) -> list[ev.Event]:
        t = self.t_s
        if action == "add":
            spec = payload
            from world.scenario import TargetSpec

            assert isinstance(spec, TargetSpec)
            if spec.id in self.world.icebergs:
                return []
            self.world.add_iceberg(
                Iceberg(
                    spec.id,
                    spec.x_m,
                    spec.y_m,
                    spec.vx_m_s,
                    spec.vy_m_s,
                    self.scenario.observer.iceberg_q_per_s,
                )
            )
            if not self.scenario.targets_known:
                return []  # floe learns of it from the camera (and the prior)
            return [
                ev.TargetAdded(
                    t, spec.id, spec.x_m, spec.y_m, spec.vx_m_s, spec.vy_m_s, spec.sigma0
                )
            ]
        target = str(payload)
        if target in self.world.icebergs:
            self.world.remove_iceberg(target)
        return [ev.TargetRemoved(t, target)]

    @property
    def boat_xy_m(self) -> tuple[float, float] | None:
        boat = self.world.boat
        return (boat.x_m, boat.y_m) if boat is not None else None

    @property
    def boat_velocity_m_s(self) -> tuple[float, float] | None:
        """The scenario's ship's velocity over ground now (its GPS's course and speed)."""
        boat = self.world.boat
        return boat.velocity_m_s if boat is not None else None

    def truth(self) -> dict[str, tuple[float, float]]:
        return self.world.true_positions()
