"""``gcs run --vehicles sim:N`` over simulated SiK radios (``--sim-radio``), end to end on
127.0.0.1 with ephemeral ports: the vehicles fly, their verified uploads go through the
radios, and the ground station hears the radios' RADIO_STATUS (system 51)."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

from daemon_run import Journal, events, run_gcs

from groundstation.commands.embedded_sim import build_embedded_sim
from groundstation.commands.run import build_config
from groundstation.link.tlog import TlogReader
from world.scenario import parse_scenario


def _both_uploaded(journal: Journal) -> bool:
    targets = events(journal, "upload", ok=True, purpose="target")
    return bool(journal) and journal[-1]["t"] >= 40.0 and {e["vehicle"] for e in targets} == {
        "1", "2"}


def test_gcs_run_flies_over_sik_radios(tmp_path: Path) -> None:
    daemon, journal = run_gcs(
        tmp_path, "--vehicles", "sim:2", "--sim-radio", "sik", "--scenario", "default",
        "--speedup", "20", "--duration", "120", until=_both_uploaded,
    )  # fmt: skip
    assert daemon.stop_reason == "test: awaited events seen", daemon.stop_reason
    assert not events(journal, "task_error") and not events(journal, "core_error")
    assert not events(journal, "upload", ok=False)
    assert not events(journal, "link_lost")
    assert {e["vehicle"] for e in events(journal, "vehicle_seen")} == {"1", "2"}
    # the tlog holds the ground radios' RADIO_STATUS, from 51/68: each radio answers every
    # heartbeat floe sends on its link (1 Hz of mission time, however slowly the simulator
    # runs: tests/test_radio_budget_daemon.py); read as a tlog: fed raw to a decoder, the
    # 8-byte timestamps can hold a chance frame
    frames = [r.message for r in TlogReader(daemon.run_dir / "flight.tlog")]
    sources = Counter((m.get_srcSystem(), m.get_srcComponent(), m.get_type()) for m in frames)
    radio_status = sources[(51, 68, "RADIO_STATUS")]
    heartbeats = sum(n for (s, _, kind), n in sources.items() if (s, kind) == (245, "HEARTBEAT"))
    assert radio_status >= 2 * 0.8 * journal[-1]["t"]
    assert 0.8 <= radio_status / (2 * heartbeats) <= 1.05
    assert {s for s, _, _ in sources} == {1, 2, 51, 245}  # the vehicles, radios, floe
    # metrics.json's links: the radios' own air time, the uploads as the journal has them,
    # and the telemetry's age against each vehicle's clock
    links = {e["vehicle"]: e for e in json.loads((daemon.run_dir / "metrics.json").read_text())[
        "links"]}
    assert set(links) == {"1", "2"}
    model = daemon.link_model() if daemon.link_model is not None else {}
    for vehicle, entry in links.items():
        uploads = events(journal, "upload", vehicle=vehicle)
        assert entry["airtime_source"] == "radio model"
        assert entry["airtime_pct"] == round(model[int(vehicle)]["air_pct"], 2)
        assert 5.0 < entry["airtime_pct"] < 60.0
        assert entry["uploads"] == len(uploads) and entry["upload_ok_pct"] == 100.0
        assert entry["link"].startswith("tcp:127.0.0.1:")
        latency = entry["upload_latency_s"]
        assert 0.2 < latency["p50"] <= latency["p95"] < 10.0  # a radio's round trips
        age = entry["telemetry_age_s"]
        assert 0.0 <= age["p50"] <= age["p95"] < 2.0


def test_the_command_line_radio_wins_over_the_scenarios() -> None:
    scenario = parse_scenario({"name": "radio", "fleet": {"count": 2},
                               "radio": ["sik,loss=0.05", "2:sik,air=32"]})
    assert scenario.radio == ("sik,loss=0.05", "2:sik,air=32")
    plain = build_embedded_sim(build_config(["--vehicles", "sim:2", "--seed", "4"]), scenario)
    assert {k: (v.loss, v.air_kbps) for k, v in plain.server.options.radios.items()} == {
        1: (0.05, 64), 2: (0.01, 32)}  # a later spec replaces the radio, not merged
    assert plain.server.options.radio_seed == 4
    config = build_config(["--vehicles", "sim:2", "--sim-radio", "1:none"])
    overridden = build_embedded_sim(config, scenario)
    assert list(overridden.server.options.radios) == [2]
    assert overridden.radio_stats() == {2: overridden.server.radio_stats()[2]}
