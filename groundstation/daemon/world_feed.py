"""What the world tells the daemon's core, and what the daemon journals of it: scripted
scenario events (targets appearing, removed), camera frames and detections, the metrics
sampled every mission second, and the periodic ``track`` and ``truth`` lines reports draw."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from groundstation.core import events as ev
from groundstation.core.decision import DecisionCore
from groundstation.core.metrics import MetricsRecorder

__all__ = ["WorldFeed"]


class _Truth(Protocol):
    def truth(self) -> dict[str, tuple[float, float]]: ...


class WorldFeed:
    """Feeds the core through ``core_event`` and journals through ``journal``."""

    def __init__(
        self,
        core: DecisionCore,
        core_event: Callable[[ev.Event], None],
        journal: Callable[..., None],
        metrics: MetricsRecorder,
        world: Callable[[], _Truth | None],
        inside_area: Callable[[float, float], bool],
    ) -> None:
        self.core = core
        self._core_event = core_event
        self._journal: Callable[..., Any] = journal
        self.metrics = metrics
        self._world = world
        self._inside = inside_area

    def scenario_event(self, event: ev.Event) -> None:
        """A scripted event of the scenario: targets outside the operating area are refused."""
        if isinstance(event, ev.Detection):
            self.detection(event)
            return
        if isinstance(event, ev.TargetAdded):
            if not self._inside(event.x_m, event.y_m):
                self._journal("target_refused", target=event.target, x_m=event.x_m,
                              y_m=event.y_m, reason="outside the operating area")
                return
            self._journal("target_added", target=event.target, x_m=event.x_m, y_m=event.y_m,
                          vx_m_s=event.vx_m_s, vy_m_s=event.vy_m_s, sigma0=event.sigma0,
                          source="scenario")
        elif isinstance(event, ev.TargetRemoved):
            self._journal("target_removed", target=event.target, source="scenario")
        self._core_event(event)

    def frame(self, event: ev.CameraFrame) -> None:
        """A camera frame's footprint for the core (journalled as its input, like every
        input; its detections follow with the same ``t_s`` and vehicle)."""
        self._core_event(event)

    def detection(self, event: ev.Detection) -> bool:
        """A camera measurement for the core; False if it lies outside the operating area
        (dropped). Accepted ones count as visits in the metrics."""
        if not self._inside(event.x_m, event.y_m):
            return False
        self._core_event(event)
        outcome = self.core.last_measurement
        accepted = outcome is not None and outcome.accepted
        if accepted and event.target is not None:
            self.metrics.seen(event.t_s, event.vehicle, event.target)
        self._journal("detection", vehicle=event.vehicle, target=event.target,
                      x_m=round(event.x_m, 1), y_m=round(event.y_m, 1), accepted=accepted)
        return True

    def sample(self, t_s: float) -> None:
        """Every mission second: mean sigma, lost tracks, estimation error against truth."""
        world = self._world()
        truth = world.truth() if world is not None else {}
        self.metrics.sample_tracks(t_s, self.core.observer.tracks(), truth)

    def journal_tracks(self) -> None:
        """``track`` lines of every estimate and, for simulated targets, ``truth`` lines."""
        for tr in self.core.observer.tracks():
            self._journal("track", target=tr.id, sigma=round(tr.sigma, 3), x_m=round(tr.x_m, 1),
                          y_m=round(tr.y_m, 1), lost=tr.lost or None)
        world = self._world()
        if world is not None:
            for target, (x, y) in sorted(world.truth().items()):
                self._journal("truth", target=target, x_m=round(x, 1), y_m=round(y, 1))
