"""Observer configuration (:class:`ObserverConfig`) and its validation.

Units: metres, seconds. The Kalman process noise is an *intensity* ``q_per_s`` (m^2/s^3):
a prediction over a step ``dT`` adds ``Q(dT) = diag(0, 0, q, q) * dT`` to the covariance, so
the paper's ``Q = diag(0, 0, 0.01, 0.01)`` per 0.1 s step is ``q_per_s = 0.1``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

MODELS: tuple[str, ...] = ("kalman", "linear")


def _check_positive(name: str, value: float) -> None:
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        raise ValueError(f"ObserverConfig.{name} must be a number, got {value!r}")
    if not math.isfinite(value) or value <= 0.0:
        raise ValueError(f"ObserverConfig.{name} must be finite and > 0, got {value!r}")


@dataclass(frozen=True)
class ObserverConfig:
    """Parameters of the :class:`observer.Observer`.

    Attributes:
        model: ``"kalman"`` (constant-velocity Kalman filter, the paper's eq. (3)-(11)) or
            ``"linear"`` (the 2015 field test: no filter, sigma grows linearly when unseen).
        q_per_s: velocity process-noise intensity q (m^2/s^3); ``Q(dT) = diag(0,0,q,q) dT``.
        r_m2: measurement noise variance per axis (m^2); ``R = r I``.
        max_step_s: prediction sub-step (s). Predictions run on the absolute grid
            ``t = k * max_step_s``, so results never depend on how often ``predict_to`` is
            called.
        fov_radius_m: a track is lost while ``sqrt(sigma) > fov_radius_m``.
        linear_growth_per_s: linear model: sigma grows by this (m^2) per second unseen.
        gate_probability: chi-square (2 dof) gate; the threshold on the squared
            Mahalanobis distance of the innovation is ``-2 ln(1 - p)`` (18.42 for 0.9999).
    """

    model: str = "kalman"
    q_per_s: float = 0.1
    r_m2: float = 5.0
    max_step_s: float = 0.1
    fov_radius_m: float = 150.0
    linear_growth_per_s: float = 1.0
    gate_probability: float = 0.9999

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ValueError(
                f"ObserverConfig.model must be one of {', '.join(MODELS)}, got {self.model!r}"
            )
        for name in ("r_m2", "max_step_s", "fov_radius_m"):
            _check_positive(name, getattr(self, name))
        for name in ("q_per_s", "linear_growth_per_s"):
            value = getattr(self, name)
            if (
                not isinstance(value, (int, float))
                or isinstance(value, bool)
                or not math.isfinite(value)
                or value < 0.0
            ):
                raise ValueError(f"ObserverConfig.{name} must be finite and >= 0, got {value!r}")
        p = self.gate_probability
        if not isinstance(p, (int, float)) or isinstance(p, bool) or not 0.0 < p < 1.0:
            raise ValueError(f"ObserverConfig.gate_probability must be in (0, 1), got {p!r}")

    @property
    def gate_threshold(self) -> float:
        """Chi-square quantile with 2 dof: ``chi2_2(p) = -2 ln(1 - p)``."""
        return -2.0 * math.log1p(-self.gate_probability)
