"""Configuration and records of the multi-target tracker (:mod:`observer.tracker`).

Every parameter, its equation and how to choose it: docs/tracker.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

ASSOCIATIONS: tuple[str, ...] = ("gnn", "jpda")
STATUSES: tuple[str, ...] = ("tentative", "confirmed", "prior")
EVENT_KINDS: tuple[str, ...] = ("born", "confirmed", "deleted")
UNCONFIRMED = "unconfirmed"
"""A deletion's reason for a tentative track that was never confirmed."""


def _number(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"TrackerConfig.{name} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"TrackerConfig.{name} must be finite, got {value!r}")
    return v


def _integer(name: str, value: object, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ValueError(f"TrackerConfig.{name} must be an integer >= {minimum}, got {value!r}")
    return value


@dataclass(frozen=True)
class TrackerConfig:
    """Parameters of :class:`observer.Tracker` (validated: a bad one raises a one-line
    ValueError naming the field).

    Attributes:
        association: ``"gnn"`` (global nearest neighbour: the likeliest joint assignment of
            the scan, scipy ``linear_sum_assignment``) or ``"jpda"`` (joint probabilistic data
            association: marginal association probabilities, PDA-weighted update).
        pd: probability that the camera detects an iceberg inside its footprint, in (0, 1].
        clutter_per_frame: expected false alarms per frame (Poisson), spread uniformly over
            the footprint disc: clutter density ``lambda_c = clutter_per_frame / (pi R^2)``.
        birth_per_frame: expected icebergs unknown to the tracker per frame's footprint
            (> 0): the birth density ``lambda_b = birth_per_frame / (pi R^2)``; a detection
            that no track explains starts a track with existence
            ``lambda_b / (lambda_b + lambda_c)``.
        confirm_hits, confirm_window: M-of-N confirmation: M hits in the last N frames whose
            footprint covered the track.
        existence_confirm_min: a tentative track is confirmed only with existence >= this.
        existence_delete: confirmed and prior tracks are deleted below this existence.
        lost_sigma_m: confirmed and prior tracks are deleted (``lost``) once
            ``sqrt(trace P_xy) > lost_sigma_m`` (m): a track that vague is no longer a place
            to fly to but an area to search, and the search cells cover it (a covariance
            deleter, like Stone Soup's ``CovarianceBasedDeleter``). ``None``: never (the
            paper's tracks are kept whatever their uncertainty).
        existence_max: cap on the existence probability (< 1); it bounds how much evidence a
            track can bank, so that ``ceil(ln(odds_delete / odds_max) / ln(1 - pd))``
            full misses in view delete it (6 at pd 0.85 with the defaults).
        pd_evidence_max: the pd used in the evidence is ``min(pd, pd_evidence_max)`` so a
            camera modelled as perfect (pd = 1) cannot delete a track on one frame.
        new_track_vel_var_m2_s2: velocity variance per axis of a new track (m^2/s^2).
        gate_probability: chi-square (2 dof) gate ``d2 <= -2 ln(1 - p)``.
        default_radius_m: footprint radius assumed for the clutter density when a scan
            comes without a footprint (m).
        id_prefix: new tracks are named ``id_prefix + counter`` (``N1, N2, ...``), never
            reused.
        jpda_max_hypotheses: clusters with more joint hypotheses than this are solved by
            independent per-track PDA instead of exact enumeration.
        continuation_min_probability: a new track takes an old track's id only when the
            probability that it is that track's iceberg, against every other old track and
            "an iceberg no track had" (birth density), is at least this
            (:func:`observer.tracker_steps.continuation`); otherwise it keeps its new id
            (and still replaces the stale track's estimate it coalesced with). The
            same bound holds when a stale track would take a detection directly
            (:func:`observer.tracker_steps.reacquisition_gate`).
        reacquire_after_s: a track not hit for longer than this (s), or not since it was
            adopted, is stale: it takes a detection only through the reacquisition gate.
    """

    association: str = "gnn"
    pd: float = 0.9
    clutter_per_frame: float = 0.1
    birth_per_frame: float = 0.01
    confirm_hits: int = 3
    confirm_window: int = 5
    existence_confirm_min: float = 0.5
    existence_delete: float = 0.05
    lost_sigma_m: float | None = None
    existence_max: float = 0.999
    pd_evidence_max: float = 0.99
    new_track_vel_var_m2_s2: float = 0.5
    gate_probability: float = 0.9999
    default_radius_m: float = 150.0
    id_prefix: str = "N"
    jpda_max_hypotheses: int = 20000
    continuation_min_probability: float = 0.9
    reacquire_after_s: float = 10.0

    def __post_init__(self) -> None:
        if self.association not in ASSOCIATIONS:
            raise ValueError(
                f"TrackerConfig.association must be one of {', '.join(ASSOCIATIONS)}, "
                f"got {self.association!r}"
            )
        pd = _number("pd", self.pd)
        if not 0.0 < pd <= 1.0:
            raise ValueError(f"TrackerConfig.pd must be in (0, 1], got {self.pd!r}")
        if _number("clutter_per_frame", self.clutter_per_frame) < 0.0:
            raise ValueError(
                f"TrackerConfig.clutter_per_frame must be >= 0, got {self.clutter_per_frame!r}"
            )
        for name in ("birth_per_frame", "new_track_vel_var_m2_s2", "default_radius_m",
                     "reacquire_after_s"):
            if _number(name, getattr(self, name)) <= 0.0:
                raise ValueError(f"TrackerConfig.{name} must be > 0, got {getattr(self, name)!r}")
        m = _integer("confirm_hits", self.confirm_hits, 1)
        n = _integer("confirm_window", self.confirm_window, 1)
        if m > n:
            raise ValueError(
                f"TrackerConfig.confirm_hits must be <= confirm_window ({n}), got {m!r}"
            )
        _integer("jpda_max_hypotheses", self.jpda_max_hypotheses, 1)
        for name in ("existence_confirm_min", "existence_delete", "gate_probability"):
            v = _number(name, getattr(self, name))
            if not 0.0 < v < 1.0:
                raise ValueError(f"TrackerConfig.{name} must be in (0, 1), got {v!r}")
        for name in ("existence_max", "pd_evidence_max", "continuation_min_probability"):
            v = _number(name, getattr(self, name))
            if not 0.0 < v < 1.0:
                raise ValueError(f"TrackerConfig.{name} must be in (0, 1), got {v!r}")
        if not self.existence_delete < self.existence_confirm_min <= self.existence_max:
            raise ValueError(
                "TrackerConfig.existence_confirm_min must lie in (existence_delete, "
                f"existence_max], got {self.existence_confirm_min!r}"
            )
        if self.lost_sigma_m is not None and _number("lost_sigma_m", self.lost_sigma_m) <= 0.0:
            raise ValueError(
                f"TrackerConfig.lost_sigma_m must be > 0 or None, got {self.lost_sigma_m!r}"
            )
        if not isinstance(self.id_prefix, str) or not self.id_prefix:
            raise ValueError(
                f"TrackerConfig.id_prefix must be a non-empty string, got {self.id_prefix!r}"
            )

    @property
    def gate_threshold(self) -> float:
        """``-2 ln(1 - gate_probability)`` (18.42 for 0.9999)."""
        return -2.0 * math.log1p(-self.gate_probability)

    @property
    def pd_evidence(self) -> float:
        """``min(pd, pd_evidence_max)``: the pd the association and existence use."""
        return min(self.pd, self.pd_evidence_max)


@dataclass(frozen=True)
class Footprint:
    """A camera frame's footprint: a disc (local metres)."""

    x_m: float
    y_m: float
    radius_m: float


@dataclass(frozen=True)
class ScanDetection:
    """One unlabelled detection of a scan: position (m) and noise variance per axis (m^2)."""

    x_m: float
    y_m: float
    r_m2: float


@dataclass(frozen=True)
class TrackEvent:
    """A track's lifecycle event: ``kind`` in ``born | confirmed | deleted``."""

    t_s: float
    kind: str
    track_id: str
    reason: str
    successor: str | None = None
    """A deletion by coalescence: the track that goes on with this one's iceberg estimate
    (``merged into`` it, or ``succeeded by`` it); None for every other event."""


@dataclass(frozen=True)
class ScanResult:
    """What one scan did.

    Attributes:
        events: births, confirmations and deletions, in that order within the scan.
        assigned: detection index -> track id it updated (JPDA: the track with the largest
            association probability, when > 0.5).
        unassociated: detections that no track took (each started a tentative track).
        rejected: detections refused as invalid (non-finite, r_m2 <= 0).
    """

    events: tuple[TrackEvent, ...]
    assigned: dict[int, str] = field(default_factory=dict)
    unassociated: int = 0
    rejected: int = 0


@dataclass(frozen=True)
class TrackRecord:
    """A tracked object's lifecycle state; ``might_continue``: see below."""

    id: str
    status: str
    existence: float
    hits: int
    born_s: float
    confirmed_s: float | None
    might_continue: tuple[tuple[str, float], ...] = ()
    """Old tracks this one might continue, ``(id, probability)`` likeliest first, as judged
    when it was confirmed under a new id (empty: no candidate, or not born here)."""
