"""Conversions between floe's local frame and MAVLink's geodetic and compass conventions.

floe's maths runs in a flat local ENU frame in metres around a mission origin, with headings
in radians counter-clockwise from east (+x). MAVLink carries WGS-84 latitude/longitude
(degE7) and compass headings (degrees clockwise from north). Conversions are exact on the
WGS-84 ellipsoid, so a missing cos(lat) at 78.9 N, a 5x error, cannot creep in: geodetic ->
ENU is pymap3d's ``geodetic2enu``; ENU -> geodetic is pymap3d's ``enu2geodetic`` written out
for scalars (:func:`geodetic_from_enu`), the same equations in the same order in ``math``
instead of NumPy 0-d arrays, the origin's terms computed once: 48x cheaper (4.8 against
230 us a point on the idle 2-core machine, `python benchmarks/geodesy_bench.py`), within
1.4e-14 deg and 7e-10 m of pymap3d (``tests/test_geodesy_scalar.py`` holds it to 1e-12
deg and 1e-8 m). The built-in
simulator converts every position it reports with it, ten times a simulated second per
vehicle.

Compass heading ``hdg`` (clockwise from north) and ENU heading ``psi`` (counter-clockwise
from east) are related by ``psi = pi/2 - hdg``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

__all__ = [
    "WGS84_A_M",
    "WGS84_B_M",
    "GeoOrigin",
    "compass_deg_from_enu_rad",
    "ecef_from_geodetic",
    "enu_rad_from_compass_deg",
    "geodetic_from_ecef",
    "geodetic_from_enu",
    "wrap_pi",
]

WGS84_A_M = 6378137.0
"""WGS-84 semi-major axis a (m), as pymap3d's ``Ellipsoid.from_name("wgs84")``."""
WGS84_B_M = 6356752.31424518
"""WGS-84 semi-minor axis b (m), as pymap3d's."""
_E_M = math.sqrt(WGS84_A_M**2 - WGS84_B_M**2)
"""Linear eccentricity E = sqrt(a^2 - b^2) (m)."""
_NEAR_ZERO = 1e-8
"""numpy.isclose(v, 0)'s test, |v| <= 1e-8, as pymap3d uses it."""
_LAT_LIMIT_RAD = math.pi / 2 - 2.220446049250313e-16
"""pi/2 less float64's epsilon: pymap3d's clamp of the reduced latitude."""


def ecef_from_geodetic(lat_rad: float, lon_rad: float, alt_m: float) -> tuple[
    float, float, float
]:
    """ECEF (x, y, z) in metres of a geodetic point on WGS-84 (pymap3d's order)::

        N = a^2 / hypot(a cos(lat), b sin(lat))
        x = (N + h) cos(lat) cos(lon),  y = (N + h) cos(lat) sin(lon)
        z = (N (b/a)^2 + h) sin(lat)
    """
    a, b = WGS84_A_M, WGS84_B_M
    n_m = a**2 / math.hypot(a * math.cos(lat_rad), b * math.sin(lat_rad))
    return ((n_m + alt_m) * math.cos(lat_rad) * math.cos(lon_rad),
            (n_m + alt_m) * math.cos(lat_rad) * math.sin(lon_rad),
            (n_m * (b / a) ** 2 + alt_m) * math.sin(lat_rad))


