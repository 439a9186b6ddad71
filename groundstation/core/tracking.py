"""The decision core's side of the multi-target tracker (``observer.Tracker``).

Unlabelled detections (``Detection.target`` None) are not applied one by one: the core
buffers them per camera frame, keyed by ``(t_s, vehicle)``, together with the frame's
footprint when a :class:`~groundstation.core.events.CameraFrame` for that key came, and
hands every buffered scan with ``t_s <= t`` to :meth:`observer.Tracker.scan` at the next
``Tick(t)``, in ``(t_s, vehicle)`` order, before the observer is predicted to ``t``. So a
whole frame is associated at once (global assignment), whatever order its lines came in.

A frame that also brought *labelled* detections (``target`` given: applied at once, as
before the tracker existed) is scanned without its footprint: the tracker never hears of
those hits, so the footprint would count the labelled tracks in view as misses.

The tracker is created on first need (a frame, an unlabelled detection or a prior target),
adopting every track the observer already holds as ``confirmed``: a run with a labelled
camera and no prior never creates it, so it computes exactly what it did before the tracker
existed. Tracks the core creates itself (``TargetAdded``, a labelled detection of an unknown
target) are adopted as ``confirmed``; ``TargetAdded(prior=True)`` as ``prior`` with
existence 0.5. Confirmed adoptions are not ``keep``: an announced iceberg that a camera
looks for where it is predicted and does not see is deleted like any track, and found again
under a new id. Measured on ``paper-boat-clutter`` (campaigns/clutter.yaml, 20 seeds): with
``keep`` such a track stayed stale forever, drew the planner, and the mean uncertainty rose
to 512 601 +- 524 272 m^2 (6/20 bounded); without it, 4 932 +- 973 m^2 (13/20), against
6 008 +- 1 254 m^2 (12/20) for the labelled camera.

**One writer.** The observer's track set changes here only: :meth:`TrackBook.add` and
:meth:`TrackBook.remove` for the tracks the core adds and removes, and the tracker this book
owns for its births and deletions. The decision core reads the observer (estimates,
measurements, predictions) but never adds or removes a track itself, so a track the tracker
deleted cannot be removed a second time.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from groundstation.core.events import CameraFrame, Detection
from observer import Footprint, Observer, ScanDetection, Tracker, TrackerConfig, TrackEvent

__all__ = ["PendingScan", "TrackBook", "TrackerFactory"]

TrackerFactory = Callable[[Observer, TrackerConfig], Tracker]

CONFIRMED = "confirmed"
PRIOR = "prior"
TENTATIVE = "tentative"


@dataclass
class PendingScan:
    """One camera frame's unlabelled detections, waiting for the next tick."""

    t_s: float
    vehicle: str
    footprint: Footprint | None = None
    detections: list[ScanDetection] = field(default_factory=list)
    labelled: bool = False


