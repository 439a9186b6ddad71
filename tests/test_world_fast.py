"""The world's fast camera and drift give the plain path's numbers, bit for bit.

``World`` keeps its icebergs sorted, skips an iceberg far along x before the exact footprint
test (``_REACH_MARGIN``), takes its normals from blocks drawn ahead (the camera's noise, the
icebergs' random walk) and builds no frame for ``observe``. A journal recorded by
``gcs simulate`` must replay the same, so each tick here is checked against the camera and
the step as they were written before (kept below, verbatim but for names) on a twin world
of the same seed, over random worlds and cameras (``pd``, clutter, unlabelled, icebergs on
the footprint's edge): every float compared on its exact value, and the detection and
clutter generators left in the same state (the camera's and the icebergs' own draw their
normals ahead in blocks).
"""

from __future__ import annotations

import copy
import math
import random
from collections.abc import Mapping, Sequence

import numpy as np

from world.model import _NOISE_BLOCK, Boat, Camera, Frame, Iceberg, Measurement, World

# ----------------------------------------------------------------- the plain path
# World.observe_frames, _detections and _clutter as they were (main at c247c22)


def plain_observe_frames(world: World, uav_positions: Mapping[str, Sequence[float]],
                         ) -> list[Frame]:
    tick = world.camera.tick(world.t_s)
    if world._last_tick is not None and tick <= world._last_tick:
        return []
    world._last_tick = tick
    radius_m = world.camera.fov_radius_m
    frames: list[Frame] = []
    for vehicle in sorted(uav_positions):
        pos = uav_positions[vehicle]
        ux, uy = float(pos[0]), float(pos[1])
        detections = (plain_detections(world, vehicle, ux, uy)
                      + plain_clutter(world, vehicle, ux, uy))
        if not world.camera.labelled:
            detections.sort(key=lambda m: (m.x_m, m.y_m))
        frames.append(Frame(world.t_s, vehicle, ux, uy, radius_m, tuple(detections)))
    return frames


def plain_detections(world: World, vehicle: str, ux: float, uy: float) -> list[Measurement]:
    camera = world.camera
    fov2 = camera.fov_radius_m**2
    sd = math.sqrt(camera.r_m2)
    out: list[Measurement] = []
    for iid in sorted(world.icebergs):
        ice = world.icebergs[iid]
        if (ice.x_m - ux) ** 2 + (ice.y_m - uy) ** 2 > fov2:
            continue
        if camera.pd < 1.0 and world._detect_rng.random() >= camera.pd:
            continue
        n = world._camera_rng.normal(0.0, sd, size=2)
        out.append(Measurement(
            t_s=world.t_s, vehicle=vehicle, target=iid if camera.labelled else None,
            x_m=ice.x_m + float(n[0]), y_m=ice.y_m + float(n[1]), r_m2=camera.r_m2,
            true_x_m=ice.x_m, true_y_m=ice.y_m, truth=iid,
        ))
    return out


def plain_clutter(world: World, vehicle: str, ux: float, uy: float) -> list[Measurement]:
    camera = world.camera
    if camera.clutter_per_frame <= 0.0:
        return []
    out: list[Measurement] = []
    for _ in range(int(world._clutter_rng.poisson(camera.clutter_per_frame))):
        u = world._clutter_rng.random(2)
        rho = camera.fov_radius_m * math.sqrt(float(u[0]))
        theta = 2.0 * math.pi * float(u[1])
        x, y = ux + rho * math.cos(theta), uy + rho * math.sin(theta)
        out.append(Measurement(world.t_s, vehicle, None, x, y, camera.r_m2, x, y, None))
    return out


def plain_step(world: World, dt_s: float) -> None:
    """World.step as it was (the boat's own step is unchanged)."""
    for iceberg in world.icebergs.values():
        iceberg.x_m += iceberg.vx_m_s * dt_s
        iceberg.y_m += iceberg.vy_m_s * dt_s
        if iceberg.q_per_s > 0.0 and dt_s > 0.0:
            dv = world._iceberg_rngs[iceberg.id].normal(
                0.0, math.sqrt(iceberg.q_per_s * dt_s), size=2
            )
            iceberg.vx_m_s += float(dv[0])
            iceberg.vy_m_s += float(dv[1])
    if world.boat is not None:
        world.boat.step(dt_s)
    world.t_s += dt_s


# ----------------------------------------------------------------- random cases


