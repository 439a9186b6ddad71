"""The scenario fields of discovery: the camera's faults, the operating area, the prior
list of icebergs, the tracker's settings and the search (issue 13).

YAML (every section optional; absent, a scenario behaves as before these fields existed,
except that the camera is unlabelled unless ``camera.labelled`` is true)::

    camera:  {pd: 0.85, clutter_per_frame: 0.1, labelled: false}
    targets: {known: false, ...}            # read by world.scenario, see targets_known
    area:    {x_m: [0, 3000], y_m: [0, 3000]}
    prior:   {listed: 8, max_age_s: 600, phantoms: 1, sigma_m: 30}
    # or     prior: {list: [{id: P1, x_m: 10, y_m: 20, age_s: 300, sigma_m: 30, truth: T4}]}
    tracker: {association: gnn, confirm_hits: 3, confirm_window: 5, existence_delete: 0.05}
    search:  {cell_m: 300, growth_m2_per_s: 50, max_cells: 4, prior_weight: 1.0}

Bad values and unknown keys raise :class:`~domain.yaml_fields.FieldError` naming the dotted
field (``camera.pd: must be in (0, 1], got 0``).

The generated prior (:func:`resolve_prior`) is a satellite pass before the mission: it lists
``listed`` of the icebergs present at ``t = 0``, each seen ``age_s ~ U[0, max_age_s]`` ago,
so its listed position is where the iceberg was then, measured with noise ``sigma_m`` per
axis::

    x_listed = x0 - vx age + e_x,   y_listed = y0 - vy age + e_y,   e ~ N(0, sigma_m^2 I)

plus ``phantoms`` entries uniform in the area that match no iceberg (``truth_id`` None).
Ids ``P1 .. Pn`` follow a seeded random order, so an id says nothing about the truth. All of
it is drawn from ``numpy.random.default_rng([seed, 0x9E1])``, never from the run's
generator, so a prior never changes the icebergs, the camera or anything else of a run.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from domain.limits import MAX_COORDINATE_M, MAX_DURATION_S, MAX_SPEED_M_S, MAX_TARGETS
from domain.yaml_fields import FieldError, Fields, check_number
from world.model import Camera

__all__ = [
    "MAX_CLUTTER_PER_FRAME",
    "MAX_SEARCH_CELLS",
    "PRIOR_STREAM",
    "TRACKER_KEYS",
    "AreaSpec",
    "CameraSpec",
    "PriorEntry",
    "PriorSpec",
    "SearchSpec",
    "discovery_mode",
    "parse_area",
    "parse_camera",
    "parse_prior",
    "parse_search",
    "parse_tracker",
    "resolve_prior",
    "scenario_camera",
]

PRIOR_STREAM = 0x9E1
"""The second word of the prior's seed: ``default_rng([seed, PRIOR_STREAM])``."""
MAX_CLUTTER_PER_FRAME = 1000.0
"""False alarms per frame beyond this are a typo, not a camera."""
MAX_SEARCH_CELLS = 10_000
"""Search cells in the area (ceil(width / cell) * ceil(height / cell)) at most."""

TRACKER_KEYS = (
    "association",
    "confirm_hits",
    "confirm_window",
    "existence_delete",
    "existence_confirm_min",
    "new_track_vel_var_m2_s2",
    "gate_probability",
    "lost_sigma_m",
)
"""The keys of ``tracker:`` (observer.TrackerConfig's fields a scenario may set)."""


@dataclass(frozen=True)
class CameraSpec:
    """The camera's faults: each iceberg in view detected with probability ``pd``; a
    Poisson number of false alarms (mean ``clutter_per_frame``) uniform over the footprint
    disc; ``labelled`` detections carry the iceberg's id, else ``target: null``."""

    pd: float = 1.0
    clutter_per_frame: float = 0.0
    labelled: bool = False

    @property
    def classic(self) -> bool:
        """The paper's camera: labelled, never misses, never lies (no frames needed)."""
        return self.labelled and self.pd == 1.0 and self.clutter_per_frame == 0.0


@dataclass(frozen=True)
class AreaSpec:
    """The operating area, a rectangle in local metres (bounds included)."""

    x_min_m: float
    x_max_m: float
    y_min_m: float
    y_max_m: float

    def contains(self, x_m: float, y_m: float) -> bool:
        return self.x_min_m <= x_m <= self.x_max_m and self.y_min_m <= y_m <= self.y_max_m

    @property
    def centre_m(self) -> tuple[float, float]:
        return 0.5 * (self.x_min_m + self.x_max_m), 0.5 * (self.y_min_m + self.y_max_m)


