"""Wind over the operating area: a steady mean plus gusts, the same in every frontend.

The mean wind is ``speed_m_s`` blowing from compass ``from_deg`` (the convention of
ArduPilot's ``SIM_WIND_SPD`` / ``SIM_WIND_DIR``, METARs and the WIND message), i.e. the ENU
vector ``w0 = -speed (sin(from), cos(from))`` (:mod:`domain.wind_triangle`).

Gusts are a first-order Gauss-Markov (Ornstein-Uhlenbeck) process per horizontal axis with
standard deviation ``gust_m_s`` and correlation time ``gust_tau_s``, integrated exactly on a
fixed grid of ``GRID_S``::

    g[k+1] = a g[k] + gust_m_s sqrt(1 - a^2) n[k],   a = exp(-GRID_S / gust_tau_s),
    n[k] ~ N(0, I),   g[0] ~ N(0, gust_m_s^2 I)

and ``w(t) = w0 + g[floor(t / GRID_S)]``: uniform in space (the area is a few km; the
turbulence a plane feels at its own scale is left out), a function of the seed and the
mission time only, so the offline simulator, every built-in MAVLink vehicle and a replay
see the same wind at the same time whatever their step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from domain.errors import ConfigError
from domain.limits import MAX_WIND_M_S
from domain.wind_triangle import wind_vector_m_s

__all__ = ["GRID_S", "WindField", "WindSpec", "parse_wind_text"]

GRID_S = 0.1
"""Step of the gust process (s)."""
_BLOCK = 1024


@dataclass(frozen=True)
class WindSpec:
    """A scenario's wind (see module docstring); the default is still air."""

    speed_m_s: float = 0.0
    from_deg: float = 0.0
    gust_m_s: float = 0.0
    gust_tau_s: float = 5.0

    def __post_init__(self) -> None:
        for name, value, low in (("speed_m_s", self.speed_m_s, 0.0),
                                 ("gust_m_s", self.gust_m_s, 0.0)):
            if not (math.isfinite(value) and low <= value <= MAX_WIND_M_S):
                raise ValueError(f"wind {name} must be in [0, {MAX_WIND_M_S:g}], got {value}")
        if not math.isfinite(self.from_deg):
            raise ValueError(f"wind from_deg must be finite, got {self.from_deg}")
        if not (math.isfinite(self.gust_tau_s) and self.gust_tau_s > 0):
            raise ValueError(f"wind gust_tau_s must be > 0, got {self.gust_tau_s}")

    @property
    def calm(self) -> bool:
        return self.speed_m_s == 0.0 and self.gust_m_s == 0.0

    @property
    def mean_xy_m_s(self) -> tuple[float, float]:
        """The mean wind as the ENU vector the air moves towards (m/s)."""
        return wind_vector_m_s(self.speed_m_s, self.from_deg)

    def describe(self) -> str:
        if self.calm:
            return "calm"
        text = f"{self.speed_m_s:g} m/s from {self.from_deg % 360:g} deg"
        if self.gust_m_s > 0:
            text += f", gusts {self.gust_m_s:g} m/s (tau {self.gust_tau_s:g} s)"
        return text


class WindField:
    """``w(t)`` for one run: the mean plus the seeded gust process (module docstring).

    Queries may come in any order; the process is generated forward in blocks and kept, so
    a query costs O(1) after the first pass over its time (1 h is 36 000 grid points)."""

    def __init__(self, spec: WindSpec, seed: int = 0) -> None:
        self.spec = spec
        self._mean = spec.mean_xy_m_s
        self._rng = np.random.Generator(np.random.PCG64([int(seed) & 0xFFFFFFFF, 0x57494E44]))
        self._a = math.exp(-GRID_S / spec.gust_tau_s)
        self._gx: list[float] = []
        self._gy: list[float] = []

    def at(self, t_s: float) -> tuple[float, float]:
        """ENU wind vector (m/s) at mission time ``t_s`` (clamped at 0)."""
        if self.spec.gust_m_s == 0.0:
            return self._mean
        k = int(max(t_s, 0.0) / GRID_S) if math.isfinite(t_s) else 0
        while k >= len(self._gx):
            self._extend()
        return self._mean[0] + self._gx[k], self._mean[1] + self._gy[k]

    def _extend(self) -> None:
        sigma = self.spec.gust_m_s
        noise = self._rng.standard_normal((_BLOCK, 2))
        if not self._gx:
            gx, gy = sigma * float(noise[0, 0]), sigma * float(noise[0, 1])
            start = 1
            self._gx.append(gx)
            self._gy.append(gy)
        else:
            gx, gy = self._gx[-1], self._gy[-1]
            start = 0
        a, b = self._a, sigma * math.sqrt(1.0 - self._a * self._a)
        for i in range(start, _BLOCK):
            gx = a * gx + b * float(noise[i, 0])
            gy = a * gy + b * float(noise[i, 1])
            self._gx.append(gx)
            self._gy.append(gy)


def parse_wind_text(text: str, what: str = "--wind") -> WindSpec:
    """``SPEED_M_S,FROM_DEG[,GUST_M_S]`` (e.g. ``10,270``: 10 m/s from the west) -> WindSpec;
    a bad value is a one-line ConfigError naming ``what``."""
    parts = [p.strip() for p in text.split(",")]
    if len(parts) not in (2, 3):
        raise ConfigError(
            f"{what}: expected SPEED_M_S,FROM_DEG[,GUST_M_S] (e.g. 10,270 for 10 m/s from "
            f"the west), got {text!r}"
        )
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise ConfigError(f"{what}: not numbers: {text!r}") from None
    speed, from_deg = values[0], values[1]
    gust = values[2] if len(values) == 3 else 0.0
    if not all(math.isfinite(v) for v in values):
        raise ConfigError(f"{what}: values must be finite, got {text!r}")
    if not 0.0 <= from_deg <= 360.0:
        raise ConfigError(f"{what}: FROM_DEG must be a compass direction in [0, 360], "
                          f"got {from_deg:g}")
    try:
        return WindSpec(speed_m_s=speed, from_deg=from_deg % 360.0, gust_m_s=gust)
    except ValueError as exc:
        raise ConfigError(f"{what}: {exc}") from None
