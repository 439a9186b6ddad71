"""Existence probability of a track and the chance that it lies inside a footprint.

**Probability inside the footprint.** A track's position is ``N(m, P)`` (2x2). With the
eigen-decomposition ``P = s1^2 e1 e1' + s2^2 e2 e2'`` and ``d = c - m`` (``c`` the disc's
centre, ``R`` its radius) in the principal axes, ``d1 = d.e1``, ``d2 = d.e2``: along ``e1`` at
``u`` the disc's chord in ``e2`` spans ``d2 +- h(u)``, ``h(u) = sqrt(R^2 - (u - d1)^2)``, so::

    Pin = int phi(u / s1) / s1 [Phi((d2 + h(u)) / s2) - Phi((d2 - h(u)) / s2)] du

over ``u`` in ``[d1 - R, d1 + R]`` intersected with ``[-8 s1, 8 s1]``. The substitution
``u = d1 - R cos(a)`` (``h = R sin(a)``, ``du = R sin(a) da``) removes the square-root ends,
and a 24-point Gauss-Legendre rule in ``a`` over the interval is exact to ~1e-6 for a point
track and a flat one alike (tests/test_tracker_existence.py checks it against Monte Carlo).
All tracks of a scan at once (numpy, no Python loop per track).

**Existence** ``r`` (probability that the track is a real iceberg). Per frame whose footprint
may hold the track, with ``pD = min(pd, pd_evidence_max)`` and the clutter-or-new density
``lambda`` (per m^2):

* miss: ``r' = r (1 - pD Pin) / (1 - r pD Pin)`` (absence of evidence in view);
* hit by detection ``z`` with likelihood ``N = N(z; C x^-, S)``::

      r' = (r pD N + r (1 - pD Pin) lambda) / (r pD N + (1 - r pD Pin) lambda)

  (the posterior of existence given that ``z`` is either the track's or clutter);
* JPDA: the marginal over the joint hypotheses (``observer.association``).

``r`` is then capped at ``existence_max``.
"""

from __future__ import annotations

import numpy as np

_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(24)
_SPAN_SIGMAS = 8.0
_TINY = 1e-12


def inside_probability(
    means: np.ndarray, covs: np.ndarray, centre_xy: tuple[float, float], radius_m: float
) -> np.ndarray:
    """``P(|p - c| <= R)`` for ``p ~ N(means[k], covs[k])`` (n x 2, n x 2 x 2) -> (n,)."""
    m = np.asarray(means, dtype=float).reshape(-1, 2)
    p = np.asarray(covs, dtype=float).reshape(-1, 2, 2)
    n = m.shape[0]
    if n == 0:
        return np.zeros(0)
    # shortcut: a track more than 8 sigma (largest axis) inside or outside the circle
    dist = np.hypot(m[:, 0] - centre_xy[0], m[:, 1] - centre_xy[1])
    sig = np.sqrt(np.maximum(p[:, 0, 0] + p[:, 1, 1], 0.0))  # >= largest axis sigma
    margin = _SPAN_SIGMAS * sig
    out = np.where(dist + margin <= radius_m, 1.0, 0.0)
    near = np.flatnonzero(np.abs(dist - radius_m) < margin)
    if near.size:
        out[near] = _quadrature(m[near], p[near], centre_xy, radius_m)
    return out


def _quadrature(
    m: np.ndarray, p: np.ndarray, centre_xy: tuple[float, float], radius_m: float
) -> np.ndarray:
    """The Gauss-Legendre evaluation of the integral in the module docstring."""
    return _disc_integrals(m, p, centre_xy, radius_m, moments=False)[0]