def geodetic_from_ecef(x_m: float, y_m: float, z_m: float) -> tuple[float, float, float]:
    """(lat_rad, lon_rad, alt_m) of an ECEF point: You (2000), "Transformation of Cartesian
    to Geodetic Coordinates without Iterations", as pymap3d's ``ecef2geodetic``::

        r = |(x, y, z)|,   E = sqrt(a^2 - b^2)
        u = sqrt((r^2 - E^2) / 2 + hypot(r^2 - E^2, 2 E z) / 2)              (4a)
        beta = atan(hypot(u, E) / u * z / hypot(x, y))                      (4b)
        beta += (b u - a hypot(u, E) + E^2) sin(beta)
                / (a hypot(u, E) / cos(beta) - E^2 cos(beta))               (13)
        lat = atan(a / b tan(beta)),   lon = atan2(y, x)                     (4c)
        h = hypot(z - b sin(beta), hypot(x, y) - a cos(beta))               (7)

    negative inside the ellipsoid; beta is 0 or +-pi/2 where u or hypot(x, y) is 0. NaN
    in, NaN out; a point the equations cannot take (an infinite one) gives NaNs."""
    a, b, e = WGS84_A_M, WGS84_B_M, _E_M
    try:
        r = math.sqrt(x_m**2 + y_m**2 + z_m**2)
        u = math.sqrt(0.5 * (r**2 - e**2) + 0.5 * math.hypot(r**2 - e**2, 2 * e * z_m))
        hxy = math.hypot(x_m, y_m)
        hue = math.hypot(u, e)
        if abs(u) <= _NEAR_ZERO or abs(hxy) <= _NEAR_ZERO:
            beta = 0.0 if abs(z_m) <= _NEAR_ZERO else math.pi / 2 if z_m > 0 else -math.pi / 2
        else:
            beta = math.atan(hue / u * z_m / hxy)
            beta += ((b * u - a * hue + e**2) * math.sin(beta)) / (
                a * hue * 1 / math.cos(beta) - e**2 * math.cos(beta))
        lat = math.atan(a / b * math.tan(beta))
        cos_beta = math.cos(beta)
        if beta >= _LAT_LIMIT_RAD:
            lat, cos_beta = math.pi / 2, 0.0
        elif beta <= -_LAT_LIMIT_RAD:
            lat, cos_beta = -math.pi / 2, 0.0
        lon = math.atan2(y_m, x_m)
        alt = math.hypot(z_m - b * math.sin(beta), hxy - a * cos_beta)
    except (ValueError, ZeroDivisionError, OverflowError):
        return math.nan, math.nan, math.nan
    if x_m**2 / a**2 + y_m**2 / a**2 + z_m**2 / b**2 < 1:
        alt = -alt
    return lat, lon, alt


@functools.lru_cache(maxsize=16)
def _origin_frame(lat0_deg: float, lon0_deg: float, alt0_m: float) -> tuple[float, ...]:
    """An origin's ECEF (x0, y0, z0) and sin/cos of its latitude and longitude: the same
    for every point converted around it (a run has one origin, or a few)."""
    lat0, lon0 = math.radians(lat0_deg), math.radians(lon0_deg)
    return (*ecef_from_geodetic(lat0, lon0, alt0_m), math.sin(lat0), math.cos(lat0),
            math.sin(lon0), math.cos(lon0))


def geodetic_from_enu(east_m: float, north_m: float, up_m: float, lat0_deg: float,
                      lon0_deg: float, alt0_m: float) -> tuple[float, float, float]:
    """(lat_deg, lon_deg, alt_m) of a local ENU point around (lat0, lon0, h0): pymap3d's
    ``enu2geodetic`` for scalars. The ENU vector turned into ECEF (``enu2uvw``)::

        t = cos(lat0) up - sin(lat0) north,   w = sin(lat0) up + cos(lat0) north
        u = cos(lon0) t - sin(lon0) east,     v = sin(lon0) t + cos(lon0) east

    added to the origin's ECEF, then :func:`geodetic_from_ecef`."""
    x0, y0, z0, sin_lat0, cos_lat0, sin_lon0, cos_lon0 = _origin_frame(lat0_deg, lon0_deg,
                                                                       alt0_m)
    t = cos_lat0 * up_m - sin_lat0 * north_m
    w = sin_lat0 * up_m + cos_lat0 * north_m
    u = cos_lon0 * t - sin_lon0 * east_m
    v = sin_lon0 * t + cos_lon0 * east_m
    lat, lon, alt = geodetic_from_ecef(x0 + u, y0 + v, z0 + w)
    return math.degrees(lat), math.degrees(lon), alt


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
        """Local (east_m, north_m, up_m) of a geodetic point (pymap3d's ``geodetic2enu``,
        imported at the first call: a command that never converts a fix, ``gcs simulate``
        of a local scenario, does not pay its import, ~30 ms of CPU beside numpy)."""
        import pymap3d

        e, n, u = pymap3d.geodetic2enu(
            lat_deg, lon_deg, self.alt_m if alt_m is None else alt_m,
            self.lat_deg, self.lon_deg, self.alt_m,
        )
        return float(e), float(n), float(u)

    def to_geodetic(self, east_m: float, north_m: float, up_m: float = 0.0) -> tuple[
        float, float, float
    ]:
        """Geodetic (lat_deg, lon_deg, alt_m) of a local ENU point
        (:func:`geodetic_from_enu`)."""
        return geodetic_from_enu(float(east_m), float(north_m), float(up_m), self.lat_deg,
                                 self.lon_deg, self.alt_m)
