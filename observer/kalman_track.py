"""Constant-velocity Kalman track: the paper's eq. (3)-(11), filterpy's arithmetic in numpy.

State ``x = [x, y, vx, vy]`` (m, m/s). Over a step ``dT``::

    x_{k+1} = A x_k + w_k,   A = [[I, dT I], [0, I]],   w_k ~ N(0, Q(dT))      (3)
    z_k     = C x_k + v_k,   C = [I 0],                 v_k ~ N(0, R), R = r I  (4)
    Q(dT)   = diag(0, 0, q, q) dT     (q: intensity, m^2/s^3; the paper: 0.01 per 0.1 s)
    P_0     = Q(max_step_s) unless given                                        (6)

Prediction (every step) and correction (only when a UAV sees the target)::

    x^- = A x,           P^- = A P A' + Q                                       (7)-(8)
    S   = C P^- C' + R,  K = P^- C' S^-1                                        (9)
    x   = x^- + K (z - C x^-)                                                   (10)
    P   = (I - K C) P^- (I - K C)' + K R K'    (Joseph form of P = (I - K C) P^-) (11)

Uncertainty ``sigma = trace(P[:2, :2])`` (m^2).

**Time grid.** Predictions are committed only on the absolute grid ``t = k h`` (h =
``max_step_s``) or at the time of an accepted measurement; the estimate at any other time is
a non-committed prediction from the last committed point. So the result never depends on
how often (or how irregularly) ``predict_to`` is called, and the daemon's irregular ticks
and the simulator's fixed 0.1 s steps give the same tracks. ``n`` grid steps are done in one
exact closed form: ``A(h)^n = A(n h)`` and, per axis,

    sum_{j<n} A(h)^j Q(h) A(h)^j' = q h [[h^2 n(n-1)(2n-1)/6, h n(n-1)/2],
                                         [h n(n-1)/2,         n         ]],

so a long gap costs O(1).

**Batched prediction** (:class:`KalmanBatch`, the hot path of the observer). Written out in
2x2 blocks (``P = [[A, B], [C, D]]``: position, velocity), one step of eq. (8) is::

    P^- = [[A + h (B + C) + h^2 D,  B + h D],
           [C + h D,                D      ]] + Q(h)

but it is evaluated as the matrix products filterpy's ``predict`` makes,
``x^- = F x`` and ``P^- = (F P) F' + Q``, over the stack of every track that advances one
whole grid step (one ``numpy.matmul`` each for all tracks). The scalar closed form above is
exact maths but not the same floating point: numpy hands these 4x4 products to BLAS, whose
kernels accumulate ``P02 + h P22`` as one fused multiply-add (OpenBLAS on x86-64 with FMA),
which Python 3.11's float arithmetic cannot reproduce, so the closed form differs from
filterpy's result in the last bit and a replayed journal would not be bit-for-bit the same.
The batched products are the same BLAS products, matrix by matrix, so the results equal
filterpy's per-track ``predict`` bit for bit (here: benchmarks/startup_bench.py counts it
over random cases, and paper-boat journals are unchanged; tests/test_observer_batch.py
holds them to 1e-9 relative, which holds whatever BLAS numpy uses).

**No filterpy at run time.** The filter (:class:`CvFilter`) is the few lines of filterpy
2.0's ``KalmanFilter.predict`` and ``update`` that floe used, written with the very numpy
calls filterpy makes, in the same order (``numpy.dot``, ``numpy.linalg.inv``, the Joseph
form as ``dot(dot(I - K H, P), (I - K H)') + dot(dot(K, R), K')``), so the numbers are the
same bit for bit on any BLAS (tests/test_observer_batch.py compares them with filterpy's
over random cases with ``array_equal``). Importing filterpy's ``KalmanFilter`` costs ~1 s of
CPU, nearly all of it ``scipy.stats`` (through ``filterpy.stats``, which the filter needs
only for likelihoods floe never reads); that was more than a whole 200 s ``gcs simulate``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

_TINY_S = 1e-12
_GRID_EPS = 1e-9  # in grid steps

#: Measurement matrix C = [I 0].
C = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
C_T = C.T


_I4 = np.eye(4)
_I2 = np.eye(2)  # r I as r * _I2: the same numbers as r * numpy.eye(2), without a new eye


def grid_steps(anchor_s: float, t_s: float, h: float) -> tuple[int, int, float]:
    """``(k_first, k_last, first_dt)``: the grid points k h to commit on the way from the
    committed time ``anchor_s`` to ``t_s`` (none if ``k_last < k_first``), with
    k_last = floor(t_s / h + eps) and k_first = floor(anchor_s / h + eps) + 1, and the
    length of the first step, k_first h - anchor_s."""
    k_first = math.floor(anchor_s / h + _GRID_EPS) + 1
    return k_first, math.floor(t_s / h + _GRID_EPS), k_first * h - anchor_s


class CvFilter:
    """The state ``x`` (4x1), covariance ``P`` (4x4) and last gain ``K`` (4x2) of one track,
    with filterpy 2.0's ``KalmanFilter`` arithmetic (``dim_x=4``, ``dim_z=2``, no control
    input, ``alpha = 1``):

        predict:  x = dot(F, x);  P = dot(dot(F, P), F') + Q                     (7)-(8)
        update:   y = z - dot(C, x);  PC' = dot(P, C');  S = dot(C, PC') + R;
                  K = dot(PC', inv(S));  x = x + dot(K, y);
                  P = dot(dot(I - dot(K, C), P), (I - dot(K, C))') + dot(dot(K, R), K')  (9)-(11)

    filterpy's factor ``alpha^2 = 1.0`` multiplies exactly, so leaving it out changes no bit.
    """

    __slots__ = ("K", "P", "x")

    def __init__(self, x: np.ndarray, p: np.ndarray) -> None:
        self.x = x
        self.P = p
        self.K = np.zeros((4, 2))

    def predict(self, F: np.ndarray, Q: np.ndarray) -> None:
        """``x = F x``, ``P = F P F' + Q``."""
        self.x = np.dot(F, self.x)
        self.P = np.dot(np.dot(F, self.P), F.T) + Q

    def update(self, z: np.ndarray, R: np.ndarray) -> None:
        """The correction with measurement ``z`` (2 values) and its covariance ``R`` (2x2)."""
        y = np.asarray(z, dtype=float).reshape(2, 1) - np.dot(C, self.x)
        pht = np.dot(self.P, C_T)
        s = np.dot(C, pht) + R
        self.K = k = np.dot(pht, np.linalg.inv(s))
        self.x = self.x + np.dot(k, y)
        i_kh = _I4 - np.dot(k, C)
        self.P = np.dot(np.dot(i_kh, self.P), i_kh.T) + np.dot(np.dot(k, R), k.T)


def transition(dt_s: float) -> np.ndarray:
    """``A(dT) = [[I, dT I], [0, I]]``."""
    a = np.eye(4)
    a[0, 2] = dt_s
    a[1, 3] = dt_s
    return a


def process_noise(q_per_s: float, dt_s: float, n_steps: int = 1) -> np.ndarray:
    """Process noise accumulated over ``n_steps`` steps of ``dt_s`` (closed form above)."""
    n = n_steps
    s1 = n * (n - 1) / 2.0
    s2 = (n - 1) * n * (2 * n - 1) / 6.0
    qh = q_per_s * dt_s
    q = np.zeros((4, 4))
    for pos, vel in ((0, 2), (1, 3)):
        q[pos, pos] = qh * dt_s * dt_s * s2
        q[pos, vel] = q[vel, pos] = qh * dt_s * s1
        q[vel, vel] = qh * n
    return q


class KalmanTrack:
    """One target's Kalman filter plus its committed/viewed time bookkeeping."""

    def __init__(
        self,
        t_s: float,
        state: Sequence[float],
        p0_diag: Sequence[float],
        q_per_s: float,
        grid_step_s: float,
    ) -> None:
        self.kf = CvFilter(np.asarray(state, dtype=float).reshape(4, 1),
                           np.diag(np.asarray(p0_diag, dtype=float)))
        self.q_per_s = q_per_s
        self.grid_step_s = grid_step_s
        self.t_anchor_s = t_s  # time of the committed state kf.x, kf.P
        self.t_s = t_s  # time of the viewed estimate
        self.x_view: np.ndarray = self.kf.x
        self.p_view: np.ndarray = self.kf.P
        #: ``trace(P[:2, :2])`` of the viewed estimate (m^2), kept with ``p_view``.
        self.sigma = float(self.p_view[0, 0] + self.p_view[1, 1])
        self.last_seen_s: float | None = None
        self._full_step = (transition(grid_step_s), process_noise(q_per_s, grid_step_s))

    # --- prediction -----------------------------------------------------------------------
    def predict_to(self, t_s: float) -> None:
        """Advance the estimate to ``t_s`` (no-op if ``t_s <= self.t_s``)."""
        if t_s <= self.t_s:
            return
        self._commit_grid_until(t_s)
        self.t_s = t_s
        self._refresh_view()

    def _grid_steps(self, t_s: float) -> tuple[int, int, float]:
        """:func:`grid_steps` from this track's committed time."""
        return grid_steps(self.t_anchor_s, t_s, self.grid_step_s)

    def _commit_grid_until(self, t_s: float) -> None:
        h = self.grid_step_s
        k_first, k_last, first_dt = self._grid_steps(t_s)
        if k_last < k_first:
            return
        if abs(first_dt - h) <= _TINY_S:  # the common case: one whole grid step
            self.kf.predict(F=self._full_step[0], Q=self._full_step[1])
        elif first_dt > _TINY_S:
            self.kf.predict(F=transition(first_dt), Q=process_noise(self.q_per_s, first_dt))
        n = k_last - k_first
        if n > 0:
            self.kf.predict(F=transition(n * h), Q=process_noise(self.q_per_s, h, n))
        self.t_anchor_s = k_last * h

    def _refresh_view(self) -> None:
        dt = self.t_s - self.t_anchor_s
        if dt > _TINY_S:
            a = transition(dt)
            self.x_view = a @ self.kf.x
            self.p_view = a @ self.kf.P @ a.T + process_noise(self.q_per_s, dt)
        else:  # shared, not copied: no array here is ever changed in place
            self.x_view = self.kf.x
            self.p_view = self.kf.P
        self.sigma = float(self.p_view[0, 0] + self.p_view[1, 1])

    def set_process_noise(self, q_per_s: float) -> None:
        """New intensity, applied from the last committed time on."""
        self.q_per_s = q_per_s
        self._full_step = (transition(self.grid_step_s), process_noise(q_per_s, self.grid_step_s))
        self._refresh_view()

    # --- correction -----------------------------------------------------------------------
    def innovation(self, x_m: float, y_m: float, r_m2: float) -> float:
        """Squared Mahalanobis distance ``y' S^-1 y`` of ``z`` against the current estimate."""
        y = np.array([x_m, y_m]) - (C @ self.x_view).ravel()
        s = C @ self.p_view @ C_T + r_m2 * _I2
        return float(y @ np.linalg.solve(s, y))

    def correct(self, t_s: float, x_m: float, y_m: float, r_m2: float) -> None:
        """Commit the prediction at ``t_s`` (== self.t_s) and apply eq. (9)-(11)."""
        self.kf.x = self.x_view  # not copied: update replaces them, changes none in place
        self.kf.P = self.p_view
        self.t_anchor_s = t_s
        self.kf.update(np.array([x_m, y_m]), R=r_m2 * _I2)
        self.kf.P = 0.5 * (self.kf.P + self.kf.P.T)
        self.x_view = self.kf.x
        self.p_view = self.kf.P
        self.sigma = float(self.p_view[0, 0] + self.p_view[1, 1])
        self.last_seen_s = t_s

    def correct_pda(
        self, t_s: float, zs: np.ndarray, betas: np.ndarray, r_m2: float
    ) -> None:
        """Probabilistic data association update at ``t_s`` (== self.t_s).

        ``zs`` (k x 2) are the candidate measurements, ``betas`` (k) their association
        probabilities, ``beta0 = 1 - sum(betas)`` the probability that none is the target's.
        With ``nu_i = z_i - C x^-`` and the combined innovation ``nu = sum_i beta_i nu_i``::

            x   = x^- + K nu                         (filterpy's update with z = C x^- + nu)
            P   = beta0 P^- + (1 - beta0) P_c + K (sum_i beta_i nu_i nu_i' - nu nu') K'

        where ``K`` and ``P_c`` (Joseph form, eq. (11)) are those of the ordinary update.
        """
        self.kf.x = self.x_view.copy()
        self.kf.P = self.p_view.copy()
        self.t_anchor_s = t_s
        p_prior = self.kf.P
        hx = (C @ self.kf.x).ravel()
        nus = np.asarray(zs, dtype=float).reshape(-1, 2) - hx
        b = np.asarray(betas, dtype=float).ravel()
        beta0 = max(0.0, 1.0 - float(b.sum()))
        nu = b @ nus
        self.kf.update(hx + nu, R=r_m2 * np.eye(2))
        k = self.kf.K
        spread = (nus * b[:, None]).T @ nus - np.outer(nu, nu)
        p = beta0 * p_prior + (1.0 - beta0) * self.kf.P + k @ spread @ k.T
        self.kf.P = 0.5 * (p + p.T)
        self.x_view = self.kf.x
        self.p_view = self.kf.P
        self.sigma = float(self.p_view[0, 0] + self.p_view[1, 1])
        self.last_seen_s = t_s

    def set_position_moments(self, t_s: float, mean_xy: np.ndarray, cov_xy: np.ndarray) -> None:
        """Commit the estimate at ``t_s`` (== self.t_s) with new position moments
        ``(m', P'_pp)``, carried to the velocity through the joint Gaussian (what a linear
        update that moved the position marginal there would do)::

            G = P[:, :2] P_pp^-1,   x' = x + G (m' - m),   P' = P + G (P'_pp - P_pp) G'
        """
        x = self.x_view
        p = self.p_view
        g = p[:, :2] @ np.linalg.inv(p[:2, :2])
        dm = np.asarray(mean_xy, dtype=float).reshape(2, 1) - x[:2]
        dp = np.asarray(cov_xy, dtype=float).reshape(2, 2) - p[:2, :2]
        new_p = p + g @ dp @ g.T
        self.kf.x = x + g @ dm
        self.kf.P = 0.5 * (new_p + new_p.T)
        self.t_anchor_s = t_s
        self.x_view = self.kf.x
        self.p_view = self.kf.P
        self.sigma = float(self.p_view[0, 0] + self.p_view[1, 1])

    def rewind_to(self, t_s: float) -> bool:
        """Move the viewed estimate back to ``t_s`` if it is not before the committed time
        (the view is a pure function of the committed state, so nothing is lost); returns
        whether the track is now at ``t_s``."""
        if t_s == self.t_s:
            return True
        if t_s < self.t_anchor_s or t_s > self.t_s:
            return False
        self.t_s = t_s
        self._refresh_view()
        return True

    # --- read-out -------------------------------------------------------------------------
    @property
    def state(self) -> tuple[float, float, float, float]:
        x = self.x_view  # 4x1; item(k): element k as a Python float, exactly
        return x.item(0), x.item(1), x.item(2), x.item(3)

    @property
    def cov_xy(self) -> tuple[float, float, float]:
        p = self.p_view  # 4x4: flat 0, 1, 5 are (0, 0), (0, 1), (1, 1)
        return p.item(0), p.item(1), p.item(5)


class KalmanBatch:
    """Advances the tracks of one observer (grid step ``h``) together: those whose next
    commit is one whole grid step are predicted at once (``x^- = F x``,
    ``P^- = (F P) F' + Q`` over the stacked states, see the module docstring); any other
    track (a partial first step, a gap of several steps, no grid point passed) goes through
    :meth:`KalmanTrack.predict_to`. Every track shares the batch's grid step (the
    observer's ``max_step_s``).

    The stacks of one call are kept: when the next call advances the same tracks, its
    products start from them without re-stacking; the rows of tracks changed since (a
    correction, a new ``q``) are replaced in a copy. Tracks committed at the same time share
    the decision to batch them (computed once per distinct committed time).
    """

    def __init__(self, grid_step_s: float) -> None:
        self.grid_step_s = grid_step_s
        f = transition(grid_step_s)
        self._f, self._f_t = f, f.T.copy()
        self._tracks: list[KalmanTrack] = []
        # each track's kf.x, kf.P and Q as the last step left them (views of the stacks)
        self._x_rows: list[np.ndarray] = []
        self._p_rows: list[np.ndarray] = []
        self._q_rows: list[np.ndarray] = []
        self._x = np.empty((0, 4, 1))
        self._p = np.empty((0, 4, 4))
        self._q = np.empty((0, 4, 4))

    def predict_to(self, tracks: Sequence[KalmanTrack], t_s: float) -> None:
        """Advance every track of ``tracks`` (all on this batch's grid step) to ``t_s``
        (tracks at or past it are left). A track is batched when its next commit, as
        :meth:`KalmanTrack._grid_steps` decides it, is the last one and one whole step.
        Tracks committed at the same time (nearly always all of them) share that
        decision: it is computed once per distinct committed time, by the same
        arithmetic."""
        h = self.grid_step_s
        k_last = math.floor(t_s / h + _GRID_EPS)
        whole_step: dict[float, bool] = {}  # committed time -> its next commit is batched
        batch: list[KalmanTrack] = []
        for track in tracks:
            if t_s <= track.t_s:
                continue
            anchor = track.t_anchor_s
            batched = whole_step.get(anchor)
            if batched is None:
                k_first, _, first_dt = grid_steps(anchor, t_s, h)
                batched = whole_step[anchor] = (
                    k_first == k_last and abs(first_dt - h) <= _TINY_S)
            if batched:
                batch.append(track)
            else:
                track.predict_to(t_s)
        if batch:
            self._predict_one_step(batch, t_s, k_last * h)

    def _predict_one_step(self, batch: list[KalmanTrack], t_s: float, t_grid_s: float) -> None:
        self._restack(batch)
        self._x = xs = np.matmul(self._f, self._x)
        self._p = ps = np.matmul(np.matmul(self._f, self._p), self._f_t) + self._q
        x_rows, p_rows = list(xs), list(ps)  # each track's x (4x1) and P (4x4), views
        if t_s - t_grid_s <= _TINY_S:  # on the grid: the view is the committed state
            sigmas = (ps[:, 0, 0] + ps[:, 1, 1]).tolist()
            for tr, x, p, sigma in zip(batch, x_rows, p_rows, sigmas, strict=True):
                kf = tr.kf
                kf.x = tr.x_view = x
                kf.P = tr.p_view = p
                tr.t_anchor_s = t_grid_s
                tr.t_s = t_s
                tr.sigma = sigma
        else:  # each view is predicted on from the grid
            for tr, x, p in zip(batch, x_rows, p_rows, strict=True):
                kf = tr.kf
                kf.x = x
                kf.P = p
                tr.t_anchor_s = t_grid_s
                tr.t_s = t_s
                tr._refresh_view()
        self._tracks = batch
        self._x_rows, self._p_rows = x_rows, p_rows

    def _restack(self, batch: list[KalmanTrack]) -> None:
        """The stacks ``_x``, ``_p``, ``_q`` of ``batch``'s committed states and noises: kept
        when the last step advanced the same tracks, untouched since; when only some were
        changed since (a correction, a new ``q``), a copy with their rows replaced; else
        stacked anew. Every way holds the same numbers as ``numpy.stack`` of the tracks'."""
        last = self._tracks
        if len(batch) == len(last) and all(a is b for a, b in zip(batch, last, strict=True)):
            changed = [
                k for k, (tr, x, p, q) in enumerate(
                    zip(batch, self._x_rows, self._p_rows, self._q_rows, strict=True))
                if tr.kf.x is not x or tr.kf.P is not p or tr._full_step[1] is not q
            ]
            if not changed:
                return
            xs, ps, qs = self._x.copy(), self._p.copy(), self._q.copy()
            for k in changed:
                tr = batch[k]
                xs[k], ps[k], qs[k] = tr.kf.x, tr.kf.P, tr._full_step[1]
                self._q_rows[k] = tr._full_step[1]
            self._x, self._p, self._q = xs, ps, qs
            return
        self._x = np.stack([tr.kf.x for tr in batch])
        self._p = np.stack([tr.kf.P for tr in batch])
        self._q_rows = [tr._full_step[1] for tr in batch]
        self._q = np.stack(self._q_rows)
