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

**The stacks own the state** (issue 30). The tracks that stepped together last time are
the batch's *members*: their committed states are the rows of the batch's stacks, not
copied out, so a tick on the grid is one decision (:func:`grid_steps` from the members'
shared committed time), the three stacked products and ``sigma`` per row, with no Python
per track; a track points its fields at its row only when something reads it
(:meth:`KalmanTrack._fresh`). A track changed on its own (a correction, a rewind) leaves
the members and joins again at its next whole grid step, written into a free row of copies
of the stacks. tests/test_observer_batch_rows.py checks every track against the same
track advanced alone (the plain per-track path) with ``array_equal``, over random ticks,
detections, noise changes, rewinds, births and removals.

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
import operator
from collections.abc import Sequence

import numpy as np

_TINY_S = 1e-12
_GRID_EPS = 1e-9  # in grid steps

#: Measurement matrix C = [I 0].
C = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
C_T = C.T


_I4 = np.eye(4)
_I2 = np.eye(2)  # r I as r * _I2: the same numbers as r * numpy.eye(2), without a new eye


MemberReadout = tuple[tuple[float, float, float, float], float, tuple[float, float, float]]
"""A member's ``(state, sigma, cov_xy)`` (:meth:`KalmanBatch.read_members`)."""


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
    a = _I4.copy()
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
    """One target's Kalman filter plus its committed/viewed time bookkeeping.

    **A row of a batch.** While the track steps with its observer's :class:`KalmanBatch`
    (``_stack`` is that batch), its committed state is row ``_row`` of the batch's stacks
    and its times are the batch's: ``kf``, ``x_view``, ``p_view``, ``t_s``, ``t_anchor_s``
    and ``sigma`` are then read through :meth:`_fresh`, which points the fields at the row
    (views of the stacks, no arithmetic) when the batch has stepped since the last read.
    A change of the committed state or of the times by the track's own methods first takes
    the track out of the batch (:meth:`KalmanBatch.release`, the fields written back); it
    joins again at its next whole grid step. Nothing else writes ``kf.x`` or ``kf.P``.
    """

    def __init__(
        self,
        t_s: float,
        state: Sequence[float],
        p0_diag: Sequence[float],
        q_per_s: float,
        grid_step_s: float,
    ) -> None:
        self._kf = CvFilter(np.asarray(state, dtype=float).reshape(4, 1),
                            np.diag(np.asarray(p0_diag, dtype=float)))
        self.q_per_s = q_per_s
        self.grid_step_s = grid_step_s
        self._t_anchor_s = t_s  # time of the committed state kf.x, kf.P
        self._t_s = t_s  # time of the viewed estimate
        self._x_view: np.ndarray = self._kf.x
        self._p_view: np.ndarray = self._kf.P
        # trace(P[:2, :2]) of the viewed estimate (m^2), kept with p_view
        self._sigma = float(self._p_view[0, 0] + self._p_view[1, 1])
        self.last_seen_s: float | None = None
        self._full_step = (transition(grid_step_s), process_noise(q_per_s, grid_step_s))
        self._stack: KalmanBatch | None = None  # the batch whose stacks hold the state
        self._row = -1  # the row there
        self._epoch = -1  # the batch's step count when the fields were last pointed at it

    # --- fields (up to date also while the state is a row of a batch) --------------------
    def _fresh(self) -> None:
        """Point the fields at the batch's row if the batch stepped since (see the class)."""
        stack = self._stack
        if stack is not None and self._epoch != stack.epoch:
            stack.write_back(self)

    @property
    def kf(self) -> CvFilter:
        """The committed state ``kf.x`` (4x1) and ``kf.P`` (4x4), at ``t_anchor_s``."""
        self._fresh()
        return self._kf

    @property
    def t_anchor_s(self) -> float:
        """Time of the committed state (s)."""
        self._fresh()
        return self._t_anchor_s

    @property
    def t_s(self) -> float:
        """Time of the viewed estimate (s)."""
        self._fresh()
        return self._t_s

    @property
    def x_view(self) -> np.ndarray:
        """The state at ``t_s`` (4x1)."""
        self._fresh()
        return self._x_view

    @x_view.setter
    def x_view(self, value: np.ndarray) -> None:
        self._leave_stack()
        self._x_view = value

    @property
    def p_view(self) -> np.ndarray:
        """The covariance at ``t_s`` (4x4)."""
        self._fresh()
        return self._p_view

    @p_view.setter
    def p_view(self, value: np.ndarray) -> None:
        self._leave_stack()
        self._p_view = value

    @property
    def sigma(self) -> float:
        """``trace(P[:2, :2])`` of the viewed estimate (m^2)."""
        self._fresh()
        return self._sigma

    def _leave_stack(self) -> None:
        """Out of the batch, the fields written back (before any change of them)."""
        if self._stack is not None:
            self._stack.release(self)

    # --- prediction -----------------------------------------------------------------------
    def predict_to(self, t_s: float) -> None:
        """Advance the estimate to ``t_s`` (no-op if ``t_s <= self.t_s``)."""
        if t_s <= self.t_s:
            return
        self._leave_stack()
        self._commit_grid_until(t_s)
        self._t_s = t_s
        self._refresh_view()

    def _grid_steps(self, t_s: float) -> tuple[int, int, float]:
        """:func:`grid_steps` from this track's committed time."""
        return grid_steps(self.t_anchor_s, t_s, self.grid_step_s)

    def _commit_grid_until(self, t_s: float) -> None:
        h = self.grid_step_s
        k_first, k_last, first_dt = self._grid_steps(t_s)
        if k_last < k_first:
            return
        kf = self._kf
        if abs(first_dt - h) <= _TINY_S:  # the common case: one whole grid step
            kf.predict(F=self._full_step[0], Q=self._full_step[1])
        elif first_dt > _TINY_S:
            kf.predict(F=transition(first_dt), Q=process_noise(self.q_per_s, first_dt))
        n = k_last - k_first
        if n > 0:
            kf.predict(F=transition(n * h), Q=process_noise(self.q_per_s, h, n))
        self._t_anchor_s = k_last * h

    def _refresh_view(self) -> None:
        dt = self._t_s - self._t_anchor_s
        if dt <= _TINY_S:
            self._view_committed()
            return
        kf = self._kf
        a = transition(dt)
        self._x_view = a @ kf.x
        self._p_view = a @ kf.P @ a.T + process_noise(self.q_per_s, dt)
        self._sigma = float(self._p_view[0, 0] + self._p_view[1, 1])

    def _view_committed(self) -> None:
        """The view is the committed state ``kf.x``, ``kf.P`` (shared, not copied: no array
        here is ever changed in place), with its ``sigma``."""
        kf = self._kf
        self._x_view = kf.x
        self._p_view = kf.P
        self._sigma = float(kf.P[0, 0] + kf.P[1, 1])

    def set_process_noise(self, q_per_s: float) -> None:
        """New intensity, applied from the last committed time on (a track in a batch
        keeps its row: its view is its committed state, so only its row of ``Q`` changes)."""
        self.q_per_s = q_per_s
        self._full_step = (transition(self.grid_step_s), process_noise(q_per_s, self.grid_step_s))
        if self._stack is not None:
            self._stack.set_noise_row(self)
        else:
            self._refresh_view()

    # --- correction -----------------------------------------------------------------------
    def innovation(self, x_m: float, y_m: float, r_m2: float) -> float:
        """Squared Mahalanobis distance ``y' S^-1 y`` of ``z`` against the current estimate."""
        self._fresh()
        y = np.array([x_m, y_m]) - (C @ self._x_view).ravel()
        s = C @ self._p_view @ C_T + r_m2 * _I2
        return float(y @ np.linalg.solve(s, y))

    def correct(self, t_s: float, x_m: float, y_m: float, r_m2: float) -> None:
        """Commit the prediction at ``t_s`` (== self.t_s) and apply eq. (9)-(11)."""
        self._leave_stack()
        kf = self._kf
        kf.x = self._x_view  # not copied: update replaces them, changes none in place
        kf.P = self._p_view
        self._t_anchor_s = t_s
        kf.update(np.array([x_m, y_m]), R=r_m2 * _I2)
        kf.P = 0.5 * (kf.P + kf.P.T)
        self._view_committed()
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
        self._leave_stack()
        kf = self._kf
        kf.x = self._x_view.copy()
        kf.P = self._p_view.copy()
        self._t_anchor_s = t_s
        p_prior = kf.P
        hx = (C @ kf.x).ravel()
        nus = np.asarray(zs, dtype=float).reshape(-1, 2) - hx
        b = np.asarray(betas, dtype=float).ravel()
        beta0 = max(0.0, 1.0 - float(b.sum()))
        nu = b @ nus
        kf.update(hx + nu, R=r_m2 * np.eye(2))
        k = kf.K
        spread = (nus * b[:, None]).T @ nus - np.outer(nu, nu)
        p = beta0 * p_prior + (1.0 - beta0) * kf.P + k @ spread @ k.T
        kf.P = 0.5 * (p + p.T)
        self._view_committed()
        self.last_seen_s = t_s

    def set_position_moments(self, t_s: float, mean_xy: np.ndarray, cov_xy: np.ndarray) -> None:
        """Commit the estimate at ``t_s`` (== self.t_s) with new position moments
        ``(m', P'_pp)``, carried to the velocity through the joint Gaussian (what a linear
        update that moved the position marginal there would do)::

            G = P[:, :2] P_pp^-1,   x' = x + G (m' - m),   P' = P + G (P'_pp - P_pp) G'
        """
        self._leave_stack()
        x = self._x_view
        p = self._p_view
        g = p[:, :2] @ np.linalg.inv(p[:2, :2])
        dm = np.asarray(mean_xy, dtype=float).reshape(2, 1) - x[:2]
        dp = np.asarray(cov_xy, dtype=float).reshape(2, 2) - p[:2, :2]
        new_p = p + g @ dp @ g.T
        kf = self._kf
        kf.x = x + g @ dm
        kf.P = 0.5 * (new_p + new_p.T)
        self._t_anchor_s = t_s
        self._view_committed()

    def rewind_to(self, t_s: float) -> bool:
        """Move the viewed estimate back to ``t_s`` if it is not before the committed time
        (the view is a pure function of the committed state, so nothing is lost); returns
        whether the track is now at ``t_s``."""
        if t_s == self.t_s:
            return True
        if t_s < self._t_anchor_s or t_s > self._t_s:
            return False
        self._leave_stack()
        self._t_s = t_s
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
    """The Kalman tracks of one observer (grid step ``h``), advanced together.

    **Members.** The tracks that stepped together at the last whole grid step are the
    batch's members: their committed states are the rows of the stacks ``_x`` (n x 4 x 1),
    ``_p`` (n x 4 x 4) and ``_q`` (their ``Q(h)``), and they share one committed time
    ``t_anchor_s`` and one viewed time ``t_s``, within ``_TINY_S`` of each other, so that
    each view is its committed state. A step of the members is then three stacked products
    and no per-track Python: ``x^- = F x``, ``P^- = (F P) F' + Q`` (the module docstring)
    and ``sigma = P[0, 0] + P[1, 1]`` per row; a member reads its row only when asked
    (:meth:`KalmanTrack._fresh`). A track that changes on its own (a correction, a rewind,
    a prediction of its own) leaves the members (:meth:`release`); its row stays in the
    stacks, unread, until a joining track takes it.

    **Loose tracks** step as :meth:`KalmanTrack.predict_to` would, one by one, except that
    a loose track whose next commit is the last one and one whole grid step (the tracks'
    own rule, :func:`grid_steps`, decided once per distinct committed time) joins the
    members' step: its state is written into a free row of copies of the stacks (the
    stacks are never changed in place: members' fields are views of them).

    Every way gives the numbers of :meth:`KalmanTrack.predict_to` bit for bit: the same
    BLAS products per matrix, the same elementwise sums.
    """

    def __init__(self, grid_step_s: float, watch_floor_m2: float = math.inf) -> None:
        self.grid_step_s = grid_step_s
        f = transition(grid_step_s)
        self._f, self._f_t = f, f.T.copy()
        self._rows: list[KalmanTrack | None] = []  # row k's member (None: a free row)
        # per row: sigma above it is reported by watched_above (inf: a free row, or a
        # member unwatched); a joining member is watched from watch_floor_m2
        self._watch_floor_m2 = watch_floor_m2
        self._watch: list[float] = []
        self._members = 0
        self._loose: list[KalmanTrack] = []
        self._x = np.empty((0, 4, 1))
        self._p = np.empty((0, 4, 4))
        self._q = np.empty((0, 4, 4))
        self._sigmas: list[float] = []
        self.t_anchor_s = 0.0  # the members' committed time
        self.t_s = 0.0  # the members' viewed time
        #: Steps (and moves of ``t_s``) so far: a member's fields are current when equal.
        self.epoch = 0

    # --- membership -----------------------------------------------------------------------
    def add(self, track: KalmanTrack) -> None:
        """Advance ``track`` with the others from now on (it starts loose)."""
        if track._stack is not self and track not in self._loose:
            self._loose.append(track)

    def remove(self, track: KalmanTrack) -> None:
        """Stop advancing ``track`` (its fields written back)."""
        if track._stack is self:
            self.release(track)
        if track in self._loose:
            self._loose.remove(track)

    def release(self, track: KalmanTrack) -> None:
        """``track`` (a member) leaves the members, loose, with its fields written back."""
        self.write_back(track)
        self._rows[track._row] = None
        self._watch[track._row] = math.inf
        self._members -= 1
        track._stack, track._row = None, -1
        self._loose.append(track)

    def write_back(self, track: KalmanTrack) -> None:
        """Point a member's fields at its row (views) and the members' times."""
        k = track._row
        kf = track._kf
        kf.x = track._x_view = self._x[k]
        kf.P = track._p_view = self._p[k]
        track._t_anchor_s = self.t_anchor_s
        track._t_s = self.t_s
        track._sigma = self._sigmas[k]
        track._epoch = self.epoch

    def set_noise_row(self, track: KalmanTrack) -> None:
        """A member's new ``Q(h)`` into its row of ``_q`` (a stack of the batch's own,
        never handed out, so changed in place)."""
        self._q[track._row] = track._full_step[1]

    def _release_all(self) -> list[KalmanTrack]:
        """Release every member; returns them."""
        released = [track for track in self._rows if track is not None]
        for track in released:
            self.release(track)
        return released

    def read_members(self) -> dict[KalmanTrack, MemberReadout]:
        """Every member's ``(state, sigma, cov_xy)`` at ``t_s`` as :attr:`KalmanTrack.state`,
        :attr:`KalmanTrack.sigma` and :attr:`KalmanTrack.cov_xy` give them, read from the
        stacks at once (``tolist``: each float exactly; the rows' flat 0, 1, 5 of ``P`` are
        ``Pxx, Pxy, Pyy``) instead of pointing each member's fields at its row."""
        n = len(self._rows)
        if not self._members:
            return {}
        states = self._x.reshape(n, 4).tolist()
        covs = self._p.reshape(n, 16)[:, [0, 1, 5]].tolist()
        sigmas = self._sigmas
        return {tr: ((s[0], s[1], s[2], s[3]), sigmas[k], (c[0], c[1], c[2]))
                for k, (tr, s, c) in enumerate(zip(self._rows, states, covs, strict=True))
                if tr is not None}

    def watched_above(self) -> list[KalmanTrack]:
        """The watched members whose ``sigma`` is above the watch floor (m^2): one
        comparison per row in C (``map``) first, the rows themselves only if any is."""
        sigmas, watch = self._sigmas, self._watch
        if not any(map(operator.gt, sigmas, watch)):
            return []
        return [tr for tr, s, w in zip(self._rows, sigmas, watch, strict=True)
                if s > w and tr is not None]

    def unwatch(self, track: KalmanTrack) -> None:
        """``track`` is no longer reported by :meth:`watched_above` while it stays a
        member (from its next joining it is watched again)."""
        if track._stack is self:
            self._watch[track._row] = math.inf

    # --- time -----------------------------------------------------------------------------
    def predict_to(self, tracks: Sequence[KalmanTrack], t_s: float) -> None:
        """Add any of ``tracks`` not in the batch yet (:meth:`add`) and advance every
        track of the batch to ``t_s`` (:meth:`advance`)."""
        for track in tracks:
            self.add(track)
        self.advance(t_s)

    def advance(self, t_s: float) -> tuple[bool, list[KalmanTrack]]:
        """Advance every track to ``t_s`` (tracks at or past it are left). Returns whether
        the members moved (every one of them) and the loose tracks that moved.

        The members' next commit (:func:`grid_steps` from ``t_anchor_s``) decides:
        one whole grid step to the last grid point, ``t_s`` on that grid point (within
        ``_TINY_S``): the stacked step; no grid point passed and ``t_s`` still within
        ``_TINY_S`` of ``t_anchor_s``: only ``t_s`` moves (each view stays its committed
        state, as :meth:`KalmanTrack._refresh_view` decides); anything else: the members
        are released and step as loose tracks."""
        h = self.grid_step_s
        k_last = math.floor(t_s / h + _GRID_EPS)
        t_grid_s = k_last * h
        on_grid = t_s - t_grid_s <= _TINY_S
        members_step = False
        members_moved = False
        if self._members and t_s > self.t_s:
            k_first, _, first_dt = grid_steps(self.t_anchor_s, t_s, h)
            if k_first == k_last and abs(first_dt - h) <= _TINY_S and on_grid:
                members_step = members_moved = True
            elif k_last < k_first and t_s - self.t_anchor_s <= _TINY_S:
                self.t_s = t_s
                self.epoch += 1
                members_moved = True
            else:
                self._release_all()
        moved: list[KalmanTrack] = []
        if self._loose:
            joiners: list[KalmanTrack] = []
            whole_step: dict[float, bool] = {}  # committed time -> its next commit joins
            for track in list(self._loose):
                if t_s <= track._t_s:
                    continue
                moved.append(track)
                anchor = track._t_anchor_s
                joins = whole_step.get(anchor)
                if joins is None:
                    k_first, _, first_dt = grid_steps(anchor, t_s, h)
                    joins = whole_step[anchor] = (
                        k_first == k_last and abs(first_dt - h) <= _TINY_S)
                if joins:
                    joiners.append(track)
                else:
                    track.predict_to(t_s)
            if joiners:
                if self._members and not members_step:  # the members stay: not their step
                    released = self._release_all()
                    if members_moved:  # in t_s only: they count as moved tracks
                        moved += released
                        members_moved = False
                self._join(joiners)
                members_step = True
        if members_step:
            self._step(t_s, t_grid_s)
            if not on_grid:  # each view is predicted on from the grid, track by track
                for track in self._release_all():
                    track._refresh_view()
        return members_moved, moved

    def _join(self, joiners: list[KalmanTrack]) -> None:
        """Write the joiners' committed states and noises into free rows of copies of the
        stacks (new rows appended when too few are free); they become members."""
        rows = self._rows
        free = [k for k, tr in enumerate(rows) if tr is None]
        extra = len(joiners) - len(free)
        if extra > 0:
            self._x = np.concatenate([self._x, np.zeros((extra, 4, 1))])
            self._p = np.concatenate([self._p, np.zeros((extra, 4, 4))])
            self._q = np.concatenate([self._q, np.zeros((extra, 4, 4))])
            free += range(len(rows), len(rows) + extra)
            rows += [None] * extra
            self._watch += [math.inf] * extra
        else:
            self._x, self._p, self._q = self._x.copy(), self._p.copy(), self._q.copy()
        xs, ps, qs = self._x, self._p, self._q
        for k, track in zip(free, joiners, strict=False):
            kf = track._kf
            xs[k], ps[k], qs[k] = kf.x, kf.P, track._full_step[1]
            rows[k] = track
            self._watch[k] = self._watch_floor_m2
            track._stack, track._row = self, k
            self._loose.remove(track)
        self._members += len(joiners)

    def _step(self, t_s: float, t_grid_s: float) -> None:
        """One whole grid step of every row: ``x^- = F x``, ``P^- = (F P) F' + Q``."""
        self._x = np.matmul(self._f, self._x)
        self._p = ps = np.matmul(np.matmul(self._f, self._p), self._f_t) + self._q
        self._sigmas = (ps[:, 0, 0] + ps[:, 1, 1]).tolist()
        self.t_anchor_s = t_grid_s
        self.t_s = t_s
        self.epoch += 1