class TrackBook:
    """Buffers scans, owns the tracker, and answers track status (module docstring)."""

    def __init__(self, observer: Observer, config: TrackerConfig,
                 factory: TrackerFactory | None = None) -> None:
        self._observer = observer
        self._config = config
        self._factory: TrackerFactory = factory or Tracker
        self.tracker: Tracker | None = None
        self._scans: dict[tuple[float, str], PendingScan] = {}

    # ------------------------------------------------------------------ lifecycle
    def ensure(self, *, but: str | None = None) -> Tracker:
        """The tracker, created (adopting every existing track but ``but`` as confirmed)
        if need be."""
        if self.tracker is None:
            self.tracker = self._factory(self._observer, self._config)
            for track_id in self._observer.target_ids:
                if track_id != but:
                    self.tracker.adopt(track_id, status=CONFIRMED, existence=1.0)
        return self.tracker

    def add(self, track_id: str, t_s: float, x_m: float, y_m: float, *, vx_m_s: float = 0.0,
            vy_m_s: float = 0.0, sigma0: float | None = None, q_per_s: float | None = None,
            prior: bool = False) -> None:
        """Start a track the core was told of (``TargetAdded``, a labelled detection of an
        unknown target) and adopt it (:meth:`adopt`)."""
        self._observer.add_target(track_id, t_s, x_m, y_m, vx_m_s=vx_m_s, vy_m_s=vy_m_s,
                                  sigma0=sigma0, q_per_s=q_per_s)
        self.adopt(track_id, prior=prior)

    def reseat(self, track_id: str, t_s: float, x_m: float, y_m: float,
               sigma0: float) -> None:
        """An operator's fix (``TargetFixed``): the observer re-seats the track
        (``Observer.reseat``) and the tracker, if any, holds it as confirmed."""
        self._observer.reseat(track_id, t_s, x_m, y_m, sigma0)
        if self.tracker is not None:
            self.tracker.forget(track_id)
            self.tracker.adopt(track_id, status=CONFIRMED, existence=1.0)

    def remove(self, track_id: str) -> None:
        """Stop a track the core was told to remove (``TargetRemoved``); no-op if the
        observer no longer holds it."""
        if track_id in self._observer.target_ids:
            self._observer.remove_target(track_id)
        if self.tracker is not None:
            self.tracker.forget(track_id)

    def adopt(self, track_id: str, *, prior: bool = False) -> None:
        """A track the core created (TargetAdded, labelled detection)."""
        if prior:
            self.ensure(but=track_id).adopt(track_id, status=PRIOR, existence=0.5)
        elif self.tracker is not None:
            self.tracker.adopt(track_id, status=CONFIRMED, existence=1.0)

    def forget(self, track_id: str) -> None:
        """The core removed the target (TargetRemoved)."""
        if self.tracker is not None:
            self.tracker.forget(track_id)

    def status(self, track_id: str) -> str:
        """``tentative``, ``confirmed`` or ``prior`` (``confirmed`` for a track the tracker
        does not know, e.g. every track while there is no tracker)."""
        if self.tracker is None:
            return CONFIRMED
        try:
            return str(self.tracker.status(track_id))
        except KeyError:
            return CONFIRMED

    def existence(self, track_id: str) -> float:
        if self.tracker is None:
            return 1.0
        try:
            return float(self.tracker.existence(track_id))
        except KeyError:
            return 1.0

    # ------------------------------------------------------------------ buffering
    def _scan(self, t_s: float, vehicle: str | None) -> PendingScan:
        key = (t_s, vehicle or "")
        scan = self._scans.get(key)
        if scan is None:
            scan = self._scans[key] = PendingScan(t_s, vehicle or "")
        return scan

    def frame(self, event: CameraFrame) -> bool:
        """Buffer a frame's footprint; False (ignored) if a value is not finite or the
        radius not > 0."""
        values = (event.t_s, event.x_m, event.y_m, event.radius_m)
        if not all(math.isfinite(v) for v in values) or not event.radius_m > 0:
            return False
        self.ensure()
        self._scan(event.t_s, event.vehicle).footprint = Footprint(
            event.x_m, event.y_m, event.radius_m)
        return True

    def detection(self, event: Detection, r_m2: float) -> bool:
        """Buffer an unlabelled detection (``r_m2``: its noise variance, the observer's
        default when the detection gives none); False if a value is not finite."""
        values = (event.t_s, event.x_m, event.y_m, r_m2)
        if not all(math.isfinite(v) for v in values) or not r_m2 > 0:
            return False
        self.ensure()
        self._scan(event.t_s, event.vehicle).detections.append(
            ScanDetection(event.x_m, event.y_m, r_m2))
        return True

    def labelled(self, event: Detection) -> None:
        """A labelled detection: its frame (if one is buffered) loses its footprint."""
        if not self._scans:
            return  # nothing buffered (every detection of a labelled camera's run)
        scan = self._scans.get((event.t_s, event.vehicle or ""))
        if scan is not None:
            scan.labelled = True

    @property
    def pending(self) -> int:
        return len(self._scans)

    def process(self, t_s: float
                ) -> list[tuple[PendingScan, tuple[TrackEvent, ...], tuple[str, ...]]]:
        """Scan every buffered frame with ``t_s`` at or before ``t_s``, in order; each
        scan with the tracker's events and the tracks its detections were assigned to."""
        if not self._scans:
            return []  # no camera frame waits (every tick of a labelled camera's run)
        due = sorted(key for key in self._scans if key[0] <= t_s)
        if not due:
            return []
        tracker = self.ensure()
        out = []
        for key in due:
            scan = self._scans.pop(key)
            footprint = None if scan.labelled else scan.footprint
            result = tracker.scan(scan.t_s, scan.vehicle, footprint, scan.detections)
            hits = tuple(sorted(set(result.assigned.values())))
            out.append((scan, tuple(result.events), hits))
        return out
