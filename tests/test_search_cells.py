"""Search cells: values grow with time since a camera covered them, weighted by the prior."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from planner.search_cells import SearchConfig, SearchGrid


@dataclass(frozen=True)
class Area:
    x_min_m: float
    x_max_m: float
    y_min_m: float
    y_max_m: float


AREA = Area(0.0, 3000.0, 0.0, 3000.0)


def test_cells_tile_the_area_and_values_grow_and_reset_when_covered() -> None:
    grid = SearchGrid(AREA, SearchConfig(cell_m=300.0, growth_m2_per_s=50.0, max_cells=4,
                                         prior_weight=0.0))
    cells = grid.values(0.0)
    assert len(cells) == 100 and grid.size_m == 300.0
    assert grid.centre("S0-0") == (150.0, 150.0) and grid.centre("S9-9") == (2850.0, 2850.0)
    assert all(c.value_m2 == 0.0 for c in cells)
    assert grid.value_m2("S3-7", 20.0) == pytest.approx(50.0 * 20.0)
    # a footprint of 150 m around (1050, 2250) holds the centre of S3-7 only
    assert grid.cover(20.0, 1050.0, 2250.0, 150.0) == 1
    assert grid.value_m2("S3-7", 20.0) == 0.0
    assert grid.value_m2("S3-7", 30.0) == pytest.approx(50.0 * 10.0)
    assert grid.value_m2("S3-6", 30.0) == pytest.approx(50.0 * 30.0)
    # an older frame does not move the cover back
    grid.cover(5.0, 1050.0, 2250.0, 150.0)
    assert grid.value_m2("S3-7", 30.0) == pytest.approx(50.0 * 10.0)
    top = grid.top(30.0)
    assert len(top) == 4 and "S3-7" not in {c.id for c in top}
    assert next(c.id for c in grid.top(30.0, exclude={top[0].id})) == top[1].id
    assert grid.cover(40.0, float("nan"), 0.0, 150.0) == 0


def test_prior_points_weight_the_cells_near_them() -> None:
    config = SearchConfig(cell_m=300.0, growth_m2_per_s=1.0, max_cells=2, prior_weight=1.0)
    grid = SearchGrid(AREA, config, [(150.0, 150.0), (450.0, 150.0)])
    weights = {c.id: c.weight for c in grid.values(10.0)}
    assert sum(weights.values()) / len(weights) == pytest.approx(2.0)  # 1 + prior_weight
    assert weights["S0-0"] > weights["S5-5"] > 1.0 - 1e-12
    assert {c.id for c in grid.top(10.0)} == {"S0-0", "S1-0"}
    grid.set_prior_points([])
    assert {c.weight for c in grid.values(10.0)} == {1.0}


@pytest.mark.parametrize("bad", [
    {"cell_m": 0.0}, {"cell_m": float("nan")}, {"growth_m2_per_s": -1.0},
    {"max_cells": -1}, {"max_cells": 2.5}, {"prior_weight": float("inf")},
])
def test_bad_settings_name_the_field(bad: dict) -> None:
    with pytest.raises(ValueError, match=f"search.{next(iter(bad))}"):
        SearchConfig(**bad)


def test_bad_area_and_too_many_cells_are_refused() -> None:
    with pytest.raises(ValueError, match="x_max > x_min"):
        SearchGrid(Area(10.0, 0.0, 0.0, 1.0), SearchConfig())
    with pytest.raises(ValueError, match="cells over the area"):
        SearchGrid(Area(0.0, 1e6, 0.0, 1e6), SearchConfig(cell_m=1.0))
