"""floe observer: one constant-velocity Kalman filter (or the field test's linear model)
per iceberg. Pure maths: no I/O, no clocks; time is an argument."""

from observer.config import ObserverConfig
from observer.observer import Observer
from observer.priority import boat_priority_q
from observer.records import MeasurementOutcome, TrackSnapshot

__all__ = [
    "MeasurementOutcome",
    "Observer",
    "ObserverConfig",
    "TrackSnapshot",
    "boat_priority_q",
]
