"""Hostile or absurd input files and flags: one line naming the field, exit 2, never a
traceback (MemoryError, RecursionError, UnicodeDecodeError) and never a run that cannot end."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from domain.limits import MAX_FLEET, MAX_TARGETS, MAX_YAML_DEPTH
from groundstation.cli import main

DEEP = "a: " + "[" * 5000 + "]" * 5000 + "\n"
ALIAS_BOMB = "a: &a [x,x,x,x,x,x,x,x,x,x]\n" + "".join(
    f"{n}: &{n} [{', '.join([f'*{p}'] * 10)}]\n" for p, n in zip("abcde", "bcdef", strict=True)
)


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str]:
    status = main(list(argv))
    err = capsys.readouterr().err
    return status, err


def one_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        (DEEP, f"nested deeper than {MAX_YAML_DEPTH} levels"),
        (ALIAS_BOMB, "more than 200000 values"),
        (b"\x89PNG\r\n\x1a\n" + bytes(range(256)), "not UTF-8 text"),
        ("name: x\nfleet: {count: 100000000}\n", f"fleet.count: must be an integer <= {MAX_FLEET}"),
        ("name: x\ntargets: {random: {count: 1000000000}}\n", "targets.random.count"),
        ("name: x\ntargets: {list: [{id: A, x_m: 0, y_m: 0, vx_m_s: 1e12}]}\n",
         "targets.list[0].vx_m_s: must be <= 100"),
        ("name: x\ntargets: {list: [{id: A, x_m: 1.0e+300, y_m: 0}]}\n", "targets.list[0].x_m"),
        ("name: x\nduration_s: 1.0e+15\n", "duration_s: must be <="),
    ],
)
def test_bad_scenarios_are_one_line_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str | bytes, expected: str
) -> None:
    path = tmp_path / "bad.yaml"
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    status, err = run(capsys, "simulate", "--scenario", str(path), "--out", str(tmp_path / "o"))
    assert status == 2
    assert expected in one_line(err)
    assert not (tmp_path / "o" / "metrics.json").exists()


def test_too_many_targets_in_all_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    listed = ", ".join(f"{{id: L{i}, x_m: {i}, y_m: 0}}" for i in range(10))
    path = tmp_path / "many.yaml"
    path.write_text(f"name: x\ntargets:\n  list: [{listed}]\n  random: {{count: {MAX_TARGETS}}}\n")
    status, err = run(capsys, "simulate", "--scenario", str(path), "--out", str(tmp_path / "o"))
    assert status == 2 and f"limit is {MAX_TARGETS}" in one_line(err)


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        (DEEP, "nested deeper than"),
        (ALIAS_BOMB, "more than 200000 values"),
        (bytes(range(256)) * 4, "not UTF-8 text"),
        ("vehicles: [sim:1]\n\x00\n", "NUL"),
    ],
)
def test_bad_daemon_config_files_are_one_line_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str | bytes, expected: str
) -> None:
    path = tmp_path / "config.yaml"
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    status, err = run(
        capsys, "run", "--config", str(path), "--vehicles", "sim:1", "--duration", "1",
        "--run-dir", str(tmp_path / "run"), "--http", "off", "--detections", "off",
    )  # fmt: skip
    assert status == 2
    line = one_line(err)
    assert "--config" in line and expected in line


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        (DEEP, "nested deeper than"),
        ("- {id: A, x_m: 0, y_m: 0, vx_m_s: 1e12}\n", "vx_m_s: must be <= 100"),
        ("".join(f"- {{id: T{i}, x_m: 0, y_m: 0}}\n" for i in range(MAX_TARGETS + 1)),
         f"limit is {MAX_TARGETS}"),
    ],
)
def test_bad_target_files_are_one_line_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str, expected: str
) -> None:
    path = tmp_path / "targets.yaml"
    path.write_text(content)
    status, err = run(
        capsys, "run", "--targets", str(path), "--vehicles", "sim:1", "--duration", "1",
        "--run-dir", str(tmp_path / "run"), "--http", "off", "--detections", "off",
    )  # fmt: skip
    assert status == 2
    line = one_line(err)
    assert "--targets" in line and expected in line


def test_huge_fleets_are_refused_by_every_command(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["simulate", "--scenario", "paper-boat", "--uavs", "100000"])
    assert exc.value.code == 2
    err = capsys.readouterr().err  # argparse's usage, then the one error line
    assert f"limit of {MAX_FLEET}" in err.splitlines()[-1] and "Traceback" not in err
    problem = {
        "uavs": [{"id": f"U{i}", "x": 0, "y": 0, "heading": 0} for i in range(MAX_FLEET + 1)],
        "targets": [], "turn_radius": 100,
    }  # fmt: skip
    path = tmp_path / "p.json"
    path.write_text(json.dumps(problem))
    status = main(["plan", str(path)])
    assert status == 2
    assert f"limit is {MAX_FLEET}" in one_line(capsys.readouterr().err)
