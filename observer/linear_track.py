"""The 2015 field test's uncertainty model: no filter, a staleness clock.

``sigma(t) = sigma_ref + g (t - t_ref)`` with ``g = linear_growth_per_s``; a measurement
sets ``sigma_ref = 0`` and ``t_ref`` to its time. The position estimate is the last measured
(or given) position, dead-reckoned with the given velocity:
``p(t) = p_ref + v (t - t_ref)`` (the last measured position itself when v = 0, as in the
field test). ``cov_xy`` is reported as ``(sigma/2, 0, sigma/2)``.
"""

from __future__ import annotations


class LinearTrack:
    """One target under the linear model."""

    def __init__(
        self,
        t_s: float,
        state: tuple[float, float, float, float],
        sigma0: float,
        q_per_s: float,
        growth_per_s: float,
    ) -> None:
        self.x_ref_m, self.y_ref_m, self.vx_m_s, self.vy_m_s = state
        self.t_ref_s = t_s
        self.sigma_ref = sigma0
        self.t_s = t_s
        self.q_per_s = q_per_s  # reported only: the linear model has no process noise
        self.growth_per_s = growth_per_s
        self.last_seen_s: float | None = None

    def predict_to(self, t_s: float) -> None:
        if t_s > self.t_s:
            self.t_s = t_s

    def rewind_to(self, t_s: float) -> bool:
        """Move the estimate back to ``t_s`` if not before the last measurement."""
        if t_s < self.t_ref_s or t_s > self.t_s:
            return t_s == self.t_s
        self.t_s = t_s
        return True

    def set_process_noise(self, q_per_s: float) -> None:
        self.q_per_s = q_per_s

    def innovation(self, x_m: float, y_m: float, r_m2: float) -> float:
        """``|z - p|^2 / (sigma/2 + r)``: the Kalman form with an isotropic covariance."""
        x, y, _, _ = self.state
        return ((x_m - x) ** 2 + (y_m - y) ** 2) / (0.5 * self.sigma + r_m2)

    def correct(self, t_s: float, x_m: float, y_m: float, r_m2: float) -> None:
        del r_m2
        self.x_ref_m, self.y_ref_m = x_m, y_m
        self.t_ref_s = t_s
        self.sigma_ref = 0.0
        self.last_seen_s = t_s

    @property
    def state(self) -> tuple[float, float, float, float]:
        dt = self.t_s - self.t_ref_s
        return (
            self.x_ref_m + self.vx_m_s * dt,
            self.y_ref_m + self.vy_m_s * dt,
            self.vx_m_s,
            self.vy_m_s,
        )

    @property
    def sigma(self) -> float:
        return self.sigma_ref + self.growth_per_s * (self.t_s - self.t_ref_s)

    @property
    def cov_xy(self) -> tuple[float, float, float]:
        s = 0.5 * self.sigma
        return s, 0.0, s
