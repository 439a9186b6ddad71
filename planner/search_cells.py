"""Search cells: where nobody has looked for a while, as visit targets with a growing value.

The operating area ``[x_min, x_max] x [y_min, y_max]`` is cut into ``nx x ny`` cells,
``nx = ceil((x_max - x_min) / cell_m)`` (likewise ``ny``), so each cell is
``dx = (x_max - x_min) / nx`` by ``dy = (y_max - y_min) / ny`` metres (``cell_m`` square
when the area divides). Cell ``S{i}-{j}`` (column ``i``, row ``j``, from 0) has its centre at
``(x_min + (i + 1/2) dx, y_min + (j + 1/2) dy)``.

A camera frame *covers* every cell whose centre lies in its footprint disc
(:meth:`SearchGrid.cover`). A cell's value at mission time ``t`` is::

    value_c(t) = w_c * g * (t - t_c)            [m^2]

with ``g`` = ``growth_m2_per_s``, ``t_c`` the last time a frame covered it (the grid's start
``t0_s`` if never) and the weight ``w_c`` from the prior density of icebergs::

    k(d) = exp(-d^2 / (2 h^2)),  h = cell_m           (Gaussian kernel, bandwidth one cell)
    rho_c = sum over prior points p of k(|centre_c - p|)
    w_c = 1 + prior_weight * rho_c / mean_c(rho_c)    (w_c = 1 without prior points)

so the mean weight is ``1 + prior_weight`` and a cell near many listed icebergs is worth
more. The value is in m^2, the unit of a track's uncertainty ``sigma = trace(P_xy)``, so a
planner that weighs tracks by sigma weighs cells alike: a cell unseen for ``T`` seconds is
worth a track of ``sigma = w g T``. Only the ``max_cells`` most valuable cells (value > 0,
ties broken by id) are offered to the planner (:meth:`SearchGrid.top`), so the problem
stays small.

Pure: no clock, no I/O, no randomness; time is an argument.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

__all__ = ["Area", "SearchCell", "SearchConfig", "SearchGrid"]

MAX_GRID_CELLS = 10_000


class Area(Protocol):
    """The operating area's bounds (``world.scenario``'s ``AreaSpec`` has them)."""

    @property
    def x_min_m(self) -> float: ...
    @property
    def x_max_m(self) -> float: ...
    @property
    def y_min_m(self) -> float: ...
    @property
    def y_max_m(self) -> float: ...


def _positive(name: str, value: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"search.{name} must be a number, got {value!r}")
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"search.{name} must be finite and > 0, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class SearchConfig:
    """The search model's parameters (module docstring)."""

    cell_m: float = 300.0
    growth_m2_per_s: float = 50.0
    max_cells: int = 4
    prior_weight: float = 1.0

    def __post_init__(self) -> None:
        _positive("cell_m", self.cell_m)
        _positive("growth_m2_per_s", self.growth_m2_per_s)
        if isinstance(self.max_cells, bool) or not isinstance(self.max_cells, int) or (
            self.max_cells < 0
        ):
            raise ValueError(f"search.max_cells must be an integer >= 0, got {self.max_cells!r}")
        w = self.prior_weight
        if isinstance(w, bool) or not isinstance(w, (int, float)) or not math.isfinite(w) or (
            w < 0
        ):
            raise ValueError(f"search.prior_weight must be finite and >= 0, got {w!r}")


@dataclass(frozen=True)
class SearchCell:
    """One cell as the planner and the displays see it."""

    id: str
    x_m: float
    y_m: float
    size_m: float
    weight: float
    value_m2: float
    last_covered_s: float | None


