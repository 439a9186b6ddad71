"""The ``links`` figures of metrics.json (``groundstation/core/link_metrics.py``): nearest-rank
percentiles, the air time's sources, uploads per hour and their success."""

from __future__ import annotations

from groundstation.core.link_metrics import (
    LinkUse,
    link_entries,
    offline_link_entries,
    percentiles,
)


def test_percentiles_are_nearest_rank_never_interpolated() -> None:
    values = [float(v) for v in range(1, 21)]  # 1..20
    assert percentiles(values) == {"p50": 10.0, "p95": 19.0}
    assert percentiles([3.0]) == {"p50": 3.0, "p95": 3.0}
    assert percentiles([]) == {"p50": None, "p95": None}
    assert percentiles([0.1, 5.0]) == {"p50": 0.1, "p95": 5.0}


def test_air_time_from_the_radio_model_else_the_serial_line_else_unknown() -> None:
    base = dict(uploads_ok=9, uploads_failed=1, upload_latencies_s=[1.0, 2.0],
                telemetry_ages_s=[0.5], bytes_in=288_000, bytes_out=28_800)
    radio, serial, socket = link_entries([
        LinkUse("1", "tcp:127.0.0.1:1", model_airtime_pct=23.456, **base),  # type: ignore[arg-type]
        LinkUse("2", "serial:/dev/ttyUSB0:57600", rate_bps=57600.0, **base),  # type: ignore[arg-type]
        LinkUse("3", "udpin:0.0.0.0:14550", **base),  # type: ignore[arg-type]
    ], mission_s=100.0)  # fmt: skip
    assert (radio["airtime_pct"], radio["airtime_source"]) == (23.46, "radio model")
    # the busier direction: 288 000 bytes x 10 bits in 100 s on a 57 600 bit/s line = 50 %
    assert (serial["airtime_pct"], serial["airtime_source"]) == (50.0, "serial line")
    assert (socket["airtime_pct"], socket["airtime_source"]) == (None, None)
    for entry in (radio, serial, socket):
        assert entry["uploads"] == 10 and entry["upload_ok_pct"] == 90.0
        assert entry["uploads_per_hour"] == 360.0
        assert entry["upload_latency_s"] == {"p50": 1.0, "p95": 2.0}


def test_a_vehicle_without_uploads_has_no_success_rate() -> None:
    (entry,) = link_entries([LinkUse("1", None, 0, 0, [], [])], mission_s=0.0)
    assert entry["upload_ok_pct"] is None and entry["uploads_per_hour"] is None
    assert entry["telemetry_age_s"] == {"p50": None, "p95": None}


def test_the_offline_simulator_has_no_link_and_exact_telemetry() -> None:
    one, two = offline_link_entries(["1", "2"], {"1": 6}, mission_s=1800.0)
    assert one["link"] is None and one["airtime_pct"] is None
    assert (one["uploads"], one["uploads_per_hour"], one["upload_ok_pct"]) == (6, 12.0, 100.0)
    assert one["upload_latency_s"] == {"p50": 0.0, "p95": 0.0}
    assert two["uploads"] == 0 and two["upload_ok_pct"] is None
    assert two["telemetry_age_s"] == {"p50": 0.0, "p95": 0.0}
