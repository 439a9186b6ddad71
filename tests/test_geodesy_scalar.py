"""``domain.geodesy.geodetic_from_enu``: pymap3d's ``enu2geodetic`` written out for scalars
must give pymap3d's answer (to float rounding) everywhere floe flies and beyond."""

from __future__ import annotations

import math
import random

import pymap3d
import pytest

from domain.geodesy import GeoOrigin, geodetic_from_ecef, geodetic_from_enu

ORIGINS = [(78.9, 11.9, 0.0), (0.0, 0.0, 0.0), (-45.3, 170.2, 35.0), (63.4, -179.99, 0.0),
           (89.99, 30.0, 0.0), (-89.5, -120.0, 5.0), (47.4, 8.5, 420.0)]


@pytest.mark.parametrize(("lat0", "lon0", "h0"), ORIGINS)
def test_matches_pymap3d_within_float_rounding(lat0: float, lon0: float, h0: float) -> None:
    rng = random.Random(f"{lat0},{lon0}")
    for _ in range(400):
        e, n, u = rng.uniform(-60e3, 60e3), rng.uniform(-60e3, 60e3), rng.uniform(-200, 4e3)
        got = geodetic_from_enu(e, n, u, lat0, lon0, h0)
        want = [float(v) for v in pymap3d.enu2geodetic(e, n, u, lat0, lon0, h0)]
        assert got[0] == pytest.approx(want[0], abs=1e-12)
        assert (got[1] - want[1] + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-12)
        assert got[2] == pytest.approx(want[2], abs=1e-8)


def test_the_origin_maps_to_itself_and_gcs_origin_uses_it() -> None:
    origin = GeoOrigin(78.9, 11.9, 12.0)
    lat, lon, alt = origin.to_geodetic(0.0, 0.0, 0.0)
    assert (lat, lon, alt) == pytest.approx((78.9, 11.9, 12.0), abs=1e-9)
    # a point 1 km north is 1 km north again through the inverse (pymap3d's geodetic2enu)
    back = origin.to_local(*origin.to_geodetic(0.0, 1000.0, 0.0))
    assert back == pytest.approx((0.0, 1000.0, 0.0), abs=1e-3)
    assert isinstance(lat, float) and isinstance(lon, float) and isinstance(alt, float)


def test_poles_centre_and_bad_input() -> None:
    a, b = 6378137.0, 6356752.31424518
    assert geodetic_from_ecef(0.0, 0.0, b + 10.0) == pytest.approx((math.pi / 2, 0.0, 10.0))
    assert geodetic_from_ecef(0.0, 0.0, -b - 10.0) == pytest.approx((-math.pi / 2, 0.0, 10.0))
    lat, lon, alt = geodetic_from_ecef(a - 5.0, 0.0, 0.0)  # below the surface: negative
    assert (lat, lon) == pytest.approx((0.0, 0.0)) and alt == pytest.approx(-5.0)
    assert all(math.isnan(v) for v in geodetic_from_enu(math.nan, 0.0, 0.0, 78.9, 11.9, 0.0))
    lat, _lon, alt = geodetic_from_enu(math.inf, 0.0, 0.0, 78.9, 11.9, 0.0)
    assert math.isnan(lat) and math.isnan(alt)
