"""The offline simulator: the paper's claims, the field test, metrics, scripted events."""

from __future__ import annotations

import dataclasses
import json
import math
import statistics
from pathlib import Path

import pytest

from groundstation.cli import main
from groundstation.core.decision import ANSWER_REASON
from groundstation.core.metrics import boundedness_ratio
from groundstation.runners.simulate.simulator import SimulationOptions, run_simulation
from world.scenario import ScriptedEvent, load_scenario

METRIC_KEYS = {
    "uncertainty_series", "mean_uncertainty", "max_uncertainty", "final_uncertainty",
    "max_estimation_error_m", "lost_targets", "visits", "plans", "solve_time_s", "wall_time_s",
}
NO_SNAPSHOTS = (1.0,)


def simulate(name: str, uavs: int | None = None, seed: int = 0, **kw: object) -> dict:
    options = SimulationOptions(seed=seed, uavs=uavs, snapshot_times_s=NO_SNAPSHOTS, **kw)
    return run_simulation(load_scenario(name), options).metrics


def test_three_uavs_keep_uncertainty_bounded_where_one_cannot() -> None:
    """The paper's Figure 4 over four seeds (figures for 20 seeds: benchmarks/)."""
    one = [simulate("paper-boat", 1, seed) for seed in range(4)]
    three = [simulate("paper-boat", 3, seed) for seed in range(4)]
    assert not any(m["bounded"] for m in one)
    assert not any(m["bounded_trend"] for m in one)  # the trend test (metrics.trend_growth)
    assert all(m["trend"] > 0.5 for m in one)
    assert sum(m["bounded"] for m in three) >= 3
    for m1, m3 in zip(one, three, strict=True):
        assert m3["mean_uncertainty"] < m1["mean_uncertainty"] / 3
        assert len(m3["visits"]) > len(m1["visits"])
    # one UAV: the average keeps growing to the end of the run
    assert all(m["final_uncertainty"] > 0.5 * m["max_uncertainty"] for m in one)


def test_field_test_visits_every_target_and_the_fifth_after_it_appears() -> None:
    metrics = simulate("svalbard-2015")
    visited = {v["target"] for v in metrics["visits"]}
    assert visited == {"T1", "T2", "T3", "T4", "T5"}
    first_t5 = min(v["t_s"] for v in metrics["visits"] if v["target"] == "T5")
    assert first_t5 > 100.0
    # event-based: one plan per loiter end (30 s loiters over an 800 s run)
    assert 5 <= metrics["plans"] <= 800 / 30
    # linear model: sigma grows 1/s unseen, so the average stays below the run length
    assert metrics["max_uncertainty"] < 800
    assert metrics["lost_targets"] == []


def test_metrics_have_the_documented_keys_and_a_sample_every_second() -> None:
    metrics = simulate("paper-boat", 3, duration_s=20.0)
    assert set(metrics) >= METRIC_KEYS
    times = [t for t, _ in metrics["uncertainty_series"]]
    assert times == pytest.approx([float(k) for k in range(21)])
    assert set(metrics["solve_time_s"]) == {"median", "max"}
    json.dumps(metrics)  # serialisable


def test_runs_are_reproducible_for_a_seed() -> None:
    a = simulate("paper-boat", 3, seed=7, duration_s=60.0)
    b = simulate("paper-boat", 3, seed=7, duration_s=60.0)
    c = simulate("paper-boat", 3, seed=8, duration_s=60.0)
    assert a["uncertainty_series"] == b["uncertainty_series"]
    assert a["visits"] == b["visits"]
    assert a["uncertainty_series"] != c["uncertainty_series"]


def test_scripted_fleet_events_change_who_is_planned() -> None:
    base = load_scenario("paper-boat")
    events = (
        ScriptedEvent(20.0, "vehicle_lost", vehicle="2"),
        ScriptedEvent(50.0, "vehicle_returned", vehicle="2"),
        ScriptedEvent(60.0, "override", vehicle="3"),
        ScriptedEvent(80.0, "resume", vehicle="3"),
        ScriptedEvent(90.0, "battery_low", vehicle="1"),
        ScriptedEvent(95.0, "target_removed", target_id="T1"),
    )
    scenario = dataclasses.replace(base, duration_s=200.0, events=events)
    run = run_simulation(scenario, SimulationOptions(seed=1, uavs=3,
                                                     snapshot_times_s=NO_SNAPSHOTS))
    kinds = [e["event"] for e in run.events]
    assert "release" in kinds and "send_home" in kinds
    visits = run.metrics["visits"]
    assert not [v for v in visits if v["vehicle"] == "2" and 20.0 < v["t_s"] < 50.0]
    assert not [v for v in visits if v["target"] == "T1" and v["t_s"] > 95.0]
    # the vehicle sent home ends near the launch point (the boat's start)
    x, y = run.uav_tracks["1"][-1][1:]
    assert abs(x - 1500.0) < 400 and abs(y) < 400


