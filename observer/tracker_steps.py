"""Two steps of :class:`observer.Tracker` kept apart to keep the tracker readable: the JPDA
update of one scan (:func:`jpda_step`) and the track-coalescence test (:func:`stale_twin`).
Equations: observer.association, observer.existence and docs/tracker.md."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from observer.association import jpda_marginals
from observer.existence import existence_after_miss
from observer.observer import Observer

#: Track coalescence needs the likeliest gating track this many times likelier than the
#: runner-up. 1: the likeliest wins. Measured on a 3-UAV random-flight proxy of `discovery`
#: (4 seeds, q = 0.1): 59 changes of a true iceberg's track id at 1, 65 at 3, 88 at 20 (an
#: ambiguous case left unmerged leaves a duplicate that is later merged or deleted anyway).
MERGE_ODDS = 1.0


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
        old = observer.track(oid)
        a = old.cov_xy[0] + new.cov_xy[0]
        b = old.cov_xy[1] + new.cov_xy[1]
        c = old.cov_xy[2] + new.cov_xy[2]
        det = a * c - b * b
        dx, dy = new.x_m - old.x_m, new.y_m - old.y_m
        d2 = (c * dx * dx - 2.0 * b * dx * dy + a * dy * dy) / det
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
