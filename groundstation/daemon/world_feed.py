"""What the world tells the daemon's core, and what the daemon journals of it: scripted
scenario events (targets appearing, removed), camera frames and detections, the metrics
sampled every mission second, and the periodic ``track`` and ``truth`` lines reports draw."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol

from groundstation.core import events as ev
from groundstation.core.commands import Verdict
from groundstation.core.metrics import MetricsRecorder
from groundstation.core.records import (
    SearchSchedule,
    search_record,
    track_records,
    truth_records,
)
from groundstation.daemon.hosts import CoreHost
from groundstation.daemon.track_views import TrackNotes

__all__ = ["WorldFeed", "WorldFeedHost"]


class _Truth(Protocol):
    def truth(self) -> dict[str, tuple[float, float]]: ...


class WorldFeedHost(CoreHost, Protocol):
    """What the feed needs of the daemon: the core and the way into it, the journal, the
    area (:class:`~groundstation.daemon.hosts.CoreHost`), the metrics and the scenario's
    world (its truth, None without a scenario)."""

    @property
    def metrics(self) -> MetricsRecorder: ...
    @property
    def world(self) -> _Truth | None: ...


class WorldFeed:
    """Feeds the core through ``host.core_event`` and journals through ``host.journal``."""

    def __init__(self, host: WorldFeedHost) -> None:
        self.core = host.core
        self._core_event: Callable[[ev.Event], Sequence[Verdict]] = host.core_event
        self._journal: Callable[..., Any] = host.journal
        self.metrics = host.metrics
        self._world: Callable[[], _Truth | None] = lambda: host.world
        self._inside = host.inside_area
        self.notes = TrackNotes()
        self._search = SearchSchedule()

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
        (dropped). Accepted labelled ones count as visits in the metrics."""
        if not self._inside(event.x_m, event.y_m):
            return False
        verdicts = self._core_event(event)
        accepted = verdicts[0].accepted if verdicts else None
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
        self.metrics.sample_tracks(t_s, self.core.view().firm_tracks(), truth)

    def journal_tracks(self) -> None:
        """``track`` lines of every estimate (with its ``status``: tentative, confirmed or
        prior), for simulated targets ``truth`` lines, and every ``SEARCH_RECORD_S`` a
        ``search`` line when the core searches: the records of ``core/records.py``, as
        ``gcs simulate`` writes them (the journal stamps the time)."""
        view = self.core.view()
        lines = track_records(view.t_s, view)
        if self._search.due(view.t_s, view):
            lines.append(search_record(view.t_s, view))
        world = self._world()
        if world is not None:
            lines += truth_records(view.t_s, dict(sorted(world.truth().items())))
        for line in lines:
            fields = {k: v for k, v in line.items() if k not in ("event", "t")}
            self._journal(line["event"], **fields)