class SearchGrid:
    """The operating area's search cells and when a camera last covered each."""

    def __init__(
        self,
        area: Area,
        config: SearchConfig,
        prior_points: Sequence[tuple[float, float]] = (),
        *,
        t0_s: float = 0.0,
    ) -> None:
        bounds = (area.x_min_m, area.x_max_m, area.y_min_m, area.y_max_m)
        if not all(math.isfinite(b) for b in bounds):
            raise ValueError(f"search area bounds must be finite, got {bounds!r}")
        x0, x1, y0, y1 = (float(b) for b in bounds)
        if not (x1 > x0 and y1 > y0):
            raise ValueError(f"search area must have x_max > x_min and y_max > y_min, "
                             f"got {bounds!r}")
        if not math.isfinite(t0_s):
            raise ValueError(f"t0_s must be finite, got {t0_s!r}")
        self.config = config
        nx = max(1, math.ceil((x1 - x0) / config.cell_m - 1e-9))
        ny = max(1, math.ceil((y1 - y0) / config.cell_m - 1e-9))
        if nx * ny > MAX_GRID_CELLS:
            raise ValueError(f"search.cell_m {config.cell_m:g} gives {nx * ny} cells over the "
                             f"area (at most {MAX_GRID_CELLS})")
        dx, dy = (x1 - x0) / nx, (y1 - y0) / ny
        self.size_m = dx
        self._t0_s = float(t0_s)
        self._ids: list[str] = []
        self._centres: list[tuple[float, float]] = []
        for i in range(nx):
            for j in range(ny):
                self._ids.append(f"S{i}-{j}")
                self._centres.append((x0 + (i + 0.5) * dx, y0 + (j + 0.5) * dy))
        self._weights = [1.0] * len(self._centres)
        self.set_prior_points(prior_points)
        self._last: list[float | None] = [None] * len(self._ids)
        self._index = {cid: k for k, cid in enumerate(self._ids)}

    def set_prior_points(self, points: Sequence[tuple[float, float]]) -> None:
        """Recompute the cells' weights from the prior's points (module docstring);
        non-finite points are ignored."""
        self._weights = self._prior_weights(points)

    def _prior_weights(self, points: Sequence[tuple[float, float]]) -> list[float]:
        pts = [(float(x), float(y)) for x, y in points if math.isfinite(x) and math.isfinite(y)]
        if not pts or self.config.prior_weight == 0:
            return [1.0] * len(self._centres)
        h2 = 2.0 * self.config.cell_m**2
        rho = [sum(math.exp(-((cx - px) ** 2 + (cy - py) ** 2) / h2) for px, py in pts)
               for cx, cy in self._centres]
        mean = sum(rho) / len(rho)
        if not mean > 0:
            return [1.0] * len(self._centres)
        return [1.0 + self.config.prior_weight * r / mean for r in rho]

    @property
    def ids(self) -> list[str]:
        return list(self._ids)

    def __contains__(self, cell_id: object) -> bool:
        return cell_id in self._index

    def centre(self, cell_id: str) -> tuple[float, float]:
        """A cell's centre (the point a vehicle is sent to). Raises KeyError if unknown."""
        return self._centres[self._index[cell_id]]

    def cover(self, t_s: float, x_m: float, y_m: float, radius_m: float) -> int:
        """Mark every cell whose centre lies in the disc as covered at ``t_s``; returns how
        many. Non-finite input covers nothing; a frame older than a cell's last cover does
        not move it back."""
        if not all(math.isfinite(v) for v in (t_s, x_m, y_m, radius_m)) or radius_m <= 0:
            return 0
        r2 = radius_m * radius_m
        count = 0
        for k, (cx, cy) in enumerate(self._centres):
            if (cx - x_m) ** 2 + (cy - y_m) ** 2 <= r2:
                last = self._last[k]
                if last is None or t_s > last:
                    self._last[k] = float(t_s)
                count += 1
        return count

    def last_covered_s(self, cell_id: str) -> float | None:
        """When a footprint last covered the cell's centre (None: never)."""
        return self._last[self._index[cell_id]]

    def value_m2(self, cell_id: str, t_s: float) -> float:
        k = self._index[cell_id]
        return self._value(k, t_s)

    def _value(self, k: int, t_s: float) -> float:
        last = self._last[k]
        since = self._t0_s if last is None else last
        return self._weights[k] * self.config.growth_m2_per_s * max(0.0, t_s - since)

    def values(self, t_s: float) -> list[SearchCell]:
        """Every cell with its value at ``t_s``, in id order (columns, then rows)."""
        return [
            SearchCell(cid, cx, cy, self.size_m, self._weights[k], self._value(k, t_s),
                       self._last[k])
            for k, (cid, (cx, cy)) in enumerate(zip(self._ids, self._centres, strict=True))
        ]

    def top(self, t_s: float, exclude: frozenset[str] | set[str] = frozenset()) -> list[SearchCell]:
        """The ``max_cells`` most valuable cells with a positive value, not in ``exclude``
        (cells a vehicle already heads for), most valuable first (ties: by id)."""
        cells = [c for c in self.values(t_s) if c.value_m2 > 0 and c.id not in exclude]
        cells.sort(key=lambda c: (-c.value_m2, c.id))
        return cells[: self.config.max_cells]