def test_boundedness_ratio_definition() -> None:
    flat = [[float(t), 10.0] for t in range(11)]
    assert boundedness_ratio(flat) == 1.0
    growing = [[float(t), float(t)] for t in range(11)]
    assert boundedness_ratio(growing) == pytest.approx(10 / 5)


def test_cli_writes_metrics_and_plots_for_a_fleet_list(tmp_path: Path,
                                                       capsys: pytest.CaptureFixture) -> None:
    status = main(["simulate", "--scenario", "paper-boat", "--uavs", "1,3", "--seed", "2",
                   "--duration", "30", "--out", str(tmp_path), "--quiet"])
    assert status == 0
    for k in (1, 3):
        metrics = json.loads((tmp_path / f"uavs-{k}" / "metrics.json").read_text())
        assert metrics["uavs"] == k
        for png in ("uncertainty.png", "map.png"):
            data = (tmp_path / f"uavs-{k}" / png).read_bytes()
            assert data.startswith(b"\x89PNG") and len(data) > 10_000
    assert (tmp_path / "comparison.png").read_bytes().startswith(b"\x89PNG")
    out = capsys.readouterr().out
    assert "uavs" in out and str(tmp_path / "uavs-3") in out


def test_uncertainty_plot_title_quotes_the_growth_not_the_withdrawn_ratio_test() -> None:
    from groundstation.runners.simulate.plots import uncertainty_title

    scenario = load_scenario("paper-boat")
    run = run_simulation(scenario, SimulationOptions(seed=1, uavs=1, duration_s=30.0))
    series = run.metrics["uncertainty_series"]
    middle = [v for t, v in series if 10.0 < t <= 20.0]
    last = [v for t, v in series if t > 20.0]
    ratio = (sum(last) / len(last)) / (sum(middle) / len(middle))
    title = uncertainty_title(run)
    assert title.endswith(f"growth over the 2nd half: last/middle third {ratio:.2f}")
    assert "bounded" not in title and "2nd/1st half max" not in title


