"""What the displays (live map, status, report) show of the tracks and the search cells."""

from __future__ import annotations

from dataclasses import dataclass

from planner.search_cells import SearchCell

__all__ = ["SearchCellView", "TrackView", "search_cell_view"]


@dataclass(frozen=True)
class TrackView:
    """One track: ``status`` is ``tentative``, ``confirmed`` or ``prior``; ``sigma_m2`` is
    ``trace(P_xy)``; ``existence`` the tracker's probability that it is a real iceberg
    (1 for a track the core added while no tracker exists); ``t_s`` the estimate's time."""

    id: str
    status: str
    x_m: float
    y_m: float
    sigma_m2: float
    existence: float
    t_s: float


@dataclass(frozen=True)
class SearchCellView:
    """One search cell (``planner/search_cells.py``): centre, side, value now, and when a
    camera last covered it (None: never)."""

    id: str
    x_m: float
    y_m: float
    size_m: float
    value_m2: float
    last_covered_s: float | None


def search_cell_view(cell: SearchCell) -> SearchCellView:
    return SearchCellView(cell.id, cell.x_m, cell.y_m, cell.size_m, cell.value_m2,
                          cell.last_covered_s)
