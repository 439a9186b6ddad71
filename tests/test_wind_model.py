"""The wind model (world/wind.py) and the wind triangle (domain/wind_triangle.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from domain.errors import ConfigError
from domain.wind_triangle import (
    crab_heading_rad,
    ground_speed_along_m_s,
    wind_from_vector,
    wind_vector_m_s,
)
from domain.yaml_fields import FieldError
from world.scenario import load_scenario, parse_scenario
from world.wind import GRID_S, WindField, WindSpec, parse_wind_text


@pytest.mark.parametrize(("from_deg", "expected"), [
    (0.0, (0.0, -1.0)),    # from the north: the air moves south
    (90.0, (-1.0, 0.0)),   # from the east: moves west
    (270.0, (1.0, 0.0)),   # from the west: moves east
])
def test_wind_vector_blows_away_from_its_compass_direction(
    from_deg: float, expected: tuple[float, float]
) -> None:
    wx, wy = wind_vector_m_s(10.0, from_deg)
    assert (wx, wy) == pytest.approx((10 * expected[0], 10 * expected[1]), abs=1e-9)
    speed, back = wind_from_vector(wx, wy)
    assert speed == pytest.approx(10.0)
    assert (back - from_deg + 180) % 360 - 180 == pytest.approx(0.0, abs=1e-9)


def test_crab_heading_makes_good_the_course() -> None:
    rng = np.random.default_rng(1)
    for _ in range(200):
        course = float(rng.uniform(-math.pi, math.pi))
        wind = (float(rng.uniform(-15, 15)), float(rng.uniform(-15, 15)))
        psi = crab_heading_rad(course, wind, 22.0)
        vg = (22.0 * math.cos(psi) + wind[0], 22.0 * math.sin(psi) + wind[1])
        # the ground velocity points along the course, at the predicted speed
        err = (math.atan2(vg[1], vg[0]) - course + math.pi) % (2 * math.pi) - math.pi
        assert abs(err) < 1e-9
        assert math.hypot(*vg) == pytest.approx(ground_speed_along_m_s(course, wind, 22.0))


def test_ground_speed_head_and_tail_wind_and_unflyable() -> None:
    assert ground_speed_along_m_s(0.0, (-10.0, 0.0), 22.0) == pytest.approx(12.0)
    assert ground_speed_along_m_s(0.0, (10.0, 0.0), 22.0) == pytest.approx(32.0)
    assert ground_speed_along_m_s(0.0, (-25.0, 0.0), 22.0) is None
    assert ground_speed_along_m_s(math.pi / 2, (25.0, 0.0), 22.0) is None


def test_gusts_are_seeded_stationary_and_order_free() -> None:
    spec = WindSpec(speed_m_s=10.0, from_deg=270.0, gust_m_s=2.0, gust_tau_s=5.0)
    a, b = WindField(spec, seed=7), WindField(spec, seed=7)
    times = [0.0, 3.3, 1000.0, 7.1, 3.3]
    first = [a.at(t) for t in times]
    assert [b.at(t) for t in reversed(times)] == list(reversed(first))
    assert first[1] == first[4]
    assert WindField(spec, seed=8).at(3.3) != first[1]
    samples = np.array([a.at(k * GRID_S) for k in range(0, 36000, 10)])
    assert samples[:, 0].mean() == pytest.approx(10.0, abs=0.5)
    assert samples[:, 1].std() == pytest.approx(2.0, rel=0.25)
    # correlation over one tau is about exp(-1)
    g = samples[:, 1]
    lag = int(5.0 / (10 * GRID_S))
    rho = float(np.corrcoef(g[:-lag], g[lag:])[0, 1])
    assert rho == pytest.approx(math.exp(-1), abs=0.15)


def test_calm_is_the_default_and_steady_wind_has_no_gusts() -> None:
    assert load_scenario("paper-boat").wind.calm
    field = WindField(WindSpec(speed_m_s=8.0, from_deg=0.0), seed=1)
    assert field.at(0.0) == field.at(500.0) == pytest.approx((0.0, -8.0))


def test_wind_text_and_scenario_errors_are_one_line() -> None:
    assert parse_wind_text("10,270").mean_xy_m_s == pytest.approx((10.0, 0.0))
    assert parse_wind_text("5, 90, 1.5").gust_m_s == 1.5
    for bad in ("10", "a,b", "10,400", "nan,3", "-1,0", "100,0", "1,2,3,4"):
        with pytest.raises(ConfigError) as info:
            parse_wind_text(bad)
        assert "\n" not in str(info.value) and str(info.value).startswith("--wind")
    spec = parse_scenario({"wind": {"speed_m_s": 12, "from_deg": 45, "gust_m_s": 1}}).wind
    assert (spec.speed_m_s, spec.from_deg, spec.gust_m_s) == (12, 45, 1)
    for bad_wind, field_name in (({"speed_m_s": -1}, "wind.speed_m_s"),
                                 ({"from_deg": 361}, "wind.from_deg"),
                                 ({"gust_tau_s": 0}, "wind.gust_tau_s"),
                                 ({"knots": 3}, "wind.knots")):
        with pytest.raises(FieldError) as err:
            parse_scenario({"wind": bad_wind})
        assert str(err.value).startswith(field_name)
