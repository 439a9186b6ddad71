"""Data association of one scan: gating, global nearest neighbour (GNN) and JPDA.

Notation (one scan; tracks ``j`` predicted to the scan time, detections ``i``)::

    nu_ij = z_i - C x_j^-,        S_ij = P_j^-[:2,:2] + r_i I
    d2_ij = nu_ij' S_ij^-1 nu_ij  (gated when d2_ij <= gamma = -2 ln(1 - P_G))
    N_ij  = exp(-d2_ij / 2) / sqrt(det(2 pi S_ij))

A joint hypothesis ``theta`` (each detection to at most one track, each track at most one
detection) has the likelihood, with existence ``r_j``, ``pD`` (the evidence pd), ``Pin_j`` the
probability that track ``j`` lies in the footprint, and ``lambda`` the density (per m^2) of
detections that no track explains (clutter or new icebergs)::

    L(theta) = prod_{(i,j) in theta} r_j pD N_ij * prod_{j free} (1 - r_j pD Pin_j)
               * prod_{i free} lambda

Divided by the constant ``prod_j (1 - r_j pD Pin_j) prod_i lambda`` each pair contributes the
ratio ``a_ij = r_j pD N_ij / ((1 - r_j pD Pin_j) lambda)``.

**GNN** maximises ``L``: ``scipy.optimize.linear_sum_assignment`` on the n x (m + n) matrix

    cost_ij     = d2_ij + ln det(2 pi S_ij) - 2 ln(r_j pD) + 2 ln(1 - r_j pD Pin_j)
                  (gated pairs; others forbidden)
    cost_i,m+i  = -2 ln lambda            (detection i left to "clutter or new")

(twice the negative log likelihood; subtracting the constant ``-2 ln lambda`` from row i gives
``-2 ln a_ij`` against 0 for the dummy, which is what is solved).

**JPDA** marginalises over every joint hypothesis of a cluster (tracks and detections linked
by gated pairs), enumerated exactly: ``beta_ij = sum_{theta ni (i,j)} w(theta)``,
``w = prod a_ij / sum``. Existence after the scan (JIPDA)::

    r_j' = sum_i beta_ij + beta_0j r_j (1 - pD Pin_j) / (1 - r_j pD Pin_j)

and the state update uses the association probabilities given existence,
``beta_ij / r_j'``. A cluster with more hypotheses than ``max_hypotheses`` is solved track
by track (each track's own gated detections, ignoring the others: PDA).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

_FORBIDDEN = 1e18


@dataclass(frozen=True)
class ScanLikelihoods:
    """Gating and log likelihoods of a scan (n detections x m tracks).

    ``log_ratio[i, j] = ln a_ij`` (``-inf`` where not gated); ``log_lik[i, j] = ln N_ij``.
    """

    gated: np.ndarray
    log_ratio: np.ndarray
    log_lik: np.ndarray


def scan_likelihoods(
    z: np.ndarray,
    r_m2: np.ndarray,
    means: np.ndarray,
    covs: np.ndarray,
    existence: np.ndarray,
    miss: np.ndarray,
    pd: float,
    log_lambda: float,
    gate: float,
) -> ScanLikelihoods:
    """``z`` (n x 2), ``r_m2`` (n), ``means`` (m x 2), ``covs`` (m x 2 x 2), ``existence``
    (m), ``miss = 1 - r pD Pin`` (m). Vectorised over all pairs."""
    nu = z[:, None, :] - means[None, :, :]
    s00 = covs[None, :, 0, 0] + r_m2[:, None]
    s11 = covs[None, :, 1, 1] + r_m2[:, None]
    s01 = 0.5 * (covs[None, :, 0, 1] + covs[None, :, 1, 0]) + 0.0 * r_m2[:, None]
    det = s00 * s11 - s01 * s01
    d2 = (s11 * nu[..., 0] ** 2 - 2.0 * s01 * nu[..., 0] * nu[..., 1] + s00 * nu[..., 1] ** 2) / det
    gated = d2 <= gate
    log_lik = -0.5 * d2 - 0.5 * np.log((2.0 * math.pi) ** 2 * det)
    with np.errstate(divide="ignore"):
        log_prior = np.log(existence * pd) - np.log(miss)
    log_ratio = np.where(gated, log_lik + log_prior[None, :] - log_lambda, -np.inf)
    return ScanLikelihoods(gated, log_ratio, log_lik)


def gnn_assign(log_ratio: np.ndarray) -> dict[int, int]:
    """Likeliest joint assignment: detection index -> track index (pairs with
    ``a_ij > 1`` against the detection's own "clutter or new" column).

    The cost matrix is ``-2 ln a_ij`` for gated pairs, 0 for each detection's own dummy
    column (``-2 ln lambda`` minus the constant), forbidden elsewhere."""
    from scipy.optimize import linear_sum_assignment  # scipy only once a scan needs it

    n, m = log_ratio.shape
    if n == 0 or m == 0:
        return {}
    cost = np.full((n, m + n), _FORBIDDEN)
    finite = np.isfinite(log_ratio)
    cost[:, :m] = np.where(finite, -2.0 * np.where(finite, log_ratio, 0.0), _FORBIDDEN)
    cost[np.arange(n), m + np.arange(n)] = 0.0
    rows, cols = linear_sum_assignment(cost)
    return {int(i): int(j) for i, j in zip(rows, cols, strict=True) if j < m and finite[i, j]}


def clusters(gated: np.ndarray) -> list[tuple[list[int], list[int]]]:
    """Connected components of the gated pairs: ``(detection indices, track indices)``;
    tracks with no gated detection are left out."""
    n, m = gated.shape
    parent = list(range(n + m))

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    pairs = np.argwhere(gated)
    for i, j in pairs.tolist():
        ra, rb = find(i), find(n + j)
        if ra != rb:
            parent[ra] = rb
    groups: dict[int, tuple[list[int], list[int]]] = {}
    for i, j in pairs.tolist():
        root = find(i)
        dets, trks = groups.setdefault(root, ([], []))
        if i not in dets:
            dets.append(i)
        if j not in trks:
            trks.append(j)
    return [(sorted(d), sorted(t)) for d, t in groups.values()]


def _count_hypotheses(options: list[list[int]], limit: int) -> int:
    """Upper bound on the joint hypotheses (product of per-track choices), stops at limit."""
    total = 1
    for opts in options:
        total *= len(opts) + 1
        if total > limit:
            return total
    return total


def _enumerate(
    options: list[list[int]], columns: list[np.ndarray]
) -> list[tuple[float, tuple[int, ...]]]:
    """Every joint hypothesis of a cluster: ``(sum of ln a_ij, detection per track or -1)``,
    depth-first over the tracks (``options[k]``: track k's gated detections,
    ``columns[k][i] = ln a_ik``)."""
    hyps: list[tuple[float, tuple[int, ...]]] = []
    choice = [-1] * len(options)

    def walk(k: int, used: frozenset[int], logw: float) -> None:
        if k == len(options):
            hyps.append((logw, tuple(choice)))
            return
        choice[k] = -1
        walk(k + 1, used, logw)
        for i in options[k]:
            if i not in used:
                choice[k] = i
                walk(k + 1, used | {i}, logw + float(columns[k][i]))
        choice[k] = -1

    walk(0, frozenset(), 0.0)
    return hyps


def jpda_marginals(log_ratio: np.ndarray, max_hypotheses: int) -> np.ndarray:
    """``beta`` (n x m): marginal probability that detection i is track j's, over the exact
    joint hypotheses of every cluster (``1 - sum_i beta_ij`` is track j's "none").

    Enumeration: depth-first over the cluster's tracks, each taking no detection or one
    gated detection not yet taken; weights ``exp(sum ln a_ij - max)``. Clusters above
    ``max_hypotheses`` use per-track PDA (``beta_ij = a_ij / (1 + sum_k a_kj)``)."""
    n, m = log_ratio.shape
    beta = np.zeros((n, m))
    if n == 0 or m == 0:
        return beta
    gated = np.isfinite(log_ratio)
    for dets, trks in clusters(gated):
        options = [[i for i in dets if gated[i, j]] for j in trks]
        if _count_hypotheses(options, max_hypotheses) > max_hypotheses:
            for j, opts in zip(trks, options, strict=True):
                lr = log_ratio[opts, j]
                top = max(0.0, float(lr.max()))
                w = np.exp(lr - top)
                beta[opts, j] = w / (math.exp(-top) + w.sum())
            continue
        hyps = _enumerate(options, [log_ratio[:, j] for j in trks])
        logs = np.array([h[0] for h in hyps])
        w = np.exp(logs - logs.max())
        w /= w.sum()
        for weight, (_, picks) in zip(w.tolist(), hyps, strict=True):
            for k, i in enumerate(picks):
                if i >= 0:
                    beta[i, trks[k]] += weight
    return beta
