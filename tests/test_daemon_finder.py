"""`gcs target` / `gcs vehicle` find the running daemon through its control.json, and two
`gcs run --vehicles sim:N` run side by side (free ports for what the user did not name).

The daemons are real `gcs run` processes on ephemeral ports (control API 127.0.0.1:0, the
built-in vehicles' TCP, the detection feed), stopped with SIGTERM; every wait is bounded.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from groundstation.commands import target, vehicle
from groundstation.commands.daemon_finder import find_daemon

GCS = [sys.executable, "-m", "groundstation.cli"]


@pytest.fixture(autouse=True)
def no_env(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("FLOE_API", raising=False)
    monkeypatch.delenv("FLOE_TOKEN", raising=False)


def _start(run_dir: Path, log: Path) -> subprocess.Popen[bytes]:
    argv = [
        *GCS, "run", "--vehicles", "sim:1", "--sim-airborne", "--scenario", "none",
        "--speedup", "5", "--duration", "3000", "--run-dir", str(run_dir),
        "--status", "log",
    ]  # fmt: skip
    with log.open("wb") as out:
        return subprocess.Popen(argv, stdout=out, stderr=subprocess.STDOUT)


def _wait_control_files(run_dir: Path, count: int, procs: list[subprocess.Popen[bytes]],
                        logs: list[Path], timeout_s: float = 60.0) -> list[Path]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        files = sorted(run_dir.glob("*/control.json"))
        if len(files) >= count:
            return files
        for proc, log in zip(procs, logs, strict=True):
            if proc.poll() is not None:
                pytest.fail(f"gcs run exited {proc.returncode}: {log.read_text()[-2000:]}")
        time.sleep(0.1)
    pytest.fail("no control.json within the time bound")


def _wait_logs(logs: list[Path], text: str, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not all(text in log.read_text() for log in logs):
        if time.monotonic() > deadline:
            pytest.fail(f"{text!r} not in every log within the time bound")
        time.sleep(0.1)


def _stop(procs: list[subprocess.Popen[bytes]]) -> list[int]:
    for proc in procs:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
    codes = []
    for proc in procs:
        try:
            codes.append(proc.wait(timeout=30))
        except subprocess.TimeoutExpired:
            proc.kill()
            codes.append(proc.wait())
    return codes


@pytest.fixture
def two_daemons(tmp_path: Path) -> Iterator[tuple[Path, list[subprocess.Popen[bytes]], list[Path]]]:
    run_dir = tmp_path / "runs"
    logs = [tmp_path / "first.log", tmp_path / "second.log"]
    procs = [_start(run_dir, logs[0])]
    try:
        _wait_control_files(run_dir, 1, procs, logs[:1])
        time.sleep(0.05)  # the second's control.json is newer, whatever the file system
        procs.append(_start(run_dir, logs[1]))
        _wait_control_files(run_dir, 2, procs, logs)
        yield run_dir, procs, logs
    finally:
        _stop(procs)


@pytest.mark.timeout(150)
def test_two_sim_runs_side_by_side_and_the_cli_finds_the_newest(
    two_daemons: tuple[Path, list[subprocess.Popen[bytes]], list[Path]],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    run_dir, procs, logs = two_daemons
    assert all(p.poll() is None for p in procs)  # both run: no port collided (UDP 14600)
    controls = [json.loads(p.read_text()) for p in sorted(run_dir.glob("*/control.json"))]
    assert len({c["url"] for c in controls}) == 2
    newest = max(run_dir.glob("*/control.json"), key=lambda p: p.stat().st_mtime)
    newest_url = json.loads(newest.read_text())["url"]

    monkeypatch.chdir(run_dir.parent)  # the default --run-dir is ./runs
    assert target.run(["list"]) == 0
    captured = capsys.readouterr()
    assert captured.out.splitlines()[0].split()[:3] == ["id", "x_m", "y_m"]
    err = captured.err.strip()
    relative = newest.relative_to(run_dir.parent)
    assert err.startswith(f"gcs target: using the daemon at {newest_url} ({relative}")
    assert "newest of 2 running" in err

    # a write with the token of the found daemon's control.json, no --token needed
    assert target.run(["add", "ICE9", "--x", "300", "--y", "200", "--run-dir", str(run_dir)]) == 0
    assert capsys.readouterr().out.strip() == "added target ICE9"
    assert target.run(["list", "--json", "--api", newest_url]) == 0
    assert "ICE9" in {t["id"] for t in json.loads(capsys.readouterr().out)["targets"]}
    assert vehicle.run(["list", "--run-dir", str(run_dir)]) == 0
    assert capsys.readouterr().out.splitlines()[0].split()[:3] == ["id", "name", "sysid"]

    # each printed where its detection feed went: a free port, said so
    for log in logs:
        text = log.read_text()
        assert "detection feed on udp:127.0.0.1:" in text
        assert "(a free port; --detections HOST:PORT to choose)" in text
        assert "udp:127.0.0.1:14600 " not in text

    # a run stopped before it heard its vehicle exits 1 (issue 11): wait until both have
    _wait_logs(logs, "vehicle_seen vehicle=1")
    assert _stop(procs) == [0, 0]  # both stopped cleanly
    assert target.run(["list", "--run-dir", str(run_dir)]) == 1
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "no running daemon found" in err and "stopped" in err


def test_no_control_json_is_a_clear_error(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    assert vehicle.run(["list", "--run-dir", str(tmp_path / "nowhere")]) == 1
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    assert "no running daemon found: no control.json under" in err and "--api" in err


def test_explicit_api_takes_the_token_of_its_control_json(tmp_path: Path) -> None:
    for name, url, token in (("a", "http://127.0.0.1:4001", "ta"),
                             ("b", "http://127.0.0.1:4002", "tb")):
        (tmp_path / name).mkdir()
        (tmp_path / name / "control.json").write_text(json.dumps({"url": url, "token": token}))
    found = find_daemon("http://127.0.0.1:4001/", None, str(tmp_path), lambda _: False, {})
    assert (found.url, found.token, found.note) == ("http://127.0.0.1:4001/", "ta", None)
    env = {"FLOE_API": "http://127.0.0.1:4002", "FLOE_TOKEN": "mine"}
    assert find_daemon(None, None, str(tmp_path), lambda _: False, env).token == "mine"
    # discovery: only live ones count, the newest first; FLOE_TOKEN alone is not used
    os.utime(tmp_path / "a" / "control.json", (1e9, 1e9))
    found = find_daemon(None, None, str(tmp_path), lambda url: True, {"FLOE_TOKEN": "old"})
    assert (found.url, found.token) == ("http://127.0.0.1:4002", "tb")
    assert found.note is not None and "newest of 2 running" in found.note
    found = find_daemon(None, "given", str(tmp_path), lambda url: url.endswith("4001"), {})
    assert (found.url, found.token) == ("http://127.0.0.1:4001", "given")
    assert found.note is not None and "newest of" not in found.note
