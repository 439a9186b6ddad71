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
import logging
import os
from pathlib import Path
from typing import Any

import pytest
from daemon_run import events
from environment import need

from groundstation import storage
from groundstation.commands import run as run_cmd
from groundstation.commands.run import build_config, run_daemon
from groundstation.daemon import journal as journal_module
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.journal import Journal

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

        def spy(data: bytes, **kwargs: Any) -> bool:
            appended.append(data)
            return real_append(data, **kwargs)

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
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert metrics["summary"]["mission_s"] >= 20
    # the event loop's worst stall (loop_monitor.py), measured through the run
    assert metrics["loop_stall_max_ms"] >= 0 and metrics["loop_stalls_over_100ms"] >= 0
    assert sorted(p.name for p in run_dir.iterdir()) == [
        "config.yaml", "control.json", "flight.tlog", "gcs.log", "journal.jsonl", "metrics.json",
        "missions", "params",
    ]  # fmt: skip
    # the files other ground stations open (docs/daemon.md): whole, none left half-written
    waypoints = sorted((run_dir / "missions").rglob("*.waypoints"))
    assert waypoints and all(p.read_text().startswith("QGC WPL 110\n") for p in waypoints)
    parms = sorted((run_dir / "params").glob("*.parm"))
    assert parms and all(len(line.split()) == 2 for p in parms
                         for line in p.read_text().splitlines() if line.strip())
    assert not [p for p in run_dir.rglob("*") if p.name.endswith((".tmp", ".part"))]


# ------------------------------------------------------------------ a disk still full at exit


class SpaceDisk:
    """One file's disk with a size: once ``full``, its writes fit in ``free`` bytes only (a
    short write, then ENOSPC, as a real disk does); removing the journal's reserve
    (``storage._os_unlink``) gives its bytes back. ``full_from_t``: the disk fills with the
    first journal line of mission time at or after it (and stays full)."""

    def __init__(self, path: Path, full_from_t: float | None = None) -> None:
        self.path = str(path)
        self.full = False
        self.free = 0
        self.full_from_t = full_from_t
        self.released: list[str] = []

    def _ours(self, fd: int) -> bool:
        try:
            return os.readlink(f"/proc/self/fd/{fd}") == self.path
        except OSError:
            return False

    def write(self, fd: int, data: bytes) -> int:
        if not self._ours(fd):
            return os.write(fd, data)
        if not self.full and self.full_from_t is not None and data.startswith(b'{"t":'):
            t = float(data[5:data.index(b",")])
            self.full = t >= self.full_from_t
        if not self.full:
            return os.write(fd, data)
        if self.free <= 0:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        n = min(len(data), self.free)
        self.free -= n
        return os.write(fd, bytes(data[:n]))

    def unlink(self, path: str) -> None:
        size = os.stat(path).st_size
        os.unlink(path)
        self.released.append(path)
        if self.full:
            self.free += size


