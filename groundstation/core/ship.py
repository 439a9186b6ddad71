"""The ship's track: where the ship is now and will be, from its fixes (``BoatPosition``).

A constant-velocity Kalman filter per axis, the state ``s = [x, y, vx, vy]`` (local ENU m,
m/s). Between fixes the state is predicted with

    s(t + dt) = F s(t),   F = [[I, dt I], [0, I]]
    P(t + dt) = F P F^T + Q,   Q = q [[dt^3/3 I, dt^2/2 I], [dt^2/2 I, dt I]]

where ``q`` (m^2/s^3, :data:`SHIP_Q_M2_S3`) is the white-noise acceleration of a ship that
changes course and speed; a fix measures the position (1-sigma ``sigma_m``, else
:data:`FIX_SIGMA_M`) and, where its source says (NMEA RMC/VTG, the scenario), the velocity
(1-sigma :data:`VELOCITY_SIGMA_M_S`). The first fix starts the track at rest with a wide
velocity (``INITIAL_VELOCITY_SIGMA_M_S``) unless it carries a velocity.

:meth:`ShipTrack.predict` is the ship at any later time, with ``sigma_m`` the square root
of the larger eigenvalue of the position covariance: it grows while the fixes stop (a
silent feed), so what depends on it (homes, the returns) can see how much to trust it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from groundstation.core.events import BoatPosition

__all__ = ["FIX_SIGMA_M", "ShipPrediction", "ShipTrack"]

SHIP_Q_M2_S3 = 0.05
FIX_SIGMA_M = 5.0
VELOCITY_SIGMA_M_S = 0.5
INITIAL_VELOCITY_SIGMA_M_S = 10.0


@dataclass(frozen=True)
class ShipPrediction:
    """The ship at ``t_s``: position, velocity (ENU), and the position's 1-sigma (m)."""

    t_s: float
    x_m: float
    y_m: float
    vx_m_s: float
    vy_m_s: float
    sigma_m: float
    fix_age_s: float
    """Mission seconds since the last fix."""

    @property
    def xy_m(self) -> tuple[float, float]:
        return self.x_m, self.y_m

    @property
    def v_m_s(self) -> tuple[float, float]:
        return self.vx_m_s, self.vy_m_s


class ShipTrack:
    """The ship's constant-velocity filter (module docstring)."""

    def __init__(self, q_m2_s3: float = SHIP_Q_M2_S3) -> None:
        self.q_m2_s3 = q_m2_s3
        self._s: np.ndarray | None = None
        self._p = np.zeros((4, 4))
        self._t_s = 0.0
        self.last_fix_s: float | None = None
        self.heading_rad: float | None = None
        self.fixes = 0

    @property
    def known(self) -> bool:
        return self._s is not None

    def _transition(self, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
        f = np.eye(4)
        f[0, 2] = f[1, 3] = dt_s
        q = self.q_m2_s3
        qp, qc, qv = q * dt_s**3 / 3.0, q * dt_s**2 / 2.0, q * dt_s
        big_q = np.array([[qp, 0, qc, 0], [0, qp, 0, qc], [qc, 0, qv, 0], [0, qc, 0, qv]])
        return f, big_q

    def fix(self, event: BoatPosition) -> bool:
        """Take one fix; False (ignored) when it is not finite or older than the track."""
        values = [event.x_m, event.y_m]
        velocity = event.vx_m_s is not None and event.vy_m_s is not None
        if velocity:
            values += [float(event.vx_m_s or 0.0), float(event.vy_m_s or 0.0)]
        if not all(isinstance(v, int | float) and math.isfinite(v) for v in values):
            return False
        sigma = event.sigma_m if event.sigma_m is not None and math.isfinite(
            event.sigma_m) and event.sigma_m > 0 else FIX_SIGMA_M
        if event.heading_rad is not None and math.isfinite(event.heading_rad):
            self.heading_rad = event.heading_rad
        if self._s is None:
            vx, vy = (values[2], values[3]) if velocity else (0.0, 0.0)
            sv = VELOCITY_SIGMA_M_S if velocity else INITIAL_VELOCITY_SIGMA_M_S
            self._s = np.array([values[0], values[1], vx, vy])
            self._p = np.diag([sigma**2, sigma**2, sv**2, sv**2])
            self._t_s = event.t_s
        else:
            if event.t_s < self._t_s:
                return False
            self._advance(event.t_s)
            rows = 4 if velocity else 2
            h = np.eye(4)[:rows]
            r = np.diag([sigma**2, sigma**2, VELOCITY_SIGMA_M_S**2, VELOCITY_SIGMA_M_S**2][:rows])
            z = np.array(values[:rows])
            innovation = z - h @ self._s
            s_cov = h @ self._p @ h.T + r
            gain = self._p @ h.T @ np.linalg.inv(s_cov)
            self._s = self._s + gain @ innovation
            self._p = (np.eye(4) - gain @ h) @ self._p
        self.last_fix_s = event.t_s
        self.fixes += 1
        return True

    def _advance(self, t_s: float) -> None:
        assert self._s is not None
        dt = t_s - self._t_s
        if dt > 0:
            f, q = self._transition(dt)
            self._s = f @ self._s
            self._p = f @ self._p @ f.T + q
            self._t_s = t_s

    def predict(self, t_s: float) -> ShipPrediction | None:
        """The ship at ``t_s`` (not before the last fix); None before the first fix."""
        if self._s is None:
            return None
        dt = max(0.0, t_s - self._t_s)
        f, q = self._transition(dt)
        s = f @ self._s
        p = f @ self._p @ f.T + q
        sigma = math.sqrt(float(max(np.linalg.eigvalsh(p[:2, :2]))))
        age = t_s - self.last_fix_s if self.last_fix_s is not None else math.inf
        return ShipPrediction(t_s, float(s[0]), float(s[1]), float(s[2]), float(s[3]),
                              sigma, max(0.0, age))
