"""``gcs run`` with its disk full: refused at start, survived during the run.

The full disk during the run is simulated by replacing ``groundstation.storage._os_write``
with one that fails with ENOSPC for the journal's file descriptor between two mission
times (first writing half a line, as a real full disk does); the built-in simulated
vehicles fly on 127.0.0.1 with ephemeral ports.
"""

from __future__ import annotations

import asyncio
import errno
import json
import os
from pathlib import Path
from typing import Any

import pytest
from daemon_run import events
from environment import need

from groundstation import storage
from groundstation.commands import run as run_cmd
from groundstation.commands.run import build_config, run_daemon
from groundstation.daemon.daemon import Daemon

OUTAGE_S = (60.0, 110.0)


class JournalOutage:
    """ENOSPC for writes to ``path`` while the daemon's mission time is in the window;
    the first failing write writes 9 bytes (half a line) before the error."""

    def __init__(self, path: Path) -> None:
        self.path = str(path)
        self.daemon: Daemon | None = None
        self.failed = 0
        self.partial_done = False
        self.real = os.write

    def __call__(self, fd: int, data: bytes) -> int:
        d = self.daemon
        if d is not None and OUTAGE_S[0] <= d.clock.now_s() < OUTAGE_S[1]:
            try:
                ours = os.readlink(f"/proc/self/fd/{fd}") == self.path
            except OSError:
                ours = False
            if ours:
                self.failed += 1
                if not self.partial_done:
                    self.partial_done = True
                    return self.real(fd, bytes(data[:9]))
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return self.real(fd, data)


@pytest.mark.timeout(120)
def test_journal_outage_mid_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    journal_path = (tmp_path / "journal.jsonl").resolve()
    outage = JournalOutage(journal_path)
    monkeypatch.setattr(storage, "_os_write", outage)
    config = build_config(
        ["--vehicles", "sim:2", "--scenario", "default", "--sim-airborne", "--loiter", "20",
         "--speedup", "40", "--duration", "200", "--journal", str(journal_path),
         "--run-dir", str(tmp_path / "runs"), "--http", "off", "--detections", "off",
         "--status", "quiet"]
    )  # fmt: skip

    appended: list[bytes] = []

    def started(daemon: Daemon) -> None:
        outage.daemon = daemon
        sink = daemon.journal_file.file
        assert sink is not None
        real_append = sink.append

        def spy(data: bytes, *, keep: bool = False) -> bool:
            appended.append(data)
            return real_append(data, keep=keep)

        sink.append = spy  # type: ignore[method-assign]

    daemon = asyncio.run(
        asyncio.wait_for(
            run_daemon(config, print_fn=lambda _: None, on_started=started, install_signals=False),
            100.0,
        )
    )
    assert outage.partial_done and outage.failed >= 2 and daemon.journal_file.file is not None
    assert daemon.journal_file.file.write_errors >= 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    storage_lines = [line for line in err.splitlines() if str(journal_path) in line]
    # one error for the outage, one line when writing works again
    assert len(storage_lines) == 2, err
    assert "cannot write (No space left on device)" in storage_lines[0]
    assert "writing again" in storage_lines[1] and ", 0 dropped" in storage_lines[1]

    # readable line by line: no half line anywhere
    journal: list[dict[str, Any]] = []
    for number, text in enumerate(journal_path.read_text().splitlines(), 1):
        try:
            journal.append(json.loads(text))
        except json.JSONDecodeError:
            pytest.fail(f"journal line {number} is not JSON: {text[:60]!r}")
    assert journal[0]["event"] == "start" and journal[-1]["event"] == "stop"
    # the held records are there, in order: the file ends with exactly the lines the
    # daemon journalled since it started, outage or not
    file_lines = journal_path.read_bytes().splitlines(keepends=True)
    assert len(appended) > 1000 and file_lines[-len(appended) :] == appended
    inputs = [e for e in journal if e["event"] == "input"]
    times = [e["t"] for e in inputs if e["kind"] == "Tick"]
    assert times == sorted(times)
    held = [t for t in times if OUTAGE_S[0] <= t < OUTAGE_S[1]]
    ticks_held = [e for e in inputs if e["kind"] == "Tick" and OUTAGE_S[0] <= e["t"] < OUTAGE_S[1]]
    assert len(ticks_held) >= 0.9 * (OUTAGE_S[1] - OUTAGE_S[0]) / 0.1 and held
    # the vehicles kept flying their missions: loiters end and verified uploads go on after
    loiter_ends = [e for e in inputs if e["kind"] == "LoiterEnded"]
    assert [e for e in loiter_ends if OUTAGE_S[0] <= e["t"] < OUTAGE_S[1]] or [
        e for e in events(journal, "upload", ok=True) if OUTAGE_S[0] <= e["t"] < OUTAGE_S[1]
    ]
    assert [e for e in loiter_ends if e["t"] >= OUTAGE_S[1]]
    assert [e for e in events(journal, "upload", ok=True, purpose="target")
            if e["t"] >= OUTAGE_S[1]]  # fmt: skip
    assert not events(journal, "task_error") and not events(journal, "core_error")
    # metrics.json complete
    metrics = json.loads((daemon.run_dir / "metrics.json").read_text())
    expected = json.loads(json.dumps(daemon.metrics_dict()))
    assert set(metrics) == set(expected) and metrics["plans"] == expected["plans"] >= 3
    assert metrics["uncertainty_series"] == expected["uncertainty_series"]


