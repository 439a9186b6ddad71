"""The simulated world: drifting icebergs, the boat, and the UAVs' camera.

Pure and seeded: no clock, no I/O; all randomness comes from the ``numpy.random.Generator``
given to :class:`World`, split (``Generator.spawn``) so that the icebergs' paths never depend
on how many UAVs look at them:

* one child generator for the camera noise;
* one child generator per iceberg (spawned in the order icebergs are added).

Iceberg dynamics per step ``dt`` (the observer's constant-velocity model, eq. (3))::

    p <- p + v dt,    then    v <- v + dv,   dv ~ N(0, q dt I)

Boat: fixed course, ``p <- p + speed (cos psi, sin psi) dt``.

Camera: at every tick ``t = k / rate_hz`` each UAV takes one frame of the disc of radius
``fov_radius_m`` (horizontal distance) around it. Each iceberg in the disc is detected with
probability ``pd`` and measured ``z = p + n``, ``n ~ N(0, r I)``; then ``N ~ Poisson(lambda)``
false alarms (``lambda = clutter_per_frame``) fall uniformly over the disc
(``rho = R sqrt(u1)``, ``theta = 2 pi u2``), reported with the same variance ``r``. A labelled
camera reports the iceberg's id (``Measurement.target``), an unlabelled one ``None`` and
lists the frame's detections sorted by measured position, so their order says nothing about
the truth; ``Measurement.truth`` always holds the true iceberg (``None`` for a false alarm).
:meth:`World.observe_frames` is meant to be called after each :meth:`World.step`; it returns
the frames of the camera tick reached since the previous call (at most one tick per call;
one frame per vehicle, even without a detection), stamped with the current ``t_s`` (the tick
itself when the step divides the camera period). :meth:`World.observe` is the same tick as
a flat list of measurements.

Random streams: the noise comes from the camera's generator as it always has; the
detection draws (one uniform per iceberg in view, only if ``pd < 1``) and the false alarms
(only if ``clutter_per_frame > 0``) come from two generators spawned from the camera's
(``Generator.spawn`` does not advance it). So the paper's camera (``pd = 1``, no clutter)
draws exactly what it drew before these faults existed.

The noise is the camera generator's stream of standard normals ``z`` taken in order, each
detection's ``n = (0 + s z_k, 0 + s z_k+1)`` with ``s = sqrt(r)``: what
``normal(0, s, size=2)`` returns (numpy draws it a sample at a time, each
``loc + scale * z``), so the numbers are those of one such draw per detection; an
iceberg's ``dv`` likewise, ``s = sqrt(q dt)``, from its own generator. They are drawn ahead
in blocks of ``_NOISE_BLOCK`` (:class:`_Normals`: one numpy call for many frames or
steps); a generator itself is then ahead of what the world has used.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

_GRID_EPS = 1e-9
_NOISE_BLOCK = 256
_REACH_MARGIN = 1.0 + 1e-9
"""An iceberg further than ``R (1 + 1e-9)`` from the camera along x is out of view
without the exact test ``dx^2 + dy^2 > R^2``: then ``dx^2 > R^2 (1 + 2e-9)``, which the
rounding of ``**`` (under one unit in the last place, ~1e-16 relative) cannot bring
down to the rounded ``R^2``, and adding ``dy^2 >= 0`` cannot either. Nearer icebergs
(and a NaN) take the exact test, so the verdict is always the exact test's."""


@dataclass
class Iceberg:
    """A drifting iceberg: constant velocity plus process noise of intensity ``q_per_s``."""

    id: str
    x_m: float
    y_m: float
    vx_m_s: float
    vy_m_s: float
    q_per_s: float = 0.0


@dataclass
class Boat:
    """The boat (the ship): on a fixed course (heading counter-clockwise from +x), or, with
    ``route``, sailing those waypoints in a loop at ``speed_m_s`` (an ice-management
    pattern: it turns at each waypoint to the next, the last leading back to the first;
    it starts at (x_m, y_m) heading for ``route[0]``)."""

    x_m: float
    y_m: float
    heading_rad: float
    speed_m_s: float
    route: tuple[tuple[float, float], ...] = ()
    leg: int = 0
    """The waypoint of ``route`` it is heading for."""

    def step(self, dt_s: float) -> None:
        """Sail ``dt_s`` seconds (on the route, turning at waypoints within the step)."""
        travel_m = self.speed_m_s * dt_s
        if not self.route:
            self.x_m += travel_m * math.cos(self.heading_rad)
            self.y_m += travel_m * math.sin(self.heading_rad)
            return
        for _ in range(len(self.route) + 1):
            wx, wy = self.route[self.leg % len(self.route)]
            gap_m = math.hypot(wx - self.x_m, wy - self.y_m)
            if gap_m > 1e-9:
                self.heading_rad = math.atan2(wy - self.y_m, wx - self.x_m)
            if travel_m < gap_m:
                self.x_m += travel_m * math.cos(self.heading_rad)
                self.y_m += travel_m * math.sin(self.heading_rad)
                return
            self.x_m, self.y_m = wx, wy
            travel_m -= gap_m
            self.leg = (self.leg + 1) % len(self.route)

    @property
    def velocity_m_s(self) -> tuple[float, float]:
        """Velocity over ground now (ENU m/s)."""
        return (self.speed_m_s * math.cos(self.heading_rad),
                self.speed_m_s * math.sin(self.heading_rad))


