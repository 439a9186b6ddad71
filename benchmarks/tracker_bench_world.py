"""The tracker benchmark's recorded world: a small deterministic generator of camera frames
over drifting icebergs (independent of floe's ``world`` package, so the benchmark does not
depend on any scenario's random streams).

- Icebergs: ``n_icebergs`` at uniform positions in the area, constant velocities uniform in
  ``[-v_max, v_max]`` per axis (drifting ice); they may drift out of the area.
- UAVs: UAV ``k`` of ``n_uavs`` flies a lawnmower over its strip ``x in [k w, (k + 1) w]``
  (``w`` = area width / ``n_uavs``): lanes along y, ``lane_spacing_m`` apart, joined by
  straight legs (no turn radius: this records detections, it is not a flight model), and
  back along the same path when the strip is done, at ``speed_m_s``.
- Camera: every ``1 / camera_hz`` s, one frame per UAV with footprint ``(x, y,
  footprint_radius_m)``; each iceberg inside the disc is detected with probability ``pd``
  at its position plus N(0, r I); a Poisson(``clutter_per_frame``) number of false alarms
  uniform over the disc. Detections are shuffled (unlabelled: the truth id is kept only to
  score). All draws come from ``numpy.random.default_rng(seed)``, in a fixed order.
- Crossing pairs (``crossing_pairs`` > 0, the benchmark's ``crossing`` stress case): the
  first ``2 crossing_pairs`` icebergs are redrawn as pairs that pass each other: pair ``k``
  meets at a point ``c`` uniform in the area inset by ``crossing_inset_m``, at a time ``t_c``
  uniform in ``[0.3, 0.7] duration_s``; each has a heading uniform in ``[0, 2 pi)`` (the
  second's ``pi/3 .. pi`` from the first's) and a speed uniform in ``[0.5, 1] v_max``; the
  closest approach ``d`` is uniform in ``[0, crossing_miss_m]``, at ``t_c``: positions
  ``c +- (d / 2) n`` with ``n`` the unit normal of the relative velocity. These draws come
  after the other icebergs', so a recording without crossing pairs is unchanged.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class WorldParams:
    """Parameters of a recording (see the module docstring)."""

    seed: int = 0
    duration_s: float = 1800.0
    n_icebergs: int = 12
    x_min_m: float = 0.0
    x_max_m: float = 3000.0
    y_min_m: float = 0.0
    y_max_m: float = 3000.0
    v_max_m_s: float = 0.5
    n_uavs: int = 3
    speed_m_s: float = 22.0
    lane_spacing_m: float = 250.0
    footprint_radius_m: float = 150.0
    camera_hz: float = 2.0
    pd: float = 0.85
    clutter_per_frame: float = 0.1
    r_m2: float = 5.0
    crossing_pairs: int = 0
    crossing_miss_m: float = 50.0
    crossing_inset_m: float = 500.0


@dataclass(frozen=True)
class Iceberg:
    id: str
    x0_m: float
    y0_m: float
    vx_m_s: float
    vy_m_s: float


@dataclass(frozen=True)
class Frame:
    """One camera frame; ``detections``: ``(x_m, y_m, truth id or None for clutter)``."""

    t_s: float
    vehicle: str
    x_m: float
    y_m: float
    radius_m: float
    detections: tuple[tuple[float, float, str | None], ...]


@dataclass(frozen=True)
class Recording:
    params: WorldParams
    truth: tuple[Iceberg, ...]
    frames: tuple[Frame, ...]

    def truth_at(self, t_s: float) -> dict[str, tuple[float, float]]:
        """Every iceberg's true position at ``t_s``."""
        return {b.id: (b.x0_m + b.vx_m_s * t_s, b.y0_m + b.vy_m_s * t_s) for b in self.truth}


def lawnmower(p: WorldParams, k: int) -> np.ndarray:
    """Waypoints (n, 2) of UAV ``k``'s strip, there and back (closed ping-pong path)."""
    width = (p.x_max_m - p.x_min_m) / p.n_uavs
    x0 = p.x_min_m + k * width
    n_lanes = max(1, math.ceil(width / p.lane_spacing_m))
    spacing = width / n_lanes
    margin = min(p.footprint_radius_m, (p.y_max_m - p.y_min_m) / 2)
    pts: list[tuple[float, float]] = []
    for lane in range(n_lanes):
        x = x0 + (lane + 0.5) * spacing
        ys = (p.y_min_m + margin, p.y_max_m - margin)
        if lane % 2:
            ys = ys[::-1]
        pts.extend([(x, ys[0]), (x, ys[1])])
    there = np.asarray(pts)
    return np.vstack([there, there[-2::-1]])


def position_on(path: np.ndarray, s_m: float) -> tuple[float, float]:
    """The point at arc length ``s_m`` along the closed path (wrapping around)."""
    seg = np.diff(path, axis=0)
    lengths = np.hypot(seg[:, 0], seg[:, 1])
    s = s_m % float(lengths.sum())
    for (x, y), (dx, dy), length in zip(path[:-1], seg, lengths, strict=True):
        if s <= length and length > 0:
            f = s / length
            return (float(x + f * dx), float(y + f * dy))
        s -= length
    return (float(path[-1, 0]), float(path[-1, 1]))


