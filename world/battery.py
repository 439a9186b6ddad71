"""The simulated X8's battery: how fast a flying plane drains it.

Both simulators (``gcs simulate``'s offline vehicles and ``gcs sitl``'s ArduPlane-like
ones) drain their pack with this model, so a watch's energy figures mean the same in both.

The electric power a fixed-wing plane draws in level flight at airspeed ``v`` is the
parasite part, growing with ``v^3``, plus the induced part, falling with ``1/v``; at the
cruise airspeed ``v_c`` floe takes the parasite share as ``PARASITE_SHARE`` = 0.6:

    I_level(v) = I_c * (0.6 * (v / v_c)^3 + 0.4 * v_c / v)

``I_c``, the cruise current, is what drains the full pack in ``endurance_s`` at cruise in
still air: ``I_c = 3.6 * capacity_mah / endurance_s`` (mAh to A s). A climb adds the power
that lifts the plane, ``m g dh/dt``, at the propulsion efficiency ``eta``:

    I = I_level(v) + m g max(0, climb_m_s) / (eta * U)

where ``U`` is the pack's voltage. ArduPlane holds airspeed in a steady wind, so a steady
wind changes no current; what it changes is the throttle's work in the wind's gusts, which
floe models as a share growing with the wind's speed ``w`` (``GUST_SHARE_PER_M_S`` = 1 %
per m/s):

    I_wind = I * (1 + 0.01 * w)

On the ground (disarmed, or armed and waiting) the plane draws ``idle_current_a``.

The pack's voltage falls linearly from ``full_v`` to ``empty_v`` with the charge used (a
3S LiPo's useful range); at 0 % the motor stops and the plane falls.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

__all__ = ["GRAVITY_M_S2", "Battery", "BatteryModel"]

GRAVITY_M_S2 = 9.80665
PARASITE_SHARE = 0.6
GUST_SHARE_PER_M_S = 0.01


@dataclass(frozen=True)
class BatteryModel:
    """One airframe's pack and power curve (the X8 with a 3S pack by default)."""

    endurance_s: float = 3600.0
    """Flight time on a full pack at cruise airspeed in still air."""
    cruise_speed_m_s: float = 22.0
    capacity_mah: float = 10_000.0
    full_v: float = 12.6
    empty_v: float = 10.2
    mass_kg: float = 3.0
    efficiency: float = 0.5
    idle_current_a: float = 0.5

    def __post_init__(self) -> None:
        for name in ("endurance_s", "cruise_speed_m_s", "capacity_mah", "full_v", "empty_v",
                     "mass_kg", "efficiency"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0, got {value!r}")
        if self.empty_v >= self.full_v:
            raise ValueError("empty_v must be below full_v")

    @cached_property
    def cruise_current_a(self) -> float:
        """``I_c = 3.6 * capacity_mah / endurance_s`` (computed once: the model is frozen)."""
        return 3.6 * self.capacity_mah / self.endurance_s

    def current_a(self, airspeed_m_s: float, wind_m_s: float = 0.0, climb_m_s: float = 0.0,
                  voltage_v: float | None = None, flying: bool = True) -> float:
        """The current drawn (module docstring's equations); idle when not ``flying``."""
        if not flying:
            return self.idle_current_a
        v_c = self.cruise_speed_m_s
        v = min(max(airspeed_m_s, 0.3 * v_c), 3.0 * v_c) if math.isfinite(airspeed_m_s) else v_c
        level = self.cruise_current_a * (
            PARASITE_SHARE * (v / v_c) ** 3 + (1.0 - PARASITE_SHARE) * v_c / v
        )
        u = self.full_v if voltage_v is None else max(voltage_v, self.empty_v)
        climb = max(0.0, climb_m_s) if math.isfinite(climb_m_s) else 0.0
        lift = self.mass_kg * GRAVITY_M_S2 * climb / (self.efficiency * u)
        wind = abs(wind_m_s) if math.isfinite(wind_m_s) else 0.0
        return (level + lift) * (1.0 + GUST_SHARE_PER_M_S * wind)


@dataclass
class Battery:
    """A pack being drained: ``used_mah`` of ``model.capacity_mah``."""

    model: BatteryModel
    used_mah: float = 0.0
    current_a: float = 0.0

    @property
    def remaining(self) -> float:
        """Charge left, 0-1."""
        return max(0.0, 1.0 - self.used_mah / self.model.capacity_mah)

    @property
    def voltage_v(self) -> float:
        """``empty_v + (full_v - empty_v) * remaining``."""
        m = self.model
        return m.empty_v + (m.full_v - m.empty_v) * self.remaining

    @property
    def empty(self) -> bool:
        return self.remaining <= 0.0

    def drain(self, dt_s: float, airspeed_m_s: float, wind_m_s: float = 0.0,
              climb_m_s: float = 0.0, flying: bool = True) -> float:
        """Draw the current for ``dt_s`` seconds (``used_mah += I dt / 3.6``); returns the
        pack's voltage it was drawn at (the voltage before the step)."""
        voltage_v = self.voltage_v
        self.current_a = self.model.current_a(airspeed_m_s, wind_m_s, climb_m_s,
                                              voltage_v, flying)
        self.used_mah = min(self.model.capacity_mah,
                            self.used_mah + self.current_a * max(0.0, dt_s) / 3.6)
        return voltage_v

    def swap(self) -> None:
        """A fresh pack (a recovered plane's battery swap)."""
        self.used_mah = 0.0
