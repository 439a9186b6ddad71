"""floe observer: one constant-velocity Kalman filter (or the field test's linear model)
per iceberg. Pure maths: no I/O, no clocks; time is an argument."""

from observer.config import ObserverConfig
from observer.observer import Observer
from observer.priority import boat_priority_q
from observer.records import MeasurementOutcome, TrackSnapshot
from observer.tracker import Tracker
from observer.tracker_config import (
    UNCONFIRMED,
    Footprint,
    ScanDetection,
    ScanResult,
    TrackerConfig,
    TrackEvent,
    TrackRecord,
)

__all__ = [
    "UNCONFIRMED",
    "Footprint",
    "MeasurementOutcome",
    "Observer",
    "ObserverConfig",
    "ScanDetection",
    "ScanResult",
    "TrackEvent",
    "TrackRecord",
    "TrackSnapshot",
    "Tracker",
    "TrackerConfig",
    "boat_priority_q",
]