@pytest.fixture
def space(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> SpaceDisk:
    disk = SpaceDisk((tmp_path / "journal.jsonl").resolve())
    monkeypatch.setattr(storage, "_os_write", disk.write)
    monkeypatch.setattr(storage, "_os_unlink", disk.unlink, raising=False)
    return disk


def journal_with_outage(disk: SpaceDisk, held_lines: int) -> tuple[Journal, list[bytes]]:
    """A journal: 3 lines written, then the disk full, ``held_lines`` track lines (about
    100 bytes each) and the stop line held; returns it and every line it meant to write."""
    t = [0.0]
    journal = Journal(disk.path, lambda: t[0], lambda: 1.7e9)
    for event in ("start", "plan", "fly"):
        journal.write(event)
    disk.full = True
    for i in range(held_lines):
        t[0] = 1.0 + i
        journal.write("track", target="A", x_m=float(i), y_m=-float(i), sigma=12.5)
    t[0] = 500.0
    journal.write("stop", reason="duration", mission_s=500.0, plans=7, uploads_ok=9)
    assert journal.file is not None and journal.file.held == held_lines + 1
    wanted = Path(disk.path).read_bytes().splitlines(keepends=True)
    return journal, wanted


def held_records(journal: Journal) -> list[bytes]:
    """The lines a journal holds, in the order they were written (test's view)."""
    assert journal.file is not None
    items = [*journal.file._low, *journal.file._high, *getattr(journal.file, "_vital", [])]
    return [data for _, data in sorted(items)]


def test_disk_full_at_exit_writes_the_stop_line_first_from_the_reserve(
        space: SpaceDisk, monkeypatch: pytest.MonkeyPatch,
        caplog: pytest.LogCaptureFixture) -> None:
    """The held lines do not fit in the released reserve: the stop line first, then the
    held lines in order while they fit; one ERROR line says how many were not written."""
    monkeypatch.setattr(journal_module, "RESERVE_BYTES", 1000, raising=False)
    journal, before = journal_with_outage(space, held_lines=40)  # ~4 kB held
    held = held_records(journal)
    reserve = Path(space.path).parent / ".journal.jsonl.reserve"
    assert reserve.stat().st_size == 1000
    with caplog.at_level(logging.WARNING, logger="groundstation.storage"):
        journal.close()
    got = Path(space.path).read_bytes().splitlines(keepends=True)
    stop = held[-1]
    assert json.loads(stop)["event"] == "stop" and json.loads(stop)["plans"] == 7
    written = len(got) - len(before) - 1
    assert 1 <= written < 40
    assert got == [*before, stop, *held[:written]]  # stop first, the rest in order
    assert space.released == [str(reserve)] and not reserve.exists()
    said = [r.getMessage() for r in caplog.records if "at exit" in r.getMessage()]
    assert len(said) == 1 and space.path in said[0]
    assert "the stop line and summary written first" in said[0]
    assert f"{written} of 40 held records written in order" in said[0]
    assert f"{40 - written} records not written" in said[0] and "lost" in said[0]


def test_space_returning_at_exit_takes_the_stop_line_first(
        space: SpaceDisk, monkeypatch: pytest.MonkeyPatch,
        caplog: pytest.LogCaptureFixture) -> None:
    """No reserve; a little space back by the end: the stop line takes it first (before, the
    oldest held lines took it in order and the stop line was lost)."""
    monkeypatch.setattr(journal_module, "RESERVE_BYTES", 0, raising=False)
    journal, before = journal_with_outage(space, held_lines=40)
    held = held_records(journal)
    space.free = len(held[-1]) + len(held[0]) + len(held[1]) + 10  # room for 3 lines
    with caplog.at_level(logging.WARNING, logger="groundstation.storage"):
        journal.close()
    got = Path(space.path).read_bytes().splitlines(keepends=True)
    assert got == [*before, held[-1], held[0], held[1]]
    said = [r.getMessage() for r in caplog.records if "at exit" in r.getMessage()]
    assert len(said) == 1 and "38 records not written" in said[0]


def test_held_lines_that_fit_the_reserve_are_written_in_order(
        space: SpaceDisk, caplog: pytest.LogCaptureFixture) -> None:
    """The default reserve (1 MiB) takes a short outage's lines: all of them, in order, the
    stop line last, and one line saying so."""
    journal, before = journal_with_outage(space, held_lines=40)
    held = held_records(journal)
    with caplog.at_level(logging.WARNING, logger="groundstation.storage"):
        journal.close()
    assert Path(space.path).read_bytes().splitlines(keepends=True) == [*before, *held]
    said = [r.getMessage() for r in caplog.records if "at exit" in r.getMessage()]
    assert len(said) == 1 and "all 41 held records written in order" in said[0]
    assert journal.file is not None and journal.file.lost == 0


@pytest.mark.timeout(120)
def test_gcs_run_on_a_disk_that_stays_full_keeps_its_stop_line(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """``gcs run`` whose journal's disk fills at mission time 60 s and stays full: the stop
    line and summary are in the journal (from the reserve, first after the lines written
    before the outage), the console prints the summary and says how many lines of which
    file were not written."""
    journal_path = (tmp_path / "journal.jsonl").resolve()
    disk = SpaceDisk(journal_path, full_from_t=60.0)
    monkeypatch.setattr(storage, "_os_write", disk.write)
    monkeypatch.setattr(storage, "_os_unlink", disk.unlink, raising=False)
    monkeypatch.setattr(journal_module, "RESERVE_BYTES", 16 * 1024, raising=False)
    appended: list[bytes] = []
    real_append = storage.AppendLog.append

    def spy(self: storage.AppendLog, data: bytes, **kwargs: Any) -> bool:
        if self.path == str(journal_path):
            appended.append(data)
        return real_append(self, data, **kwargs)

    monkeypatch.setattr(storage.AppendLog, "append", spy)
    code = run_cmd.run(["--vehicles", "sim:2", "--scenario", "default", "--sim-airborne",
                        "--speedup", "40", "--duration", "90", "--journal", str(journal_path),
                        "--run-dir", str(tmp_path / "runs"), "--http", "off",
                        "--detections", "off", "--status", "quiet"])  # fmt: skip
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "Traceback" not in err
    stopped = [line for line in out.splitlines() if line.startswith("gcs run: stopped")]
    assert len(stopped) == 1 and "(duration) after 9" in stopped[0], out
    got = journal_path.read_bytes().splitlines(keepends=True)
    stop_at = [i for i, line in enumerate(got) if json.loads(line)["event"] == "stop"]
    assert len(stop_at) == 1
    i = stop_at[0]
    before = appended[:i]
    assert got[:i] == before and all(json.loads(line)["t"] < 60.0 for line in before)
    stop = json.loads(got[i])
    assert stop["reason"] == "duration" and stop["mission_s"] >= 90 and "plans" in stop
    held = [data for data in appended[i:] if json.loads(data)["event"] != "stop"]
    written = got[i + 1:]
    assert written == held[:len(written)] and len(written) < len(held)  # in order, not all
    lost = len(held) - len(written)
    said = [line for line in err.splitlines() if str(journal_path) in line]
    assert len(said) == 2, err  # the outage, then what became of the held lines at exit
    assert "cannot write (No space left on device)" in said[0]
    assert "the stop line and summary written first" in said[1]
    assert f"{lost} records not written" in said[1]
    assert not (journal_path.parent / ".journal.jsonl.reserve").exists()


def test_the_summary_is_printed_when_metrics_json_cannot_be_written(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A full disk at the very end: metrics.json fails (one line, exit 2), and the console
    still has the run's summary line."""
    from groundstation.daemon import startup

    real = startup.atomic_write_text

    def full(path: Any, text: str, **kwargs: Any) -> None:
        if Path(path).name == "metrics.json":
            raise storage.StorageError(f"cannot write {path}: No space left on device")
        real(path, text, **kwargs)

    monkeypatch.setattr(startup, "atomic_write_text", full)
    code = run_cmd.run(["--vehicles", "sim:1", "--scenario", "default", "--sim-airborne",
                        "--speedup", "40", "--duration", "10", "--run-dir", str(tmp_path),
                        "--http", "off", "--detections", "off", "--status", "quiet"])  # fmt: skip
    out, err = capsys.readouterr()
    assert code == 2
    assert [line for line in out.splitlines() if line.startswith("gcs run: stopped")], out
    errors = [line for line in err.splitlines() if line.startswith("gcs run: error:")]
    assert len(errors) == 1 and "metrics.json" in errors[0] and "No space left" in errors[0]