def test_cli_prints_each_fleet_sizes_growth_over_the_second_half_with_its_interval(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """Issue 31: ``gcs simulate --uavs 1,3 --seeds K`` judges Figure 4 on the ensemble: the
    mean curve's last third over its middle third, with a bootstrap interval over seeds."""
    from groundstation.core.metrics import ensemble_growth, third_means

    status = main(["simulate", "--scenario", "paper-boat", "--uavs", "1,3", "--seeds", "3",
                   "--duration", "30", "--out", str(tmp_path), "--quiet", "--no-plots"])
    assert status == 0
    out = capsys.readouterr().out
    assert "bounded" not in out
    for k in (1, 3):
        thirds = []
        for seed in range(3):
            series = json.loads(
                (tmp_path / f"uavs-{k}" / f"seed-{seed}" / "metrics.json").read_text()
            )["uncertainty_series"]
            thirds.append(third_means([t for t, _ in series], [v for _, v in series]))
        growth = ensemble_growth(thirds)
        assert growth.low is not None
        assert (f"uavs {k}: growth over the second half (mean curve, last third / middle "
                f"third, 3 seed(s)): {growth.text()}") in out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--scenario", "nope"], "no such file or bundled scenario"),
        (["--uavs", "0"], "--uavs takes positive integers"),
        (["--uavs", "two"], "--uavs takes positive integers"),
        (["--duration", "-5"], "expected a positive number"),
        (["--seeds", "0"], "--seeds must be in [1, 10000]"),
    ],
)
def test_cli_user_errors_are_one_line_with_status_2(
    args: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    try:
        status = main(["simulate", *args, "--out", str(tmp_path)])
    except SystemExit as exc:  # argparse reports type errors by exiting with 2
        status = int(exc.code or 0)
    assert status == 2
    err = capsys.readouterr().err
    assert message in err
    assert "Traceback" not in err


@pytest.mark.parametrize("objective", ["sequence", "arrival", "latency"])
def test_cli_objective_takes_every_planner_objective(objective: str, tmp_path: Path) -> None:
    status = main(["simulate", "--scenario", "paper-boat", "--duration", "10", "--no-plots",
                   "--quiet", "--objective", objective, "--out", str(tmp_path)])
    assert status == 0
    assert json.loads((tmp_path / "metrics.json").read_text())["objective"] == objective


def test_arrival_objective_runs_and_is_reported() -> None:
    metrics = simulate("paper-boat", 3, seed=1, duration_s=60.0, objective="arrival")
    assert metrics["objective"] == "arrival"
    assert statistics.fmean(s for _, s in metrics["uncertainty_series"]) > 0


def test_boat_priority_run_replays_identically(tmp_path: Path) -> None:
    """The boat's position is a recorded core input, so a priority run replays exactly."""
    from importlib import resources

    text = (resources.files("world") / "scenarios" / "paper-boat.yaml").read_text()
    scenario = tmp_path / "priority.yaml"
    scenario.write_text(text.replace("  iceberg_q_per_s: 0.0",
                                     "  iceberg_q_per_s: 0.0\n  priority_gain: 4.0"))
    out = tmp_path / "run"
    assert main(["simulate", "--scenario", str(scenario), "--uavs", "2", "--duration", "40",
                 "--out", str(out), "--quiet", "--no-plots"]) == 0
    lines = (out / "journal.jsonl").read_text().splitlines()
    assert any('"kind": "BoatPosition"' in line for line in lines)
    assert main(["replay", str(out)]) == 0
    # and a changed priority gain is a difference
    assert main(["replay", str(out), "--set", "priority_gain=0.5"]) == 1


def test_cli_full_disk_is_one_line_and_leaves_no_half_file(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    import errno
    import io
    import os

    from groundstation import storage

    class FullFile(io.BufferedWriter):
        def write(self, data: object) -> int:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    real_fdopen = os.fdopen

    def fdopen(fd: int, mode: str = "r", *args: object, **kwargs: object) -> object:
        if mode == "wb":  # what storage's atomic writes open
            return FullFile(io.FileIO(fd, "w"))
        return real_fdopen(fd, mode, *args, **kwargs)  # type: ignore[call-overload]

    monkeypatch.setattr(storage.os, "fdopen", fdopen)
    status = main(["simulate", "--scenario", "default", "--duration", "10", "--no-plots",
                   "--out", str(tmp_path), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert status == 2 and "\n" not in err and "Traceback" not in err
    assert err == f"gcs simulate: error: cannot write {tmp_path / 'metrics.json'}: " \
        "No space left on device"
    assert list(tmp_path.iterdir()) == []  # no empty metrics.json, no temporary file


@pytest.mark.parametrize("objective", ["sequence", "latency"])
def test_first_plan_sends_each_uav_to_its_own_iceberg(objective: str) -> None:
    """At t = 0 the three UAVs leave the boat together; the idle-UAV rule once sent idle
    ones to the nearest iceberg, the one another UAV already flew to (all three to one)."""
    options = SimulationOptions(seed=0, uavs=3, duration_s=12.0, snapshot_times_s=NO_SNAPSHOTS,
                                objective=objective, journal=True)
    run = run_simulation(load_scenario("paper-boat"), options)
    plans = [r for r in run.journal if r["event"] == "plan"]
    assert len([p for p in plans if p["reason"] != ANSWER_REASON]) >= 2  # t = 0, 5 and 10 s
    flying: dict[str, str] = {}  # each vehicle's leg, from the journal's fly lines
    for record in run.journal:
        if record["event"] == "fly":
            flying[record["vehicle"]] = record["target"]
        if record["event"] != "plan":
            continue
        targets = list(record["assignments"].values())
        if record["reason"] == ANSWER_REASON:  # commands only the vehicles whose pass ended
            others = {t for v, t in flying.items() if v not in record["assignments"]}
            assert targets and not set(targets) & others, (record["assignments"], flying)
        else:
            assert len(targets) == 3 and len(set(targets)) == 3, record["assignments"]


def test_the_operating_area_refuses_targets_outside_it() -> None:
    """core/area.py's rule in the offline simulator: with a 1 km area around the origin,
    paper-boat's icebergs beyond it are refused (journalled), the others announced."""
    scenario = load_scenario("paper-boat")
    options = SimulationOptions(duration_s=5.0, journal=True, operating_radius_m=1000.0)
    run = run_simulation(scenario, options)
    refused = {r["target"] for r in run.journal if r["event"] == "target_refused"}
    added = {r["target"]: (r["x_m"], r["y_m"]) for r in run.journal
             if r["event"] == "input" and r["kind"] == "TargetAdded"}
    scripted = {r["target"] for r in run.journal if r["event"] == "target_added"}
    assert refused and added and not refused & set(added)
    assert refused | set(added) == scripted
    assert all(math.hypot(x, y) <= 1000.0 for x, y in added.values())
    whole = run_simulation(scenario, dataclasses.replace(options, operating_radius_m=None))
    assert not [r for r in whole.journal if r["event"] == "target_refused"]


def test_cli_refuses_a_wind_at_or_above_the_airspeed(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """Issue 29: ``gcs simulate --wind 30,270`` printed a normal table with 0 visits and
    exited 0 (the reason only in the journal). As ``gcs plan``: one line, exit 2."""
    out = tmp_path / "out"
    assert main(["simulate", "--scenario", "paper-boat", "--wind", "30,270", "--duration",
                 "10", "--no-plots", "--quiet", "--out", str(out)]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert err == ("gcs simulate: error: --wind: a wind of 30 m/s is not below the airspeed "
                   "22 m/s: legs into it cannot be flown")
    assert captured.out == "" and not out.exists()


def test_fallbacks_of_the_core_are_console_lines() -> None:
    from groundstation.commands.simulate import fallback_lines

    journal = [{"event": "plan", "t": 0.0},
               {"event": "wind_refused", "t": 3.0, "detail": "planning as in still air: x"},
               {"event": "wind_refused", "t": 9.0, "detail": "planning as in still air: x"}]
    assert fallback_lines(journal) == [
        "fallback: wind_refused at t=3.0 s: planning as in still air: x (2 times)"]


def test_ctrl_c_keeps_the_partial_journal_and_metrics(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 29: Ctrl-C in ``gcs simulate`` left an empty folder. The run so far is kept
    (metrics of the mission seconds flown, the journal, which replays), exit 130."""
    from groundstation.commands import simulate as simulate_cmd

    def progress(_update: object) -> object:
        def at(t_s: float, _duration_s: float) -> None:
            if t_s >= 20.0:
                raise KeyboardInterrupt

        return at

    monkeypatch.setattr(simulate_cmd, "_mission_progress", progress)
    out = tmp_path / "run"
    assert main(["simulate", "--scenario", "paper-boat", "--uavs", "2", "--duration", "100",
                 "--no-plots", "--quiet", "--out", str(out)]) == 130
    err = capsys.readouterr().err
    assert "interrupted at t=20.0 s" in err and str(out) in err
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["interrupted_at_s"] == 20.0 and metrics["duration_s"] == 20.0
    assert len(metrics["uncertainty_series"]) >= 20
    assert (out / "journal.jsonl").stat().st_size > 0
    assert main(["replay", str(out), "--no-resolve"]) == 0


@pytest.mark.parametrize(("value", "label"), [
    (1000.0, "10³"), (0.01, "10⁻²"), (1.0, "10⁰"), (1e12, "10¹²"), (2000.0, ""),
    (0.0, ""), (-10.0, ""), (math.inf, ""), (math.nan, ""),
])
def test_a_log_axis_is_labelled_at_its_decades_in_plain_text(value: float, label: str) -> None:
    from groundstation.runners.html_page import decade_label

    assert decade_label(value) == label


def test_the_uncertainty_plot_draws_without_the_mathtext_parser(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Its log axis is labelled 10³-style and its units are m²: no label goes through
    matplotlib's mathtext parser (about 15 % of a default ``gcs simulate``, py-spy)."""
    from matplotlib.mathtext import MathTextParser

    from groundstation.runners.simulate.plots import plot_uncertainty

    parsed: list[str] = []
    original = MathTextParser.parse

    def counting(self: MathTextParser, s: str, *args: object, **kw: object) -> object:
        parsed.append(s)
        return original(self, s, *args, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(MathTextParser, "parse", counting)
    run = run_simulation(load_scenario("paper-boat"),
                         SimulationOptions(seed=1, uavs=3, duration_s=60.0))
    path = plot_uncertainty(run, tmp_path / "uncertainty.png")
    assert path.read_bytes().startswith(b"\x89PNG")
    assert parsed == []
