"""Two steps of :class:`observer.Tracker` kept apart to keep the tracker readable: the JPDA
update of one scan (:func:`jpda_step`), the reacquisition gate (:func:`reacquisition_gate`),
track coalescence (:func:`stale_twin`: which old track's estimate a newly confirmable track
replaces) and the continuation test (:func:`continuation`: whether it is that old track's
iceberg, so takes its id).
Equations: observer.association, observer.existence and docs/tracker.md."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from observer.association import jpda_marginals
from observer.existence import existence_after_miss
from observer.observer import Observer
from observer.records import TrackSnapshot

#: Track coalescence needs the likeliest gating track this many times likelier than the
#: runner-up. 1: the likeliest wins. Measured on a 3-UAV random-flight proxy of `discovery`
#: (4 seeds, q = 0.1): 59 changes of a true iceberg's track id at 1, 65 at 3, 88 at 20 (an
#: ambiguous case left unmerged leaves a duplicate that is later merged or deleted anyway).
MERGE_ODDS = 1.0

#: Old tracks whose continuation probability is below this are not listed in a new track's
#: ``might_continue`` (they are counted in the denominator all the same).
CONTINUATION_LIST_MIN = 0.01


@dataclass(frozen=True)
class Continuation:
    """Which old track, if any, a newly confirmable track continues (:func:`continuation`).

    Attributes:
        take: the old track whose id the new track takes, or None (a new id).
        probability: ``P_j`` of ``take`` (0.0 when None).
        candidates: ``(old id, P_j)`` of every gated old track with ``P_j >=``
            :data:`CONTINUATION_LIST_MIN`, likeliest first (the new track's history).
        new_probability: ``P_new``, the probability that it is an iceberg no track had.
    """

    take: str | None
    probability: float
    candidates: tuple[tuple[str, float], ...]
    new_probability: float


def jpda_step(
    observer: Observer,
    t: float,
    ids: list[str],
    z: np.ndarray,
    r_m2: np.ndarray,
    log_ratio: np.ndarray,
    exist: np.ndarray,
    p_in: np.ndarray,
    pd: float,
    max_hypotheses: int,
    hit: np.ndarray,
    updated: np.ndarray,
    taken: np.ndarray,
) -> tuple[np.ndarray, dict[int, str]]:
    """JPDA/JIPDA update of one scan. Fills ``hit`` (``sum_i beta_ij >= 0.5``), ``updated``
    (any ``beta_ij > 0``: PDA-corrected), ``taken`` (``sum_j beta_ij >= 0.5``: the
    detection is the tracks', not a birth); returns the new existences
    ``r_j' = sum_i beta_ij + beta_0j q_j`` and ``{detection: track id}`` for
    ``beta_ij > 0.5``. The PDA update uses ``b_ij = beta_ij / r_j'`` (given existence) and
    the ``b``-weighted mean of the detections' ``r``."""
    beta = jpda_marginals(log_ratio, max_hypotheses)
    detected = beta.sum(axis=0)  # P(track j produced one of the detections)
    q_miss = existence_after_miss(exist, pd, p_in)
    new_exist = detected + (1.0 - detected) * q_miss
    for j, tid in enumerate(ids):
        rows = np.flatnonzero(beta[:, j] > 0.0)
        if rows.size == 0:
            continue
        updated[j] = True
        b = beta[rows, j] / new_exist[j]
        r_eff = float(b @ r_m2[rows] / b.sum())
        observer.correct_pda(tid, t, z[rows], np.minimum(b, 1.0) / max(1.0, float(b.sum())),
                             r_eff)
        hit[j] = detected[j] >= 0.5
    picks: dict[int, str] = {}
    best = beta.argmax(axis=1) if beta.shape[1] else np.zeros(0, dtype=int)
    for i in range(beta.shape[0]):
        if beta[i].sum() >= 0.5:
            taken[i] = True
        if beta[i, best[i]] > 0.5:
            picks[i] = ids[int(best[i])]
    return new_exist, picks


def reacquisition_gate(
    log_ratio: np.ndarray, stale: np.ndarray, min_probability: float
) -> np.ndarray:
    """``log_ratio`` with the pairs a stale track may not take forbidden (``-inf``).

    A stale track (``stale[j]``: not hit for longer than ``reacquire_after_s``, or never
    since it was adopted) takes a detection directly only when the detection is its
    iceberg's rather than another track's with probability ``>= min_probability``
    (``a_ij`` as in :mod:`observer.association`, the sum over every track that gates
    detection ``i``):

        Q_ij = a_ij / sum_k a_ik

    So a lone stale track found again takes the detection as any track does (whether it is
    a new iceberg instead is the association's own "clutter or new" cost), while two
    stale tracks near one detection (icebergs that may have passed each other unseen) take
    it only when one is clearly likelier. Otherwise the detection is left to the other
    tracks or starts a track, and at that track's confirmation :func:`continuation` decides
    with more evidence, "a new iceberg" included."""
    if not stale.any() or log_ratio.size == 0:
        return log_ratio
    finite = np.isfinite(log_ratio)
    top = np.where(finite, log_ratio, -np.inf).max(axis=1, initial=-np.inf)
    rows = np.isfinite(top)
    shifted = np.where(finite, log_ratio - np.where(rows, top, 0.0)[:, None], -np.inf)
    total = np.where(finite, np.exp(shifted), 0.0).sum(axis=1)
    log_q = shifted - np.log(np.where(rows, total, 1.0))[:, None]
    forbid = stale[None, :] & finite & (log_q < math.log(min_probability))
    return np.where(forbid, -np.inf, log_ratio)


def _pair_distance(new: TrackSnapshot, old: TrackSnapshot) -> tuple[float, float]:
    """Two tracks' positions against each other: ``S = P_old + P_new`` (position blocks,
    ``cov_xy = (a, b, c)``), ``d2 = dx' S^-1 dx`` with ``dx = x_new - x_old``, and
    ``det S``."""
    a = old.cov_xy[0] + new.cov_xy[0]
    b = old.cov_xy[1] + new.cov_xy[1]
    c = old.cov_xy[2] + new.cov_xy[2]
    det = a * c - b * b
    dx, dy = new.x_m - old.x_m, new.y_m - old.y_m
    return (c * dx * dx - 2.0 * b * dx * dy + a * dy * dy) / det, det


def stale_twin(
    observer: Observer,
    statuses: Mapping[str, str],
    tid: str,
    hit_ids: set[str],
    gate: float,
) -> str | None:
    """The confirmed or prior track whose iceberg the newly confirmable ``tid`` is, if any.

    Every confirmed or prior track (``statuses``; all in the observer) that gates ``tid``'s
    position, ``d2 = dx' (P_old + P_new)^-1 dx <= gate``, is a candidate with cost
    ``d2 + ln det(2 pi S)``. The likeliest is returned when it was not hit in this scan,
    is vaguer than ``tid`` (larger ``trace P``) and is at least :data:`MERGE_ODDS` times
    likelier than the runner-up; else None."""
    new = observer.track(tid)
    costs: list[tuple[float, str]] = []
    for oid, status in statuses.items():
        if oid == tid or status == "tentative":
            continue
        d2, det = _pair_distance(new, observer.track(oid))
        if d2 <= gate:
            costs.append((d2 + math.log((2.0 * math.pi) ** 2 * det), oid))
    if not costs:
        return None
    costs.sort()
    best_cost, best = costs[0]
    if best in hit_ids or observer.sigma(best) <= new.sigma:
        return None
    if len(costs) > 1 and costs[1][0] - best_cost < 2.0 * math.log(MERGE_ODDS):
        return None
    return best


def continuation(
    observer: Observer,
    lives: Mapping[str, tuple[str, float]],
    tid: str,
    hit_ids: set[str],
    gate: float,
    birth_density_m2: float,
    min_probability: float,
) -> Continuation:
    """Is the newly confirmable tentative ``tid`` an old track's iceberg found again?

    ``lives``: every track's ``(status, existence)``. The hypotheses for ``tid``'s iceberg:
    it is old track ``j`` (each confirmed or prior track not hit in this scan; all in the
    observer, predicted to the scan's time), or an iceberg no track had (birth density
    ``lambda_b``, per m^2). With ``dx = x_new - x_j``, ``S_j = P_j + P_new`` (positions) and
    ``r_j`` the old track's existence,

        g_j = r_j N(dx; 0, S_j)                      (0 outside the gate dx' S_j^-1 dx > gate)
        P_j = g_j / (lambda_b + sum_k g_k),          P_new = lambda_b / (lambda_b + sum_k g_k)

    so a nearby old track of another iceberg lowers every ``P_j`` (the ambiguity counts) and
    a vague old track (``det S`` large) loses to "new" by itself. The new track takes the id
    of the likeliest ``j`` only when ``P_j >= min_probability`` and ``j`` is vaguer than the
    new track (larger ``trace P``: a precise old track that did not take this detection is
    another iceberg); otherwise it keeps its own id and ``candidates`` says which old
    tracks it might continue."""
    new = observer.track(tid)
    liks: list[tuple[float, str]] = []
    for oid, (status, existence) in lives.items():
        if oid == tid or status == "tentative" or oid in hit_ids:
            continue
        d2, det = _pair_distance(new, observer.track(oid))
        if d2 <= gate:
            liks.append((existence * math.exp(-0.5 * d2) / (2.0 * math.pi * math.sqrt(det)),
                         oid))
    total = birth_density_m2 + sum(g for g, _ in liks)
    ranked = sorted(((g / total, oid) for g, oid in liks), key=lambda x: (-x[0], x[1]))
    candidates = tuple((oid, p) for p, oid in ranked if p >= CONTINUATION_LIST_MIN)
    take: str | None = None
    probability = 0.0
    if ranked:
        p_best, best = ranked[0]
        if p_best >= min_probability and observer.sigma(best) > new.sigma:
            take, probability = best, p_best
    return Continuation(take, probability, candidates, birth_density_m2 / total)