def hexes(*values: object) -> tuple[object, ...]:
    """Floats by their exact value (the sign of zero included), anything else as it is."""
    return tuple(v.hex() if isinstance(v, float) else v for v in values)


def measurement_bits(m: Measurement) -> tuple[object, ...]:
    return hexes(m.t_s, m.vehicle, m.target, m.x_m, m.y_m, m.r_m2, m.true_x_m, m.true_y_m,
                 m.truth)


def frame_bits(frame: Frame) -> tuple[object, ...]:
    return hexes(frame.t_s, frame.vehicle, frame.x_m, frame.y_m, frame.radius_m) + tuple(
        measurement_bits(m) for m in frame.detections)


def generator_states(world: World) -> list[object]:
    """The detection and clutter generators (the camera's and the icebergs' draw their
    normals ahead: their numbers are compared in the measurements and the velocities)."""
    return [g.bit_generator.state for g in (world._detect_rng, world._clutter_rng)]


def random_camera(rng: random.Random) -> Camera:
    return Camera(rng.choice([150.0, 97.3, rng.uniform(20.0, 400.0)]),
                  rng.choice([2.0, 5.0, 1.3]),
                  rng.choice([5.0, 0.0, rng.uniform(0.1, 30.0)]),
                  pd=rng.choice([1.0, 1.0, 0.7, rng.uniform(0.05, 1.0)]),
                  clutter_per_frame=rng.choice([0.0, 0.0, 1.5, rng.uniform(0.0, 4.0)]),
                  labelled=rng.random() < 0.5)


def edge_m(rng: random.Random, radius_m: float) -> float:
    """A distance on the footprint's edge: at R, just inside or outside it (by a unit in
    the last place and less), and within the reach margin or just beyond it."""
    edge = radius_m * rng.choice([1.0, 1.0, 1.0 + 5e-10, 1.0 + 2e-9, 1.0 - 1e-12,
                                  math.nextafter(1.0, 2.0), math.nextafter(1.0, 0.0)])
    return edge * rng.choice([1.0, -1.0])


def random_icebergs(rng: random.Random, camera: Camera,
                    vehicles: dict[str, tuple[float, float]],
                    count: int | None = None) -> list[Iceberg]:
    """Anywhere in the field, near a vehicle, or on a footprint's edge along x or y."""
    radius_m = camera.fov_radius_m
    out = []
    for k in range(rng.randrange(16) if count is None else count):
        ux, uy = rng.choice(list(vehicles.values()))
        kind = rng.randrange(4)
        if kind == 0:
            x_m, y_m = rng.uniform(-500.0, 2000.0), rng.uniform(-500.0, 2000.0)
        elif kind == 1:
            x_m, y_m = ux + rng.uniform(-2 * radius_m, 2 * radius_m), uy + rng.uniform(
                -2 * radius_m, 2 * radius_m)
        else:
            edge = edge_m(rng, radius_m)
            x_m, y_m = (ux + edge, uy) if kind == 2 else (ux, uy + edge)
        q_per_s = rng.choice([0.0, 0.0, 0.05, rng.uniform(0.0, 0.5)])
        out.append(Iceberg(f"T{rng.randrange(10**9)}-{k}", x_m, y_m,
                           rng.uniform(-3.0, 3.0), rng.uniform(-3.0, 3.0), q_per_s))
    return out


