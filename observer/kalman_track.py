"""Constant-velocity Kalman track: the paper's eq. (3)-(11), built on filterpy.

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
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from filterpy.kalman import KalmanFilter

_TINY_S = 1e-12
_GRID_EPS = 1e-9  # in grid steps

#: Measurement matrix C = [I 0].
C = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])


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
        self.kf = KalmanFilter(dim_x=4, dim_z=2)
        self.kf.x = np.asarray(state, dtype=float).reshape(4, 1)
        self.kf.P = np.diag(np.asarray(p0_diag, dtype=float))
        self.kf.H = C.copy()
        self.q_per_s = q_per_s
        self.grid_step_s = grid_step_s
        self.t_anchor_s = t_s  # time of the committed state kf.x, kf.P
        self.t_s = t_s  # time of the viewed estimate
        self.x_view: np.ndarray = self.kf.x.copy()
        self.p_view: np.ndarray = self.kf.P.copy()
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

    def _commit_grid_until(self, t_s: float) -> None:
        h = self.grid_step_s
        k_last = math.floor(t_s / h + _GRID_EPS)
        k_first = math.floor(self.t_anchor_s / h + _GRID_EPS) + 1
        if k_last < k_first:
            return
        first_dt = k_first * h - self.t_anchor_s
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
        else:
            self.x_view = self.kf.x.copy()
            self.p_view = self.kf.P.copy()

    def set_process_noise(self, q_per_s: float) -> None:
        """New intensity, applied from the last committed time on."""
        self.q_per_s = q_per_s
        self._full_step = (transition(self.grid_step_s), process_noise(q_per_s, self.grid_step_s))
        self._refresh_view()

    # --- correction -----------------------------------------------------------------------
    def innovation(self, x_m: float, y_m: float, r_m2: float) -> float:
        """Squared Mahalanobis distance ``y' S^-1 y`` of ``z`` against the current estimate."""
        y = np.array([x_m, y_m]) - (C @ self.x_view).ravel()
        s = C @ self.p_view @ C.T + r_m2 * np.eye(2)
        return float(y @ np.linalg.solve(s, y))

    def correct(self, t_s: float, x_m: float, y_m: float, r_m2: float) -> None:
        """Commit the prediction at ``t_s`` (== self.t_s) and apply eq. (9)-(11)."""
        self.kf.x = self.x_view.copy()
        self.kf.P = self.p_view.copy()
        self.t_anchor_s = t_s
        self.kf.update(np.array([x_m, y_m]), R=r_m2 * np.eye(2))
        self.kf.P = 0.5 * (self.kf.P + self.kf.P.T)
        self.x_view = self.kf.x.copy()
        self.p_view = self.kf.P.copy()
        self.last_seen_s = t_s

    # --- read-out -------------------------------------------------------------------------
    @property
    def state(self) -> tuple[float, float, float, float]:
        x = self.x_view.ravel()
        return float(x[0]), float(x[1]), float(x[2]), float(x[3])

    @property
    def sigma(self) -> float:
        return float(self.p_view[0, 0] + self.p_view[1, 1])

    @property
    def cov_xy(self) -> tuple[float, float, float]:
        p = self.p_view
        return float(p[0, 0]), float(p[0, 1]), float(p[1, 1])