@dataclass(frozen=True)
class PriorEntry:
    """One iceberg of the prior list: listed position, age of the listing (s), position
    standard deviation per axis (m), and the true iceberg (None: a phantom). ``drift_m_s``:
    the standard deviation per axis of the drift the ground station assumes for a stale
    listing, so the variance it announces per axis is::

        variance_m2 = sigma_m^2 + (drift_m_s * age_s)^2
    """

    id: str
    x_m: float
    y_m: float
    age_s: float
    sigma_m: float
    truth_id: str | None
    drift_m_s: float = 0.0

    @property
    def variance_m2(self) -> float:
        """The announced position variance per axis (m^2), the class docstring's."""
        return self.sigma_m**2 + (self.drift_m_s * self.age_s) ** 2


@dataclass(frozen=True)
class PriorSpec:
    """A generated prior (``listed``, ``max_age_s``, ``phantoms``, ``sigma_m``) or an
    explicit list (``entries``; then the generated counts are 0)."""

    listed: int = 0
    max_age_s: float = 0.0
    phantoms: int = 0
    sigma_m: float = 30.0
    entries: tuple[PriorEntry, ...] = ()
    drift_m_s: float = 0.0


@dataclass(frozen=True)
class SearchSpec:
    """Search cells of ``cell_m`` over the area; value grows by ``growth_m2_per_s`` per
    second since a camera last covered a cell, weighted by ``1 + prior_weight * density``;
    the planner considers at most ``max_cells`` cells at a time (planner/search_cells.py)."""

    cell_m: float = 300.0
    growth_m2_per_s: float = 50.0
    max_cells: int = 4
    prior_weight: float = 1.0


class _Target(Protocol):
    """What :func:`resolve_prior` reads of a ``world.scenario.TargetSpec`` (world.scenario
    imports this module, so it is named by shape, not imported)."""

    @property
    def id(self) -> str: ...
    @property
    def x_m(self) -> float: ...
    @property
    def y_m(self) -> float: ...
    @property
    def vx_m_s(self) -> float: ...
    @property
    def vy_m_s(self) -> float: ...
    @property
    def appear_s(self) -> float: ...


class _Fleet(Protocol):
    @property
    def fov_radius_m(self) -> float: ...


class _Observer(Protocol):
    @property
    def camera_rate_hz(self) -> float: ...
    @property
    def r_m2(self) -> float: ...


class _Scenario(Protocol):
    """What this module reads of a ``world.scenario.Scenario``."""

    @property
    def prior(self) -> PriorSpec | None: ...
    @property
    def area(self) -> AreaSpec | None: ...
    @property
    def camera(self) -> CameraSpec: ...
    @property
    def fleet(self) -> _Fleet: ...
    @property
    def observer(self) -> _Observer: ...
    @property
    def search(self) -> SearchSpec | None: ...


def discovery_mode(scenario: _Scenario) -> bool:
    """Whether the ground station must find the icebergs itself: an unlabelled camera, a
    prior or search. The offline runner and the daemon's scenario world both ask this."""
    return not scenario.camera.labelled or scenario.prior is not None or (
        scenario.search is not None)


def _in_unit(f: Fields, key: str, default: float, *, closed_low: bool = False,
             closed_high: bool = True) -> float:
    """A probability, with the interval in the error message: ``camera.pd: must be in
    (0, 1], got 0``."""
    raw = f.raw(key)
    if raw is None:
        return default
    path = f.path_of(key)
    value = check_number(path, raw)
    low_ok = value >= 0.0 if closed_low else value > 0.0
    high_ok = value <= 1.0 if closed_high else value < 1.0
    if not (low_ok and high_ok):
        interval = f"{'[' if closed_low else '('}0, 1{']' if closed_high else ')'}"
        raise FieldError(path, f"must be in {interval}, got {value:g}")
    return value


def parse_camera(f: Fields) -> CameraSpec:
    spec = CameraSpec(
        pd=_in_unit(f, "pd", 1.0),
        clutter_per_frame=f.number("clutter_per_frame", 0.0, minimum=0.0,
                                   maximum=MAX_CLUTTER_PER_FRAME),
        labelled=f.boolean("labelled", False),
    )
    f.done()
    return spec


def parse_area(f: Fields) -> AreaSpec:
    x = f.range_pair("x_m", (math.nan, math.nan), limit=MAX_COORDINATE_M)
    y = f.range_pair("y_m", (math.nan, math.nan), limit=MAX_COORDINATE_M)
    for key, (lo, hi) in (("x_m", x), ("y_m", y)):
        if math.isnan(lo):
            raise FieldError(f.path_of(key), "is required (a [low, high] pair in metres)")
        if not hi > lo:
            raise FieldError(f.path_of(key), f"must have high > low, got [{lo:g}, {hi:g}]")
    f.done()
    return AreaSpec(x[0], x[1], y[0], y[1])


