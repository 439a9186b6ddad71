"""gcs campaign: campaign files (every mistake one line, exit 2), run identity, columns."""

from __future__ import annotations

from pathlib import Path

import pytest

from groundstation.cli import main
from groundstation.runners.campaign.grid import load_campaign, parse_campaign, run_id
from groundstation.runners.campaign.run import RunOutcome, flatten_metrics
from groundstation.runners.campaign.schema import (
    ARRIVAL_SUMMARIES,
    COORDINATE_METRICS,
    metrics_columns,
)
from groundstation.runners.simulate.simulator import SimulationOptions, run_simulation
from world.scenario import load_scenario

GOOD = """\
name: t
grid:
  scenario: [paper-boat]
  uavs: [1, 3]
  seed: {from: 0, to: 1}
set: {duration_s: 20}
"""


def write(tmp_path: Path, text: str, name: str = "c.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize(("text", "expected"), [
    ("name: t\ngrid: {scenario: [paper-boat]}\nextra: 1\n", "extra: unknown field"),
    ("grid: {scenario: [paper-boat], uav: [1]}\n", "grid.uav: unknown key"),
    ("grid: {scenario: [paper-boat], uavs: []}\n", "grid.uavs: must not be empty"),
    ("grid: {scenario: [paper-boat], uavs: 3}\n", "grid.uavs: must be a list"),
    ("grid: {scenario: [paper-boat], uavs: [1, 1.5]}\n",
     "grid.uavs[1]: must be an integer, got 1.5"),
    ("grid: {scenario: [paper-boat], seed: {from: 5, to: 2}}\n",
     "grid.seed.to: must be >= from (5), got 2"),
    ("grid: {scenario: [paper-boat], seed: [0, 0]}\n", "grid.seed[1]: repeats the value 0"),
    ("grid: {scenario: [paper-boat], tau: [2]}\n", "grid.tau[0]: must be <= 1, got 2"),
    ("grid: {scenario: [paper-boat], objective: [fastest]}\n",
     "grid.objective[0]: must be one of sequence, arrival, latency"),
    ("grid: {scenario: [no-such-scenario]}\n", "grid.scenario[0]: scenario 'no-such-scenario'"),
    ("grid: {scenario: [paper-boat]}\nset: {fleet.speed_m_s: -1}\n",
     "set.fleet.speed_m_s: scenario paper-boat: fleet.speed_m_s: must be > 0, got -1"),
    ("grid: {scenario: [paper-boat], fleet.sped_m_s: [20]}\n",
     "grid.fleet.sped_m_s: scenario paper-boat with fleet.sped_m_s=20: "
     "fleet.sped_m_s: unknown field"),
    ("grid: {scenario: [paper-boat], observer.r_m2: [5, 0]}\n",
     "grid.observer.r_m2: scenario paper-boat with observer.r_m2=0: observer.r_m2: must be > 0"),
    ("grid: {scenario: [paper-boat], tau: [0.5]}\nset: {planner.tau: 0.9}\n",
     "set.planner.tau: conflicts with grid key 'tau'"),
    ("grid: {scenario: [paper-boat], seed: {from: 0, to: 999999}, uavs: [1, 2]}\n",
     "grid: 2,000,000 runs; a campaign takes at most 1,000,000"),
    ("grid: [1, 2]\n", "grid: must be a mapping"),
    ("grid: {scenario: [paper-boat]}\nset: {boat.x_m: 2020-01-01}\n",
     "set.boat.x_m: must be a finite number, a string"),
    ("grid: {scenario: [paper-boat]}\nper_plan: yes please\n", "per_plan: must be true or false"),
])
def test_a_bad_campaign_file_is_one_line_naming_the_field(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, expected: str
) -> None:
    path = write(tmp_path, text)
    assert main(["campaign", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith(f"gcs campaign: error: {path}: "), err
    assert expected in err, err
    assert not (tmp_path / "out").exists()  # nothing runs before the whole grid is valid


@pytest.mark.parametrize("scenario_text", ["- a\n- b\n", "just words\n", "42\n"])
def test_a_scenario_file_that_is_yaml_but_not_a_mapping_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], scenario_text: str
) -> None:
    """Issue 28's probe: a grid's scenario file that parses as YAML but holds a list, a
    string or a number was a 26-line traceback."""
    write(tmp_path, scenario_text, "odd.yaml")
    path = write(tmp_path, "grid: {scenario: [odd.yaml]}\n")
    assert main(["campaign", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert "grid.scenario[0]: scenario " in err and "not a mapping of scenario fields" in err
    assert not (tmp_path / "out").exists()


def test_a_changed_grid_needs_extend_and_keeps_the_runs_it_holds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from groundstation.runners.campaign.driver import open_campaign
    from groundstation.runners.campaign.store import RUNS_DIR

    out = tmp_path / "out"
    first = open_campaign(write(tmp_path, GOOD), out)
    one = next(first.spec.tasks())
    first.store.write(RunOutcome(one.run_id, {"run_id": one.run_id, **one.coords}, []))
    wider = write(tmp_path, GOOD.replace("to: 1", "to: 2"), "wider.yaml")
    assert main(["campaign", str(wider), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "holds another campaign (grid.seed: [0, 1] there, [0, 1, 2] here)" in err
    assert "--extend" in err and err.count("\n") == 1
    extended = open_campaign(wider, out, extend=True)
    assert extended.total == 6 and extended.done == {one.run_id}
    assert (out / "campaign.yaml").read_text() == wider.read_text()
    assert [p.name for p in (out / RUNS_DIR).iterdir()] == [f"run-{one.run_id}.parquet"]


def test_run_ids_are_stable_hashes_of_the_coordinates(tmp_path: Path) -> None:
    spec = load_campaign(write(tmp_path, GOOD))
    ids = list(spec.run_ids())
    assert len(set(ids)) == 4 and ids == [t.run_id for t in spec.tasks()]
    # the same coordinates give the same id on every machine and in every release
    coords = {"scenario": "paper-boat", "uavs": 1, "objective": "sequence", "tau": 0.5,
              "seed": 0, "duration_s": 20}
    assert next(spec.tasks()).coords == coords
    assert run_id(coords) == run_id({**coords, "duration_s": 20.0}) == "7761aaf19bec6e5f"


def test_a_dotted_grid_key_is_a_column_and_reaches_the_scenario(tmp_path: Path) -> None:
    spec = parse_campaign({"grid": {"scenario": ["paper-boat"], "observer.r_m2": [5, 10]},
                           "set": {"duration_s": 10, "planner.tau": 0.25}},
                          base_dir=tmp_path)
    tasks = list(spec.tasks())
    assert [t.coords["observer.r_m2"] for t in tasks] == [5, 10]
    assert [t.coords["tau"] for t in tasks] == [0.25, 0.25]  # the effective value
    assert tasks[1].scenario_data["observer"]["r_m2"] == 10
    assert tasks[1].scenario_data["planner"]["tau"] == 0.25
    lists = parse_campaign({"grid": {"scenario": ["paper-boat"],
                                     "fleet.headings_rad": [[0.0], [0.0, 3.14]]}},
                           base_dir=tmp_path)
    assert [t.scenario_data["fleet"]["headings_rad"] for t in lists.tasks()] == [
        [0.0], [0.0, 3.14]]


@pytest.mark.parametrize("scenario", ["svalbard-2015", "discovery"])
def test_every_scalar_of_metrics_json_has_a_column(scenario: str) -> None:
    """discovery: its track-quality keys too (gospa_mean_m, time_to_confirm_s, ...)."""
    metrics = run_simulation(load_scenario(scenario), SimulationOptions(
        duration_s=10, snapshot_times_s=(0.0,))).metrics
    columns = metrics_columns()
    flat = flatten_metrics(metrics)
    for key, value in metrics.items():
        if key in COORDINATE_METRICS:
            continue
        if key in ARRIVAL_SUMMARIES:  # None when no arrival was counted
            assert {f"{key}_{inner}" for inner in ARRIVAL_SUMMARIES[key]} <= set(columns)
        elif key == "uploads_per_hour":  # per vehicle: its maximum
            assert "uploads_per_hour_max" in columns
        elif isinstance(value, dict) and key not in ("solve_time_s", "max_estimation_error_m",
                                                     "uploads"):
            assert all(f"{key}_{inner}" in columns for inner in value), key
        else:
            assert key in columns or key == "solve_time_s", f"metrics.json {key} has no column"
    assert set(flat) == set(columns)
