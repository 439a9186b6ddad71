"""Sans-IO: the telemetry age estimator (``groundstation/mavlink/telemetry_age.py``) and
the freshness rules built on it (``groundstation/vehicle/freshness.py``): backlog, jitter,
pause, reboot, forged clocks, and the prediction a lagging vehicle is planned from."""

from __future__ import annotations

import itertools
import math
import random
from dataclasses import replace

import pytest

from groundstation.mavlink.telemetry_age import TelemetryAge
from groundstation.mavlink.telemetry_events import VehicleSnapshot
from groundstation.vehicle.freshness import Freshness

OFFSET_S = -1000.0  # mission time = vehicle time - 1000 s (+ delay)


def feed(est: TelemetryAge, t0: float, t1: float, rate_hz: float, delay_s: float = 0.0,
         offset_s: float = OFFSET_S) -> float | None:
    """Frames made every 1/rate_hz vehicle s from t0 to t1 (mission), each arriving
    ``delay_s`` late; the age of the last."""
    age = None
    n = round((t1 - t0) * rate_hz)
    for k in range(n + 1):
        made = t0 + k / rate_hz
        age = est.observe(round((made - offset_s) * 1000), made + delay_s)
    return age


def test_fresh_frames_with_jitter_are_fresh() -> None:
    est = TelemetryAge()
    rng = random.Random(1)
    ages = []
    for k in range(600):  # 60 s at 10 Hz, 0-300 ms of random delay
        made = k * 0.1
        ages.append(est.observe(round((made - OFFSET_S) * 1000), made + rng.uniform(0, 0.3)))
    assert max(a for a in ages[10:] if a is not None) <= 0.31


def test_a_backlog_is_measured_and_drains() -> None:
    """10 s of fresh frames, then a stall that delivers each frame later and later (the
    lag grows 1 s per s for 20 s; the frames come in bursts between the flood's, every
    3 s), then the backlog drained in 1 s, then fresh again."""
    est = TelemetryAge()
    feed(est, 0.0, 10.0, 10)
    ages = []
    for k in range(200):  # made 10..30 s, arriving at 10 + 2 * (made - 10) (growing lag)
        made = 10.0 + k * 0.1
        burst = 3.0 * math.ceil((10.0 + 2.0 * (made - 10.0)) / 3.0)
        ages.append(est.observe(round((made - OFFSET_S) * 1000), burst))
    assert ages[-1] == pytest.approx(21.1, abs=0.6)  # creep: 1 % of 21 s at most
    assert est.resyncs == 0
    drained = []
    for k in range(100):  # made 30..40 s, all delivered between 50 and 51 s
        made = 30.0 + k * 0.1
        drained.append(est.observe(round((made - OFFSET_S) * 1000), 50.0 + k * 0.01))
    assert drained[0] == pytest.approx(20.0, abs=0.6)
    assert drained[-1] == pytest.approx(11.0, abs=0.5)  # made at 39.9, read at 50.99
    assert feed(est, 51.0, 55.0, 10) == pytest.approx(0.0, abs=0.3)  # the baseline held


def test_a_pause_is_not_a_lag() -> None:
    """A silence (no frames) changes nothing: the next frame is as fresh as it is."""
    est = TelemetryAge()
    feed(est, 0.0, 10.0, 10)
    assert feed(est, 40.0, 41.0, 10) == pytest.approx(0.0, abs=0.35)  # creep 0.3 s max


def test_a_reboot_starts_a_new_clock() -> None:
    est = TelemetryAge()
    feed(est, 0.0, 100.0, 5)
    # rebooted at 100 s: its clock restarts at 0; without reset every frame looks 1100 s old
    assert feed(est, 101.0, 102.0, 5, offset_s=101.0) > 1000.0
    est.reset()
    assert feed(est, 102.2, 105.0, 5, offset_s=101.0) == pytest.approx(0.0, abs=1e-6)


def test_one_forged_large_boot_time_changes_nothing() -> None:
    est = TelemetryAge()
    feed(est, 0.0, 10.0, 10)
    assert est.observe(4_000_000_000, 10.05) == 0.0  # judged fresh, not believed
    assert feed(est, 10.1, 12.0, 10) == pytest.approx(0.0, abs=0.05)
    # a burst of them (no span) either
    for _ in range(5):
        est.observe(4_000_000_000, 12.05)
    assert feed(est, 12.1, 14.0, 10) == pytest.approx(0.0, abs=0.05)