def _parse_prior_item(f: Fields, sigma_m: float) -> PriorEntry:
    entry = PriorEntry(
        id=f.string("id"),
        x_m=f.number("x_m", minimum=-MAX_COORDINATE_M, maximum=MAX_COORDINATE_M),
        y_m=f.number("y_m", minimum=-MAX_COORDINATE_M, maximum=MAX_COORDINATE_M),
        age_s=f.number("age_s", 0.0, minimum=0.0, maximum=MAX_DURATION_S),
        sigma_m=f.number("sigma_m", sigma_m, minimum=0.0, exclusive_minimum=True,
                         maximum=MAX_COORDINATE_M),
        truth_id=f.string("truth") if f.has("truth") else None,
    )
    f.raw("truth")
    if not entry.id:
        raise FieldError(f.path_of("id"), "must not be empty")
    f.done()
    return entry


def parse_prior(f: Fields, area: AreaSpec | None, target_count: int) -> PriorSpec:
    """``prior:``; ``target_count`` is the scenario's listed plus random icebergs."""
    sigma_m = f.number("sigma_m", 30.0, minimum=0.0, exclusive_minimum=True,
                       maximum=MAX_COORDINATE_M)
    drift_m_s = f.number("drift_m_s", 0.0, minimum=0.0, maximum=MAX_SPEED_M_S)
    items = f.items("list")
    if items:
        for key in ("listed", "max_age_s", "phantoms"):
            if f.has(key):
                raise FieldError(f.path_of(key), "cannot be given with prior.list")
        entries = tuple(_parse_prior_item(Fields(item, f"{f.path_of('list')}[{i}]"), sigma_m)
                        for i, item in enumerate(items))
        ids = [e.id for e in entries]
        twice = sorted({i for i in ids if ids.count(i) > 1})
        if twice:
            raise FieldError(f.path_of("list"), f"duplicate id {twice[0]!r}")
        f.done()
        return PriorSpec(sigma_m=sigma_m, entries=entries, drift_m_s=drift_m_s)
    spec = PriorSpec(
        listed=f.integer("listed", 0, minimum=0, maximum=MAX_TARGETS),
        max_age_s=f.number("max_age_s", 0.0, minimum=0.0, maximum=MAX_DURATION_S),
        phantoms=f.integer("phantoms", 0, minimum=0, maximum=MAX_TARGETS),
        sigma_m=sigma_m,
        drift_m_s=drift_m_s,
    )
    if spec.listed > target_count:
        raise FieldError(f.path_of("listed"),
                         f"lists {spec.listed} icebergs but the scenario has {target_count}")
    if spec.phantoms and area is None:
        raise FieldError(f.path_of("phantoms"), "needs an area (phantoms are drawn in it)")
    f.done()
    return spec


def parse_tracker(f: Fields) -> dict[str, float | int | str]:
    """``tracker:`` as a plain mapping of the keys given (observer.TrackerConfig checks
    it again); ranges are checked here so a typo names the field."""
    out: dict[str, float | int | str] = {}
    if f.has("association"):
        out["association"] = f.string("association", choices=("gnn", "jpda"))
    for key in ("confirm_hits", "confirm_window"):
        if f.has(key):
            out[key] = f.integer(key, minimum=1, maximum=1000)
    hits, window = out.get("confirm_hits"), out.get("confirm_window")
    if isinstance(hits, int) and isinstance(window, int) and hits > window:
        raise FieldError(f.path_of("confirm_hits"),
                         f"must be <= confirm_window ({window}), got {hits}")
    if f.has("existence_delete"):
        out["existence_delete"] = _in_unit(f, "existence_delete", 0.0, closed_high=False)
    if f.has("existence_confirm_min"):
        out["existence_confirm_min"] = _in_unit(f, "existence_confirm_min", 0.0)
    if f.has("gate_probability"):
        out["gate_probability"] = _in_unit(f, "gate_probability", 0.0, closed_high=False)
    if f.has("new_track_vel_var_m2_s2"):
        out["new_track_vel_var_m2_s2"] = f.number(
            "new_track_vel_var_m2_s2", minimum=0.0, exclusive_minimum=True, maximum=1e6)
    if f.has("lost_sigma_m"):
        out["lost_sigma_m"] = f.number("lost_sigma_m", minimum=0.0, exclusive_minimum=True,
                                       maximum=1e7)
    delete, confirm = out.get("existence_delete"), out.get("existence_confirm_min")
    if isinstance(delete, float) and isinstance(confirm, float) and delete >= confirm:
        raise FieldError(f.path_of("existence_delete"),
                         f"must be below existence_confirm_min ({confirm:g}), got {delete:g}")
    f.done()
    return out