def _disc_integrals(
    m: np.ndarray,
    p: np.ndarray,
    centre_xy: tuple[float, float],
    radius_m: float,
    *,
    moments: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(M0, M1, M2)``: ``M0 = P(in disc)``; with ``moments``, ``M1 = E[y 1_D]`` (n x 2)
    and ``M2 = E[y y' 1_D]`` (n x 2 x 2) of ``y = p - m``, from the same quadrature (the
    chord integrals of the truncated normal along ``e2`` are closed-form)."""
    from scipy.special import ndtr  # scipy only once a scan needs it

    a, b, c = p[:, 0, 0], 0.5 * (p[:, 0, 1] + p[:, 1, 0]), p[:, 1, 1]
    half_tr, half_diff = 0.5 * (a + c), 0.5 * (a - c)
    root = np.hypot(half_diff, b)
    s1 = np.sqrt(np.maximum(half_tr + root, _TINY))
    s2 = np.sqrt(np.maximum(half_tr - root, _TINY))
    theta = 0.5 * np.arctan2(2.0 * b, a - c)
    e1 = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    e2 = np.stack([-e1[:, 1], e1[:, 0]], axis=1)
    d = np.array(centre_xy, dtype=float) - m
    d1 = np.einsum("ij,ij->i", d, e1)
    d2 = np.einsum("ij,ij->i", d, e2)
    r = float(radius_m)
    lo = np.maximum(d1 - r, -_SPAN_SIGMAS * s1)
    hi = np.minimum(d1 + r, _SPAN_SIGMAS * s1)
    ok = hi > lo
    # a = arccos((d1 - u) / R): u = lo -> a_lo, u = hi -> a_hi (a increases with u)
    a_lo = np.arccos(np.clip((d1 - lo) / r, -1.0, 1.0))
    a_hi = np.arccos(np.clip((d1 - hi) / r, -1.0, 1.0))
    half = 0.5 * (a_hi - a_lo)
    ang = (0.5 * (a_hi + a_lo))[:, None] + half[:, None] * _NODES[None, :]
    u = d1[:, None] - r * np.cos(ang)
    h = r * np.sin(ang)
    gauss = np.exp(-0.5 * (u / s1[:, None]) ** 2) / (np.sqrt(2.0 * np.pi) * s1[:, None])
    lo_v = (d2[:, None] - h) / s2[:, None]
    hi_v = (d2[:, None] + h) / s2[:, None]
    i0 = ndtr(hi_v) - ndtr(lo_v)
    w = gauss * r * np.sin(ang) * (half[:, None] * _WEIGHTS[None, :])
    w = np.where(ok[:, None], w, 0.0)
    m0 = np.clip(np.einsum("ij,ij->i", w, i0), 0.0, 1.0)
    if not moments:
        return m0, np.zeros((0, 2)), np.zeros((0, 2, 2))
    phi_lo = np.exp(-0.5 * lo_v**2) / np.sqrt(2.0 * np.pi)
    phi_hi = np.exp(-0.5 * hi_v**2) / np.sqrt(2.0 * np.pi)
    sv = s2[:, None]
    i1 = sv * (phi_lo - phi_hi)  # int v phi
    i2 = sv * sv * (i0 + lo_v * phi_lo - hi_v * phi_hi)  # int v^2 phi
    mu = np.einsum("ij,ij->i", w, u * i0)
    mv = np.einsum("ij,ij->i", w, i1)
    muu = np.einsum("ij,ij->i", w, u * u * i0)
    muv = np.einsum("ij,ij->i", w, u * i1)
    mvv = np.einsum("ij,ij->i", w, i2)
    rot = np.stack([e1, e2], axis=2)  # columns e1, e2: y = rot @ (u, v)
    m1 = np.einsum("nij,nj->ni", rot, np.stack([mu, mv], axis=1))
    m2p = np.stack([np.stack([muu, muv], axis=1), np.stack([muv, mvv], axis=1)], axis=1)
    m2 = rot @ m2p @ np.transpose(rot, (0, 2, 1))
    return m0, m1, m2


def position_after_miss(
    means: np.ndarray, covs: np.ndarray, centre_xy: tuple[float, float], radius_m: float,
    pd: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Negative information: the position density after a frame that did not see the
    track, ``N(y; m, P) (1 - pd 1_D(y)) / (1 - pd M0)``, moment-matched to a Gaussian::

        m' = m - pd M1 / Z,   P' = (P - pd M2) / Z - (m' - m)(m' - m)',   Z = 1 - pd M0

    Returns ``(changed mask, m', P')`` for the tracks that change (``1e-4 < M0`` and not
    deep inside the disc, where the cut is symmetric and nothing moves); the next frame's
    ``Pin`` is then computed from what is left, so overlapping frames of one pass are not
    counted as independent looks at the same water."""
    m = np.asarray(means, dtype=float).reshape(-1, 2)
    p = np.asarray(covs, dtype=float).reshape(-1, 2, 2)
    dist = np.hypot(m[:, 0] - centre_xy[0], m[:, 1] - centre_xy[1])
    margin = _SPAN_SIGMAS * np.sqrt(np.maximum(p[:, 0, 0] + p[:, 1, 1], 0.0))
    near = np.flatnonzero(np.abs(dist - radius_m) < margin)
    mask = np.zeros(m.shape[0], dtype=bool)
    if near.size == 0:
        return mask, m[:0], p[:0]
    m0, m1, m2 = _disc_integrals(m[near], p[near], centre_xy, radius_m, moments=True)
    z = 1.0 - pd * m0
    delta = -pd * m1 / z[:, None]
    new_p = (p[near] - pd * m2) / z[:, None, None] - delta[:, :, None] * delta[:, None, :]
    det = new_p[:, 0, 0] * new_p[:, 1, 1] - new_p[:, 0, 1] * new_p[:, 1, 0]
    good = (m0 > 1e-4) & (new_p[:, 0, 0] > 0.0) & (new_p[:, 1, 1] > 0.0) & (det > 0.0)
    mask[near[good]] = True
    return mask, m[near[good]] + delta[good], 0.5 * (new_p[good] + new_p[good].transpose(0, 2, 1))


def existence_after_miss(r: np.ndarray, pd: float, p_in: np.ndarray) -> np.ndarray:
    """``r (1 - pd Pin) / (1 - r pd Pin)``."""
    e = pd * p_in
    return r * (1.0 - e) / (1.0 - r * e)


def existence_after_hit(r: float, pd: float, p_in: float, lik: float, lam: float) -> float:
    """``(r pd N + r (1 - pd Pin) lam) / (r pd N + (1 - r pd Pin) lam)``."""
    g = r * pd * lik
    return (g + r * (1.0 - pd * p_in) * lam) / (g + (1.0 - r * pd * p_in) * lam)