def test_first_heard_through_a_backlog_corrected_by_fresher_frames() -> None:
    """The first frames were 8 s late (a backlog when floe connected); three fresher frames
    over a second correct the baseline, so the backlog is seen for what it was."""
    est = TelemetryAge()
    feed(est, 0.0, 2.0, 10, delay_s=8.0)
    assert est.observe(round((1.0 - OFFSET_S) * 1000), 9.0) == 0.0  # looks fresh: no reference
    ages = [est.observe(round((made - OFFSET_S) * 1000), made) for made in (10.0, 10.5, 11.0)]
    assert ages[-1] == pytest.approx(0.0, abs=0.01)
    assert est.age_s(round((2.0 - OFFSET_S) * 1000), 11.0) == pytest.approx(9.0, abs=0.01)


def test_a_step_that_stays_is_followed() -> None:
    """The clock moved by 40 s (a reboot unseen during a long silence): after resync_after_s
    of steady frames the baseline follows; a growing backlog (frames in bursts between a
    flood's) never resyncs."""
    est = TelemetryAge()
    feed(est, 0.0, 10.0, 10)
    assert feed(est, 60.0, 80.0, 10, offset_s=OFFSET_S + 40.0) > 39.0
    assert feed(est, 80.1, 95.0, 10, offset_s=OFFSET_S + 40.0) == pytest.approx(0.0, abs=0.01)
    assert est.resyncs == 1
    grow = TelemetryAge()
    feed(grow, 0.0, 10.0, 10)
    for k in range(600):  # 60 s of a lag growing at 0.5 s per s, in bursts every 3 s
        made = 10.0 + k * 0.1
        burst = 3.0 * math.ceil((10.0 + 1.5 * (made - 10.0)) / 3.0)
        grow.observe(round((made - OFFSET_S) * 1000), burst)
    assert grow.resyncs == 0


def test_a_slow_clock_drift_is_followed() -> None:
    """The vehicle's clock runs 0.5 % slow against the mission clock: within the creep."""
    est = TelemetryAge()
    age = None
    for k in range(6000):  # 600 s
        t = k * 0.1
        age = est.observe(round((0.995 * t - OFFSET_S) * 1000), t)
    assert age is not None and age < 0.2


# ------------------------------------------------------------------ freshness, prediction
def snap_at(boot_ms: int, heard_s: float, **kw: float) -> VehicleSnapshot:
    return replace(VehicleSnapshot(system_id=1), x_m=0.0, y_m=0.0, ve_m_s=20.0, vn_m_s=0.0,
                   heading_rad=0.0, speed_m_s=20.0, position_boot_ms=boot_ms,
                   last_heard_s=heard_s, **kw)


def test_lagging_needs_frames_heard_after_the_fix_went_stale() -> None:
    fresh = Freshness(2.0)
    for k in range(20):
        fresh.frame(k * 100, 100.0 + k * 0.1)  # vehicle 0..1.9 s at mission 100..101.9
    snap = snap_at(1900, 101.9)
    assert fresh.assess(snap, 104.5, link_lost=False) is None  # silence: not lagging
    change = fresh.assess(replace(snap, last_heard_s=104.5), 104.5, link_lost=False)
    assert change is not None and change.lagging and change.age_s == pytest.approx(2.6, abs=0.1)
    assert fresh.lagging
    end = fresh.assess(replace(snap, position_boot_ms=4000), 104.6, link_lost=False)
    assert end is not None and not end.lagging and end.lagged_s == pytest.approx(0.1)


def test_prediction_dead_reckons_and_goes_to_the_loiter() -> None:
    fresh = Freshness(2.0)
    fresh.frame(0, 100.0)
    snap = snap_at(0, 110.0)
    p = fresh.predict(snap, 110.0)
    assert p is not None and p.how == "dead_reckoning"
    assert p.fix_age_s == pytest.approx(9.9)  # 10 s, less the creep of 1 % since
    assert (p.x_m, p.y_m) == pytest.approx((198.0, 0.0))
    assert p.sigma_m == pytest.approx(5.0 + 198.0 / 3.0)
    to_aim = fresh.predict(snap, 110.0, aim_xy_m=(0.0, 1000.0), loiter_radius_m=100.0)
    assert to_aim is not None and to_aim.how == "to_aim"
    assert (to_aim.x_m, to_aim.y_m) == pytest.approx((0.0, 198.0))
    assert to_aim.heading_rad == pytest.approx(math.pi / 2)
    there = fresh.predict(snap, 110.0, aim_xy_m=(0.0, 250.0), loiter_radius_m=100.0)
    assert there is not None and there.how == "loiter"
    assert (there.x_m, there.y_m) == (0.0, 250.0) and there.sigma_m >= 100.0
    assert fresh.predict(snap, 101.0) is None  # 1 s old: the fix itself is used