def parse_search(f: Fields, area: AreaSpec | None) -> SearchSpec:
    spec = SearchSpec(
        cell_m=f.number("cell_m", 300.0, minimum=0.0, exclusive_minimum=True,
                        maximum=MAX_COORDINATE_M),
        growth_m2_per_s=f.number("growth_m2_per_s", 50.0, minimum=0.0,
                                 exclusive_minimum=True, maximum=1e9),
        max_cells=f.integer("max_cells", 4, minimum=1, maximum=MAX_TARGETS),
        prior_weight=f.number("prior_weight", 1.0, minimum=0.0, maximum=1e6),
    )
    f.done()
    if area is None:
        raise FieldError("search", "needs an area to cover (area: {x_m: [lo, hi], ...})")
    cells = (math.ceil((area.x_max_m - area.x_min_m) / spec.cell_m)
             * math.ceil((area.y_max_m - area.y_min_m) / spec.cell_m))
    if cells > MAX_SEARCH_CELLS:
        raise FieldError(f.path_of("cell_m"), f"gives {cells} cells over the area; floe's "
                         f"limit is {MAX_SEARCH_CELLS}")
    return spec


@dataclass(frozen=True)
class DiscoveryFields:
    """Everything this module parses, as :func:`parse_discovery` returns it."""

    camera: CameraSpec
    area: AreaSpec | None
    prior: PriorSpec | None
    tracker: dict[str, float | int | str]
    search: SearchSpec | None


def parse_discovery(top: Fields, target_count: int) -> DiscoveryFields:
    """The sections ``camera``, ``area``, ``prior``, ``tracker``, ``search`` of a scenario
    (``top`` is its top-level mapping; the other sections are world.scenario's)."""
    camera = parse_camera(top.sub("camera"))
    area = parse_area(top.sub("area")) if top.has("area") else None
    top.raw("area")
    prior = parse_prior(top.sub("prior"), area, target_count) if top.has("prior") else None
    top.raw("prior")
    tracker = parse_tracker(top.sub("tracker"))
    search = parse_search(top.sub("search"), area) if top.has("search") else None
    top.raw("search")
    return DiscoveryFields(camera, area, prior, tracker, search)


def resolve_prior(scenario: _Scenario, targets: Sequence[_Target], seed: int
                  ) -> list[PriorEntry]:
    """The prior list of a run with ``seed`` whose icebergs are ``targets`` (as
    :func:`world.scenario.resolve_targets` drew them); see the module docstring. Empty
    without ``prior``. An explicit list is returned as written; a ``truth`` naming no
    iceberg raises FieldError."""
    spec = scenario.prior
    if spec is None:
        return []
    if spec.entries:
        ids = {t.id for t in targets}
        for i, entry in enumerate(spec.entries):
            if entry.truth_id is not None and entry.truth_id not in ids:
                raise FieldError(f"prior.list[{i}].truth",
                                 f"names no iceberg of the scenario: {entry.truth_id!r}")
        return [replace(entry, drift_m_s=spec.drift_m_s) for entry in spec.entries]
    rng = np.random.default_rng([int(seed), PRIOR_STREAM])
    present = [t for t in targets if t.appear_s <= 0.0]
    count = min(spec.listed, len(present))
    chosen = [int(i) for i in rng.choice(len(present), size=count, replace=False)] if count else []
    drafts: list[tuple[float, float, float, str | None]] = []
    for index in chosen:
        target = present[index]
        age_s = float(rng.uniform(0.0, spec.max_age_s))
        noise = rng.normal(0.0, spec.sigma_m, size=2)
        drafts.append((target.x_m - target.vx_m_s * age_s + float(noise[0]),
                       target.y_m - target.vy_m_s * age_s + float(noise[1]), age_s, target.id))
    area = scenario.area
    for _ in range(spec.phantoms):
        if area is None:  # parse_prior refuses this; a hand-built Scenario may not
            raise FieldError("prior.phantoms", "needs an area (phantoms are drawn in it)")
        drafts.append((float(rng.uniform(area.x_min_m, area.x_max_m)),
                       float(rng.uniform(area.y_min_m, area.y_max_m)),
                       float(rng.uniform(0.0, spec.max_age_s)), None))
    order = rng.permutation(len(drafts))
    return [PriorEntry(f"P{k + 1}", *drafts[int(i)][:3], spec.sigma_m, drafts[int(i)][3],
                       spec.drift_m_s)
            for k, i in enumerate(order)]


def scenario_camera(scenario: _Scenario) -> Camera:
    """The scenario's camera for :class:`world.model.World`: footprint ``fleet.fov_radius_m``,
    ``observer.camera_rate_hz`` and ``observer.r_m2``, and the faults of ``camera:``."""
    spec = scenario.camera
    return Camera(scenario.fleet.fov_radius_m, scenario.observer.camera_rate_hz,
                  scenario.observer.r_m2, pd=spec.pd, clutter_per_frame=spec.clutter_per_frame,
                  labelled=spec.labelled)
