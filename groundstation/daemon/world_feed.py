"""What the world tells the daemon's core, and what the daemon journals of it: scripted
scenario events (targets appearing, removed), camera frames and detections, the metrics
sampled every mission second, and the periodic ``track`` and ``truth`` lines reports draw."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from groundstation.core import events as ev
from groundstation.core.decision import DecisionCore
from groundstation.core.metrics import MetricsRecorder
from groundstation.daemon.track_views import TrackNotes

__all__ = ["SEARCH_RECORD_S", "WorldFeed", "WorldFeedHost"]

SEARCH_RECORD_S = 10.0
"""Mission seconds between two ``search`` journal lines (as ``gcs simulate`` writes them)."""
TENTATIVE = "tentative"


class _Truth(Protocol):
    def truth(self) -> dict[str, tuple[float, float]]: ...


class WorldFeedHost(Protocol):
    """What the feed needs of the daemon: the core and the way into it, the journal, the
    metrics, the scenario's world (its truth, None without a scenario) and the area."""

    @property
    def core(self) -> DecisionCore: ...
    @property
    def metrics(self) -> MetricsRecorder: ...
    @property
    def world(self) -> _Truth | None: ...

    def core_event(self, event: ev.Event) -> None: ...
    def journal(self, event: str, *, logged: bool = False, **fields: Any) -> None: ...
    def inside_area(self, x_m: float, y_m: float) -> bool: ...


class WorldFeed:
    """Feeds the core through ``host.core_event`` and journals through ``host.journal``."""

    def __init__(self, host: WorldFeedHost) -> None:
        self.core = host.core
        self._core_event = host.core_event
        self._journal: Callable[..., Any] = host.journal
        self.metrics = host.metrics
        self._world: Callable[[], _Truth | None] = lambda: host.world
        self._inside = host.inside_area
        self.notes = TrackNotes()
        self._next_search_s = 0.0

    def scenario_event(self, event: ev.Event) -> None:
        """A scripted event of the scenario or its camera: targets (and prior entries)
        outside the operating area are refused."""
        if isinstance(event, ev.Detection):
            self.detection(event)
            return
        if isinstance(event, ev.CameraFrame):
            self.frame(event)
            return
        if isinstance(event, ev.TargetAdded):
            if not self._inside(event.x_m, event.y_m):
                self._journal("target_refused", target=event.target, x_m=event.x_m,
                              y_m=event.y_m, reason="outside the operating area")
                return
            self._journal("target_added", target=event.target, x_m=event.x_m, y_m=event.y_m,
                          vx_m_s=event.vx_m_s, vy_m_s=event.vy_m_s, sigma0=event.sigma0,
                          source="prior" if event.prior else "scenario",
                          prior=event.prior or None)
            if event.prior:
                self.notes.prior(event.target)
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
        accepted: bool | None = outcome is not None and outcome.accepted
        if outcome is None and event.target is None:
            accepted = None  # buffered for the tracker's scan: not decided yet
        if accepted and event.target is not None:
            self.metrics.seen(event.t_s, event.vehicle, event.target)
        self._journal("detection", vehicle=event.vehicle, target=event.target,
                      x_m=round(event.x_m, 1), y_m=round(event.y_m, 1), accepted=accepted)
        return True

    def sample(self, t_s: float) -> None:
        """Every mission second: mean sigma, lost tracks, estimation error against truth,
        over the confirmed and prior tracks (tentative ones are candidates, not icebergs;
        as ``gcs simulate`` samples them)."""
        world = self._world()
        truth = world.truth() if world is not None else {}
        status = self._statuses()
        tracks = [tr for tr in self.core.observer.tracks() if status.get(tr.id) != TENTATIVE]
        self.metrics.sample_tracks(t_s, tracks, truth)

    def _statuses(self) -> dict[str, str]:
        return {v.id: v.status for v in self.core.track_views()}

    def journal_tracks(self) -> None:
        """``track`` lines of every estimate (with its ``status``: tentative, confirmed or
        prior), for simulated targets ``truth`` lines, and every ``SEARCH_RECORD_S`` a
        ``search`` line (``cells``: ``[id, x_m, y_m, size_m, value_m2]`` each) when the core
        searches."""
        status = self._statuses()
        for tr in self.core.observer.tracks():
            self._journal("track", target=tr.id, sigma=round(tr.sigma, 3), x_m=round(tr.x_m, 1),
                          y_m=round(tr.y_m, 1), lost=tr.lost or None, status=status.get(tr.id))
        t_s = self.core.t_s
        if self.core.search is not None and t_s >= self._next_search_s - 1e-9:
            while self._next_search_s <= t_s + 1e-9:
                self._next_search_s += SEARCH_RECORD_S
            self._journal("search", cells=[[c.id, round(c.x_m, 1), round(c.y_m, 1),
                                            round(c.size_m, 1), round(c.value_m2, 1)]
                                           for c in self.core.search_view()])
        world = self._world()
        if world is not None:
            for target, (x, y) in sorted(world.truth().items()):
                self._journal("truth", target=target, x_m=round(x, 1), y_m=round(y, 1))