# ------------------------------------------------------------------ the controller
def test_controller_plans_a_lagging_vehicle_from_a_prediction() -> None:
    """Sans-IO (the controller rig of ``test_vehicle_controller``): fresh fixes go to the
    core as they come; when the positions arrive ever later (a backlog: frames keep
    arriving) the controller says so once, gives the core predictions (at most one per
    mission second), never the stale fix, and says when it is fresh again."""
    from test_vehicle_controller import active_rig

    from groundstation.core import events as ev
    from groundstation.vehicle import controller_io as vio

    rig = active_rig()
    x0 = rig.snap.x_m or 0.0

    def position(boot_s: float, x_m: float) -> None:
        boot_ms = round(boot_s * 1000)
        rig.snap = replace(rig.snap, last_heard_s=rig.t, x_m=x_m, ve_m_s=20.0, vn_m_s=0.0,
                           position_boot_ms=boot_ms)
        rig.feed(vio.AutopilotFrame(rig.t, "GLOBAL_POSITION_INT", rig.snap, (), boot_ms))
        rig.feed(vio.TimePassed(rig.t))

    while rig.t < 10.0:  # fresh: vehicle clock = mission clock + 100 s
        rig.t = round(rig.t + 0.1, 6)
        position(rig.t + 100.0, x0 + 20.0 * rig.t)
    fresh_poses = rig.core(ev.Telemetry)
    assert fresh_poses and all(p.fix_age_s is None for p in fresh_poses)
    n_fresh = len(fresh_poses)
    while rig.t < 30.0:  # a backlog: each fix made 0.5 s of vehicle time per s, then 0.1 s
        rig.t = round(rig.t + 0.1, 6)
        made = 10.0 + 0.5 * (rig.t - 10.0)
        position(made + 100.0, x0 + 20.0 * made)
    [lagging] = rig.journal("telemetry_lagging")
    assert lagging.logged and 2.0 < lagging.fields["age_s"] < 3.0
    backlog = rig.core(ev.Telemetry)[n_fresh:]
    raw = [p for p in backlog if p.fix_age_s is None]
    assert all(p.t_s <= 14.2 for p in raw)  # fixes while they were at most 2 s old
    predicted = [p for p in backlog if p.fix_age_s is not None]
    assert len(predicted) >= 14 and max(p.fix_age_s for p in predicted) > 9.0
    assert all(b.t_s - a.t_s >= 1.0 - 1e-9 for a, b in itertools.pairwise(predicted))
    for p in predicted:  # dead reckoning at its 20 m/s: where it really is (less the creep)
        assert abs(p.x_m - (x0 + 20.0 * p.t_s)) < 0.01 * (p.t_s - 10.0) * 20.0 + 2.5
    assert not rig.journal("telemetry_fresh")
    rig.t = round(rig.t + 0.1, 6)
    position(rig.t + 100.0, x0 + 20.0 * rig.t)  # the backlog drained: fresh again
    rig.feed(vio.TimePassed(rig.t))
    [fresh] = rig.journal("telemetry_fresh")
    assert fresh.fields["worst_age_s"] > 9.0 and rig.core(ev.Telemetry)[-1].fix_age_s is None
    assert not rig.journal("link_lost")


def test_a_clock_measured_slow_is_no_backlog() -> None:
    """A simulator that keeps only 0.44 of its speed-up: frames arrive regularly, their
    offsets grow 0.56 s per s; after resync_after_s the estimator takes it for the clock."""
    est = TelemetryAge()
    ages = []
    for k in range(600):  # 60 s at 10 Hz
        t = k * 0.1
        ages.append(est.observe(round((0.44 * t + 5.0) * 1000), t))
    assert max(a for a in ages if a is not None) > 10.0
    assert est.resyncs == 1 and est.creep_s_per_s == pytest.approx(0.56, abs=0.01)
    assert ages[-1] is not None and ages[-1] < 0.3