def test_journal_on_dev_full_is_refused_at_start(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    need(os.path.exists("/dev/full"), "needs /dev/full")
    code = run_cmd.run(["--vehicles", "sim:1", "--journal", "/dev/full",
                        "--run-dir", str(tmp_path / "runs"), "--http", "off",
                        "--detections", "off", "--status", "quiet", "--duration", "1"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2
    assert err.strip().splitlines() == [
        "gcs run: error: journal: cannot write /dev/full: No space left on device"
    ]
    assert not (tmp_path / "runs").exists() or not list((tmp_path / "runs").iterdir())


def test_run_dir_on_a_full_disk_is_refused_at_start(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def full(fd: int, data: bytes) -> int:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(storage, "_os_write", full)
    runs = tmp_path / "runs"
    code = run_cmd.run(["--vehicles", "sim:1", "--run-dir", str(runs), "--http", "off",
                        "--detections", "off", "--status", "quiet", "--duration", "1"])  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert str(runs) in err[0] and "No space left on device" in err[0]
    assert list(runs.iterdir()) == []


def test_run_folder_files_are_whole_and_control_json_is_private(tmp_path: Path) -> None:
    """config.yaml, control.json (0600 from creation) and metrics.json are written
    atomically: whole, and no temporary file is left in the run folder."""
    import stat

    import yaml

    created: list[tuple[str, int]] = []
    real_open = os.open

    def spy(path: Any, flags: int, mode: int = 0o777, *args: Any, **kwargs: Any) -> int:
        fd = real_open(path, flags, mode, *args, **kwargs)
        if flags & os.O_CREAT and "control.json" in str(path):
            created.append((str(path), stat.S_IMODE(os.fstat(fd).st_mode)))
        return fd

    config = build_config(
        ["--vehicles", "sim:1", "--scenario", "default", "--sim-airborne", "--speedup", "40",
         "--duration", "20", "--run-dir", str(tmp_path), "--http", "127.0.0.1:0",
         "--detections", "off", "--status", "quiet"]
    )  # fmt: skip
    printed: list[str] = []
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(storage.os, "open", spy)
        daemon = asyncio.run(
            asyncio.wait_for(
                run_daemon(config, print_fn=printed.append, install_signals=False), 60.0
            )
        )
    run_dir = daemon.run_dir
    assert created and all(mode == 0o600 for _, mode in created)
    assert stat.S_IMODE((run_dir / "control.json").stat().st_mode) == 0o600
    control = json.loads((run_dir / "control.json").read_text())
    told = [line for line in printed if line.startswith("gcs run: control API ")]
    assert len(told) == 1  # "gcs run: control API URL token TOKEN (...)": what the operator got
    assert told[0].split()[4:7] == [daemon.control_url, "token", control["token"]], told
    assert control["url"] == daemon.control_url
    assert yaml.safe_load((run_dir / "config.yaml").read_text())["mission"]["duration_s"] == 20
    assert json.loads((run_dir / "metrics.json").read_text())["summary"]["mission_s"] >= 20
    assert sorted(p.name for p in run_dir.iterdir()) == [
        "config.yaml", "control.json", "flight.tlog", "gcs.log", "journal.jsonl", "metrics.json"
    ]  # fmt: skip
