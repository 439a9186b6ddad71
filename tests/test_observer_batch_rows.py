"""The batch's bookkeeping per tick (issue 30: the simulation loop). The members' committed
states live in the batch's stacks: a tick on the grid is one decision and three stacked
products, with no per-track Python, and every track reads exactly what the plain
per-track path (:meth:`KalmanTrack.predict_to`, one track at a time) gives, bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from observer import Observer, ObserverConfig, kalman_track
from observer.kalman_track import KalmanBatch, KalmanTrack


def _observer(n: int, fov_radius_m: float = 150.0) -> Observer:
    obs = Observer(ObserverConfig(fov_radius_m=fov_radius_m))
    for k in range(n):
        obs.add_target(f"T{k}", 0.0, 100.0 * k, 50.0 - 7.0 * k, vx_m_s=1.0 + 0.1 * k,
                       vy_m_s=-0.5, sigma0=20.0 + k)
    return obs


def _kalman(obs: Observer, target_id: str) -> KalmanTrack:
    track = obs._tracks[target_id]
    assert isinstance(track, KalmanTrack)
    return track


def test_a_tick_of_tracks_on_the_grid_decides_once_and_touches_no_track(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    obs = _observer(10)
    obs.predict_to(0.1)  # the first step: every track joins the members
    grid_steps: list[float] = []
    per_track: list[str] = []
    real_grid_steps = kalman_track.grid_steps
    real_write_back, real_predict = KalmanBatch.write_back, KalmanTrack.predict_to

    def counting_grid_steps(anchor_s: float, t_s: float, h: float) -> tuple[int, int, float]:
        grid_steps.append(t_s)
        return real_grid_steps(anchor_s, t_s, h)

    def counting_write_back(batch: KalmanBatch, track: KalmanTrack) -> None:
        per_track.append(obs._id_of[track])
        real_write_back(batch, track)

    def counting_predict(track: KalmanTrack, t_s: float) -> None:
        per_track.append("predict_to " + obs._id_of[track])
        real_predict(track, t_s)

    monkeypatch.setattr(kalman_track, "grid_steps", counting_grid_steps)
    monkeypatch.setattr(KalmanBatch, "write_back", counting_write_back)
    monkeypatch.setattr(KalmanTrack, "predict_to", counting_predict)
    for k in range(2, 12):
        obs.predict_to(k * 0.1)
    # one decision per tick for all 10 tracks, and no track's fields written
    assert grid_steps == [k * 0.1 for k in range(2, 12)]
    assert per_track == []
    # a read brings one track's fields up to date, not the others'
    assert obs.track("T3").t_s == 11 * 0.1
    assert per_track == ["T3"]
    # a correction just after the grid point (the simulator's camera clock): T3 leaves the
    # members and joins them again at the next whole step
    assert obs.measure(11 * 0.1 + 3e-14, 300.0, 30.0, "T3").accepted
    assert _kalman(obs, "T3")._stack is None
    obs.predict_to(1.2)
    assert _kalman(obs, "T3")._stack is obs._batch
    # only T3's fields were written (its reads and its release), no track predicted alone
    assert set(per_track) == {"T3"}


def _plain_track(track: KalmanTrack) -> KalmanTrack:
    """A copy of ``track`` outside any batch (the plain per-track path from here on)."""
    plain = KalmanTrack(track.t_s, [0.0] * 4, [0.0] * 4, track.q_per_s, track.grid_step_s)
    plain.kf.x, plain.kf.P = track.kf.x.copy(), track.kf.P.copy()
    plain._t_anchor_s, plain._t_s = track.t_anchor_s, track.t_s
    plain._x_view, plain._p_view = track.x_view.copy(), track.p_view.copy()
    plain._sigma = track.sigma
    return plain


def _assert_same(a: KalmanTrack, b: KalmanTrack) -> None:
    assert a.t_s == b.t_s and a.t_anchor_s == b.t_anchor_s and a.sigma == b.sigma
    assert np.array_equal(a.kf.x, b.kf.x) and np.array_equal(a.kf.P, b.kf.P)
    assert np.array_equal(a.x_view, b.x_view) and np.array_equal(a.p_view, b.p_view)


@pytest.mark.parametrize("seed", range(6))
def test_batched_observer_equals_the_plain_per_track_path_bit_for_bit(seed: int) -> None:
    """Random ticks (the simulator's fixed steps, a summed clock's jitter, the daemon's
    irregular ticks, gaps of several steps), detections just before, on and after the
    grid, new noise intensities, rewinds, new tracks and removals: every track of the
    observer equals the same track advanced alone, exactly, and is flagged lost when a
    prediction or a correction of that track alone passes the rule."""
    rng = np.random.default_rng(seed)
    obs = _observer(8, fov_radius_m=6.5)  # sigma > 42.25 m^2: lost within seconds unseen
    plain = {tid: _plain_track(_kalman(obs, tid)) for tid in obs.target_ids}
    lost = dict.fromkeys(plain, False)

    def note_lost(target_id: str) -> None:
        sigma = plain[target_id].sigma
        lost[target_id] |= sigma > 0.0 and math.sqrt(sigma) > 6.5

    def predict_plain(t_s: float) -> None:
        for target_id, tr in plain.items():
            if t_s > tr.t_s:
                tr.predict_to(t_s)
                note_lost(target_id)
    t, k = 0.0, 0
    born = 8
    mixed_steps = 0
    for _ in range(250):
        # mostly the next grid point, as a clock that sums its steps gives it; now and
        # then the same point again, a point off the grid or a gap of several steps
        k += int(rng.choice([1, 1, 1, 1, 1, 1, 0, 6]))
        jitter = float(rng.choice([0.0, 0.0, 0.0, 2e-15, -3e-15, 1e-13, 0.037]))
        t = max(t, k * 0.1 + jitter)
        obs.predict_to(t)
        predict_plain(t)
        event = rng.uniform()
        tid = str(rng.choice(sorted(plain)))
        if event < 0.25:  # a detection, off the grid by a clock's error
            t_det = t + float(rng.choice([0.0, 3e-14, -4e-14, 2e-12, 0.05]))
            x, y = plain[tid].state[:2]
            mx, my = x + float(rng.normal(0, 2)), y + float(rng.normal(0, 2))
            outcome = obs.measure(t_det, mx, my, tid)
            if outcome.accepted:
                predict_plain(t_det)
                plain[tid].correct(t_det, mx, my, obs.config.r_m2)
                note_lost(tid)
                t = max(t, t_det)
        elif event < 0.3:
            q = float(rng.uniform(0.01, 0.5))
            obs.set_process_noise(tid, q)
            plain[tid].set_process_noise(q)
        elif event < 0.33:  # a rewind into the last committed step
            t_back = t - float(rng.uniform(0.0, 0.1))
            obs.estimates_at(t_back, [tid])
            plain[tid].rewind_to(t_back)
        elif event < 0.35 and len(plain) > 3:
            obs.remove_target(tid)
            del plain[tid], lost[tid]
        elif event < 0.37:
            new_id = f"T{born}"
            born += 1
            obs.add_target(new_id, t, float(rng.normal(0, 300)), float(rng.normal(0, 300)),
                           vx_m_s=1.0, sigma0=30.0)
            plain[new_id] = _plain_track(_kalman(obs, new_id))
            lost[new_id] = False
            note_lost(new_id)
        elif event < 0.41:  # the tracker's updates: a miss's moments, a PDA update
            tr = plain[tid]
            mean = np.array(tr.state[:2]) + rng.normal(0.0, 1.0, size=2)
            obs.set_position_moments(tid, t, mean, 0.8 * tr.p_view[:2, :2])
            tr.set_position_moments(tr.t_s, mean, 0.8 * tr.p_view[:2, :2])
            note_lost(tid)
            zs = np.array(tr.state[:2]) + rng.normal(0.0, 2.0, size=(2, 2))
            betas = np.array([0.5, 0.3])
            obs.correct_pda(tid, t, zs, betas, 5.0)
            tr.correct_pda(tr.t_s, zs, betas, 5.0)
            note_lost(tid)
        elif event < 0.43 and len(plain) > 3:  # a newer estimate takes an old id over
            source = str(rng.choice([k for k in sorted(plain) if k != tid]))
            obs.take_over(tid, source)
            moved = plain.pop(source)
            del lost[source]
            moved.set_process_noise(plain[tid].q_per_s)
            plain[tid] = moved
            note_lost(tid)
        # every snapshot at once (the members read from the stacks) as one by one, exactly
        assert repr(obs.tracks()) == repr([obs.track(tid) for tid in obs.target_ids])
        for target_id, tr in plain.items():
            _assert_same(_kalman(obs, target_id), tr)
            assert obs.track(target_id).ever_lost == lost[target_id]
        mixed_steps += 0 < sum(lost.values()) < len(lost)
    assert mixed_steps > 20  # the flags were checked while some tracks were lost, some not


def test_rows_joined_after_corrections_equal_stacks_built_anew() -> None:
    """Two observers fed the same inputs: one through the batch as it is, the other with
    every member released before every step (so every track joins anew, written into
    copies of the stacks, each tick)."""
    kept, fresh = _observer(8), _observer(8)
    rng = np.random.default_rng(7)
    t_s = 0.0
    for step in range(1, 120):
        t_s = step * 0.1
        if step % 5 == 0:  # a detection just after the grid point, as the simulator's
            k = int(rng.integers(8))
            t_det = t_s + 1e-13 * float(rng.integers(0, 30))
            x, y = float(rng.normal(100.0 * k, 5.0)), float(rng.normal(50.0 - 7.0 * k, 5.0))
            for obs in (kept, fresh):
                obs.measure(t_det, x, y, f"T{k}")
        fresh._batch._release_all()
        for obs in (kept, fresh):
            obs.predict_to(t_s)
        for tid in kept.target_ids:
            _assert_same(_kalman(kept, tid), _kalman(fresh, tid))
    assert kept.counters["accepted"] == fresh.counters["accepted"] > 0


def test_lost_flags_follow_the_rule_with_the_members_stepped_together() -> None:
    """``ever_lost`` is set exactly when a moved track's ``sqrt(sigma)`` passes the
    field-of-view radius, as track by track (the batch checks only rows above a floor)."""
    cfg = ObserverConfig(fov_radius_m=12.0, q_per_s=0.5)
    obs = Observer(cfg)
    for k in range(6):
        obs.add_target(f"T{k}", 0.0, 10.0 * k, 0.0, sigma0=10.0 * k)
    t = 0.0
    for _ in range(100):
        t += 0.1
        obs.predict_to(t)
        for snap in obs.tracks():
            lost_now = snap.sigma > 0.0 and float(np.sqrt(snap.sigma)) > cfg.fov_radius_m
            assert snap.lost == lost_now
            assert not lost_now or snap.ever_lost
    assert all(s.ever_lost for s in obs.tracks())
    assert obs._batch._members == 6


def test_watched_members_are_reported_until_unwatched_and_again_after_rejoining() -> None:
    batch = KalmanBatch(0.1, watch_floor_m2=50.0)
    tracks = [KalmanTrack(0.0, [0.0] * 4, [s / 2, s / 2, 0.01, 0.01], 0.1, 0.1)
              for s in (10.0, 60.0, 80.0)]
    batch.predict_to(tracks, 0.1)  # all three join and step
    assert batch.watched_above() == tracks[1:]
    batch.unwatch(tracks[2])
    batch.advance(0.2)
    assert batch.watched_above() == [tracks[1]]
    tracks[2].correct(0.2, 0.0, 0.0, 100.0)  # leaves the members (its sigma stays > 50)
    batch.advance(0.3)  # joins again, watched from the floor
    assert tracks[2]._stack is batch and tracks[2].sigma > 50.0
    assert tracks[2] in batch.watched_above()


def test_a_member_just_inside_the_radius_stays_watched_until_it_is_lost() -> None:
    """Above the watch floor but not lost at one tick, lost at the next: flagged then."""
    def run(fov_radius_m: float, ticks: int) -> Observer:
        obs = Observer(ObserverConfig(fov_radius_m=fov_radius_m))
        obs.add_target("A", 0.0, 0.0, 0.0, sigma0=100.0)
        obs.add_target("B", 0.0, 500.0, 0.0, sigma0=1.0)
        for k in range(1, ticks + 1):
            obs.predict_to(k * 0.1)
        return obs

    sigma_20 = run(1e9, 20).sigma("A")
    fov = math.nextafter(math.sqrt(sigma_20), math.inf)  # sqrt(sigma_20) < fov, just
    obs = run(fov, 20)
    assert obs.sigma("A") == sigma_20 > fov ** 2 * (1.0 - 1e-9)  # above the floor
    assert not obs.track("A").ever_lost
    obs.predict_to(2.1)
    assert obs.track("A").lost and obs.track("A").ever_lost
    assert not obs.track("B").ever_lost
