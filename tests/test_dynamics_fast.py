"""The simulated UAV's fast path gives the plain path's numbers, bit for bit.

``world.dynamics`` steers and steps a bare pose (``point_turn_rate``, ``circle_turn_rate``,
``advance_pose``: one ``cos psi, sin psi`` shared, no state object built per call), and
``OfflineVehicle.step`` flies on them. A journal recorded by ``gcs simulate`` must replay
the same, so each is checked here against the plain formulas as they were written before
(kept below, verbatim but for names) over random poses, aims, circles and winds: every float
compared with ``==`` on its exact value (and the sign of zero), not approximately.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

from domain.geodesy import wrap_pi
from domain.wind_triangle import crab_heading_rad
from groundstation.core.mission import TargetMission
from groundstation.runners.simulate.vehicle import OfflineVehicle
from world.dynamics import (
    LoiterCommand,
    UavState,
    _saturated,
    advance_pose,
    circle_turn_rate,
    point_turn_rate,
    step_kinematics,
    step_pose,
    turn_rate_to_circle,
    turn_rate_to_point,
)

# ----------------------------------------------------------------- the plain path
# world/dynamics.py and runners/simulate/vehicle.py as they were (main at c247c22)


def plain_step_pose(x_m: float, y_m: float, heading_rad: float, speed_m_s: float,
                    turn_rate_rad_s: float, dt_s: float,
                    wind_xy_m_s: tuple[float, float]) -> tuple[float, float, float]:
    v = speed_m_s
    psi0 = heading_rad
    wx, wy = wind_xy_m_s
    drift_x, drift_y = (0.0, 0.0) if wx == 0.0 and wy == 0.0 else (wx * dt_s, wy * dt_s)
    if abs(turn_rate_rad_s) < 1e-9:
        x1 = x_m + v * math.cos(psi0) * dt_s
        y1 = y_m + v * math.sin(psi0) * dt_s
        if drift_x or drift_y:
            x1, y1 = x1 + drift_x, y1 + drift_y
        return x1, y1, psi0
    psi1 = psi0 + turn_rate_rad_s * dt_s
    radius = v / turn_rate_rad_s
    x1 = x_m + radius * (math.sin(psi1) - math.sin(psi0))
    y1 = y_m - radius * (math.cos(psi1) - math.cos(psi0))
    if drift_x or drift_y:
        x1, y1 = x1 + drift_x, y1 + drift_y
    return x1, y1, wrap_pi(psi1)


def plain_turn_rate_to_point(state: UavState, x_m: float, y_m: float,
                             min_turn_radius_m: float,
                             wind_xy_m_s: tuple[float, float]) -> float:
    u_max = state.speed_m_s / min_turn_radius_m
    dx, dy = x_m - state.x_m, y_m - state.y_m
    if math.hypot(dx, dy) < 1e-6:
        return 0.0
    bearing = math.atan2(dy, dx)
    if wind_xy_m_s[0] != 0.0 or wind_xy_m_s[1] != 0.0:
        bearing = crab_heading_rad(bearing, wind_xy_m_s, state.speed_m_s)
    err = wrap_pi(bearing - state.heading_rad)
    side = 1.0 if err >= 0.0 else -1.0
    cx = state.x_m - side * min_turn_radius_m * math.sin(state.heading_rad)
    cy = state.y_m + side * min_turn_radius_m * math.cos(state.heading_rad)
    if math.hypot(x_m - cx, y_m - cy) < min_turn_radius_m * 0.999 and abs(err) > 1e-3:
        return 0.0
    return max(-u_max, min(u_max, 2.0 * err))


def plain_turn_rate_to_circle(state: UavState, command: LoiterCommand,
                              min_turn_radius_m: float,
                              wind_xy_m_s: tuple[float, float]) -> float:
    v = state.speed_m_s
    u_max = v / min_turn_radius_m
    radius = max(command.radius_m, min_turn_radius_m)
    lam = -1.0 if command.clockwise else 1.0
    dx, dy = state.x_m - command.x_m, state.y_m - command.y_m
    d = math.hypot(dx, dy)
    if d < 1e-6:
        return 0.0
    gamma = math.atan2(dy, dx)
    chi_d = gamma + lam * (math.pi / 2.0 + math.atan(2.0 * (d - radius) / radius))
    wx, wy = wind_xy_m_s
    if wx == 0.0 and wy == 0.0:
        err = wrap_pi(chi_d - state.heading_rad)
        feed_forward = lam * v / max(d, radius)
    else:
        err = wrap_pi(crab_heading_rad(chi_d, wind_xy_m_s, v) - state.heading_rad)
        c, s = math.cos(chi_d), math.sin(chi_d)
        w_perp = wx * s - wy * c
        along = math.sqrt(max(v * v - w_perp * w_perp, (1e-3 * v) ** 2))
        ground = max(wx * c + wy * s + along, 0.0)
        feed_forward = lam * ground * ground / (max(d, radius) * along)
    return max(-u_max, min(u_max, 2.0 * err + feed_forward))


@dataclass
class PlainVehicle:
    """``OfflineVehicle`` as it was, on the plain functions."""

    state: UavState
    turn_radius_m: float
    arrival_radius_m: float
    loiter_radius_m: float
    phase: str = "free"
    aim_xy_m: tuple[float, float] | None = None
    loiter_s: float = 0.0
    loiter_end_s: float | None = None
    through: tuple[tuple[float, float], ...] = ()

    def step(self, t_s: float, dt_s: float, wind_xy_m_s: tuple[float, float]) -> bool:
        ended = False
        s = self.state
        if self.aim_xy_m is None:
            rate = 0.0
        elif self.phase == "transit" and self.loiter_s <= 0.0:
            rate = plain_turn_rate_to_point(s, *self.aim_xy_m, self.turn_radius_m,
                                            wind_xy_m_s)
        else:
            circle = LoiterCommand(*self.aim_xy_m, self.loiter_radius_m)
            rate = plain_turn_rate_to_circle(s, circle, self.turn_radius_m, wind_xy_m_s)
        self.state = UavState(*plain_step_pose(s.x_m, s.y_m, s.heading_rad, s.speed_m_s,
                                               rate, dt_s, wind_xy_m_s), s.speed_m_s)
        t_next = t_s + dt_s
        if self.aim_xy_m is None:
            return False
        if self.phase == "transit":
            if self.loiter_s <= 0.0:
                if math.dist((self.state.x_m, self.state.y_m), self.aim_xy_m) <= (
                    self.arrival_radius_m
                ):
                    here = (self.state.x_m, self.state.y_m)
                    while self.through and math.dist(here, self.through[0]) <= (
                            self.arrival_radius_m):
                        self.aim_xy_m, self.through = self.through[0], self.through[1:]
                    if self.through:
                        self.aim_xy_m, self.through = self.through[0], self.through[1:]
                    else:
                        self.phase, ended = "hold", True
            else:
                radius = max(self.loiter_radius_m, self.turn_radius_m)
                gap_m = abs(math.hypot(self.state.x_m - self.aim_xy_m[0],
                                       self.state.y_m - self.aim_xy_m[1]) - radius)
                if gap_m <= 15.0:
                    self.phase, self.loiter_end_s = "loiter", t_next + self.loiter_s
        elif self.phase == "loiter" and self.loiter_end_s is not None and (
            t_next >= self.loiter_end_s - 1e-9
        ):
            self.phase, ended = "hold", True
        return ended


# ----------------------------------------------------------------- random cases


def bits(*values: float) -> tuple[str, ...]:
    """Exact values, the sign of zero included (``0.0 == -0.0`` would hide it)."""
    return tuple(float(v).hex() for v in values)


def pose(state: UavState) -> tuple[float, float, float, float]:
    return state.x_m, state.y_m, state.heading_rad, state.speed_m_s


def random_wind(rng: random.Random) -> tuple[float, float]:
    """Still air, one axis only, or both (the still-air branches are exact in themselves)."""
    kind = rng.randrange(4)
    if kind == 0:
        return (0.0, 0.0)
    speed = rng.choice([0.5, 5.0, 12.0, 25.0]) * rng.random()
    if kind == 1:
        return (speed, 0.0)
    if kind == 2:
        return (0.0, -speed)
    return (rng.uniform(-15.0, 15.0), rng.uniform(-15.0, 15.0))


def random_state(rng: random.Random) -> UavState:
    heading = rng.choice([rng.uniform(-math.pi, math.pi), math.pi - 1e-12, -math.pi, 0.0,
                          rng.uniform(-10.0, 10.0)])
    return UavState(rng.uniform(-2000.0, 2000.0), rng.uniform(-2000.0, 2000.0), heading,
                    rng.choice([22.0, rng.uniform(5.0, 35.0)]))


def random_aim(rng: random.Random, state: UavState) -> tuple[float, float]:
    """Anywhere, close by (inside the turning circles too), or on the vehicle itself."""
    kind = rng.randrange(4)
    if kind == 0:
        return (state.x_m, state.y_m)
    spread = 3000.0 if kind == 1 else 250.0 if kind == 2 else 1e-6
    return (state.x_m + rng.uniform(-spread, spread), state.y_m + rng.uniform(-spread, spread))


def test_point_guidance_is_the_plain_rule_bit_for_bit() -> None:
    rng = random.Random(20261127)
    for _ in range(20_000):
        state = random_state(rng)
        aim = random_aim(rng, state)
        r_min = rng.choice([105.0, rng.uniform(20.0, 300.0)])
        wind = random_wind(rng)
        plain = plain_turn_rate_to_point(state, *aim, r_min, wind)
        psi = state.heading_rad
        fast = point_turn_rate(state.x_m, state.y_m, psi, math.cos(psi), math.sin(psi),
                               state.speed_m_s, *aim, r_min, wind)
        wrapped = turn_rate_to_point(state, *aim, r_min, wind_xy_m_s=wind)
        assert bits(fast) == bits(plain) == bits(wrapped), (state, aim, r_min, wind)


def test_circle_guidance_is_the_plain_rule_bit_for_bit() -> None:
    rng = random.Random(4)
    for _ in range(20_000):
        state = random_state(rng)
        centre = random_aim(rng, state)
        circle = LoiterCommand(*centre, rng.uniform(30.0, 400.0), rng.random() < 0.5)
        r_min = rng.choice([105.0, rng.uniform(20.0, 300.0)])
        wind = random_wind(rng)
        plain = plain_turn_rate_to_circle(state, circle, r_min, wind)
        fast = circle_turn_rate(state.x_m, state.y_m, state.heading_rad, state.speed_m_s,
                                circle.x_m, circle.y_m, circle.radius_m, circle.clockwise,
                                r_min, wind)
        wrapped = turn_rate_to_circle(state, circle, r_min, wind_xy_m_s=wind)
        assert bits(fast) == bits(plain) == bits(wrapped), (state, circle, r_min, wind)


def test_a_step_of_the_pose_is_the_plain_arc_bit_for_bit() -> None:
    rng = random.Random(7)
    for _ in range(20_000):
        state = random_state(rng)
        u_max = state.speed_m_s / 105.0
        rate = rng.choice([0.0, -0.0, 5e-10, -5e-10, 1e-9, -1e-9, 2e-9,
                           rng.uniform(-u_max, u_max)])
        dt_s = rng.choice([0.1, 0.02, rng.uniform(0.0, 2.0)])
        wind = random_wind(rng)
        plain = plain_step_pose(state.x_m, state.y_m, state.heading_rad, state.speed_m_s,
                                rate, dt_s, wind)
        psi = state.heading_rad
        fast = advance_pose(state.x_m, state.y_m, psi, math.cos(psi), math.sin(psi),
                            state.speed_m_s, rate, dt_s, wind)
        bare = step_pose(state.x_m, state.y_m, psi, state.speed_m_s, rate, dt_s, wind)
        stepped = step_kinematics(state, rate, dt_s, wind_xy_m_s=wind)
        assert bits(*fast) == bits(*plain) == bits(*bare), (state, rate, dt_s, wind)
        assert bits(*pose(stepped)) == bits(*plain, state.speed_m_s)


def random_mission(rng: random.Random, here: UavState) -> TargetMission:
    """A pass (with or without waypoints to fly through, some repeated) or a timed loiter,
    near enough for arrivals, circles reached and loiters ended to happen."""
    aim = (here.x_m + rng.uniform(-350.0, 350.0), here.y_m + rng.uniform(-350.0, 350.0))
    if rng.random() < 0.4:
        return TargetMission("T1", *aim, rng.choice([1, 2, 5]), rng.uniform(60.0, 200.0))
    through: list[tuple[float, float]] = []
    for _ in range(rng.randrange(4)):
        last = through[-1] if through else aim
        through.append(last if rng.random() < 0.3 else
                       (last[0] + rng.uniform(-250.0, 250.0), last[1] + rng.uniform(-250.0, 250.0)))
    return TargetMission("T1", *aim, 0, rng.uniform(60.0, 200.0), tuple(through))


def fly_both(seed: int) -> set[tuple[str, str]]:
    """Random commands (passes, waypoints, loiters, holds, none) in random winds over
    3 000 steps of both vehicles: the same pose after every step, the same phases and loiter
    ends. Returns the phase changes flown (before, after)."""
    rng = random.Random(seed)
    start = random_state(rng)
    fast = OfflineVehicle("1", start, 105.0, 30.0, loiter_radius_m=120.0)
    plain = PlainVehicle(start, 105.0, 30.0, 120.0)
    wind = random_wind(rng)
    flown: set[tuple[str, str]] = set()
    for k in range(3_000):
        t_s = k * 0.1
        if k % 150 == 0:
            wind = random_wind(rng) if rng.random() < 0.5 else wind
            choice = rng.random()
            if choice < 0.7:
                mission = random_mission(rng, fast.state)
                fast.command_fly(mission)
                plain.aim_xy_m, plain.through = (mission.x_m, mission.y_m), mission.through
                plain.loiter_s = float(mission.loiter_s)
                plain.loiter_radius_m = mission.loiter_radius_m
                plain.loiter_end_s, plain.phase = None, "transit"
            elif choice < 0.9:
                x_m, y_m = fast.state.x_m + 300.0, fast.state.y_m
                fast.command_hold(x_m, y_m, 150.0)
                plain.aim_xy_m, plain.loiter_radius_m = (x_m, y_m), 150.0
                plain.phase, plain.through = "hold", ()
            else:  # launched, nothing commanded yet
                fast.aim_xy_m = plain.aim_xy_m = None
                fast.phase = plain.phase = "free"
        before = fast.phase
        assert fast.step(t_s, 0.1, wind) == plain.step(t_s, 0.1, wind)
        assert bits(*pose(fast.state)) == bits(*pose(plain.state)), (seed, k)
        assert (fast.phase, fast.aim_xy_m, fast.through, fast.loiter_end_s) == (
            plain.phase, plain.aim_xy_m, plain.through, plain.loiter_end_s)
        flown.add((before, fast.phase))
    return flown


def test_the_offline_vehicle_flies_the_plain_path_bit_for_bit() -> None:
    flown: set[tuple[str, str]] = set()
    for seed in range(8):
        flown |= fly_both(seed)
    # the cases reach what they are meant to check: a pass's end, a loiter circle reached,
    # a loiter's end, holds and free flight
    assert {("transit", "hold"), ("transit", "loiter"), ("loiter", "hold"), ("hold", "hold"),
            ("free", "free")} <= flown


def test_saturation_is_the_builtins_min_and_max_bit_for_bit() -> None:
    """``_saturated`` against ``max(-u, min(u, r))``: ties, signed zeros, infinities, NaN."""
    rng = random.Random(11)
    specials = [0.0, -0.0, 1.0, -1.0, math.inf, -math.inf, math.nan, 0.2095, -0.2095]
    cases = [(r, u) for r in specials for u in specials if not math.isnan(u)]
    cases += [(rng.uniform(-1.0, 1.0), rng.uniform(0.0, 0.5)) for _ in range(10_000)]
    for rate, u_max in cases:
        assert bits(_saturated(rate, u_max)) == bits(max(-u_max, min(u_max, rate))), (
            rate, u_max)
