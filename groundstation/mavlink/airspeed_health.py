"""Whether a vehicle's airspeed sensor is failed, on the autopilot's own word (sans-IO).

Without airspeed, ArduPlane's EKF cannot observe the wind in straight flight, and its WIND
estimate goes wrong (against real SITL: 15 m/s of true wind reported as 5.5-8.8 m/s after
the sensor was disabled on an upwind take-off). So a vehicle whose sensor failed must not
be trusted on the wind. ArduPlane says so in two ways:

**STATUSTEXT** (``AP_Airspeed::check_sensor_ahrs_wind_max_failures``, AP_Airspeed_Health.cpp).
The health check compares the airspeed with the GPS ground speed (and, with ARSPD_OPTIONS
bit 3, the EKF's airspeed innovation); its health probability ``p`` decays as ``0.9 p`` per
bad check and grows as ``0.98 p + 0.02`` per good one (checks at 5 Hz). Below 0.1 it sends,
at MAV_SEVERITY_ERROR, ``Airspeed sensor N failure. Disabling`` and sets ARSPD_USE to 0
(not saved: a reboot uses the sensor again); above 0.95 again, ``Airspeed sensor N now OK.
Re-enabled`` (NOTICE); without a 3D GPS fix it re-enables the sensor as ``Airspeed sensor
N, Re-enabled as GPS fall-back`` (NOTICE). The text is the autopilot's own verdict: it acts
at once (:meth:`AirspeedHealth.text`).

**SYS_STATUS** ``onboard_control_sensors_*`` bit MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE
(0x10; ``GCS_MAVLINK::update_sensor_status_flags``): *present* while a sensor is configured
(ARSPD_TYPE), *enabled* while it is used (ARSPD_USE, which the health check clears), and
*healthy* while every configured sensor reads (``all_healthy()``) and, when used, the AHRS
uses it. So a sensor disabled by the health check reads present, **not enabled**, healthy;
a used sensor that stops reading reads present, enabled, **not healthy**. Bits are
telemetry like any other: one frame is no evidence. They say *failed* when

    present and ((enabled seen before in this boot and not enabled) or (enabled and not healthy))

on ``min_frames`` consecutive SYS_STATUS frames spanning ``min_span_s``
(:class:`~.evidence.Sustained`), and *healthy* when present, enabled and healthy on as
many. A sensor never seen enabled (ARSPD_USE 0 by choice) or not present is never judged:
its vehicle's estimate is the airspeed-less one it always was.

**Verdict.** Failed on the text, or when the bits turn to *failed*. Recovered when every
sensor a text named is named again by a recovery text, or when the bits turn to *healthy*
after they had shown this failure (an autopilot whose bits never showed it cannot clear it
with them). A reboot forgets it all (:meth:`reset`): ArduPlane uses the sensor again then.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from groundstation.mavlink.evidence import Sustained

__all__ = [
    "DIFFERENTIAL_PRESSURE_BIT",
    "AirspeedChange",
    "AirspeedHealth",
    "airspeed_text",
]

DIFFERENTIAL_PRESSURE_BIT = 0x10  # MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE
_FAILED = re.compile(r"Airspeed sensor (\d+) failure\. Disabling")
_RECOVERED = re.compile(r"Airspeed sensor (\d+)(?: now OK\. Re-enabled|, Re-enabled as GPS)")


def airspeed_text(text: str) -> tuple[str, int] | None:
    """``("failed" | "recovered", sensor number)`` for ArduPlane's airspeed health texts,
    None for any other text."""
    for verdict, pattern in (("failed", _FAILED), ("recovered", _RECOVERED)):
        match = pattern.search(text)
        if match is not None:
            return verdict, int(match.group(1))
    return None


@dataclass(frozen=True)
class AirspeedChange:
    """The verdict changed at ``t_s``: ``failed`` or not, ``how`` (``statustext`` or
    ``sys_status``) and ``detail`` (the autopilot's text, or what the bits said)."""

    t_s: float
    failed: bool
    how: str
    detail: str


class AirspeedHealth:
    """One vehicle's airspeed-sensor verdict (module docstring). ``text`` and
    ``sys_status`` return the change they cause, or None."""

    def __init__(self, min_frames: int = 3, min_span_s: float = 2.0) -> None:
        self._bad = Sustained(min_frames, min_span_s)
        self._good = Sustained(min_frames, min_span_s)
        self.reset()

    def reset(self) -> None:
        """Forget everything (and at a reboot: ArduPlane uses its sensor again then)."""
        self._bad.reset()
        self._good.reset()
        self.failed = False
        self.detail = ""
        self._bits: str | None = None  # the bits' sustained verdict: "failed" | "healthy"
        self._bits_showed = False  # the bits showed the current failure
        self._seen_enabled = False
        self._sensors: set[int] = set()  # sensors a failure text named, not recovered

    def text(self, text: str, t_s: float) -> AirspeedChange | None:
        """One whole STATUSTEXT of the vehicle's autopilot."""
        said = airspeed_text(text)
        if said is None:
            return None
        verdict, sensor = said
        if verdict == "failed":
            self._sensors.add(sensor)
            return self._fail(t_s, "statustext", text) if not self.failed else None
        self._sensors.discard(sensor)
        if self.failed and not self._sensors:
            return self._recover(t_s, "statustext", text)
        return None

    def sys_status(self, present: int, enabled: int, health: int,
                   t_s: float) -> AirspeedChange | None:  # fmt: skip
        """One SYS_STATUS frame's three sensor bitmasks."""
        bit = DIFFERENTIAL_PRESSURE_BIT
        is_present, is_enabled, is_healthy = (bool(m & bit) for m in (present, enabled, health))
        self._seen_enabled |= is_present and is_enabled
        unused = self._seen_enabled and not is_enabled
        bad = is_present and (unused or (is_enabled and not is_healthy))
        good = is_present and is_enabled and is_healthy
        was = self._bits
        if self._bad.observe(bad, t_s):
            self._bits = "failed"
        if self._good.observe(good, t_s):
            self._bits = "healthy"
        if self._bits == was:
            return None
        if self._bits == "failed":
            self._bits_showed = True
            if self.failed:
                return None
            state = "not enabled" if unused else "not healthy"
            detail = f"SYS_STATUS: differential pressure sensor present, {state}"
            return self._fail(t_s, "sys_status", detail)
        if self.failed and self._bits_showed:
            self._sensors.clear()
            detail = "SYS_STATUS: differential pressure sensor enabled and healthy"
            return self._recover(t_s, "sys_status", detail)
        return None

    def _fail(self, t_s: float, how: str, detail: str) -> AirspeedChange:
        self.failed, self.detail = True, detail
        self._bits_showed = self._bits == "failed"
        return AirspeedChange(t_s, True, how, detail)

    def _recover(self, t_s: float, how: str, detail: str) -> AirspeedChange:
        self.failed, self.detail = False, ""
        self._bits_showed = False
        return AirspeedChange(t_s, False, how, detail)
