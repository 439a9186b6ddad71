"""The multi-target observer: one track per iceberg, predicted every step, corrected on sight.

Pure maths: no I/O, no clock; every time is an argument (mission seconds).

Measurement handling (:meth:`Observer.measure`):

1. ``t_s``, ``x_m``, ``y_m`` or ``r_m2`` not finite, or ``r_m2 <= 0`` -> ``invalid``.
2. Every track is predicted to ``t_s``.
3. With a ``target_id``: unknown -> ``unknown_target`` (counted ``unassociated``); the track
   is already past ``t_s`` (late or out of order) -> ``late``; Kalman model: squared
   Mahalanobis distance ``d2 = y' S^-1 y`` of the innovation above the chi-square (2 dof)
   gate ``-2 ln(1 - p)`` -> ``gate``. The linear model is not gated when the id is given
   (its sigma is a staleness clock, not a variance).
4. Without a ``target_id``: the track with the smallest ``d2`` among those not past ``t_s``
   is chosen; none at all -> ``no_track``; all past ``t_s`` -> ``late``; the nearest one
   outside the gate -> ``no_track`` (counted ``unassociated``: possibly a new target).
5. Otherwise the track is corrected -> ``accepted``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from types import MappingProxyType

import numpy as np

from observer.checks import finite_number, is_finite_number
from observer.config import ObserverConfig
from observer.kalman_track import KalmanBatch, KalmanTrack
from observer.linear_track import LinearTrack
from observer.records import MeasurementOutcome, TrackSnapshot

COUNTER_NAMES: tuple[str, ...] = (
    "accepted",
    "rejected_gate",
    "rejected_late",
    "rejected_invalid",
    "unassociated",
)

_Track = KalmanTrack | LinearTrack


def _non_negative(name: str, value: float) -> float:
    v = finite_number(name, value)
    if v < 0.0:
        raise ValueError(f"{name} must be >= 0, got {value!r}")
    return v


class Observer:
    """One Kalman (or linear-model) track per target; see the module docstring."""

    def __init__(self, config: ObserverConfig) -> None:
        if not isinstance(config, ObserverConfig):
            raise TypeError(f"config must be an ObserverConfig, got {type(config).__name__}")
        self.config = config
        self._tracks: dict[str, _Track] = {}
        self._ever_lost: dict[str, bool] = {}
        self._counters: dict[str, int] = dict.fromkeys(COUNTER_NAMES, 0)
        # every Kalman track, stepped together; the members above the watch floor are
        # checked for the lost flag: sigma <= fov^2 (1 - 1e-9) has sqrt(sigma) < fov by far
        # more than a rounding, so the exact rule (_is_lost) runs only above it
        self._batch = KalmanBatch(config.max_step_s, config.fov_radius_m ** 2 * (1.0 - 1e-9))
        self._id_of: dict[KalmanTrack, str] = {}  # each Kalman track's id

    # --- targets --------------------------------------------------------------------------
    def add_target(
        self,
        target_id: str,
        t_s: float,
        x_m: float,
        y_m: float,
        *,
        vx_m_s: float = 0.0,
        vy_m_s: float = 0.0,
        sigma0: float | None = None,
        p0: Sequence[float] | None = None,
        q_per_s: float | None = None,
    ) -> None:
        """Start tracking ``target_id`` at ``t_s`` from the given state.

        Kalman model: ``P0 = diag(p0)`` if ``p0`` is given; else, with ``sigma0``,
        ``diag(sigma0/2, sigma0/2, q h, q h)``; else ``Q(h) = diag(0, 0, q h, q h)`` (eq. 6),
        ``h = max_step_s``. Linear model: ``sigma = sigma0`` (else ``p0[0] + p0[1]``, else 0).

        Raises:
            ValueError: duplicate id or a bad value (the message names the argument).
        """
        if not isinstance(target_id, str) or not target_id:
            raise ValueError(f"target_id must be a non-empty string, got {target_id!r}")
        if target_id in self._tracks:
            raise ValueError(f"target_id {target_id!r} is already tracked")
        t = finite_number("t_s", t_s)
        state = (
            finite_number("x_m", x_m),
            finite_number("y_m", y_m),
            finite_number("vx_m_s", vx_m_s),
            finite_number("vy_m_s", vy_m_s),
        )
        q = self.config.q_per_s if q_per_s is None else _non_negative("q_per_s", q_per_s)
        s0 = None if sigma0 is None else _non_negative("sigma0", sigma0)
        p0_diag: list[float] | None = None
        if p0 is not None:
            values = list(p0)
            if len(values) != 4:
                raise ValueError(f"p0 must hold 4 variances (x, y, vx, vy), got {len(values)}")
            p0_diag = [_non_negative(f"p0[{i}]", v) for i, v in enumerate(values)]
        h = self.config.max_step_s
        track: _Track
        if self.config.model == "kalman":
            if p0_diag is None:
                pos = 0.0 if s0 is None else 0.5 * s0
                p0_diag = [pos, pos, q * h, q * h]
            track = KalmanTrack(t, state, p0_diag, q, h)
        else:
            if s0 is None:
                s0 = 0.0 if p0_diag is None else p0_diag[0] + p0_diag[1]
            track = LinearTrack(t, state, s0, q, self.config.linear_growth_per_s)
        self._put(target_id, track)
        self._ever_lost[target_id] = False
        self._check_lost(target_id)

    def _put(self, target_id: str, track: _Track) -> None:
        """``track`` becomes ``target_id``'s (a Kalman track joins the batch)."""
        self._tracks[target_id] = track
        if isinstance(track, KalmanTrack):
            self._batch.add(track)
            self._id_of[track] = target_id

    def _drop(self, target_id: str) -> None:
        """``target_id`` is no longer tracked (its Kalman track leaves the batch)."""
        self._unregister(self._tracks.pop(target_id))

    def _unregister(self, track: _Track) -> None:
        if isinstance(track, KalmanTrack):
            self._batch.remove(track)
            del self._id_of[track]

    def remove_target(self, target_id: str) -> None:
        """Stop tracking ``target_id``. Raises KeyError if unknown."""
        if target_id not in self._tracks:
            raise KeyError(f"unknown target_id {target_id!r}")
        self._drop(target_id)
        del self._ever_lost[target_id]

    def set_position_moments(
        self, target_id: str, t_s: float, mean_xy: np.ndarray, cov_xy: np.ndarray
    ) -> None:
        """Replace a Kalman track's position mean and covariance at ``t_s`` (negative
        information from a frame that did not see it, :func:`observer.existence.
        position_after_miss`); see :meth:`KalmanTrack.set_position_moments`. Linear-model
        tracks are left alone. Raises KeyError if unknown."""
        track = self._at(target_id, t_s)
        if isinstance(track, KalmanTrack):
            track.set_position_moments(track.t_s, mean_xy, cov_xy)
            self._check_lost(target_id)

    def reseat(self, target_id: str, t_s: float, x_m: float, y_m: float,
               sigma0: float) -> None:
        """An operator's fix: ``target_id`` is at (x_m, y_m) at ``t_s`` with position
        uncertainty ``sigma0`` (m^2, the trace of the position covariance), whatever the
        estimate said; no gate. The track keeps its velocity estimate, its velocity
        variances (Kalman), its process noise and its ever-lost flag; it counts as seen at
        ``t_s``. Raises KeyError if unknown, ValueError for a bad value."""
        old = self._at(target_id, t_s)
        x, y = finite_number("x_m", x_m), finite_number("y_m", y_m)
        s0 = _non_negative("sigma0", finite_number("sigma0", sigma0))
        _, _, vx, vy = old.state
        ever_lost = self._ever_lost[target_id]
        p0: list[float] | None = None
        if isinstance(old, KalmanTrack):
            p0 = [0.5 * s0, 0.5 * s0, float(old.p_view[2, 2]), float(old.p_view[3, 3])]
        self._drop(target_id)
        self.add_target(target_id, old.t_s, x, y, vx_m_s=vx, vy_m_s=vy,
                        sigma0=None if p0 is not None else s0, p0=p0, q_per_s=old.q_per_s)
        self._tracks[target_id].last_seen_s = old.t_s
        self._ever_lost[target_id] = ever_lost or self._ever_lost[target_id]

    def take_over(self, target_id: str, source_id: str) -> None:
        """``target_id``'s filter is replaced by ``source_id``'s (a newer estimate of the same
        object), which stops being tracked; ``target_id`` keeps its process-noise intensity
        and its ever-lost flag. Raises KeyError if either is unknown, ValueError if equal."""
        target, source = self._get(target_id), self._get(source_id)
        if target_id == source_id:
            raise ValueError(f"cannot take over {target_id!r} by itself")
        source.set_process_noise(target.q_per_s)
        self._drop(source_id)
        self._unregister(target)
        self._put(target_id, source)  # in target_id's place
        del self._ever_lost[source_id]
        self._check_lost(target_id)

    def set_process_noise(self, target_id: str, q_per_s: float) -> None:
        """Set a track's process-noise intensity (applies from its last committed time)."""
        q = _non_negative("q_per_s", q_per_s)
        self._get(target_id).set_process_noise(q)

    # --- time -----------------------------------------------------------------------------
    def predict_to(self, t_s: float) -> None:
        """Advance every track to ``t_s``; a track already at or past ``t_s`` is left alone."""
        t = finite_number("t_s", t_s)
        if self.config.model != "kalman":
            for target_id, track in self._tracks.items():
                if t > track.t_s:
                    track.predict_to(t)
                    self._check_lost(target_id)
            return
        # every Kalman track at once (the batch: bit for bit the per-track predictions)
        batch = self._batch
        members_moved, moved = batch.advance(t)
        id_of = self._id_of
        for track in moved:
            self._check_lost(id_of[track])
        if members_moved:  # the few members above the watch floor may be lost
            for track in batch.watched_above():
                target_id = id_of[track]
                self._check_lost(target_id)
                if self._ever_lost[target_id]:  # flagged for good: no need to look again
                    batch.unwatch(track)

    # --- measurements ---------------------------------------------------------------------
    def measure(
        self,
        t_s: float,
        x_m: float,
        y_m: float,
        target_id: str | None = None,
        *,
        r_m2: float | None = None,
    ) -> MeasurementOutcome:
        """Apply one position measurement; never raises on bad measurement data."""
        r = self.config.r_m2 if r_m2 is None else r_m2
        if not (is_finite_number(t_s) and is_finite_number(x_m) and is_finite_number(y_m)
                and is_finite_number(r)) or r <= 0.0:
            return self._reject("rejected_invalid", target_id, "invalid", None)
        t, x, y, r = float(t_s), float(x_m), float(y_m), float(r)
        if target_id is not None and (
            not isinstance(target_id, str) or target_id not in self._tracks
        ):
            return self._reject("unassociated", target_id, "unknown_target", None)
        self.predict_to(t)
        gate = self.config.gate_threshold
        if target_id is not None:
            track = self._tracks[target_id]
            if track.t_s > t:
                return self._reject("rejected_late", target_id, "late", None)
            d2 = track.innovation(x, y, r)
            if isinstance(track, KalmanTrack) and not d2 <= gate:
                return self._reject("rejected_gate", target_id, "gate", d2)
            return self._accept(target_id, t, x, y, r, d2)
        if not self._tracks:
            return self._reject("unassociated", None, "no_track", None)
        candidates = [(tid, tr) for tid, tr in sorted(self._tracks.items()) if tr.t_s <= t]
        if not candidates:
            return self._reject("rejected_late", None, "late", None)
        best_id, best_d2 = None, math.inf
        for tid, tr in candidates:
            d2 = tr.innovation(x, y, r)
            if d2 < best_d2:
                best_id, best_d2 = tid, d2
        if best_id is None or not best_d2 <= gate:
            return self._reject(
                "unassociated", None, "no_track", None if best_id is None else best_d2
            )
        return self._accept(best_id, t, x, y, r, best_d2)

    # --- associated updates (the multi-target tracker's path) ------------------------------
    def estimates_at(
        self, t_s: float, target_ids: Sequence[str]
    ) -> tuple[list[str], np.ndarray, np.ndarray]:
        """Predict every track to ``t_s`` and return, for the listed ids (unknown ones left
        out), ``(ids, means (n x 2), covariances (n x 2 x 2))`` of their positions.

        A track already past ``t_s`` is moved back to it when its committed time allows
        (:meth:`KalmanTrack.rewind_to`: the view is a function of the committed state);
        one committed after ``t_s`` (the grid or a later measurement) stays at its own time,
        and :meth:`correct` / :meth:`correct_pda` apply the measurement there (an error of
        ``v (t_track - t_s)``: the caller is late by less than a tick).
        """
        t = finite_number("t_s", t_s)
        self.predict_to(t)
        ids: list[str] = []
        means: list[tuple[float, float]] = []
        covs: list[tuple[float, float, float]] = []
        tracks = self._tracks
        for tid in target_ids:
            tr = tracks.get(tid)
            if tr is None:
                continue
            if tr.t_s != t:
                tr.rewind_to(t)
            x, y, _, _ = tr.state
            ids.append(tid)
            means.append((x, y))
            covs.append(tr.cov_xy)
        mean_arr = np.array(means, dtype=float).reshape(-1, 2)
        c = np.array(covs, dtype=float).reshape(-1, 3)
        cov_arr = np.stack([c[:, 0], c[:, 1], c[:, 1], c[:, 2]], axis=1).reshape(-1, 2, 2)
        return ids, mean_arr, cov_arr

    def correct(self, target_id: str, t_s: float, x_m: float, y_m: float, r_m2: float) -> None:
        """Apply a measurement already associated to ``target_id`` (no gate: the caller
        associated it) at ``t_s`` (see :meth:`estimates_at` for a track already past it).
        Counted ``accepted``. Raises KeyError (unknown id) or ValueError (bad value)."""
        track = self._at(target_id, t_s)
        r = finite_number("r_m2", r_m2)
        if r <= 0.0:
            raise ValueError(f"r_m2 must be > 0, got {r_m2!r}")
        x, y = finite_number("x_m", x_m), finite_number("y_m", y_m)
        self._accept(target_id, track.t_s, x, y, r, math.nan)  # d2: the caller's gate

    def correct_pda(
        self,
        target_id: str,
        t_s: float,
        zs: Sequence[Sequence[float]] | np.ndarray,
        betas: Sequence[float] | np.ndarray,
        r_m2: float,
    ) -> None:
        """Probabilistic data association update of a Kalman track at its current time
        ``t_s``: measurements ``zs`` with association probabilities ``betas`` (the rest,
        ``1 - sum(betas)``, is the probability that none is the target's), see
        :meth:`KalmanTrack.correct_pda`. Counted ``accepted`` once. Raises KeyError or
        ValueError (bad values, a linear-model track)."""
        track = self._at(target_id, t_s)
        if not isinstance(track, KalmanTrack):
            raise ValueError("correct_pda needs the kalman model")
        z = np.asarray(zs, dtype=float).reshape(-1, 2)
        b = np.asarray(betas, dtype=float).ravel()
        r = finite_number("r_m2", r_m2)
        if (
            b.shape[0] != z.shape[0]
            or not np.all(np.isfinite(z))
            or not np.all(np.isfinite(b))
            or np.any(b < 0.0)
            or float(b.sum()) > 1.0 + 1e-9
            or r <= 0.0
        ):
            raise ValueError("correct_pda: zs, betas (>= 0, sum <= 1) and r_m2 > 0 must match")
        if z.shape[0] == 0 or float(b.sum()) <= 0.0:
            return
        track.correct_pda(track.t_s, z, b, r)
        self._check_lost(target_id)
        self._counters["accepted"] += 1

    def _at(self, target_id: str, t_s: float) -> _Track:
        """The track brought to ``t_s`` (forward, or back within its committed step); one
        committed after ``t_s`` stays at its own time (see :meth:`estimates_at`)."""
        track = self._get(target_id)
        t = finite_number("t_s", t_s)
        if track.t_s < t:
            track.predict_to(t)
        elif track.t_s > t:
            track.rewind_to(t)
        return track

    def _accept(
        self, target_id: str, t: float, x: float, y: float, r: float, d2: float
    ) -> MeasurementOutcome:
        self._tracks[target_id].correct(t, x, y, r)
        self._check_lost(target_id)
        self._counters["accepted"] += 1
        return MeasurementOutcome(True, target_id, "accepted", d2)

    def _reject(
        self, counter: str, target_id: object, reason: str, d2: float | None
    ) -> MeasurementOutcome:
        self._counters[counter] += 1
        tid = target_id if isinstance(target_id, str) else None
        return MeasurementOutcome(False, tid, reason, d2)

    # --- read-out -------------------------------------------------------------------------
    def _get(self, target_id: str) -> _Track:
        try:
            return self._tracks[target_id]
        except KeyError:
            raise KeyError(f"unknown target_id {target_id!r}") from None

    def _is_lost(self, track: _Track) -> bool:
        """:meth:`_lost_at` the track's sigma."""
        return self._lost_at(track.sigma)

    def _lost_at(self, sigma: float) -> bool:
        """``sqrt(max(sigma, 0)) > fov_radius_m`` (fov_radius_m > 0)."""
        return sigma > 0.0 and math.sqrt(sigma) > self.config.fov_radius_m

    def _check_lost(self, target_id: str) -> None:
        if self._is_lost(self._tracks[target_id]):
            self._ever_lost[target_id] = True

    def track(self, target_id: str) -> TrackSnapshot:
        """Snapshot of one track at its current time. Raises KeyError if unknown."""
        tr = self._get(target_id)
        return self._snapshot(target_id, tr, tr.t_s, tr.state, tr.sigma, tr.cov_xy)

    def _snapshot(
        self, target_id: str, tr: _Track, t_s: float, state: tuple[float, float, float, float],
        sigma: float, cov_xy: tuple[float, float, float],
    ) -> TrackSnapshot:
        x, y, vx, vy = state
        # positional, in TrackSnapshot's field order (a third cheaper than by keyword)
        return TrackSnapshot(
            target_id, t_s, x, y, vx, vy, sigma, cov_xy,
            self._lost_at(sigma),
            self._ever_lost[target_id], tr.last_seen_s, tr.q_per_s,
        )

    def tracks(self) -> list[TrackSnapshot]:
        """Snapshots of every track (lost ones included), sorted by id; the batch's members
        read from its stacks at once (the same floats as :meth:`track`)."""
        members = self._batch.read_members()
        t_members_s = self._batch.t_s
        out: list[TrackSnapshot] = []
        for tid in sorted(self._tracks):
            tr = self._tracks[tid]
            readout = members.get(tr) if isinstance(tr, KalmanTrack) else None
            if readout is None:
                out.append(self._snapshot(tid, tr, tr.t_s, tr.state, tr.sigma, tr.cov_xy))
            else:
                state, sigma, cov_xy = readout
                out.append(self._snapshot(tid, tr, t_members_s, state, sigma, cov_xy))
        return out

    def sigma(self, target_id: str) -> float:
        """``trace(P[:2, :2])`` (m^2), or the linear model's sigma."""
        return self._get(target_id).sigma

    @property
    def target_ids(self) -> list[str]:
        """Tracked ids, sorted."""
        return sorted(self._tracks)

    @property
    def counters(self) -> Mapping[str, int]:
        """Read-only copy: accepted, rejected_gate, rejected_late, rejected_invalid,
        unassociated."""
        return MappingProxyType(dict(self._counters))
