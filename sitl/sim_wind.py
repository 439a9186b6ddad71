"""The wind a built-in vehicle flies in, set like ArduPilot SITL's, and the estimate of it
the vehicle reports in WIND, like ArduPlane's.

**Flown wind.** A vehicle flies in ``WindField(spec, seed).at(t_s)`` (:mod:`world.wind`:
the mean plus seeded Gauss-Markov gusts, a function of the seed and the mission time only),
so every vehicle of a run, and the offline simulator on the same scenario and seed, meet
the same air at the same time. ``spec`` is the scenario's wind (or ``--wind``) and is
exposed as ArduPilot SITL's own parameters (libraries/SITL/SITL.cpp):

* ``SIM_WIND_SPD``: m/s (ArduPilot's default 0);
* ``SIM_WIND_DIR``: true compass degrees the wind comes FROM (ArduPilot's default 180;
  floe starts it at the spec's ``from_deg``, or at 180 when the spec is calm, so that
  ``param set SIM_WIND_SPD 10`` on a calm vehicle blows from the south as on SITL);
* ``SIM_WIND_TURB``: m/s of random variation. ArduPilot SITL adds a low-passed random
  speed of about that standard deviation in a randomly jumping direction; floe reads it as
  the gust standard deviation per horizontal axis (``WindSpec.gust_m_s``) with the spec's
  correlation time ``gust_tau_s``.

While the three parameters hold their initial values the vehicle flies exactly the
scenario's field; a PARAM_SET (MAVProxy's ``param set SIM_WIND_SPD 12``) takes effect at
the next physics step with the field rebuilt from the new values and the same seed. (SITL
eases a change in over ``SIM_WIND_TC``, 5 s by default, and weakens the wind below
``SIM_WIND_T_ALT`` = 60 m by sqrt(alt / 60) by default; floe's wind steps and is uniform.)

**Reported wind.** ArduPlane's WIND message carries its EKF's wind estimate, not the truth
(``GCS_MAVLINK_Plane::send_wind``: ``direction = degrees(atan2(-wind.y, -wind.x))`` of the
NED air-motion vector, i.e. where the wind comes from in (-180, 180]; ``speed`` its length;
``speed_z`` its down component, 0 since EKF3 does not estimate it). The EKF keeps the wind
states frozen on the ground (``inhibitWindStates``) and starts them at zero when it starts.
Modelled as: zero at (re)boot, held while on the ground, and in flight a first-order lag
of the true wind with time constant ``ESTIMATE_TAU_S``::

    w_est += (1 - exp(-dt / tau)) (w_true - w_est)

so an estimate is within 5 % of a steady wind 3 tau = 15 s after take-off and follows
gusts slower than tau. The direction of a zero estimate is what ArduPlane's formula gives
for a zero vector: atan2(-0, -0) = -180 degrees (meaningless at speed 0).
"""

from __future__ import annotations

import math

from sitl.params import ParamStore
from world.wind import WindField, WindSpec

__all__ = [
    "ESTIMATE_TAU_S",
    "WIND_PARAMS",
    "EkfWindModel",
    "FlownWind",
    "wind_param_values",
]

ESTIMATE_TAU_S = 5.0
"""Time constant of the modelled EKF wind estimate (s)."""
WIND_PARAMS = ("SIM_WIND_SPD", "SIM_WIND_DIR", "SIM_WIND_TURB")
_ARDUPILOT_DEFAULT_DIR_DEG = 180.0  # SIM_WIND_DIR's default (sitl.params has the specs)
_CALM = (0.0, 0.0)


def wind_param_values(spec: WindSpec) -> dict[str, float]:
    """The parameters' initial values for ``spec`` (see the module docstring)."""
    from_deg = _ARDUPILOT_DEFAULT_DIR_DEG if spec.calm else spec.from_deg % 360.0
    return {
        "SIM_WIND_SPD": float(spec.speed_m_s),
        "SIM_WIND_DIR": float(from_deg),
        "SIM_WIND_TURB": float(spec.gust_m_s),
    }


class FlownWind:
    """The true wind of one vehicle: ``WindField(spec, seed)`` until the SIM_WIND_*
    parameters change, then the field of their values (same seed, same ``gust_tau_s``)."""

    def __init__(self, spec: WindSpec, seed: int) -> None:
        self.seed = seed
        self.spec = spec
        self._field = WindField(spec, seed)
        values = wind_param_values(spec)
        self._key = tuple(values[name] for name in WIND_PARAMS)
        self._calm = spec.calm
        self._read: tuple[ParamStore, int] | None = None
        """The store and its ``version`` when the SIM_WIND_* values were last compared
        with ``_key``: a store not set since needs no new look."""

    def at(self, t_s: float, params: ParamStore) -> tuple[float, float]:
        """ENU wind (m/s, towards) at mission time ``t_s`` under the current parameters."""
        read = self._read
        if read is None or read[0] is not params or read[1] != params.version:
            self._follow(params)
        if self._calm:
            return _CALM
        return self._field.at(t_s)

    def _follow(self, params: ParamStore) -> None:
        """The field of the SIM_WIND_* values in ``params`` (rebuilt when they changed)."""
        key = tuple(params.get(name) for name in WIND_PARAMS)
        if key != self._key:
            speed, from_deg, turb = key
            self.spec = WindSpec(speed, from_deg % 360.0, turb, self.spec.gust_tau_s)
            self._field = WindField(self.spec, self.seed)
            self._key = key
            self._calm = self.spec.calm
        self._read = (params, params.version)


class EkfWindModel:
    """The modelled EKF wind estimate (module docstring); zero at boot."""

    def __init__(self, tau_s: float = ESTIMATE_TAU_S) -> None:
        self.tau_s = tau_s
        self.xy_m_s: tuple[float, float] = _CALM

    def update(self, true_xy_m_s: tuple[float, float], dt_s: float, flying: bool) -> None:
        """Follow the true wind over ``dt_s`` while flying; hold it on the ground."""
        if not flying or dt_s <= 0.0 or true_xy_m_s == self.xy_m_s:
            return
        gain = 1.0 - math.exp(-dt_s / self.tau_s)
        ex, ey = self.xy_m_s
        self.xy_m_s = (ex + gain * (true_xy_m_s[0] - ex), ey + gain * (true_xy_m_s[1] - ey))

    def message_fields(self) -> tuple[float, float, float]:
        """(direction deg, speed m/s, speed_z m/s) of WIND as ArduPlane fills them:
        direction = degrees(atan2(-east, -north)) of the air motion, in (-180, 180]."""
        wx, wy = self.xy_m_s  # ENU: east, north; ArduPlane's NED wind is (wy, wx, 0)
        return math.degrees(math.atan2(-wx, -wy)), math.hypot(wx, wy), 0.0
