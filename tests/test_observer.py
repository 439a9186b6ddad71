"""Unit tests for observer/: Kalman maths, time grid, gating, association, linear model."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from observer import (
    MeasurementOutcome,
    Observer,
    ObserverConfig,
    TrackSnapshot,
    boat_priority_q,
)


def kalman(**kw: float) -> Observer:
    return Observer(ObserverConfig(**kw))  # type: ignore[arg-type]


def snap_tuple(s: TrackSnapshot) -> tuple[float, ...]:
    return (s.t_s, s.x_m, s.y_m, s.vx_m_s, s.vy_m_s, s.sigma, *s.cov_xy)


# --- one step against hand-computed matrices ------------------------------------------------
def test_one_predict_and_update_match_hand_computed_matrices() -> None:
    obs = kalman(q_per_s=0.1, r_m2=5.0)
    obs.add_target("A", 0.0, 0.0, 0.0, vx_m_s=1.0, vy_m_s=2.0, p0=(1.0, 1.0, 1.0, 1.0))
    obs.predict_to(0.1)
    s = obs.track("A")
    # x^- = A x: (0 + 0.1*1, 0 + 0.1*2, 1, 2)
    assert (s.x_m, s.y_m, s.vx_m_s, s.vy_m_s) == pytest.approx((0.1, 0.2, 1.0, 2.0))
    # per axis P^- = A P A' + Q = [[1 + 0.1^2, 0.1], [0.1, 1 + 0.1*0.1]]
    assert s.cov_xy == pytest.approx((1.01, 0.0, 1.01))
    assert s.sigma == pytest.approx(2.02)
    out = obs.measure(0.1, 1.1, 0.2, "A")
    # innovation (1, 0), S = 1.01 + 5 = 6.01 per axis
    assert (out.accepted, out.target_id, out.reason) == (True, "A", "accepted")
    assert isinstance(out, MeasurementOutcome) and out.mahalanobis2 == pytest.approx(1.0 / 6.01)
    s = obs.track("A")
    # K = P^- C' S^-1 = (1.01/6.01, 0.1/6.01) on the x axis
    assert s.x_m == pytest.approx(0.1 + 1.01 / 6.01)
    assert s.vx_m_s == pytest.approx(1.0 + 0.1 / 6.01)
    assert (s.y_m, s.vy_m_s) == pytest.approx((0.2, 2.0))
    # P = (I - K C) P^-: Pxx = 1.01 * 5 / 6.01
    pxx = 1.01 * 5.0 / 6.01
    assert s.cov_xy == pytest.approx((pxx, 0.0, pxx))
    assert s.last_seen_s == 0.1
    # one more prediction exercises the cross terms: Pxv = 0.1*5/6.01, Pvv = 1.01 - 0.01/6.01
    pxv, pvv = 0.5 / 6.01, 1.01 - 0.01 / 6.01
    obs.predict_to(0.2)
    expected_pxx = pxx + 2 * 0.1 * pxv + 0.01 * pvv
    assert obs.track("A").cov_xy == pytest.approx((expected_pxx, 0.0, expected_pxx))


def test_default_p0_is_q_of_one_step_and_sigma_growth_is_closed_form() -> None:
    obs = kalman(q_per_s=0.1)
    obs.add_target("A", 0.0, 10.0, 20.0)
    s = obs.track("A")
    assert s.sigma == 0.0 and s.cov_xy == (0.0, 0.0, 0.0)  # P0 = diag(0, 0, q dt, q dt)
    obs.predict_to(0.05)  # partial step: Pxx = dt^2 * Pvv0 = 0.05^2 * 0.01
    assert obs.sigma("A") == pytest.approx(2 * 0.05**2 * 0.01)
    obs.predict_to(1.0)
    # 10 steps of h = 0.1 from P0: Pxx = (n h)^2 Pvv0 + q h h^2 sum_{j<n} j^2 = 0.01 + 0.0285
    assert obs.sigma("A") == pytest.approx(2 * (0.01 + 0.01 * 0.01 * 285))


def test_p0_sigma0_and_q_per_target() -> None:
    obs = kalman(q_per_s=0.1)
    obs.add_target("A", 0.0, 0.0, 0.0, sigma0=8.0, q_per_s=0.5)
    assert obs.track("A").cov_xy == (4.0, 0.0, 4.0)
    assert obs.track("A").q_per_s == 0.5
    obs.add_target("B", 0.0, 0.0, 0.0, p0=(1.0, 2.0, 3.0, 4.0))
    assert obs.sigma("B") == 3.0
    obs.predict_to(1.0)
    assert obs.sigma("A") > 8.0 + 2 * 1.0 * 0.05  # q=0.5 feeds Pvv0 = 0.05 and more


# --- the time grid: how often predict_to is called does not matter ----------------------------
def test_one_call_equals_ten_calls_and_irregular_calls() -> None:
    a, b, c = kalman(), kalman(), kalman()
    for obs in (a, b, c):
        obs.add_target("T", 0.0, 1.0, 2.0, vx_m_s=0.5, vy_m_s=-1.0, p0=(3.0, 4.0, 0.2, 0.1))
    a.predict_to(1.0)
    for k in range(1, 11):
        b.predict_to(0.1 * k)
    for t in (0.037, 0.25, 0.2500001, 0.61, 0.99, 1.0):
        c.predict_to(t)
    sa, sb, sc = (snap_tuple(o.track("T")) for o in (a, b, c))
    assert sb == pytest.approx(sa, rel=1e-12, abs=1e-12)
    assert sc == pytest.approx(sa, rel=1e-12, abs=1e-12)
    assert sa[5] > 7.0  # sigma grew


def test_track_does_not_depend_on_tick_pattern_with_measurements() -> None:
    rng = np.random.default_rng(3)
    meas = [(0.5 * k + 0.013 * (k % 3), 1.0 * k + rng.normal(), 2.0) for k in range(1, 30)]
    fixed, irregular = kalman(), kalman()
    for obs in (fixed, irregular):
        obs.add_target("T", 0.0, 0.0, 2.0, vx_m_s=2.0, p0=(5.0, 5.0, 1.0, 1.0))
    t = 0.0
    for tm, x, y in meas:
        while t + 0.1 <= tm:
            t += 0.1
            fixed.predict_to(t)
        fixed.measure(tm, x, y, "T")
        for tp in np.sort(rng.uniform(tm - 0.5, tm, size=3)):
            irregular.predict_to(float(tp))
        irregular.measure(tm, x, y, "T")
    for obs in (fixed, irregular):
        obs.predict_to(20.0)
    assert snap_tuple(irregular.track("T")) == pytest.approx(
        snap_tuple(fixed.track("T")), rel=1e-9, abs=1e-9
    )
    assert fixed.counters["accepted"] == len(meas)


def test_predict_to_the_past_is_a_noop_and_long_gap_is_cheap() -> None:
    obs = kalman()
    obs.add_target("T", 0.0, 0.0, 0.0)
    obs.predict_to(5.0)
    before = obs.track("T")
    obs.predict_to(4.0)
    assert obs.track("T") == before
    obs.predict_to(1e6)  # closed form: O(1) whatever the gap
    assert obs.track("T").t_s == 1e6 and obs.track("T").lost


def test_correction_shrinks_sigma() -> None:
    obs = kalman()
    obs.add_target("T", 0.0, 0.0, 0.0, sigma0=100.0)
    obs.predict_to(3.0)
    prior = obs.sigma("T")
    assert obs.measure(3.0, 1.0, -1.0, "T").accepted
    assert obs.sigma("T") < prior
    assert obs.sigma("T") < 2 * 5.0  # below the measurement's own variance


def test_lost_flag() -> None:
    obs = kalman(q_per_s=0.0)
    obs.add_target("T", 0.0, 0.0, 0.0, p0=(150.0**2 / 2, 150.0**2 / 2, 1.0, 1.0))
    s = obs.track("T")
    assert not s.lost and not s.ever_lost  # sqrt(sigma) == 150 is not > 150
    obs.predict_to(0.1)
    s = obs.track("T")
    assert s.lost and s.ever_lost
    assert obs.measure(0.1, 0.0, 0.0, "T").accepted
    s = obs.track("T")
    assert not s.lost and s.ever_lost
    assert obs.target_ids == ["T"]  # lost tracks stay


# --- gating, association, rejections -----------------------------------------------------------
def test_gate_rejects_far_outlier_accepts_near_one() -> None:
    obs = kalman()
    obs.add_target("T", 0.0, 0.0, 0.0, sigma0=10.0)
    out = obs.measure(1.0, 100.0, 0.0, "T")
    assert not out.accepted and out.reason == "gate" and out.target_id == "T"
    assert out.mahalanobis2 is not None and out.mahalanobis2 > ObserverConfig().gate_threshold
    assert obs.track("T").x_m == 0.0 and obs.track("T").last_seen_s is None
    out = obs.measure(1.5, 2.0, -1.0, "T")
    assert out.accepted and out.mahalanobis2 is not None and out.mahalanobis2 < 18.42
    assert obs.counters["rejected_gate"] == 1 and obs.counters["accepted"] == 1
    assert ObserverConfig().gate_threshold == pytest.approx(18.4207, rel=1e-4)


def test_association_picks_the_right_track() -> None:
    obs = kalman()
    obs.add_target("A", 0.0, 0.0, 0.0)
    obs.add_target("B", 0.0, 500.0, 0.0)
    out = obs.measure(0.5, 498.0, 2.0)
    assert out.accepted and out.target_id == "B"
    assert obs.track("B").last_seen_s == 0.5 and obs.track("A").last_seen_s is None
    # Mahalanobis, not Euclidean: C is nearer to (40, 0) but far more certain than D
    obs2 = kalman()
    obs2.add_target("C", 0.0, 60.0, 0.0)
    obs2.add_target("D", 0.0, 0.0, 0.0, sigma0=1e4)
    assert obs2.measure(0.0, 40.0, 0.0).target_id == "D"


def test_unassociated_and_no_track() -> None:
    obs = kalman()
    out = obs.measure(1.0, 0.0, 0.0)
    assert (out.accepted, out.reason, out.target_id) == (False, "no_track", None)
    obs.add_target("A", 1.0, 0.0, 0.0)
    out = obs.measure(2.0, 3000.0, 0.0)
    assert (out.accepted, out.reason, out.target_id) == (False, "no_track", None)
    assert out.mahalanobis2 is not None and out.mahalanobis2 > 1e5
    out = obs.measure(2.0, 0.0, 0.0, "nope")
    assert (out.accepted, out.reason, out.target_id) == (False, "unknown_target", "nope")
    assert obs.counters["unassociated"] == 3


def test_late_and_invalid_measurements_are_rejected_and_counted() -> None:
    obs = kalman()
    obs.add_target("A", 0.0, 0.0, 0.0)
    assert obs.measure(1.0, 0.0, 0.0, "A").accepted
    assert obs.measure(0.5, 0.0, 0.0, "A").reason == "late"
    obs.predict_to(2.0)
    assert obs.measure(1.5, 0.0, 0.0, "A").reason == "late"
    assert obs.measure(1.5, 0.0, 0.0).reason == "late"  # association: every track is newer
    assert obs.measure(2.0, 0.0, 0.0, "A").accepted  # same time as the track: fine
    bad = [
        (math.nan, 0.0, 0.0, None),
        (3.0, math.nan, 0.0, None),
        (3.0, 0.0, math.inf, None),
        (math.inf, 0.0, 0.0, None),
        (3.0, 0.0, 0.0, 0.0),
        (3.0, 0.0, 0.0, math.nan),
        (3.0, "1", 0.0, None),
    ]
    for t, x, y, r in bad:
        out = obs.measure(t, x, y, "A", r_m2=r)  # type: ignore[arg-type]
        assert (out.accepted, out.reason) == (False, "invalid")
    assert obs.track("A").t_s == 2.0  # nothing moved
    c = obs.counters
    assert dict(c) == {
        "accepted": 2,
        "rejected_gate": 0,
        "rejected_late": 3,
        "rejected_invalid": len(bad),
        "unassociated": 0,
    }
    with pytest.raises(TypeError):
        c["accepted"] = 5  # type: ignore[index]


def test_measurement_r_override_weights_the_update() -> None:
    precise, vague = kalman(), kalman()
    for obs, r in ((precise, 0.1), (vague, 50.0)):
        obs.add_target("A", 0.0, 0.0, 0.0, sigma0=20.0)
        obs.measure(0.0, 3.0, 0.0, "A", r_m2=r)
    # K = 10 / (10 + r) with a position variance of 10 per axis
    assert precise.track("A").x_m == pytest.approx(3.0 * 10.0 / 10.1)
    assert vague.track("A").x_m == pytest.approx(3.0 * 10.0 / 60.0)


# --- linear model ----------------------------------------------------------------------------
def test_linear_model_grows_one_per_second_and_resets() -> None:
    obs = Observer(ObserverConfig(model="linear"))
    obs.add_target("A", 0.0, 730.0, 31.0, sigma0=2.0)
    obs.predict_to(3.0)
    assert obs.sigma("A") == pytest.approx(5.0)
    assert obs.track("A").cov_xy == pytest.approx((2.5, 0.0, 2.5))
    assert obs.measure(3.0, 732.0, 30.0, "A").accepted
    s = obs.track("A")
    assert (s.sigma, s.x_m, s.y_m, s.last_seen_s) == (0.0, 732.0, 30.0, 3.0)
    obs.predict_to(7.5)
    assert obs.sigma("A") == pytest.approx(4.5)
    assert (obs.track("A").x_m, obs.track("A").y_m) == (732.0, 30.0)
    # no gate with an explicit id: sigma is a staleness clock, not a variance
    assert obs.measure(8.0, 900.0, 30.0, "A").accepted
    obs.add_target("B", 8.0, 0.0, 0.0, vx_m_s=1.0, q_per_s=0.3)
    obs.predict_to(10.0)
    s = obs.track("B")
    assert (s.x_m, s.vx_m_s, s.sigma, s.q_per_s) == (2.0, 1.0, 2.0, 0.3)
    obs.predict_to(10.0 + 150.0**2)
    assert obs.track("B").lost and obs.track("A").ever_lost


def test_linear_growth_rate_configurable_and_association() -> None:
    obs = Observer(ObserverConfig(model="linear", linear_growth_per_s=2.0))
    obs.add_target("A", 0.0, 0.0, 0.0)
    obs.add_target("B", 0.0, 300.0, 0.0)
    obs.predict_to(2.0)
    assert obs.sigma("A") == 4.0
    assert obs.measure(2.0, 301.0, 0.0).target_id == "B"
    assert obs.measure(2.0, 1000.0, 0.0).reason == "no_track"


# --- run-time targets and validation -----------------------------------------------------------
def test_add_and_remove_at_run_time() -> None:
    obs = kalman()
    obs.add_target("b", 0.0, 0.0, 0.0)
    obs.predict_to(10.0)
    obs.add_target("a", 10.0, 5.0, 5.0)
    assert obs.target_ids == ["a", "b"]
    assert [s.id for s in obs.tracks()] == ["a", "b"]
    assert obs.track("a").sigma == 0.0 and obs.track("b").sigma > 0.0
    with pytest.raises(ValueError, match="already"):
        obs.add_target("a", 10.0, 0.0, 0.0)
    obs.remove_target("b")
    assert obs.target_ids == ["a"]
    with pytest.raises(KeyError):
        obs.remove_target("b")
    with pytest.raises(KeyError):
        obs.track("b")
    assert obs.measure(11.0, 0.0, 0.0, "b").reason == "unknown_target"
    obs.add_target("b", 11.0, 0.0, 0.0)  # re-adding starts afresh
    assert obs.track("b").last_seen_s is None


def test_set_process_noise_changes_growth() -> None:
    slow, fast = kalman(), kalman()
    for obs in (slow, fast):
        obs.add_target("A", 0.0, 0.0, 0.0)
        obs.predict_to(1.0)
    fast.set_process_noise("A", 1.0)
    assert fast.track("A").q_per_s == 1.0
    for obs in (slow, fast):
        obs.predict_to(10.0)
    assert fast.sigma("A") > 5 * slow.sigma("A")
    with pytest.raises(ValueError, match="q_per_s"):
        fast.set_process_noise("A", -1.0)
    with pytest.raises(KeyError):
        fast.set_process_noise("zz", 1.0)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"model": "particle"}, "model"),
        ({"r_m2": 0.0}, "r_m2"),
        ({"max_step_s": -0.1}, "max_step_s"),
        ({"q_per_s": math.nan}, "q_per_s"),
        ({"gate_probability": 1.0}, "gate_probability"),
        ({"fov_radius_m": math.inf}, "fov_radius_m"),
    ],
)
def test_config_validation_names_the_field(kwargs: dict[str, object], field: str) -> None:
    with pytest.raises(ValueError, match=field):
        ObserverConfig(**kwargs)  # type: ignore[arg-type]


def test_add_target_validation_names_the_argument() -> None:
    obs = kalman()
    with pytest.raises(ValueError, match="x_m"):
        obs.add_target("A", 0.0, math.nan, 0.0)
    with pytest.raises(ValueError, match="p0"):
        obs.add_target("A", 0.0, 0.0, 0.0, p0=(1.0, 1.0))
    with pytest.raises(ValueError, match="sigma0"):
        obs.add_target("A", 0.0, 0.0, 0.0, sigma0=-1.0)
    with pytest.raises(ValueError, match="target_id"):
        obs.add_target("", 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="t_s"):
        obs.predict_to(math.nan)
    assert obs.target_ids == []


# --- boat priority -----------------------------------------------------------------------------
def test_boat_priority_q_monotone_and_bounded() -> None:
    ds = np.linspace(0.0, 3000.0, 301)
    qs = [boat_priority_q(0.1, float(d)) for d in ds]
    assert all(a >= b for a, b in itertools.pairwise(qs))
    assert qs[0] == pytest.approx(0.5) and qs[-1] == pytest.approx(0.1)
    assert boat_priority_q(0.1, 300.0) == pytest.approx(0.5)
    assert boat_priority_q(0.1, 900.0) == pytest.approx(0.3)
    assert boat_priority_q(0.1, 1500.0) == pytest.approx(0.1)
    assert boat_priority_q(0.2, 100.0, gain=0.0) == pytest.approx(0.2)
    with pytest.raises(ValueError, match="near_m"):
        boat_priority_q(0.1, 10.0, near_m=2000.0)
    with pytest.raises(ValueError, match="distance_to_boat_m"):
        boat_priority_q(0.1, math.nan)
