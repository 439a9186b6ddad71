"""Conversions between floe's local frame and MAVLink's geodetic and compass conventions.

floe's maths runs in a flat local ENU frame in metres around a mission origin, with headings
in radians counter-clockwise from east (+x). MAVLink carries WGS-84 latitude/longitude
(degE7) and compass headings (degrees clockwise from north). Conversions use pymap3d's
geodetic <-> ENU transforms (exact on the WGS-84 ellipsoid, so a missing cos(lat) at 78.9 N,
a 5x error, cannot creep in).

Compass heading ``hdg`` (clockwise from north) and ENU heading ``psi`` (counter-clockwise
from east) are related by ``psi = pi/2 - hdg``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import pymap3d

__all__ = [
    "GeoOrigin",
    "compass_deg_from_enu_rad",
    "enu_rad_from_compass_deg",
    "wrap_pi",
]


def wrap_pi(angle_rad: float) -> float:
    """Wrap an angle to [-pi, pi)."""
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi


def enu_rad_from_compass_deg(heading_deg: float) -> float:
    """ENU heading psi (rad, CCW from east) from a compass heading (deg, CW from north)."""
    return wrap_pi(math.pi / 2.0 - math.radians(heading_deg))


def compass_deg_from_enu_rad(heading_rad: float) -> float:
    """Compass heading in [0, 360) degrees from an ENU heading psi: hdg = 90 - psi (deg)."""
    return (90.0 - math.degrees(heading_rad)) % 360.0


@dataclass(frozen=True)
class GeoOrigin:
    """The mission origin: the point (lat, lon, alt) where local x = y = z = 0."""

    lat_deg: float
    lon_deg: float
    alt_m: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lat_deg) and -90.0 <= self.lat_deg <= 90.0):
            raise ValueError(f"origin latitude must be in [-90, 90] deg, got {self.lat_deg}")
        if not (math.isfinite(self.lon_deg) and -180.0 <= self.lon_deg <= 180.0):
            raise ValueError(f"origin longitude must be in [-180, 180] deg, got {self.lon_deg}")

    def to_local(self, lat_deg: float, lon_deg: float, alt_m: float | None = None) -> tuple[
        float, float, float
    ]:
        """Local (east_m, north_m, up_m) of a geodetic point."""
        e, n, u = pymap3d.geodetic2enu(
            lat_deg, lon_deg, self.alt_m if alt_m is None else alt_m,
            self.lat_deg, self.lon_deg, self.alt_m,
        )
        return float(e), float(n), float(u)

    def to_geodetic(self, east_m: float, north_m: float, up_m: float = 0.0) -> tuple[
        float, float, float
    ]:
        """Geodetic (lat_deg, lon_deg, alt_m) of a local ENU point."""
        lat, lon, alt = pymap3d.enu2geodetic(
            east_m, north_m, up_m, self.lat_deg, self.lon_deg, self.alt_m
        )
        return float(lat), float(lon), float(alt)
