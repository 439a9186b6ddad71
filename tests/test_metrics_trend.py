"""The "bounded" statistic: a robust trend of the second half's windowed means, relative to
its level (groundstation.core.metrics). Synthetic series of 201 one-second samples, like a
200 s run; each case states what the old max-ratio test said about it."""

from __future__ import annotations

import math
import random

import pytest

from groundstation.core.metrics import (
    BOUNDED_RATIO,
    TREND_BOUND,
    MetricsRecorder,
    boundedness_ratio,
    theil_sen_slope,
    trend_growth,
)

T_S = range(201)


def series(f: object) -> list[list[float]]:
    return [[float(t), float(f(t))] for t in T_S]  # type: ignore[operator]


def sawtooth(t: float, period_s: float = 37.0) -> float:
    """Visits every period: the average drops and grows back (a cubic, like a Kalman track)."""
    phase = (t % period_s) / period_s
    return 400.0 + 1600.0 * phase**3


def test_theil_sen_ignores_one_outlier() -> None:
    xs = [float(k) for k in range(10)]
    ys = [2.0 * x + 1.0 for x in xs]
    ys[7] = 1e6
    assert theil_sen_slope(xs, ys) == pytest.approx(2.0)


def test_level_is_bounded() -> None:
    flat = series(lambda t: 1000.0)
    assert trend_growth(flat) == 0.0
    level = series(sawtooth)
    g = trend_growth(level)
    assert g is not None and abs(g) < 0.2


def test_noisy_level_is_bounded() -> None:
    rng = random.Random(4)
    noisy = series(lambda t: max(0.0, sawtooth(t) * rng.lognormvariate(0.0, 0.5)))
    g = trend_growth(noisy)
    assert g is not None and g <= TREND_BOUND


@pytest.mark.parametrize(("power", "low", "high"), [(1.0, 0.6, 0.7), (3.0, 1.6, 2.0)])
def test_growing_is_not_bounded(power: float, low: float, high: float) -> None:
    g = trend_growth(series(lambda t: (t + 1.0) ** power))
    assert g is not None and low < g < high and g > TREND_BOUND


def test_growing_after_an_early_peak_is_not_bounded_though_the_old_ratio_passed_it() -> None:
    """The old test's blind spot (1 UAV, seed 19): the first sweep's peak is high, the
    second half starts low and doubles; its maximum stays below 1.5 x the first peak."""

    def f(t: float) -> float:
        if t <= 100:
            return 1000.0 * math.exp(-(((t - 40.0) / 15.0) ** 2)) + 300.0
        return 300.0 + 11.0 * (t - 100.0)

    s = series(f)
    assert boundedness_ratio(s) <= BOUNDED_RATIO  # the old verdict: bounded
    g = trend_growth(s)
    assert g is not None and g > TREND_BOUND


def test_early_good_then_level_is_bounded_though_the_old_ratio_failed_it() -> None:
    """Seed 4's case: an unusually good first half, then a level (noisy) second half."""
    rng = random.Random(1)
    s = series(lambda t: (100.0 if t <= 100 else 1000.0) * rng.uniform(0.8, 1.2))
    assert boundedness_ratio(s) > BOUNDED_RATIO  # the old verdict: not bounded
    g = trend_growth(s)
    assert g is not None and abs(g) < 0.2


def test_too_short_or_zero() -> None:
    assert trend_growth([]) is None
    assert trend_growth([[0.0, 1.0], [1.0, 2.0]]) is None
    assert trend_growth([[float(t), 1.0] for t in range(40)]) is None  # 2 windows of 10 s
    assert trend_growth([[float(t), 0.0] for t in range(100)]) == 0.0


def test_metrics_keep_the_old_keys_and_add_the_trend() -> None:
    recorder = MetricsRecorder()
    for t in T_S:
        recorder.sample(float(t), [float(t + 1) ** 3, 1.0])
    m = recorder.to_dict(0.0)
    assert {"bounded", "boundedness_ratio", "trend", "bounded_trend"} <= set(m)
    assert m["bounded_trend"] is False and m["trend"] > 1.0
    short = MetricsRecorder()
    short.sample(0.0, [1.0])
    assert short.to_dict(0.0)["bounded_trend"] is None


def test_uneven_sampling_is_windowed_by_time() -> None:
    """Dense samples (0.1 s) in the first half, sparse (5 s) in the second: the windows are
    10 s of mission time, not a count of samples sized from the average spacing (which
    made one window of the whole second half: None). Linear growth sigma = t then gives
    its exact trend, slope 1 x 200 s / the second half's mean."""
    dense = [[0.1 * k, 0.1 * k] for k in range(2000)]
    sparse = [[float(t), float(t)] for t in range(200, 401, 5)]
    s = dense + sparse
    level = sum(t for t, _ in sparse[1:]) / len(sparse[1:])
    g = trend_growth(s)
    assert g is not None and g == pytest.approx(200.0 / level)
    # the same run sampled every second has the same verdict
    even = trend_growth([[float(t), float(t)] for t in range(401)])
    assert even is not None and abs(even - g) < 0.02
