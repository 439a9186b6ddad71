"""The first leg in the real wind (docs/wind.md, "The first leg"), end to end: ``gcs run``
with three built-in vehicles launched from the ground (real MAVLink on 127.0.0.1, ephemeral
ports, 20x), in 15 m/s of wind. Each vehicle's cruise airspeed is read from its
AIRSPEED_CRUISE parameter before it joins (the simulator climbs out at 28 m/s and cruises
at 22, as ArduPlane does), and its first leg arrives within 10 s of the predicted time:
with the wind given (``--wind``), and with the wind unknown to floe until the vehicles'
first estimates arrive (the wind replan). Before these changes the first legs of these
two configurations were 21-65 s (given, from 0 deg) and 20-186 s (unknown, from 270 deg)
late (benchmarks/first_leg.py, seeds 0-2; docs/wind.md, "The first leg").

20x, not 50x: the core predicts an arrival from the moment it commands the leg, and the
vehicle turns to it once the upload is verified. That exchange takes wall time, which a
speed-up multiplies into mission time: on a busy machine at 50x the first legs' median
error reached 7-10 s, at 20x it is 0.2-1.1 s (the same runs with --wind 15,0, both cores
busy). At 1x, as in the field, the exchange costs a fraction of a second."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from daemon_run import events, run_gcs

from groundstation.commands.embedded_sim import build_embedded_sim
from world.wind import WindSpec

FIRST_LEG_BOUND_S = 10.0
"""The issue's bound, on the median first leg. A single leg of any kind, later ones too,
reaches 15-30 s in these runs now and then (benchmarks/first_leg.py: later legs' max 14-30
s, first legs' 7-14 s, over 36 runs), and the daemon's timing varies from run to run, so
one leg is held to twice the bound; before, the medians were 20-80 s and the worst legs
65-185 s late."""


@pytest.mark.timeout(120)
@pytest.mark.parametrize(("from_deg", "known"), [(0.0, True), (270.0, False)])
def test_first_legs_arrive_when_predicted_in_15_m_s_of_wind(
    tmp_path: Path, from_deg: float, known: bool
) -> None:
    wind = WindSpec(15.0, from_deg)

    def vehicles(config: Any, scenario: Any, keys: Any, fallback: Any) -> Any:
        return build_embedded_sim(config, scenario, keys, wind)  # they fly in it regardless

    args = ["--vehicles", "sim:3", "--scenario", "paper-boat", "--launch", "--replan",
            "event", "--commit", "--seed", "0", "--speedup", "20", "--duration", "250"]
    if known:
        args += ["--wind", f"15,{from_deg:g}"]
    daemon, journal = run_gcs(tmp_path, *args, timeout_s=110.0, embedded=vehicles)
    assert not events(journal, "task_error") and not events(journal, "core_error")
    # the cruise airspeed came from the parameter, before the join, and is what the core
    # plans with (the climb-out's 28 m/s never reaches it)
    cruise = events(journal, "cruise_speed")
    assert sorted(e["vehicle"] for e in cruise) == ["1", "2", "3"]
    assert {(e["source"], e["speed_m_s"]) for e in cruise} == {("AIRSPEED_CRUISE", 22.0)}
    for e in cruise:
        joined = events(journal, "vehicle_joined", vehicle=e["vehicle"], how="launched")
        assert joined and e["t"] < joined[0]["t"]
    poses = [e for e in journal if e["event"] == "input"
             and e.get("kind") in ("VehicleJoined", "Telemetry")]
    assert poses and {e["speed_m_s"] for e in poses} == {22.0}
    # the first legs arrived within the bound, as the later ones do
    metrics = json.loads((daemon.run_dir / "metrics.json").read_text())
    first, later = metrics["arrival_error_first_s"], metrics["arrival_error_later_s"]
    assert first is not None and first["counted"] >= 2, metrics["arrivals"]
    errors = daemon.metrics.arrivals.first_errors_s
    assert first["median"] <= FIRST_LEG_BOUND_S, errors
    assert first["max"] <= 2 * FIRST_LEG_BOUND_S, errors
    assert later is not None and later["median"] <= FIRST_LEG_BOUND_S
    # with the wind unknown, the first estimate replanned the legs it had moved
    replans = events(journal, "wind_replan")
    if known:
        assert not replans
    else:
        assert replans and all(e["t"] > 20.0 for e in replans)
        assert {e["vehicle"] for e in replans} <= {"1", "2", "3"}