def crossing_pairs(p: WorldParams, rng: np.random.Generator) -> tuple[Iceberg, ...]:
    """``p.crossing_pairs`` pairs of icebergs that pass within ``p.crossing_miss_m`` of each
    other (see the module docstring), named ``B1 .. B{2 k}``."""
    if 2 * p.crossing_pairs > p.n_icebergs:
        raise ValueError(f"crossing_pairs {p.crossing_pairs} needs more than "
                         f"{p.n_icebergs} icebergs")
    out: list[Iceberg] = []
    inset = p.crossing_inset_m
    for k in range(p.crossing_pairs):
        cx = float(rng.uniform(p.x_min_m + inset, p.x_max_m - inset))
        cy = float(rng.uniform(p.y_min_m + inset, p.y_max_m - inset))
        t_c = float(rng.uniform(0.3, 0.7)) * p.duration_s
        h1 = float(rng.uniform(0.0, 2.0 * math.pi))
        h2 = h1 + float(rng.uniform(math.pi / 3.0, math.pi))
        s1, s2 = (float(rng.uniform(0.5, 1.0)) * p.v_max_m_s for _ in range(2))
        v1 = (s1 * math.cos(h1), s1 * math.sin(h1))
        v2 = (s2 * math.cos(h2), s2 * math.sin(h2))
        miss = float(rng.uniform(0.0, p.crossing_miss_m))
        rx, ry = v1[0] - v2[0], v1[1] - v2[1]
        norm = math.hypot(rx, ry)
        nx, ny = -ry / norm, rx / norm
        for sign, (vx, vy), n in ((1.0, v1, 2 * k + 1), (-1.0, v2, 2 * k + 2)):
            x_c, y_c = cx + sign * 0.5 * miss * nx, cy + sign * 0.5 * miss * ny
            out.append(Iceberg(f"B{n}", x_c - vx * t_c, y_c - vy * t_c, vx, vy))
    return tuple(out)


def record(p: WorldParams) -> Recording:
    """Generate the truth and every frame of a recording (deterministic in ``p.seed``)."""
    rng = np.random.default_rng(p.seed)
    truth = tuple(
        Iceberg(
            f"B{i + 1}",
            float(rng.uniform(p.x_min_m, p.x_max_m)),
            float(rng.uniform(p.y_min_m, p.y_max_m)),
            float(rng.uniform(-p.v_max_m_s, p.v_max_m_s)),
            float(rng.uniform(-p.v_max_m_s, p.v_max_m_s)),
        )
        for i in range(p.n_icebergs)
    )
    if p.crossing_pairs:
        truth = crossing_pairs(p, rng) + truth[2 * p.crossing_pairs :]
    paths = [lawnmower(p, k) for k in range(p.n_uavs)]
    sigma_m = math.sqrt(p.r_m2)
    frames: list[Frame] = []
    n_ticks = math.floor(p.duration_s * p.camera_hz + 1e-9)
    for tick in range(1, n_ticks + 1):
        t = tick / p.camera_hz
        rec_truth = {b.id: (b.x0_m + b.vx_m_s * t, b.y0_m + b.vy_m_s * t) for b in truth}
        for k, path in enumerate(paths):
            cx, cy = position_on(path, p.speed_m_s * t)
            dets: list[tuple[float, float, str | None]] = []
            for tid, (x, y) in rec_truth.items():
                if math.hypot(x - cx, y - cy) <= p.footprint_radius_m and rng.random() < p.pd:
                    nx, ny = rng.normal(0.0, sigma_m, 2)
                    dets.append((float(x + nx), float(y + ny), tid))
            for _ in range(int(rng.poisson(p.clutter_per_frame))):
                rho = p.footprint_radius_m * math.sqrt(float(rng.random()))
                phi = 2.0 * math.pi * float(rng.random())
                dets.append((cx + rho * math.cos(phi), cy + rho * math.sin(phi), None))
            order = rng.permutation(len(dets))
            frames.append(
                Frame(t, f"uav{k + 1}", cx, cy, p.footprint_radius_m, tuple(dets[i] for i in order))
            )
    return Recording(p, truth, tuple(frames))


def save_recording(rec: Recording, path: Path) -> None:
    """Write the recording as JSON (params, truth, frames)."""
    doc = {
        "params": asdict(rec.params),
        "truth": [asdict(b) for b in rec.truth],
        "frames": [
            [f.t_s, f.vehicle, f.x_m, f.y_m, f.radius_m, [list(d) for d in f.detections]]
            for f in rec.frames
        ],
    }
    path.write_text(json.dumps(doc, separators=(",", ":")) + "\n")


def load_recording(path: Path) -> Recording:
    """Read a recording written by :func:`save_recording`."""
    doc = json.loads(path.read_text())
    return Recording(
        WorldParams(**doc["params"]),
        tuple(Iceberg(**b) for b in doc["truth"]),
        tuple(
            Frame(t, v, x, y, r, tuple((dx, dy, tid) for dx, dy, tid in dets))
            for t, v, x, y, r, dets in doc["frames"]
        ),
    )