class Measurement(NamedTuple):
    """One camera measurement by one vehicle: ``target`` is what the camera reports (the
    iceberg's id if labelled, else None), ``truth`` the iceberg really seen (None for a
    false alarm, whose ``true_x_m, true_y_m`` is the false alarm's own point). Immutable;
    a named tuple rather than a frozen dataclass: a run makes one per detection, at a
    third of the cost."""

    t_s: float
    vehicle: str
    target: str | None
    x_m: float
    y_m: float
    r_m2: float
    true_x_m: float
    true_y_m: float
    truth: str | None = None


@dataclass(frozen=True)
class Frame:
    """One camera frame: the footprint disc (centre, radius) and what was reported in it."""

    t_s: float
    vehicle: str
    x_m: float
    y_m: float
    radius_m: float
    detections: tuple[Measurement, ...]


class Camera:
    """Down-looking camera: footprint radius, frame rate, noise variance per axis, and its
    faults (module docstring). The defaults are the paper's camera: never misses, never
    lies, labelled (a scenario's ``camera:`` defaults to unlabelled: see
    ``world.discovery_spec.scenario_camera``)."""

    def __init__(self, fov_radius_m: float = 150.0, rate_hz: float = 2.0, r_m2: float = 5.0,
                 *, pd: float = 1.0, clutter_per_frame: float = 0.0, labelled: bool = True):
        for name, value in (("fov_radius_m", fov_radius_m), ("rate_hz", rate_hz)):
            if not math.isfinite(value) or value <= 0.0:
                raise ValueError(f"Camera.{name} must be finite and > 0, got {value!r}")
        if not math.isfinite(r_m2) or r_m2 < 0.0:
            raise ValueError(f"Camera.r_m2 must be finite and >= 0, got {r_m2!r}")
        if not (math.isfinite(pd) and 0.0 < pd <= 1.0):
            raise ValueError(f"Camera.pd must be in (0, 1], got {pd!r}")
        if not (math.isfinite(clutter_per_frame) and clutter_per_frame >= 0.0):
            raise ValueError(
                f"Camera.clutter_per_frame must be finite and >= 0, got {clutter_per_frame!r}")
        self.fov_radius_m = float(fov_radius_m)
        self.rate_hz = float(rate_hz)
        self.r_m2 = float(r_m2)
        self.pd = float(pd)
        self.clutter_per_frame = float(clutter_per_frame)
        self.labelled = bool(labelled)

    def tick(self, t_s: float) -> int:
        """Index of the last camera tick at or before ``t_s``: ``floor(t rate)``."""
        return math.floor(t_s * self.rate_hz + _GRID_EPS)


class _Normals:
    """A generator's standard normals in order, drawn ahead ``_NOISE_BLOCK`` or more at a
    time (module docstring): ``take(n)`` gives the same numbers as ``n`` drawn one at a
    time, the generator's state apart."""

    def __init__(self, rng: np.random.Generator) -> None:
        self._rng = rng
        self._drawn: list[float] = []
        self._used = 0
        """The first ``_used`` of ``_drawn`` are taken."""

    def take(self, count: int) -> list[float]:
        """The next ``count`` standard normals."""
        start, end = self._used, self._used + count
        if end > len(self._drawn):
            fresh = self._rng.standard_normal(max(_NOISE_BLOCK, count)).tolist()
            self._drawn = self._drawn[start:] + fresh
            start, end = 0, count
        self._used = end
        return self._drawn[start:end]


def _check_iceberg(iceberg: Iceberg) -> None:
    if not isinstance(iceberg.id, str) or not iceberg.id:
        raise ValueError(f"Iceberg.id must be a non-empty string, got {iceberg.id!r}")
    for name in ("x_m", "y_m", "vx_m_s", "vy_m_s", "q_per_s"):
        value = getattr(iceberg, name)
        if not math.isfinite(value):
            raise ValueError(f"Iceberg {iceberg.id!r}: {name} must be finite, got {value!r}")
    if iceberg.q_per_s < 0.0:
        raise ValueError(f"Iceberg {iceberg.id!r}: q_per_s must be >= 0, got {iceberg.q_per_s}")


