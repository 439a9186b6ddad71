"""problem_from_dict validation, round trip, and `gcs plan` (run(argv)) exit codes and output."""

from __future__ import annotations

import copy
import io
import json
import math
from pathlib import Path
from typing import Any

import pytest

from groundstation.commands.plan import run
from planner import ProblemError, problem_from_dict, problem_to_dict, result_to_dict, solve_plan

GOOD: dict[str, Any] = {
    "uavs": [
        {"id": "a", "x": 0, "y": 0, "heading": 0.0},
        {"id": "b", "x": 500.0, "y": 0, "heading": 1.5},
    ],
    "targets": [
        {"id": "t1", "x": 300, "y": 200, "sigma": 5},
        {"id": "t2", "x": 900, "y": 100, "sigma": 1.5},
        {"id": "t3", "x": 100, "y": 800, "sigma": 0.01},
    ],
    "turn_radius": 105,
    "tau": 0.5,
}

OUTPUT_KEYS = {
    "status",
    "solver",
    "objective",
    "f1",
    "f2",
    "mu",
    "routes",
    "idle",
    "excluded",
    "solve_time_s",
    "bound",
    "gap",
}


def edited(path: list[Any], value: Any, delete: bool = False) -> dict[str, Any]:
    d = copy.deepcopy(GOOD)
    node: Any = d
    for key in path[:-1]:
        node = node[key]
    if delete:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return d


BAD = [
    (edited(["uavs"], None, delete=True), "uavs"),
    (edited(["targets"], None, delete=True), "targets"),
    (edited(["turn_radius"], None, delete=True), "turn_radius"),
    (edited(["uavs"], []), "uavs"),
    (edited(["uavs"], {}), "uavs"),
    (edited(["uavs", 0, "id"], "b"), "uavs[1].id"),
    (edited(["targets", 1, "id"], "t1"), "targets[1].id"),
    (edited(["targets", 0, "id"], "a"), "targets[0].id"),
    (edited(["targets", 0, "id"], 7), "targets[0].id"),
    (edited(["targets", 0, "id"], ""), "targets[0].id"),
    (edited(["targets", 2, "sigma"], None, delete=True), "targets[2].sigma"),
    (edited(["targets", 2, "sigma"], -1.0), "targets[2].sigma"),
    (edited(["targets", 2, "sigma"], math.nan), "targets[2].sigma"),
    (edited(["targets", 0, "x"], math.inf), "targets[0].x"),
    (edited(["targets", 0, "x"], "300"), "targets[0].x"),
    (edited(["targets", 0, "y"], 10**400), "targets[0].y"),
    (edited(["uavs", 1, "heading"], True), "uavs[1].heading"),
    (edited(["uavs", 1, "speed"], 3), "uavs[1].speed"),
    (edited(["targets", 1], "t2"), "targets[1]"),
    (edited(["turn_radius"], 0), "turn_radius"),
    (edited(["turn_radius"], -5), "turn_radius"),
    (edited(["tau"], 1.5), "tau"),
    (edited(["mu"], -1), "mu"),
    (edited(["objective"], "fastest"), "objective"),
    (edited(["speed_m_s"], 0), "speed_m_s"),
    (edited(["time_limit_s"], 0), "time_limit_s"),
    (edited(["min_sigma_fraction"], "0.1"), "min_sigma_fraction"),
    (edited(["wind"], 3), "wind"),
]


@pytest.mark.parametrize(("problem", "field"), BAD)
def test_problem_errors_name_the_field(problem: dict[str, Any], field: str) -> None:
    with pytest.raises(ProblemError) as err:
        problem_from_dict(problem)
    assert err.value.field == field


def test_not_an_object() -> None:
    with pytest.raises(ProblemError):
        problem_from_dict([1, 2])  # type: ignore[arg-type]


def test_round_trip() -> None:
    full = dict(GOOD, mu=0.3, min_sigma_fraction=0.2, time_limit_s=2.0, objective="arrival")
    p = problem_from_dict(full)
    assert problem_from_dict(problem_to_dict(p)) == p
    assert problem_to_dict(p)["mu"] == 0.3
    assert "mu" not in problem_to_dict(problem_from_dict(GOOD))
    assert p.turn_radius_m == 105.0 and p.speed_m_s == 22.0


def test_result_dict_keys_and_json() -> None:
    r = solve_plan(problem_from_dict(GOOD))
    d = result_to_dict(r)
    assert set(d) == OUTPUT_KEYS
    assert json.loads(json.dumps(d)) == d


def write(tmp_path: Path, content: str) -> str:
    path = tmp_path / "problem.json"
    path.write_text(content, encoding="utf-8")
    return str(path)


def test_run_ok(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert run([write(tmp_path, json.dumps(GOOD))]) == 0
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert set(out) == OUTPUT_KEYS
    assert out["status"] == "optimal"
    assert out["excluded"] == ["t3"]
    assert sorted(t for r in out["routes"].values() for t in r) == ["t1", "t2"]
    assert set(out["routes"]) == {"a", "b"}
    assert captured.err == ""


def test_run_deterministic_flags(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, json.dumps(GOOD))
    assert run([path, "--deterministic", "--seed", "4", "--workers", "2"]) == 0
    first = json.loads(capsys.readouterr().out)
    assert run([path, "--deterministic", "--seed", "4"]) == 0
    second = json.loads(capsys.readouterr().out)
    assert first["objective"] == second["objective"]


@pytest.mark.parametrize(
    ("content", "field"),
    [
        ("{not json", "problem"),
        ('{"uavs": [], "targets": [], "turn_radius": NaN}', "problem"),
        (json.dumps(edited(["targets", 0, "sigma"], -2)), "targets[0].sigma"),
        (json.dumps(edited(["extra"], 1)), "extra"),
        ("[]", "problem"),
    ],
)
def test_run_bad_input(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str, field: str
) -> None:
    assert run([write(tmp_path, content)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"gcs plan: error: {field}: ")
    assert "Traceback" not in captured.err


def test_run_missing_file_and_bad_args(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert run([str(tmp_path / "absent.json")]) == 2
    assert capsys.readouterr().err.startswith("gcs plan: error: problem: ")
    assert run([]) == 2
    assert capsys.readouterr().err.startswith("gcs plan: error: arguments: ")
    assert run([write(tmp_path, json.dumps(GOOD)), "--workers", "0"]) == 2
    assert capsys.readouterr().err.startswith("gcs plan: error: --workers: ")
    assert run([write(tmp_path, json.dumps(GOOD)), "--seed", "x"]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_run_reads_stdin(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr("sys.stdin", io.StringIO(json.dumps(GOOD)))
    assert run(["-"]) == 0
    assert json.loads(capsys.readouterr().out)["status"] == "optimal"


def test_run_help_exits_zero(capsys: pytest.CaptureFixture[str]) -> None:
    assert run(["--help"]) == 0
    assert "gcs plan" in capsys.readouterr().out
