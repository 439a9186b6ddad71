"""Multi-target tracker: association of whole scans, track birth, confirmation, deletion.

The :class:`observer.Observer` owns the filters (filterpy Kalman tracks); the
:class:`Tracker` owns their lifecycle: status (``tentative``, ``confirmed``, ``prior``),
existence probability, M-of-N window, ids. Pure maths: no I/O, no clock.

One scan (:meth:`Tracker.scan`), detections of one camera frame at ``t_s``:

1. Invalid detections (non-finite, ``r_m2 <= 0``) are rejected and counted; a non-finite
   ``t_s`` rejects the whole scan; a bad footprint is treated as no footprint.
2. Every track is predicted to ``t_s`` (:meth:`Observer.estimates_at`). Only tracks whose
   predicted position could be in the footprint take part: centre distance
   ``<= R + sqrt(gamma (lambda_max(P) + max r))`` (no footprint: all tracks).
3. ``Pin`` (probability inside the footprint, :func:`observer.existence.inside_probability`)
   and the likelihoods and gates of every pair (:mod:`observer.association`).
4. GNN: the likeliest assignment; assigned tracks get a Kalman update and the hit existence
   update, the others the miss update. JPDA: marginal association probabilities, a PDA
   update, JIPDA existence.
5. Each track that took part appends hit/miss to its window when the frame covered it
   (a hit, or ``Pin >= 0.5``); without a footprint only hits count and a miss is no
   evidence (nobody knows where the camera looked).
6. Lifecycle: tentative -> confirmed with ``confirm_hits`` hits in the last
   ``confirm_window`` covering frames and existence ``>= existence_confirm_min`` (or merged
   into an old confirmed/prior track when the evidence says it is that track's iceberg,
   :func:`observer.tracker_steps.continuation`; otherwise a new id whose record lists the
   old tracks it might continue);
   tentative deleted (``unconfirmed``) once its window holds more than ``N - M`` misses or
   the observer calls it lost; prior -> confirmed by the same M-of-N (one false alarm
   near a listed phantom must not confirm it); confirmed and prior deleted
   (``not seen in view``) when existence ``< existence_delete``.
7. Detections no track took start tentative tracks: state at the detection, velocity 0,
   ``P0 = diag(r, r, v, v)`` (``v = new_track_vel_var_m2_s2``), existence
   ``lambda_b / (lambda_b + lambda_c)``.

Equations and parameter choice: docs/tracker.md.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from observer.association import gnn_assign, scan_likelihoods
from observer.checks import is_finite_number
from observer.existence import (
    existence_after_hit,
    existence_after_miss,
    inside_probability,
    position_after_miss,
)
from observer.observer import Observer
from observer.tracker_config import (
    UNCONFIRMED,
    Footprint,
    ScanDetection,
    ScanResult,
    TrackerConfig,
    TrackEvent,
    TrackRecord,
)
from observer.tracker_steps import (
    Continuation,
    continuation,
    jpda_step,
    reacquisition_gate,
    stale_twin,
)

COUNTER_NAMES: tuple[str, ...] = (
    "scans",
    "detections",
    "assigned",
    "unassociated",
    "rejected_invalid",
    "rejected_footprint",
    "rejected_scans",
)


@dataclass
class _Life:
    status: str
    existence: float
    window: deque[bool]
    hits: int
    born_s: float
    confirmed_s: float | None
    keep: bool = False
    might_continue: tuple[tuple[str, float], ...] = ()
    last_hit_s: float | None = None  # None: not hit since adopted


class Tracker:
    """Lifecycle of the observer's tracks from unlabelled scans; see the module docstring."""

    def __init__(self, observer: Observer, config: TrackerConfig) -> None:
        if not isinstance(observer, Observer):
            raise TypeError(f"observer must be an Observer, got {type(observer).__name__}")
        if not isinstance(config, TrackerConfig):
            raise TypeError(f"config must be a TrackerConfig, got {type(config).__name__}")
        if config.association == "jpda" and observer.config.model != "kalman":
            raise ValueError("TrackerConfig.association 'jpda' needs the kalman observer model")
        self.observer = observer
        self.config = config
        self._life: dict[str, _Life] = {}
        self._next_id = 1
        self._counters: dict[str, int] = dict.fromkeys(COUNTER_NAMES, 0)

    # --- tracks made elsewhere ------------------------------------------------------------
    def adopt(self, track_id: str, status: str = "confirmed", existence: float | None = None,
              t_s: float | None = None, *, keep: bool = False) -> None:
        """Take over the lifecycle of ``track_id`` (already in the observer): ``confirmed``
        (default existence 1.0) or ``prior`` (default 0.5); capped at ``existence_max``.
        ``keep``: an operator's target (announced, not found by the camera): its existence
        is still updated, but missing evidence never deletes it; only the caller removes it.

        Raises:
            KeyError: not in the observer. ValueError: already adopted, or a bad value.
        """
        if track_id not in self.observer.target_ids:
            raise KeyError(f"unknown target_id {track_id!r}")
        if track_id in self._life:
            raise ValueError(f"track {track_id!r} is already adopted")
        if status not in ("confirmed", "prior"):
            raise ValueError(f"status must be 'confirmed' or 'prior', got {status!r}")
        r = (1.0 if status == "confirmed" else 0.5) if existence is None else existence
        if not is_finite_number(r) or not 0.0 < float(r) <= 1.0:
            raise ValueError(f"existence must be in (0, 1], got {existence!r}")
        born = self.observer.track(track_id).t_s if t_s is None else float(t_s)
        self._life[track_id] = _Life(
            status=status,
            existence=min(float(r), self.config.existence_max),
            window=deque(maxlen=self.config.confirm_window),
            hits=0,
            born_s=born,
            confirmed_s=born if status == "confirmed" else None,
            keep=keep,
        )

    def forget(self, track_id: str) -> None:
        """Drop the lifecycle of a track the core removed (no-op if unknown)."""
        self._life.pop(track_id, None)

    # --- read-out -------------------------------------------------------------------------
    def status(self, track_id: str) -> str:
        """``tentative``, ``confirmed`` or ``prior``. Raises KeyError if unknown."""
        return self._get(track_id).status

    def existence(self, track_id: str) -> float:
        """Existence probability. Raises KeyError if unknown."""
        return self._get(track_id).existence

    def records(self) -> list[TrackRecord]:
        """Every track's lifecycle, sorted by id."""
        return [
            TrackRecord(tid, lf.status, lf.existence, lf.hits, lf.born_s, lf.confirmed_s,
                        lf.might_continue)
            for tid, lf in sorted(self._life.items())
        ]

    @property
    def track_ids(self) -> list[str]:
        return sorted(self._life)

    @property
    def counters(self) -> Mapping[str, int]:
        """Read-only copy of :data:`COUNTER_NAMES` counts."""
        return MappingProxyType(dict(self._counters))

    def _get(self, track_id: str) -> _Life:
        try:
            return self._life[track_id]
        except KeyError:
            raise KeyError(f"unknown track {track_id!r}") from None

    # --- one scan -------------------------------------------------------------------------
    def scan(
        self,
        t_s: float,
        vehicle: str,
        footprint: Footprint | None,
        detections: Sequence[ScanDetection],
    ) -> ScanResult:
        """Process one camera frame's detections; never raises on bad detection data."""
        del vehicle  # frames are independent; the vehicle only orders scans (the caller)
        cfg = self.config
        dets = list(detections)
        self._counters["scans"] += 1
        self._counters["detections"] += len(dets)
        if not is_finite_number(t_s):
            self._counters["rejected_scans"] += 1
            self._counters["rejected_invalid"] += len(dets)
            return ScanResult(events=(), rejected=len(dets))
        t = float(t_s)
        fp = footprint
        if fp is not None and not (
            all(is_finite_number(v) for v in (fp.x_m, fp.y_m, fp.radius_m)) and fp.radius_m > 0.0
        ):
            self._counters["rejected_footprint"] += 1
            fp = None
        index: list[int] = []
        rows: list[tuple[float, float, float]] = []
        for k, d in enumerate(dets):
            if all(is_finite_number(v) for v in (d.x_m, d.y_m, d.r_m2)) and d.r_m2 > 0.0:
                index.append(k)
                rows.append((float(d.x_m), float(d.y_m), float(d.r_m2)))
        rejected = len(dets) - len(index)
        self._counters["rejected_invalid"] += rejected
        zr = np.array(rows, dtype=float).reshape(-1, 3)
        z, r_m2 = zr[:, :2], zr[:, 2]

        radius = cfg.default_radius_m if fp is None else float(fp.radius_m)
        area_m2 = math.pi * radius * radius
        lam_c = cfg.clutter_per_frame / area_m2
        lam_b = cfg.birth_per_frame / area_m2
        lam = lam_c + lam_b
        pd = cfg.pd_evidence

        confirmed: list[TrackEvent] = []
        deleted: list[TrackEvent] = []
        ids, means, covs = self._candidates(
            t, fp, float(r_m2.max()) if len(r_m2) else 0.0, deleted
        )
        exist = np.array([self._life[i].existence for i in ids], dtype=float)
        if fp is not None and ids:
            p_in = inside_probability(means, covs, (float(fp.x_m), float(fp.y_m)), radius)
        else:
            p_in = np.zeros(len(ids))
        miss = 1.0 - exist * pd * p_in
        hit = np.zeros(len(ids), dtype=bool)
        updated = np.zeros(len(ids), dtype=bool)  # had any update (JPDA: also hit < 0.5)
        deferred = np.zeros(len(ids), dtype=bool)  # refused by the reacquisition gate
        assigned: dict[int, str] = {}
        taken = np.zeros(len(index), dtype=bool)
        if ids and len(index):
            lk = scan_likelihoods(
                z, r_m2, means, covs, exist, miss, pd, math.log(lam), cfg.gate_threshold
            )
            log_ratio = reacquisition_gate(
                lk.log_ratio, self._stale(ids, t), cfg.continuation_min_probability
            )
            deferred = (np.isfinite(lk.log_ratio) & ~np.isfinite(log_ratio)).any(axis=0)
            if cfg.association == "gnn":
                new_exist = existence_after_miss(exist, pd, p_in)
                for i, j in sorted(gnn_assign(log_ratio).items()):
                    tid = ids[j]
                    self.observer.correct(tid, t, z[i, 0], z[i, 1], r_m2[i])
                    lik = math.exp(float(lk.log_lik[i, j]))
                    new_exist[j] = existence_after_hit(exist[j], pd, p_in[j], lik, lam)
                    hit[j] = updated[j] = True
                    taken[i] = True
                    assigned[index[i]] = tid
            else:
                new_exist, picks = jpda_step(
                    self.observer, t, ids, z, r_m2, log_ratio, exist, p_in, pd,
                    cfg.jpda_max_hypotheses, hit, updated, taken,
                )
                assigned.update({index[i]: tid for i, tid in picks.items()})
        else:
            new_exist = existence_after_miss(exist, pd, p_in)
        # A stale track refused a detection that may be its iceberg's was not missed: the
        # scan is no evidence about it (the continuation test decides later).
        deferred &= ~hit
        new_exist = np.where(deferred, exist, new_exist)
        updated |= deferred
        if fp is None:  # no footprint: a miss is no evidence
            new_exist = np.where(hit, new_exist, exist)
        elif ids:
            self._negative_information(t, ids, means, covs, updated, (fp.x_m, fp.y_m), radius,
                                       pd)
        new_exist = np.minimum(new_exist, cfg.existence_max)

        hit_ids = {tid for j, tid in enumerate(ids) if hit[j]}
        for j, tid in enumerate(ids):
            if tid in self._life:  # not merged away earlier in this loop
                self._lifecycle(tid, t, bool(hit[j]), float(new_exist[j]),
                                fp is not None and p_in[j] >= 0.5 and not deferred[j], hit_ids,
                                lam_b, confirmed,
                                deleted)
        born = [self._birth(t, z[i, 0], z[i, 1], r_m2[i], lam_b, lam_c, confirmed)
                for i in range(len(index)) if not taken[i]]
        self._counters["assigned"] += len(assigned)
        self._counters["unassociated"] += len(born)
        return ScanResult(
            events=tuple(born + confirmed + deleted),
            assigned=assigned,
            unassociated=len(born),
            rejected=rejected,
        )

    def _candidates(
        self, t: float, fp: Footprint | None, r_max_m2: float, deleted: list[TrackEvent]
    ) -> tuple[list[str], np.ndarray, np.ndarray]:
        """Tracks at ``t`` that could be in the footprint (all without one).

        On the way: lifecycles of tracks the caller removed from the observer are dropped,
        tentative tracks the observer calls lost (``sqrt(trace P) > fov_radius_m``: no
        frame can confirm them any more) are deleted (``unconfirmed``), and confirmed and
        prior tracks beyond ``lost_sigma_m`` (``lost``), unless kept."""
        ids, means, covs = self.observer.estimates_at(t, list(self._life))
        if len(ids) != len(self._life):
            present = set(ids)
            for tid in [tid for tid in self._life if tid not in present]:
                del self._life[tid]
        if not ids:
            return ids, means, covs
        a, b, c = covs[:, 0, 0], covs[:, 0, 1], covs[:, 1, 1]
        lost2 = self.observer.config.fov_radius_m ** 2
        keep_mask = np.ones(len(ids), dtype=bool)
        for k in np.flatnonzero(a + c > lost2).tolist():
            if self._life[ids[k]].status == "tentative":
                self._delete(ids[k], t, UNCONFIRMED, deleted)
                keep_mask[k] = False
        if self.config.lost_sigma_m is not None:
            for k in np.flatnonzero(keep_mask & (a + c > self.config.lost_sigma_m ** 2)).tolist():
                if not self._life[ids[k]].keep:
                    self._delete(ids[k], t, "lost", deleted)
                    keep_mask[k] = False
        if fp is not None:
            lam_max = 0.5 * (a + c) + np.hypot(0.5 * (a - c), b)
            reach = float(fp.radius_m) + np.sqrt(
                self.config.gate_threshold * (lam_max + r_max_m2)
            )
            dist = np.hypot(means[:, 0] - float(fp.x_m), means[:, 1] - float(fp.y_m))
            keep_mask &= dist <= reach
        keep = np.flatnonzero(keep_mask)
        return [ids[k] for k in keep.tolist()], means[keep], covs[keep]

    def _stale(self, ids: list[str], t: float) -> np.ndarray:
        """Tracks not hit for longer than ``reacquire_after_s`` (or not since adopted)."""
        after = self.config.reacquire_after_s
        return np.array(
            [(h := self._life[i].last_hit_s) is None or t - h > after for i in ids], dtype=bool
        )

    def _negative_information(
        self,
        t: float,
        ids: list[str],
        means: np.ndarray,
        covs: np.ndarray,
        updated: np.ndarray,
        centre: tuple[float, float],
        radius: float,
        pd: float,
    ) -> None:
        """Tracks with no update this scan, partly in view: their position moves out of the
        water just seen (:func:`observer.existence.position_after_miss`)."""
        missed = np.flatnonzero(~updated)
        if missed.size == 0:
            return
        mask, new_m, new_p = position_after_miss(
            means[missed], covs[missed], (float(centre[0]), float(centre[1])), radius, pd
        )
        for k, j in enumerate(missed[mask].tolist()):
            self.observer.set_position_moments(ids[j], t, new_m[k], new_p[k])

    def _lifecycle(
        self,
        tid: str,
        t: float,
        hit: bool,
        existence: float,
        in_view: bool,
        hit_ids: set[str],
        lam_b: float,
        confirmed: list[TrackEvent],
        deleted: list[TrackEvent],
    ) -> None:
        cfg = self.config
        life = self._life[tid]
        life.existence = existence
        if hit or in_view:
            life.window.append(hit)
        if hit:
            life.hits += 1
            life.last_hit_s = t
        if life.status == "tentative":
            if sum(life.window) >= cfg.confirm_hits and existence >= cfg.existence_confirm_min:
                statuses = {oid: lf.status for oid, lf in self._life.items()}
                older = stale_twin(self.observer, statuses, tid, hit_ids, cfg.gate_threshold)
                lives = {oid: (lf.status, lf.existence) for oid, lf in self._life.items()}
                cont = continuation(self.observer, lives, tid, hit_ids, cfg.gate_threshold,
                                    lam_b, cfg.continuation_min_probability)
                if older is None:
                    life.might_continue = cont.candidates
                    self._confirm(tid, t, "m_of_n" + _might_continue(cont), confirmed)
                elif cont.take == older or self._life[older].keep:
                    self._merge(older, tid, t, cont, confirmed, deleted)
                else:
                    self._succeed(older, tid, t, cont, confirmed, deleted)
            elif life.window.count(False) > cfg.confirm_window - cfg.confirm_hits:
                self._delete(tid, t, UNCONFIRMED, deleted)
        elif (
            life.status == "prior"
            and sum(life.window) >= cfg.confirm_hits
            and existence >= cfg.existence_confirm_min
        ):
            self._confirm(tid, t, "prior_seen", confirmed)
        elif existence < cfg.existence_delete and not life.keep:
            self._delete(tid, t, "not seen in view", deleted)

    def _merge(
        self, older: str, tid: str, t: float, cont: Continuation, confirmed: list[TrackEvent],
        deleted: list[TrackEvent],
    ) -> None:
        """Track coalescence: the tentative ``tid`` that reached confirmation is the stale
        ``older`` track's iceberg found again (:func:`observer.tracker_steps.continuation`
        says so with probability ``>= continuation_min_probability``): ``older`` takes its
        filter and evidence and keeps its id; ``tid`` is deleted
        (``merged into <older> (p 0.97)``)."""
        new = self._life.pop(tid)
        life = self._life[older]
        self.observer.take_over(older, tid)
        life.existence = max(life.existence, new.existence)
        life.hits += new.hits
        life.window = new.window
        life.last_hit_s = new.last_hit_s
        if life.status == "prior":
            self._confirm(older, t, "prior_seen", confirmed)
        deleted.append(TrackEvent(t, "deleted", tid,
                                  f"merged into {older} (p {cont.probability:.2f})", older))

    def _succeed(
        self, older: str, tid: str, t: float, cont: Continuation, confirmed: list[TrackEvent],
        deleted: list[TrackEvent],
    ) -> None:
        """Track coalescence without the identity: ``tid`` replaces the stale ``older``
        track's estimate, as :meth:`_merge` does, but the evidence does not say it is the
        same iceberg (its continuation probability is below ``continuation_min_probability``,
        or another old track or "a new iceberg" is likelier). So the id is ``tid``'s:
        ``older`` is deleted (``succeeded by <tid> (p 0.43)``) and ``tid`` is confirmed with
        the evidence of both and the old tracks it might continue in its record. The
        estimates are those :meth:`_merge` leaves; only the id differs."""
        old = self._life[older]
        life = self._life[tid]
        life.existence = max(life.existence, old.existence)
        life.hits += old.hits
        life.might_continue = cont.candidates
        p_older = dict(cont.candidates).get(older, 0.0)
        self._delete(older, t, f"succeeded by {tid} (p {p_older:.2f})", deleted, successor=tid)
        self._confirm(tid, t, "m_of_n" + _might_continue(cont), confirmed)

    def _confirm(self, tid: str, t: float, reason: str, out: list[TrackEvent]) -> None:
        life = self._life[tid]
        life.status = "confirmed"
        life.confirmed_s = t
        out.append(TrackEvent(t, "confirmed", tid, reason))

    def _delete(self, tid: str, t: float, reason: str, out: list[TrackEvent],
                successor: str | None = None) -> None:
        del self._life[tid]
        if tid in self.observer.target_ids:
            self.observer.remove_target(tid)
        out.append(TrackEvent(t, "deleted", tid, reason, successor))

    def _birth(
        self, t: float, x: float, y: float, r: float, lam_b: float, lam_c: float,
        confirmed: list[TrackEvent],
    ) -> TrackEvent:
        cfg = self.config
        known = set(self.observer.target_ids)
        while (tid := f"{cfg.id_prefix}{self._next_id}") in known:
            self._next_id += 1
        self._next_id += 1
        v = cfg.new_track_vel_var_m2_s2
        self.observer.add_target(tid, t, float(x), float(y), p0=[float(r), float(r), v, v])
        life = _Life(
            status="tentative",
            existence=min(lam_b / (lam_b + lam_c), cfg.existence_max),
            window=deque([True], maxlen=cfg.confirm_window),
            hits=1,
            born_s=t,
            confirmed_s=None,
            last_hit_s=t,
        )
        self._life[tid] = life
        if cfg.confirm_hits <= 1 and life.existence >= cfg.existence_confirm_min:
            self._confirm(tid, t, "m_of_n", confirmed)
        return TrackEvent(t, "born", tid, "unassociated detection")


def _might_continue(cont: Continuation) -> str:
    """``"; might continue A (p 0.49), B (p 0.48)"`` for a confirmation's reason, or ``""``
    when no old track is a candidate."""
    if not cont.candidates:
        return ""
    listed = ", ".join(f"{oid} (p {p:.2f})" for oid, p in cont.candidates)
    return f"; might continue {listed}"
