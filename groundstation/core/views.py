"""The decision core's read model: what every frontend, display and report may know of it.

:meth:`DecisionCore.view() <groundstation.core.decision.DecisionCore.view>` builds one
frozen :class:`CoreView` on request: every track with its status, the search cells with
their value now, the wind estimate and the vehicles as the core sees them. Frontends (the
daemon, ``gcs simulate``, ``gcs replay``), the console, the control API's ``state()`` and
the live map read this and nothing else of the core; the journal's ``track``, ``truth`` and
``search`` lines are written from it by ``core/records.py``. A view is a copy: the floats
are the core's own (bit for bit), and nothing a reader does changes the core.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from groundstation.core.fleet import FleetStatus
from groundstation.core.watch import WatchView
from groundstation.core.wind_estimate import WindState
from planner.search_cells import SearchCell

__all__ = ["CoreView", "SearchCellView", "TrackView", "VehicleView", "search_cell_view"]

TENTATIVE = "tentative"


@dataclass(frozen=True, init=False)
class TrackView:
    """One track: ``status`` is ``tentative``, ``confirmed`` or ``prior``; ``sigma_m2`` is
    ``trace(P_xy)``; ``existence`` the tracker's probability that it is a real iceberg
    (1 for a track the core added while no tracker exists); ``t_s`` the estimate's time;
    velocity, ``cov_xy = (Pxx, Pxy, Pyy)``, ``lost`` (``sqrt(sigma) > fov_radius_m``) and
    the last accepted measurement's time (None: never) as ``observer.TrackSnapshot``.

    One per track in every view (a view a mission second offline), so its ``__init__`` is
    written out like ``events.Telemetry``'s: the instance's ``__dict__`` filled at once
    (0.7 us against 1.8 us for the frozen dataclass's twelve ``object.__setattr__``);
    the same value, as frozen (tests/test_core_fast_paths.py)."""

    id: str
    status: str
    x_m: float
    y_m: float
    sigma_m2: float
    existence: float
    t_s: float
    vx_m_s: float = 0.0
    vy_m_s: float = 0.0
    cov_xy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    lost: bool = False
    last_seen_s: float | None = None

    def __init__(self, id: str, status: str, x_m: float, y_m: float, sigma_m2: float,
                 existence: float, t_s: float, vx_m_s: float = 0.0, vy_m_s: float = 0.0,
                 cov_xy: tuple[float, float, float] = (0.0, 0.0, 0.0), lost: bool = False,
                 last_seen_s: float | None = None) -> None:
        self.__dict__.update(id=id, status=status, x_m=x_m, y_m=y_m, sigma_m2=sigma_m2,
                             existence=existence, t_s=t_s, vx_m_s=vx_m_s, vy_m_s=vy_m_s,
                             cov_xy=cov_xy, lost=lost, last_seen_s=last_seen_s)

    @property
    def sigma(self) -> float:
        """``sigma_m2`` under the observer's name (metrics read either)."""
        return self.sigma_m2

    @property
    def firm(self) -> bool:
        """A confirmed or prior track (tentative ones are candidates, not icebergs)."""
        return self.status != TENTATIVE


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


@dataclass(frozen=True)
class VehicleView:
    """One vehicle as the core sees it: pose, status (``core/fleet.py``), the target it
    was last sent to and its planned sequence, busy (flying a leg or loitering)."""

    id: str
    status: FleetStatus
    x_m: float
    y_m: float
    heading_rad: float
    target: str | None
    route: tuple[str, ...]
    busy: bool


@dataclass(frozen=True)
class CoreView:
    """The core at mission time ``t_s`` (module docstring). ``searching`` is whether the
    core keeps search cells at all (``search_cells`` is then every cell, by id);
    ``wind_outliers`` the vehicles whose wind reports are flagged (``core/wind_estimate.py``);
    ``plans_adopted`` how many plans the core has adopted."""

    t_s: float
    tracks: tuple[TrackView, ...]
    search_cells: tuple[SearchCellView, ...]
    searching: bool
    wind: WindState
    vehicles: tuple[VehicleView, ...]
    observer_counters: Mapping[str, int] = field(default_factory=dict)
    wind_outliers: frozenset[str] = frozenset()
    plans_adopted: int = 0
    watch: WatchView | None = None
    """The ship watch (``core/watch.py``); None without one."""

    @property
    def target_ids(self) -> frozenset[str]:
        return frozenset(v.id for v in self.tracks)

    def track(self, track_id: str) -> TrackView | None:
        return next((v for v in self.tracks if v.id == track_id), None)

    def firm_tracks(self) -> tuple[TrackView, ...]:
        """The confirmed and prior tracks: what the uncertainty is measured over."""
        return tuple(v for v in self.tracks if v.firm)

    def status(self) -> dict[str, str]:
        return {v.id: v.status for v in self.tracks}
