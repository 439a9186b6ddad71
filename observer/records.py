"""Immutable records the observer hands out: :class:`TrackSnapshot`, :class:`MeasurementOutcome`."""

from __future__ import annotations

from dataclasses import dataclass

#: Reasons a :class:`MeasurementOutcome` can carry.
REASONS: tuple[str, ...] = ("accepted", "gate", "late", "invalid", "unknown_target", "no_track")


@dataclass(frozen=True)
class TrackSnapshot:
    """One track at time ``t_s``.

    Attributes:
        id: target id.
        t_s: time of the estimate (mission seconds).
        x_m, y_m, vx_m_s, vy_m_s: estimated state (local ENU).
        sigma: uncertainty in m^2: ``trace(P[:2, :2]) = Pxx + Pyy`` for the Kalman model, the
            model's own sigma for the linear model.
        cov_xy: ``(Pxx, Pxy, Pyy)`` in m^2, for error ellipses (linear model:
            ``(sigma/2, 0, sigma/2)``).
        lost: currently lost, i.e. ``sqrt(sigma) > fov_radius_m``.
        ever_lost: lost at any time the track was evaluated (every prediction view and the
            prior of every accepted measurement).
        last_seen_s: time of the last accepted measurement, ``None`` if never seen.
        q_per_s: the track's process-noise intensity (m^2/s^3).
    """

    id: str
    t_s: float
    x_m: float
    y_m: float
    vx_m_s: float
    vy_m_s: float
    sigma: float
    cov_xy: tuple[float, float, float]
    lost: bool
    ever_lost: bool
    last_seen_s: float | None
    q_per_s: float


@dataclass(frozen=True)
class MeasurementOutcome:
    """What :meth:`observer.Observer.measure` did with one measurement.

    Attributes:
        accepted: the measurement corrected a track.
        target_id: the track it was applied or compared to (``None`` if none).
        reason: one of :data:`REASONS`.
        mahalanobis2: squared Mahalanobis distance ``y' S^-1 y`` of the innovation for the
            chosen track, ``None`` when no track was compared.
    """

    accepted: bool
    target_id: str | None
    reason: str
    mahalanobis2: float | None