def test_the_camera_sees_and_draws_what_the_plain_camera_did() -> None:
    rng = random.Random(20261127)
    ticks = measured = 0
    for case in range(150):
        camera = random_camera(rng)
        vehicles = {str(rng.randrange(100)): (rng.uniform(0.0, 1500.0), rng.uniform(0.0, 1500.0))
                    for _ in range(rng.randrange(1, 5))}
        icebergs = random_icebergs(rng, camera, vehicles)
        boat = Boat(1500.0, 0.0, 2.0246, 10.0) if rng.random() < 0.5 else None

        fast, plain, flat = (World(*copy.deepcopy((icebergs, boat, camera)),
                                   np.random.default_rng(case)) for _ in range(3))
        dt_s = rng.choice([0.1, 0.25, 0.05])
        for _ in range(40):
            positions = {v: (x + rng.uniform(-5.0, 5.0), y + rng.uniform(-5.0, 5.0))
                         for v, (x, y) in vehicles.items()}
            if fast.icebergs and rng.random() < 0.7:  # a vehicle sees one on its edge
                ice = rng.choice(list(fast.icebergs.values()))
                edge = edge_m(rng, camera.fov_radius_m)
                positions[rng.choice(list(vehicles))] = rng.choice(
                    [(ice.x_m - edge, ice.y_m), (ice.x_m, ice.y_m - edge)])
            got = fast.observe_frames(positions)
            want = plain_observe_frames(plain, positions)
            assert [frame_bits(f) for f in got] == [frame_bits(f) for f in want], case
            measurements = flat.observe(positions)  # observe: the frames' detections
            assert [measurement_bits(m) for m in measurements] == [
                measurement_bits(m) for f in want for m in f.detections]
            assert generator_states(fast) == generator_states(plain)
            assert generator_states(flat) == generator_states(plain)
            ticks += bool(got)
            measured += sum(len(f.detections) for f in got)
            for w in (fast, flat):
                w.step(dt_s)
            plain_step(plain, dt_s)
            if fast.icebergs and rng.random() < 0.1:  # one melts away, or calves anew
                gone = rng.choice(sorted(fast.icebergs))
                for w in (fast, plain, flat):
                    w.remove_iceberg(gone)
            if rng.random() < 0.1:
                (new,) = random_icebergs(rng, camera, vehicles, count=1)
                for w in (fast, plain, flat):
                    w.add_iceberg(copy.deepcopy(new))
            assert hexes(*(c for i in fast.icebergs.values()
                           for c in (i.x_m, i.y_m, i.vx_m_s, i.vy_m_s))) == hexes(
                *(c for i in plain.icebergs.values()
                  for c in (i.x_m, i.y_m, i.vx_m_s, i.vy_m_s)))
            assert fast.t_s == plain.t_s == flat.t_s
    assert ticks > 1000 and measured > 1000  # the cases compared real frames and detections


def test_crowded_frames_take_the_noise_across_blocks_as_the_plain_camera_drew_it() -> None:
    """Up to 60 icebergs in view of 4 vehicles: ticks that need more normals than a block,
    and many blocks in turn, give the plain camera's numbers."""
    rng = random.Random(3)
    icebergs = [Iceberg(f"T{k}", rng.uniform(0.0, 100.0), rng.uniform(0.0, 100.0), 0.1, 0.0)
                for k in range(60)]
    fast, plain = (World(copy.deepcopy(icebergs), None, Camera(300.0, 2.0, 5.0),
                         np.random.default_rng(9)) for _ in range(2))
    used = most = 0
    for _ in range(30):
        positions = {str(v): (rng.uniform(0.0, 100.0), rng.uniform(0.0, 100.0))
                     for v in range(rng.randrange(1, 5))}
        got = fast.observe(positions)
        want = [m for f in plain_observe_frames(plain, positions) for m in f.detections]
        assert [measurement_bits(m) for m in got] == [measurement_bits(m) for m in want]
        used += 2 * len(got)
        most = max(most, 2 * len(got))
        fast.step(0.5)
        plain_step(plain, 0.5)
    assert used > 10 * _NOISE_BLOCK and most > _NOISE_BLOCK


def test_the_icebergs_random_walk_takes_its_normals_across_blocks_as_drawn_before() -> None:
    """Drifting icebergs with process noise over many blocks of normals, at irregular steps
    (some of zero length, which draw nothing): the plain step's velocities and positions."""
    rng = random.Random(5)
    icebergs = [Iceberg(f"D{k}", rng.uniform(0.0, 1500.0), rng.uniform(0.0, 1500.0),
                        rng.uniform(-3.0, 3.0), rng.uniform(-3.0, 3.0), q_per_s)
                for k, q_per_s in enumerate([0.1, 0.0, 0.5, 0.013])]
    fast, plain = (World(copy.deepcopy(icebergs), Boat(0.0, 0.0, 1.0, 5.0),
                         Camera(), np.random.default_rng(21)) for _ in range(2))
    for _ in range(4 * _NOISE_BLOCK):
        dt_s = rng.choice([0.1, 0.1, 0.0, rng.uniform(0.0, 2.0)])
        fast.step(dt_s)
        plain_step(plain, dt_s)
        assert hexes(*(c for i in fast.icebergs.values()
                       for c in (i.x_m, i.y_m, i.vx_m_s, i.vy_m_s))) == hexes(
            *(c for i in plain.icebergs.values() for c in (i.x_m, i.y_m, i.vx_m_s, i.vy_m_s)))
