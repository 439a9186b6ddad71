"""The offline runner's discovery side: unknown icebergs, a prior list, an unlabelled
camera that misses and lies, search cells, and the track-quality measures.

A run is in *discovery mode* when the camera is unlabelled, or the scenario has a prior or
search. Then:

* the scenario's icebergs are announced to the core (``TargetAdded``) only if
  ``targets.known``; the prior (``world.discovery_spec.resolve_prior``, its own generator)
  is announced at t = 0 as ``TargetAdded(prior=True)`` at the listed position, velocity 0,
  ``sigma0 = 2 variance_m2`` (``PriorEntry.variance_m2`` per axis: the listing's noise
  and its age's drift), as the daemon does;
* the camera's frames (``World.observe_frames``) reach the core as one ``CameraFrame`` each
  followed by its ``Detection`` events (of a vehicle that is not lost);
* every mission second the confirmed tracks and the true icebergs in the area go to
  ``observer.track_quality.TrackQualityRecorder`` (whose keys join ``metrics.json``), and
  every frame's footprint with the true positions (for the time to confirm);
* the journal gets a ``search`` line every ``core.records.SEARCH_RECORD_S`` of mission time.

Otherwise (the bundled labelled scenarios) nothing here draws a number or feeds an event:
the run is what it was before discovery existed.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from groundstation.core.events import CameraFrame, Detection, Event, TargetAdded
from groundstation.core.records import SearchSchedule
from groundstation.core.views import CoreView
from observer.track_quality import TrackQualityRecorder
from world.discovery_spec import resolve_prior
from world.model import World
from world.scenario import Scenario, TargetSpec

__all__ = ["Discovery"]

CONFIRMED = "confirmed"


class Discovery:
    """What a discovery-mode run adds to the offline loop (module docstring)."""

    def __init__(self, scenario: Scenario, seed: int, targets: list[TargetSpec]) -> None:
        self.scenario = scenario
        self.prior = resolve_prior(scenario, targets, seed) if scenario.prior else []
        self.quality = TrackQualityRecorder()
        self._search = SearchSchedule()

    def prior_events(self) -> list[TargetAdded]:
        return [TargetAdded.listed(0.0, p) for p in self.prior]

    def observe(self, world: World, positions: Mapping[str, tuple[float, float]],
                lost: Callable[[str], bool]) -> list[Event]:
        """The camera's frames due now, as core inputs, in the camera's order."""
        out: list[Event] = []
        truth = world.true_positions()
        for frame in world.observe_frames(positions):
            if lost(frame.vehicle):
                continue
            self.quality.frame(frame.t_s, (frame.x_m, frame.y_m, frame.radius_m), truth)
            out.append(CameraFrame(frame.t_s, frame.vehicle, frame.x_m, frame.y_m,
                                   frame.radius_m))
            out.extend(Detection(m.t_s, m.vehicle, m.target, m.x_m, m.y_m, m.r_m2)
                       for m in frame.detections)
        return out

    def in_area(self, truth: Mapping[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
        area = self.scenario.area
        if area is None:
            return dict(truth)
        return {k: xy for k, xy in truth.items() if area.contains(*xy)}

    def sample(self, t_s: float, view: CoreView,
               truth: Mapping[str, tuple[float, float]]) -> None:
        confirmed = {v.id: (v.x_m, v.y_m) for v in view.tracks if v.status == CONFIRMED}
        inside = self.in_area(truth)
        outside = {k: xy for k, xy in truth.items() if k not in inside}
        self.quality.sample(t_s, confirmed, inside, outside)

    def search_due(self, t_s: float, view: CoreView) -> bool:
        """Whether a ``search`` journal line is due (``core.records.SearchSchedule``)."""
        return self._search.due(t_s, view)

    def metrics(self, duration_s: float) -> dict[str, Any]:
        return dict(self.quality.to_dict(duration_s))
