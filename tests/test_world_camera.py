"""The world's camera (world/model.py): frames, pd, Poisson clutter over the footprint,
labels; and the paper's camera drawing exactly what it drew before frames existed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from world.discovery_spec import scenario_camera
from world.model import Boat, Camera, Frame, Iceberg, Measurement, World, random_icebergs
from world.scenario import load_scenario, resolve_targets

FOUR_SIGMA = 4.0


def legacy_observe(world_icebergs: dict[str, Iceberg], camera_rng: np.random.Generator,
                   t_s: float, positions: dict[str, tuple[float, float]], fov_m: float,
                   r_m2: float) -> list[tuple[object, ...]]:
    """What World.observe computed before the camera had faults (main before issue 13),
    written out here as the reference: vehicles and icebergs in sorted order, one
    N(0, r I) draw per iceberg in view from the camera's generator."""
    out: list[tuple[object, ...]] = []
    for vehicle in sorted(positions):
        ux, uy = positions[vehicle]
        for iid in sorted(world_icebergs):
            ice = world_icebergs[iid]
            if (ice.x_m - ux) ** 2 + (ice.y_m - uy) ** 2 > fov_m**2:
                continue
            n = camera_rng.normal(0.0, math.sqrt(r_m2), size=2)
            out.append((t_s, vehicle, iid, ice.x_m + float(n[0]), ice.y_m + float(n[1]), r_m2,
                        ice.x_m, ice.y_m))
    return out


def paper_boat_world(seed: int) -> tuple[World, np.random.Generator]:
    """The paper-boat world as gcs simulate builds it, and a copy of the camera's stream."""
    scenario = load_scenario("paper-boat")
    rng = np.random.default_rng(seed)
    targets = resolve_targets(scenario, rng)
    b = scenario.boat
    assert b is not None
    world = World([], Boat(b.x_m, b.y_m, b.heading_rad, b.speed_m_s), scenario_camera(scenario),
                  rng)
    for t in targets:
        world.add_iceberg(Iceberg(t.id, t.x_m, t.y_m, t.vx_m_s, t.vy_m_s, 0.0))
    # the camera's generator, as main spawned it: the first child of the run's generator
    reference = np.random.default_rng(seed)
    resolve_targets(scenario, reference)
    (camera_rng,) = reference.spawn(1)
    return world, camera_rng


def uav_path(t_s: float) -> dict[str, tuple[float, float]]:
    """Three vehicles sweeping the paper-boat field (they see icebergs, often several)."""
    return {
        "1": (750.0 + 700.0 * math.cos(0.02 * t_s), 750.0 + 700.0 * math.sin(0.02 * t_s)),
        "2": (22.0 * t_s % 1500.0, 400.0),
        "3": (1100.0, 22.0 * t_s % 1500.0),
    }


@pytest.mark.parametrize("seed", [3, 8])
def test_the_papers_camera_draws_what_it_drew_before(seed: int) -> None:
    """paper-boat, 60 s of 0.1 s steps: observe() and observe_frames() give main's
    measurement stream exactly (values and order), and the new generators are untouched."""
    world, camera_rng = paper_boat_world(seed)
    framed, _ = paper_boat_world(seed)
    camera = world.camera
    assert camera.labelled and camera.pd == 1.0 and camera.clutter_per_frame == 0.0
    detect_state = world._detect_rng.bit_generator.state
    clutter_state = world._clutter_rng.bit_generator.state
    seen = 0
    for _ in range(600):
        world.step(0.1)
        framed.step(0.1)
        positions = uav_path(world.t_s)
        got = [(m.t_s, m.vehicle, m.target, m.x_m, m.y_m, m.r_m2, m.true_x_m, m.true_y_m)
               for m in world.observe(positions)]
        frames = framed.observe_frames(positions)
        if got:
            want = legacy_observe(world.icebergs, camera_rng, world.t_s, positions,
                                  world.camera.fov_radius_m, world.camera.r_m2)
            assert got == want
            seen += len(got)
        from_frames = [(m.t_s, m.vehicle, m.target, m.x_m, m.y_m, m.r_m2, m.true_x_m,
                        m.true_y_m) for f in frames for m in f.detections]
        assert from_frames == got
        assert all(m.truth == m.target for f in frames for m in f.detections)
        assert world.true_positions() == framed.true_positions()
    assert seen > 30  # the check compared real measurements
    assert world._detect_rng.bit_generator.state == detect_state
    assert world._clutter_rng.bit_generator.state == clutter_state


def test_one_frame_per_vehicle_per_tick_even_without_detections() -> None:
    world = World([Iceberg("A", 0.0, 0.0, 0.0, 0.0)], None, Camera(150.0, 2.0, 5.0),
                  np.random.default_rng(0))
    frames = world.observe_frames({"b": (1000.0, 0.0), "a": (10.0, 0.0, 120.0)})
    assert [f.vehicle for f in frames] == ["a", "b"]
    assert frames[1] == Frame(0.0, "b", 1000.0, 0.0, 150.0, ())
    assert [m.target for m in frames[0].detections] == ["A"]
    assert (frames[0].x_m, frames[0].y_m, frames[0].radius_m) == (10.0, 0.0, 150.0)
    assert world.observe_frames({"a": (0.0, 0.0)}) == []  # same tick
    world.step(0.25)
    assert world.observe_frames({"a": (0.0, 0.0)}) == []  # no new tick yet
    world.step(0.25)
    assert len(world.observe_frames({"a": (0.0, 0.0)})) == 1