class World:
    """Icebergs, the boat and the camera, advanced in virtual time."""

    def __init__(
        self,
        icebergs: Sequence[Iceberg],
        boat: Boat | None,
        camera: Camera,
        rng: np.random.Generator,
        *,
        t_s: float = 0.0,
    ) -> None:
        if not math.isfinite(t_s):
            raise ValueError(f"World.t_s must be finite, got {t_s!r}")
        self.t_s = float(t_s)
        self.boat = boat
        self.camera = camera
        self._rng = rng
        (self._camera_rng,) = rng.spawn(1)
        self._detect_rng, self._clutter_rng = self._camera_rng.spawn(2)
        self._camera_normals = _Normals(self._camera_rng)
        self.icebergs: dict[str, Iceberg] = {}
        """The icebergs by id, in the order they were added (read it; add and remove through
        :meth:`add_iceberg` and :meth:`remove_iceberg`)."""
        self._by_id: list[tuple[str, Iceberg]] = []
        """``icebergs`` sorted by id, for the camera (kept by add and remove)."""
        self._iceberg_rngs: dict[str, np.random.Generator] = {}
        self._iceberg_normals: dict[str, _Normals] = {}
        self._last_tick: int | None = None
        for iceberg in icebergs:
            self.add_iceberg(iceberg)

    def add_iceberg(self, iceberg: Iceberg) -> None:
        """Add an iceberg now. Raises ValueError for a duplicate id or bad values."""
        _check_iceberg(iceberg)
        if iceberg.id in self.icebergs:
            raise ValueError(f"iceberg {iceberg.id!r} already exists")
        self.icebergs[iceberg.id] = iceberg
        self._by_id = sorted(self.icebergs.items())
        (self._iceberg_rngs[iceberg.id],) = self._rng.spawn(1)
        self._iceberg_normals[iceberg.id] = _Normals(self._iceberg_rngs[iceberg.id])

    def remove_iceberg(self, id: str) -> None:
        """Remove an iceberg. Raises KeyError if unknown."""
        if id not in self.icebergs:
            raise KeyError(f"unknown iceberg {id!r}")
        del self.icebergs[id]
        self._by_id = sorted(self.icebergs.items())
        del self._iceberg_rngs[id]
        del self._iceberg_normals[id]

    def step(self, dt_s: float) -> None:
        """Advance icebergs and boat by ``dt_s`` (see the module docstring)."""
        if not math.isfinite(dt_s) or dt_s < 0.0:
            raise ValueError(f"dt_s must be finite and >= 0, got {dt_s!r}")
        for iceberg in self.icebergs.values():
            iceberg.x_m += iceberg.vx_m_s * dt_s
            iceberg.y_m += iceberg.vy_m_s * dt_s
            if iceberg.q_per_s > 0.0 and dt_s > 0.0:
                sd = math.sqrt(iceberg.q_per_s * dt_s)
                z_x, z_y = self._iceberg_normals[iceberg.id].take(2)
                iceberg.vx_m_s += 0.0 + sd * z_x  # normal(0, sd): module docstring
                iceberg.vy_m_s += 0.0 + sd * z_y
        if self.boat is not None:
            self.boat.step(dt_s)
        self.t_s += dt_s

    def frames_due(self) -> bool:
        """Whether :meth:`observe_frames` has frames now: a camera tick passed since the
        last frames (4 steps in 5 of a 0.1 s loop with a 2 Hz camera have none)."""
        return self._last_tick is None or self.camera.tick(self.t_s) > self._last_tick

    def observe(self, uav_positions: Mapping[str, Sequence[float]]) -> list[Measurement]:
        """Measurements due at the current time (empty between camera ticks): the
        detections of :meth:`observe_frames`, frame after frame."""
        return [m for _, _, _, detections in self._scan(uav_positions) for m in detections]

    def observe_frames(self, uav_positions: Mapping[str, Sequence[float]]) -> list[Frame]:
        """Frames due at the current time (empty between camera ticks), one per vehicle.

        ``uav_positions`` maps a vehicle name to its position ``(x_m, y_m, ...)``; only the
        horizontal coordinates matter. Vehicles and icebergs are visited in sorted order, so
        the noise drawn does not depend on the mapping's order.
        """
        radius_m = self.camera.fov_radius_m
        return [Frame(self.t_s, vehicle, ux, uy, radius_m, detections)
                for vehicle, ux, uy, detections in self._scan(uav_positions)]

    def _scan(self, uav_positions: Mapping[str, Sequence[float]],
              ) -> list[tuple[str, float, float, tuple[Measurement, ...]]]:
        """The camera tick due now (empty between ticks): each vehicle in sorted order, its
        position and what its frame reports (module docstring).

        Vehicle after vehicle, iceberg after iceberg (both sorted), an iceberg is in view
        when ``(x - ux)^2 + (y - uy)^2 <= R^2`` and is then detected unless
        ``pd < 1`` and its uniform draw is ``>= pd``; the detections take the camera's
        next standard normals in that order, two each (module docstring), and each
        vehicle's false alarms follow its detections.
        """
        camera = self.camera
        tick = camera.tick(self.t_s)
        if self._last_tick is not None and tick <= self._last_tick:
            return []
        self._last_tick = tick
        fov2 = camera.fov_radius_m**2
        reach_m = camera.fov_radius_m * _REACH_MARGIN
        pd = camera.pd
        icebergs = [(iid, ice.x_m, ice.y_m) for iid, ice in self._by_id]
        views: list[tuple[str, float, float, list[tuple[str, float, float]]]] = []
        seen_count = 0
        for vehicle in sorted(uav_positions):
            pos = uav_positions[vehicle]
            ux, uy = float(pos[0]), float(pos[1])
            seen: list[tuple[str, float, float]] = []
            for iceberg in icebergs:
                _, x_m, y_m = iceberg
                dx_m = x_m - ux
                if dx_m > reach_m or dx_m < -reach_m:  # out of view (_REACH_MARGIN)
                    continue
                if dx_m ** 2 + (y_m - uy) ** 2 > fov2:  # the exact test
                    continue
                if pd < 1.0 and self._detect_rng.random() >= pd:
                    continue
                seen.append(iceberg)
            views.append((vehicle, ux, uy, seen))
            seen_count += len(seen)
        normals = self._camera_normals.take(2 * seen_count)
        sd = math.sqrt(camera.r_m2)
        t_s, r_m2, labelled = self.t_s, camera.r_m2, camera.labelled
        out: list[tuple[str, float, float, tuple[Measurement, ...]]] = []
        k = 0
        for vehicle, ux, uy, seen in views:
            detections: list[Measurement] = []
            for iid, x_m, y_m in seen:
                detections.append(Measurement(t_s, vehicle, iid if labelled else None,
                                              x_m + (0.0 + sd * normals[k]),
                                              y_m + (0.0 + sd * normals[k + 1]), r_m2,
                                              x_m, y_m, iid))
                k += 2
            detections += self._clutter(vehicle, ux, uy)
            if not labelled:
                detections.sort(key=lambda m: (m.x_m, m.y_m))
            out.append((vehicle, ux, uy, tuple(detections)))
        return out

    def _clutter(self, vehicle: str, ux: float, uy: float) -> list[Measurement]:
        """False alarms: Poisson count, uniform over the footprint disc."""
        camera = self.camera
        if camera.clutter_per_frame <= 0.0:
            return []
        out: list[Measurement] = []
        for _ in range(int(self._clutter_rng.poisson(camera.clutter_per_frame))):
            u = self._clutter_rng.random(2)
            rho = camera.fov_radius_m * math.sqrt(float(u[0]))
            theta = 2.0 * math.pi * float(u[1])
            x, y = ux + rho * math.cos(theta), uy + rho * math.sin(theta)
            out.append(Measurement(self.t_s, vehicle, None, x, y, camera.r_m2, x, y, None))
        return out

    def true_positions(self) -> dict[str, tuple[float, float]]:
        """Every iceberg's true position, by id."""
        return {iid: (ice.x_m, ice.y_m) for iid, ice in self.icebergs.items()}


def random_icebergs(
    rng: np.random.Generator,
    count: int,
    x_range_m: tuple[float, float],
    y_range_m: tuple[float, float],
    v_range_m_s: tuple[float, float],
    q_per_s: float = 0.0,
    prefix: str = "T",
) -> list[Iceberg]:
    """``count`` icebergs ``{prefix}1 ... {prefix}count``, uniform in the ranges (paper
    Table 1: x0, y0 in [0, 1500] m; vx, vy in [-3, 3] m/s)."""
    if count < 0:
        raise ValueError(f"count must be >= 0, got {count}")
    out = []
    for i in range(count):
        x, y, vx, vy = (
            rng.uniform(*x_range_m),
            rng.uniform(*y_range_m),
            rng.uniform(*v_range_m_s),
            rng.uniform(*v_range_m_s),
        )
        out.append(Iceberg(f"{prefix}{i + 1}", float(x), float(y), float(vx), float(vy), q_per_s))
    return out
