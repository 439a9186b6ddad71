"""Tests for world/model.py: icebergs, boat, camera (seeded)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from world.model import Boat, Camera, Iceberg, Measurement, World, random_icebergs


def run(world: World, seconds: float, dt: float, uavs: dict[str, tuple[float, float]]) -> list:
    out = list(world.observe(uavs))
    for _ in range(round(seconds / dt)):
        world.step(dt)
        out += world.observe(uavs)
    return out


def test_iceberg_moves_at_its_velocity_and_boat_keeps_course() -> None:
    boat = Boat(1500.0, 0.0, 2.0246, 10.0)
    world = World([Iceberg("A", 100.0, 200.0, 1.5, -2.0)], boat, Camera(), np.random.default_rng(0))
    for _ in range(100):
        world.step(0.1)
    assert world.t_s == pytest.approx(10.0)
    assert world.true_positions() == {"A": pytest.approx((115.0, 180.0))}
    assert (world.icebergs["A"].vx_m_s, world.icebergs["A"].vy_m_s) == (1.5, -2.0)
    assert world.boat is not None
    assert (world.boat.x_m, world.boat.y_m) == pytest.approx(
        (1500.0 + 100.0 * math.cos(2.0246), 100.0 * math.sin(2.0246))
    )
    assert world.boat.heading_rad == 2.0246


def test_process_noise_spreads_velocity_with_variance_q_t() -> None:
    icebergs = [Iceberg(f"I{i}", 0.0, 0.0, 0.0, 0.0, q_per_s=0.1) for i in range(400)]
    world = World(icebergs, None, Camera(), np.random.default_rng(1))
    for _ in range(100):
        world.step(0.1)
    v = np.array([(i.vx_m_s, i.vy_m_s) for i in world.icebergs.values()])
    # var(v) = q T = 0.1 * 10 = 1 per axis (800 samples: +-15 % is > 4 standard errors)
    assert v.var() == pytest.approx(1.0, rel=0.15)
    # position: sum over steps of the velocity (discrete): var = q h^3 sum_{j<n} j^2 = 28.5
    p = np.array(list(world.true_positions().values()))
    assert p.var() == pytest.approx(0.1 * 0.1**3 * sum(j * j for j in range(100)), rel=0.2)


def test_camera_sees_only_within_fov() -> None:
    icebergs = [
        Iceberg("in", 149.0, 0.0, 0.0, 0.0),
        Iceberg("out", 0.0, 151.0, 0.0, 0.0),
        Iceberg("diag", 100.0, 100.0, 0.0, 0.0),  # 141 m
    ]
    world = World(icebergs, None, Camera(fov_radius_m=150.0), np.random.default_rng(2))
    ms = world.observe({"u1": (0.0, 0.0, 120.0)})
    assert sorted(m.target for m in ms) == ["diag", "in"]
    assert all(m.vehicle == "u1" and m.r_m2 == 5.0 and m.t_s == 0.0 for m in ms)
    world.step(0.5)
    ms = world.observe({"u1": (0.0, 0.0), "u2": (0.0, 300.0)})
    assert sorted((m.vehicle, m.target) for m in ms) == [
        ("u1", "diag"),
        ("u1", "in"),
        ("u2", "out"),
    ]
    world.step(0.5)
    assert world.observe({}) == []


@pytest.mark.parametrize("dt", [0.1, 0.05, 0.25, 0.5])
def test_camera_rate_is_2_hz_on_the_grid(dt: float) -> None:
    world = World([Iceberg("A", 0.0, 0.0, 0.0, 0.0)], None, Camera(), np.random.default_rng(3))
    ms = run(world, 10.0, dt, {"u": (0.0, 0.0)})
    assert len(ms) == 21  # t = 0, 0.5, ..., 10
    assert [m.t_s for m in ms] == pytest.approx([0.5 * k for k in range(21)])
    # calling observe twice at the same time gives nothing new
    assert world.observe({"u": (0.0, 0.0)}) == []


def test_camera_rate_when_steps_do_not_divide_the_period() -> None:
    world = World([Iceberg("A", 0.0, 0.0, 0.0, 0.0)], None, Camera(), np.random.default_rng(3))
    ms = run(world, 9.9, 0.3, {"u": (0.0, 0.0)})
    assert len(ms) == 20  # one per tick 0 .. 19 (ticks at 0.5 k <= 9.9), stamped at the step
    assert all(b.t_s - a.t_s >= 0.3 - 1e-9 for a, b in itertools.pairwise(ms))


def test_camera_noise_has_variance_r_and_is_seeded() -> None:
    def errors(seed: int) -> np.ndarray:
        world = World(
            [Iceberg("A", 10.0, -20.0, 0.0, 0.0), Iceberg("far", 500.0, 0.0, 0.0, 0.0)],
            None,
            Camera(r_m2=5.0),
            np.random.default_rng(seed),
        )
        ms = run(world, 1000.0, 0.5, {"u": (0.0, 0.0)})
        ms = [m for m in ms if isinstance(m, Measurement)]
        assert len(ms) == 2001 and {m.target for m in ms} == {"A"}
        return np.array([(m.x_m - m.true_x_m, m.y_m - m.true_y_m) for m in ms])

    e = errors(4)
    # 2001 samples per axis: standard error of the variance 5 sqrt(2/2001) = 0.16; 4 SE
    assert e.var(axis=0) == pytest.approx([5.0, 5.0], rel=0.13)
    assert np.abs(e.mean(axis=0)).max() < 0.25  # 5 standard errors
    assert np.array_equal(errors(4), e)
    assert not np.array_equal(errors(5)[:10], e[:10])


def test_iceberg_paths_do_not_depend_on_the_fleet() -> None:
    def final(uavs: dict[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
        rng = np.random.default_rng(7)
        world = World(
            random_icebergs(rng, 10, (0, 1500), (0, 1500), (-3, 3), q_per_s=0.1),
            Boat(1500.0, 0.0, 2.0246, 10.0),
            Camera(),
            rng,
        )
        run(world, 20.0, 0.1, uavs)
        return world.true_positions()

    one = final({"u1": (700.0, 700.0)})
    three = final({"u1": (700.0, 700.0), "u2": (300.0, 300.0), "u3": (1200.0, 200.0)})
    assert one == three
    assert one == final({})


def test_add_and_remove_icebergs_at_run_time() -> None:
    world = World([Iceberg("A", 0.0, 0.0, 0.0, 0.0)], None, Camera(), np.random.default_rng(0))
    world.step(1.0)
    world.add_iceberg(Iceberg("B", 10.0, 0.0, 0.0, 0.0))
    assert {m.target for m in world.observe({"u": (0.0, 0.0)})} == {"A", "B"}
    with pytest.raises(ValueError, match="already"):
        world.add_iceberg(Iceberg("B", 0.0, 0.0, 0.0, 0.0))
    world.remove_iceberg("A")
    assert list(world.true_positions()) == ["B"]
    with pytest.raises(KeyError):
        world.remove_iceberg("A")
    with pytest.raises(ValueError, match="vx_m_s"):
        world.add_iceberg(Iceberg("C", 0.0, 0.0, math.nan, 0.0))
    with pytest.raises(ValueError, match="rate_hz"):
        Camera(rate_hz=0.0)


def test_random_icebergs_follow_table_1() -> None:
    ice = random_icebergs(np.random.default_rng(0), 10, (0, 1500), (0, 1500), (-3, 3))
    assert [i.id for i in ice] == [f"T{k}" for k in range(1, 11)]
    for i in ice:
        assert 0 <= i.x_m <= 1500 and 0 <= i.y_m <= 1500
        assert -3 <= i.vx_m_s <= 3 and -3 <= i.vy_m_s <= 3 and i.q_per_s == 0.0
    again = random_icebergs(np.random.default_rng(0), 10, (0, 1500), (0, 1500), (-3, 3))
    assert again == ice
    assert len({(i.x_m, i.y_m) for i in ice}) == 10


@pytest.mark.parametrize("dt", [0.1, 0.07, 0.5])
def test_frames_due_says_whether_observe_frames_has_frames(dt: float) -> None:
    """The simulator asks before building the vehicles' positions (issue 30): the answer is
    observe_frames' own rule, asked without taking the frames."""
    world = World([Iceberg("a", 0.0, 0.0, 1.0, 0.0)], None, Camera(rate_hz=2.0),
                  np.random.default_rng(3))
    due_steps = 0
    for _ in range(60):
        due = world.frames_due()
        assert world.frames_due() == due  # asking takes nothing
        frames = world.observe_frames({"u1": (0.0, 0.0)})
        assert bool(frames) == due
        due_steps += due
        world.step(dt)
    assert 0 < due_steps < 60 or dt == 0.5