def run_frames(camera: Camera, icebergs: list[Iceberg], frames: int, seed: int = 1
               ) -> list[Frame]:
    world = World(icebergs, None, camera, np.random.default_rng(seed))
    out: list[Frame] = []
    for _ in range(frames):
        out += world.observe_frames({"1": (0.0, 0.0)})
        world.step(0.5)
    return out


def test_detected_fraction_is_pd() -> None:
    pd, n = 0.7, 4000
    frames = run_frames(Camera(150.0, 2.0, 5.0, pd=pd, labelled=False),
                        [Iceberg("A", 30.0, -20.0, 0.0, 0.0), Iceberg("B", 1000.0, 0.0, 0, 0)],
                        n)
    assert len(frames) == n
    hits = sum(1 for f in frames for m in f.detections if m.truth == "A")
    assert all(m.truth != "B" for f in frames for m in f.detections)  # out of view
    bound = FOUR_SIGMA * math.sqrt(pd * (1.0 - pd) / n)
    assert abs(hits / n - pd) < bound
    assert hits < n  # it does miss


def test_clutter_is_poisson_over_the_footprint_disc() -> None:
    rate, n, radius = 0.8, 4000, 150.0
    frames = run_frames(Camera(radius, 2.0, 5.0, clutter_per_frame=rate), [], n)
    counts = np.array([len(f.detections) for f in frames])
    assert abs(counts.mean() - rate) < FOUR_SIGMA * math.sqrt(rate / n)
    assert abs(counts.var() - rate) < 0.15 * rate  # Poisson: variance = mean
    alarms = [m for f in frames for m in f.detections]
    assert all(m.target is None and m.truth is None for m in alarms)
    assert all((m.true_x_m, m.true_y_m) == (m.x_m, m.y_m) and m.r_m2 == 5.0 for m in alarms)
    dist = np.array([math.hypot(m.x_m, m.y_m) for m in alarms])
    assert dist.max() <= radius
    # uniform over the disc: half of them within R / sqrt(2), a quarter within R / 2
    for r_frac, p in ((1 / math.sqrt(2), 0.5), (0.5, 0.25)):
        share = float(np.mean(dist <= r_frac * radius))
        assert abs(share - p) < FOUR_SIGMA * math.sqrt(p * (1 - p) / len(alarms))
    angles = np.array([math.atan2(m.y_m, m.x_m) for m in alarms])
    assert abs(float(np.mean(angles > 0)) - 0.5) < FOUR_SIGMA * math.sqrt(0.25 / len(alarms))


def test_labels_truth_and_order() -> None:
    icebergs = [Iceberg("Z", 40.0, 0.0, 0.0, 0.0), Iceberg("A", -40.0, 0.0, 0.0, 0.0)]
    labelled = run_frames(Camera(150.0, 2.0, 1.0, clutter_per_frame=0.5), icebergs, 50)
    for f in labelled:
        real = [m for m in f.detections if m.truth is not None]
        assert [m.target for m in real] == ["A", "Z"]
        assert all(m.target is None for m in f.detections if m.truth is None)
    unlabelled = run_frames(Camera(150.0, 2.0, 1.0, clutter_per_frame=0.5, labelled=False),
                            icebergs, 50)
    for f in unlabelled:
        assert all(m.target is None for m in f.detections)
        assert [m.x_m for m in f.detections] == sorted(m.x_m for m in f.detections)
        assert {m.truth for m in f.detections} - {None} == {"A", "Z"}
    # clutter does not change the icebergs' noise: the truth's measurements are the same
    plain = run_frames(Camera(150.0, 2.0, 1.0, labelled=False), icebergs, 50)
    strip = [[(m.truth, m.x_m) for m in f.detections if m.truth] for f in unlabelled]
    assert strip == [[(m.truth, m.x_m) for m in f.detections] for f in plain]


def test_camera_refuses_bad_faults() -> None:
    for kw in ({"pd": 0.0}, {"pd": 1.01}, {"pd": math.nan}, {"clutter_per_frame": -0.1},
               {"clutter_per_frame": math.inf}):
        with pytest.raises(ValueError, match="Camera"):
            Camera(150.0, 2.0, 5.0, **kw)  # type: ignore[arg-type]


def test_random_icebergs_and_measurement_default_truth_unchanged() -> None:
    m = Measurement(0.0, "1", "A", 1.0, 2.0, 5.0, 1.0, 2.0)
    assert m.truth is None
    assert len(random_icebergs(np.random.default_rng(0), 3, (0, 1), (0, 1), (0, 1))) == 3
