"""The whole watch through real MAVLink on 127.0.0.1: ``gcs run`` with the built-in
simulator's ArduPlanes on a moving ship (a short-endurance copy of ``ship-watch``): the
homes follow the ship, each verified by the vehicle's HOME_POSITION and visible in the tlog
as DO_SET_HOME; a vehicle is relieved by a spare, sent home with its reserve, recovered on
deck, and comes back as a spare after its battery swap; nothing is lost."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from daemon_run import Journal, events, run_gcs

from groundstation.link.tlog import TlogReader
from groundstation.mavlink.codec import mavlink2 as M
from world.scenario import load_scenario_data

pytestmark = pytest.mark.timeout(240)


def _short_watch(tmp_path: Path) -> Path:
    """ship-watch with a 15-minute battery, a 1-minute swap and two on station of three."""
    data, _ = load_scenario_data("ship-watch")
    data["fleet"]["count"] = 3
    data["watch"].update(on_station=2, endurance_s=900, reserve_pct=20, turnaround_s=60,
                         launch_s=20)
    path = tmp_path / "short-watch.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def _one_turn_of_the_watch(journal: Journal) -> bool:
    """The watch has gone round once: homes moved with the ship (>= 10 verified, > 1 km
    apart), a spare launched to relieve a vehicle that went home, and the first vehicle
    recovered on deck is a spare again after its battery swap (~360 mission s of the
    1000 s bound, measured)."""
    homes = events(journal, "home_set")
    if len(homes) < 10:
        return False
    x0, y0 = homes[0]["x_m"], homes[0]["y_m"]
    if max(math.hypot(h["x_m"] - x0, h["y_m"] - y0) for h in homes) <= 1000.0:
        return False
    if not events(journal, "launch_order", reason="relief"):
        return False
    if not [e for e in events(journal, "send_home") if "relieved by" in e["reason"]]:
        return False
    recovered = events(journal, "vehicle_recovered")
    return bool(recovered) and any(
        e["t"] > recovered[0]["t"]
        for e in events(journal, "vehicle_spare", vehicle=recovered[0]["vehicle"])
    )


def test_a_short_watch_relieves_recovers_and_moves_homes_with_the_ship(tmp_path: Path) -> None:
    """The run stops once the watch has gone round (:func:`_one_turn_of_the_watch`);
    ``--duration`` bounds it."""
    scenario = _short_watch(tmp_path)
    daemon, journal = run_gcs(tmp_path / "run", "--vehicles", "sim:3", "--scenario", str(scenario),
                              "--launch", "--speedup", "30", "--duration", "1000",
                              timeout_s=200.0, until=_one_turn_of_the_watch)
    assert not events(journal, "task_error") and not events(journal, "core_error")
    # homes: verified by HOME_POSITION, and moving with the ship
    homes = events(journal, "home_set")
    assert len(homes) >= 10
    assert all(h["error_m"] < 5.0 for h in homes)
    assert not events(journal, "home_set_failed")
    xs = [h["x_m"] for h in homes]
    ys = [h["y_m"] for h in homes]
    assert max(math.hypot(x - xs[0], y - ys[0]) for x, y in zip(xs, ys, strict=True)) > 1000.0
    # the tlog holds the commands and the vehicles' answers
    sent = received = 0
    for record in TlogReader(daemon.run_dir / "flight.tlog"):
        msg = record.message
        if msg.get_type() == "COMMAND_INT" and msg.command == M.MAV_CMD_DO_SET_HOME:
            sent += 1
        elif msg.get_type() == "HOME_POSITION":
            received += 1
    assert sent >= len(homes) and received >= len(homes)
    # relief: a spare launched for a vehicle, which went home when it joined
    reliefs = events(journal, "launch_order", reason="relief")
    assert reliefs
    relieved = [e for e in events(journal, "send_home") if "relieved by" in e["reason"]]
    assert relieved
    # recovered on deck with its reserve, then a spare again after the swap
    recovered = events(journal, "vehicle_recovered")
    assert recovered
    first = recovered[0]
    spare_again = [e for e in events(journal, "vehicle_spare", vehicle=first["vehicle"])
                   if e["t"] > first["t"]]
    assert spare_again
    assert not events(journal, "vehicle_down") and not events(journal, "vehicle_fell")
    metrics = daemon.metrics_dict()
    assert metrics["vehicles_lost"] == 0
    assert metrics["min_landing_battery_pct"] is not None
    assert metrics["min_landing_battery_pct"] >= 10.0  # half the 20 % reserve


def test_a_config_file_s_watch_turns_it_on_and_bad_values_are_one_line(tmp_path: Path) -> None:
    """Real vehicles and a real ship have no scenario: the config's ``watch:`` keys turn the
    watch on (the core's defaults for the rest); over a scenario's they override it."""
    from groundstation.commands.run import build_config
    from groundstation.core.config import WatchConfig
    from groundstation.daemon.composition import StartError
    from groundstation.daemon.startup import core_config
    from world.scenario import load_scenario

    good = tmp_path / "good.yaml"
    good.write_text("watch: {on_station: 2, reserve_pct: 20}\n", encoding="utf-8")
    config = build_config(["--vehicles", "sim:2", "--config", str(good)])
    watch = core_config(config, None, 1.0).watch
    assert watch == WatchConfig(on_station=2, reserve_pct=20.0)
    over = core_config(config, load_scenario("ship-watch"), 1.0).watch
    assert over is not None and over.on_station == 2 and over.reserve_pct == 20.0
    assert over.endurance_s == 3600.0  # the scenario's, not overridden
    assert core_config(build_config(["--vehicles", "sim:2"]), None, 1.0).watch is None
    bad = tmp_path / "bad.yaml"
    bad.write_text("watch: {reserve_pct: 120}\n", encoding="utf-8")
    with pytest.raises(StartError, match=r"watch: reserve_pct must be a number in \[0, 90\]"):
        core_config(build_config(["--vehicles", "sim:2", "--config", str(bad)]), None, 1.0)
