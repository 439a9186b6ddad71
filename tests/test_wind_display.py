"""The wind as ``gcs run`` resolves and shows it: ``--wind`` and the config key, the
fallback's source, the status table, the live map's state document, the journal's
operator events, the embedded simulator's wind and ``gcs report``."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from daemon_run import status_text
from test_wind_reports import _record_run, wind_msg

from domain.errors import ConfigError
from domain.geodesy import GeoOrigin
from groundstation.commands.embedded_sim import build_embedded_sim
from groundstation.commands.run import build_config, run
from groundstation.core import events as ev
from groundstation.core.config import CoreConfig, ReplanPolicy
from groundstation.daemon.clock import MissionClock
from groundstation.daemon.config_parse import parse_config
from groundstation.daemon.control.bodies import jsonable
from groundstation.daemon.control.controller import DaemonController
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.journal import Journal, read_journal
from groundstation.daemon.log_lines import describe_line, is_operator_event, line_level
from groundstation.daemon.startup import core_config
from groundstation.daemon.wind_view import fallback_wind
from groundstation.runners.report.data import load_run_data
from groundstation.runners.report.page import render_html
from groundstation.runners.report.plots import plot_wind
from world.scenario import parse_scenario
from world.wind import WindSpec


def _daemon(tmp_path: Path, t: list[float], fallback: tuple[float, float]) -> Daemon:
    config = parse_config({"vehicles": ["udpin:127.0.0.1:0"], "wind": "3,180"}, {})
    journal = Journal(tmp_path / "journal.jsonl", lambda: t[0], lambda: 1.7e9)
    clock = MissionClock(1.0, source=lambda: t[0])
    daemon = Daemon(config, CoreConfig(wind_xy_m_s=fallback), clock, tmp_path,
                    GeoOrigin(78.9, 11.9, 0.0), journal, None)
    daemon.wind_fallback_source = "config"
    return daemon


def test_status_state_and_journal_show_the_vehicles_wind(tmp_path: Path) -> None:
    t = [0.0]
    daemon = _daemon(tmp_path, t, (0.0, 3.0))  # 3 m/s from the south
    state = jsonable(DaemonController(daemon).state())["wind"]
    assert state["source"] == "config" and state["label"] == "3.0 m/s from 180° (config)"
    assert "wind 3.0 m/s from 180° (config)" in status_text(daemon)
    session = daemon._new_session(1)  # a vehicle whose own WIND the table shows
    for k in range(3):
        t[0] = float(k)
        session.on_message(wind_msg(-90.0, 12.0))
    for v in "12":
        daemon.core_event(ev.VehicleJoined(t[0], v, 0.0, 0.0, 0.0, 22.0))
    for k in range(3, 20):
        t[0] = float(k)
        daemon.core_event(ev.WindReport(t[0], "1", 12.0, 0.0))
        daemon.core_event(ev.WindReport(t[0], "2", 11.8, 0.4))
        daemon.core_event(ev.Tick(t[0] + 0.5))
    text = status_text(daemon)
    assert "wind 11.9 m/s from 269° (vehicles 1,2)" in text
    assert "12/270" in text  # vehicle 1's own accepted WIND, in its row
    doc = jsonable(DaemonController(daemon).state())
    assert doc["wind"]["source"] == "vehicles" and doc["wind"]["vehicles"] == ["1", "2"]
    assert doc["wind"]["wx_m_s"] == pytest.approx(11.9) and doc["wind"]["planning"] is True
    assert doc["wind"]["from_deg"] == pytest.approx(269.04, abs=0.01)
    own = doc["vehicles"][0]["wind"]
    assert own["speed_m_s"] == pytest.approx(12.0, abs=1e-4)
    assert own["from_deg"] == pytest.approx(270.0, abs=1e-3)
    daemon.journal_file.close()
    lines = read_journal(tmp_path / "journal.jsonl")
    winds = [line for line in lines if line["event"] == "wind"]
    assert len(winds) == 1  # vehicle 1 alone; both then (a 0.1 m/s change is not news)
    assert all(is_operator_event(w) and line_level(w) == 20 for w in winds)
    assert describe_line(winds[-1]) == "t=3.0 wind 12.0 m/s from 270 deg (vehicles 1)"
    inputs = [line for line in lines if line.get("kind") == "WindReport"]
    assert len(inputs) == 34 and not any(is_operator_event(i) for i in inputs)


def test_wind_blind_is_said_in_the_header(tmp_path: Path) -> None:
    t = [0.0]
    daemon = _daemon(tmp_path, t, (0.0, 0.0))
    daemon.core_config = CoreConfig(wind_aware=False)
    daemon.wind_fallback_source = "none"
    assert "wind calm (none), not used by the planner" in status_text(daemon)
    daemon.journal_file.close()


def test_bad_wind_flag_is_one_line_and_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    for text in ("10", "fast,270", "10,361", "nan,90", "61,90", "10,270,-1"):
        assert run(["--vehicles", "sim:1", "--wind", text]) == 2
        err = capsys.readouterr().err
        assert err.startswith("gcs run: error: --wind: ") and err.count("\n") == 1, err


def test_wind_from_the_flag_the_config_file_or_the_scenario(tmp_path: Path) -> None:
    config_file = tmp_path / "field.yaml"
    config_file.write_text("vehicles: [sim:2]\nwind: {speed_m_s: 12, from_deg: 90}\n")
    config = build_config(["--config", str(config_file)])
    assert config.wind == WindSpec(12.0, 90.0)
    assert build_config(["--config", str(config_file), "--wind", "8,0,2"]).wind == WindSpec(
        8.0, 0.0, 2.0)  # the flag wins
    assert parse_config(config.to_dict(), {}) == config  # config.yaml parses back
    bad = tmp_path / "bad.yaml"
    bad.write_text("vehicles: [sim:2]\nwind: {speed_m_s: 12, from: 90}\n")
    with pytest.raises(ConfigError, match=r"^wind\.from: unknown key"):
        build_config(["--config", str(bad)])
    windy = parse_scenario({"name": "windy", "wind": {"speed_m_s": 9, "from_deg": 45}})
    calm = parse_scenario({"name": "calm"})
    plain = parse_config({"vehicles": ["sim:2"]}, {})
    assert fallback_wind(config, windy) == (WindSpec(12.0, 90.0), "config")
    assert fallback_wind(plain, windy) == (windy.wind, "scenario")
    assert fallback_wind(plain, calm) == (WindSpec(), "none")
    wx, wy = core_config(plain, windy, 1.0).wind_xy_m_s
    assert (wx, wy) == pytest.approx((-9 / math.sqrt(2), -9 / math.sqrt(2)))
    assert core_config(config, windy, 1.0).wind_xy_m_s == pytest.approx((-12.0, 0.0))
    assert core_config(plain, None, 1.0).wind_xy_m_s == (0.0, 0.0)
    sim = build_embedded_sim(plain, windy, None, WindSpec(12.0, 90.0))
    assert sim.wind == WindSpec(12.0, 90.0)  # handed on to the built-in vehicles
    assert build_embedded_sim(plain, windy).wind == windy.wind


def test_report_shows_the_wind_estimate_over_time(tmp_path: Path) -> None:
    run_dir = tmp_path / "windy"
    config = CoreConfig(policy=ReplanPolicy(on_events=True, period_s=20.0, commit=True),
                        wind_xy_m_s=(0.0, -4.0), time_limit_s=1.0)
    _record_run(run_dir, config, wind=True)
    data = load_run_data(run_dir)
    assert len(data.wind) >= 2 and set(data.wind_reports) == {"1", "2", "3"}
    assert [o["vehicle"] for o in data.wind_outliers] == ["3"]
    figure = plot_wind(data)
    assert figure is not None and figure.info == {"changes": len(data.wind), "vehicles": 3}
    page = render_html(data, [figure])
    assert '<table id="wind">' in page and 'id="fig-wind"' in page
    assert "wind_outlier" in page and "outliers flagged: 3" in page
    calm = tmp_path / "calm"
    _record_run(calm, CoreConfig(time_limit_s=1.0), wind=False)
    calm_data = load_run_data(calm)
    assert plot_wind(calm_data) is None and '<table id="wind">' not in render_html(calm_data, [])
