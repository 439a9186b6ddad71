"""groundstation.storage: atomic whole files, start-up probes, and append logs that survive
a full disk (ENOSPC simulated by replacing ``storage._os_write``; no root, no real full
filesystem needed)."""

from __future__ import annotations

import errno
import json
import logging
import os
import stat
from collections.abc import Callable
from pathlib import Path

import pytest

from groundstation import storage
from groundstation.daemon.journal import Journal, read_journal
from groundstation.link import TlogReader, TlogWriter
from groundstation.storage import (
    AppendLog,
    AppendLogHandler,
    StorageError,
    atomic_write_bytes,
    atomic_write_text,
    atomic_write_with,
    check_writable,
)


class Disk:
    """A fake ``os.write`` for one file: full (ENOSPC) while ``full`` is set; with
    ``partial`` the first write at the fault writes that many bytes before failing."""

    def __init__(self, path: Path) -> None:
        self.path = str(path)
        self.full = False
        self.partial = 0
        self.real = os.write

    def _ours(self, fd: int) -> bool:
        try:
            return os.readlink(f"/proc/self/fd/{fd}") == self.path
        except OSError:
            return False

    def __call__(self, fd: int, data: bytes) -> int:
        if self.full and self._ours(fd):
            if self.partial:
                n, self.partial = self.partial, 0
                return self.real(fd, bytes(data[:n]))
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return self.real(fd, data)


class Clock:
    def __init__(self) -> None:
        self.t_s = 0.0

    def __call__(self) -> float:
        return self.t_s


@pytest.fixture
def disk(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Disk:
    d = Disk(tmp_path / "log.jsonl")
    monkeypatch.setattr(storage, "_os_write", d)
    return d


def reports() -> tuple[list[tuple[int, str]], Callable[[int, str], None]]:
    out: list[tuple[int, str]] = []
    return out, lambda level, text: out.append((level, text))


def lines(path: Path) -> list[str]:
    return path.read_text().splitlines()


def test_outage_is_one_error_then_records_written_in_order_on_recovery(
    tmp_path: Path, disk: Disk
) -> None:
    said, report = reports()
    clock = Clock()
    log = AppendLog(disk.path, "journal", retry_s=1.0, monotonic=clock, report=report)
    assert log.append(b"a\n")
    disk.full = True
    for i in range(50):
        clock.t_s += 0.1
        log.append(f"r{i}\n".encode(), keep=i % 10 == 0)
    assert [lv for lv, _ in said] == [logging.ERROR]
    assert "No space left on device" in said[0][1] and disk.path in said[0][1]
    assert log.held == 50 and log.failing and lines(Path(disk.path)) == ["a"]
    disk.full = False
    clock.t_s += 0.5  # the retry interval has passed: the next append writes everything
    assert log.append(b"z\n")
    assert lines(Path(disk.path)) == ["a", *(f"r{i}" for i in range(50)), "z"]
    assert [lv for lv, _ in said] == [logging.ERROR, logging.WARNING]
    assert "51 held records written in order, 0 dropped" in said[1][1]  # with "z"
    assert log.write_errors >= 2  # retried while full, silently
    log.close()


def test_a_short_write_at_enospc_is_cut_back_to_the_last_whole_record(
    tmp_path: Path, disk: Disk
) -> None:
    _said, report = reports()
    clock = Clock()
    log = AppendLog(disk.path, "journal", monotonic=clock, report=report)
    log.append(b'{"n":1}\n')
    disk.full, disk.partial = True, 4
    log.append(b'{"n":2}\n')
    assert Path(disk.path).read_bytes() == b'{"n":1}\n'  # no half line in the file
    log.append(b'{"n":3}\n')
    disk.full = False
    clock.t_s = 5.0
    assert log.retry()
    assert [json.loads(x)["n"] for x in lines(Path(disk.path))] == [1, 2, 3]


def test_over_the_cap_telemetry_goes_first_then_decisions(tmp_path: Path, disk: Disk) -> None:
    said, report = reports()
    clock = Clock()
    log = AppendLog(disk.path, "journal", cap_bytes=60, monotonic=clock, report=report)
    disk.full = True
    log.append(b"decision-0\n", keep=True)  # 11 bytes each
    for i in range(6):
        log.append(f"telemetr-{i}\n".encode())
    assert log.dropped == 2  # 7 x 11 = 77 > 60: the two oldest telemetry lines went
    for i in range(1, 5):
        log.append(f"decision-{i}\n".encode(), keep=True)
    assert log.held_bytes <= 60
    disk.full = False
    clock.t_s = 10.0
    log.retry()
    written = lines(Path(disk.path))
    assert written == [f"decision-{i}" for i in range(5)]
    assert log.dropped == 6
    assert "0 held records" not in said[-1][1] and "6 dropped" in said[-1][1]
    log.close()


def test_close_while_full_reports_the_loss_and_leaves_whole_lines(
    tmp_path: Path, disk: Disk
) -> None:
    said, report = reports()
    log = AppendLog(disk.path, "journal", report=report)
    log.append(b"one\n")
    disk.full, disk.partial = True, 2
    log.append(b"two\n")
    log.close()
    log.close()
    assert lines(Path(disk.path)) == ["one"]
    assert said[-1][0] == logging.ERROR and "1 records not written" in said[-1][1]
    assert log.append(b"three\n") is False


def test_journal_holds_lines_and_reads_back_complete(
    tmp_path: Path, disk: Disk, caplog: pytest.LogCaptureFixture
) -> None:
    path = Path(disk.path)
    t = [0.0]
    journal = Journal(path, lambda: t[0], lambda: 1.7e9 + t[0], retry_s=0.0)
    journal.write("start")
    disk.full, disk.partial = True, 7
    with caplog.at_level(logging.WARNING, logger="groundstation.storage"):
        for i in range(20):
            t[0] = i * 0.5
            journal.write_record({"event": "input", "kind": "Tick", "t": t[0]})
            journal.write("track", target="a", sigma=float(i))
        disk.full = False
        journal.write("plan", request=1)
    errors = [r for r in caplog.records if r.levelno == logging.ERROR]
    assert len(errors) == 1
    got = read_journal(path)
    assert len(got) == len(path.read_text().splitlines()) == 42
    assert [e["event"] for e in got][:3] == ["start", "input", "track"]
    assert [e["sigma"] for e in got if e["event"] == "track"] == [float(i) for i in range(20)]
    journal.close()


def test_tlog_survives_a_full_disk(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from test_link_tlog import T0, frames

    path = tmp_path / "flight.tlog"
    disk = Disk(path)
    monkeypatch.setattr(storage, "_os_write", disk)
    w = TlogWriter(path, retry_s=0.0)
    fs = frames()
    w.write(fs[0], T0)
    disk.full, disk.partial = True, 5
    assert w.write(fs[1], T0 + 1) is False
    assert w.write(fs[2], T0 + 2) is False
    assert w.held == 2
    disk.full = False
    assert w.write(fs[3], T0 + 3) is True
    reader = TlogReader(path)
    assert [r.raw for r in reader] == fs[:4] and reader.skipped == []
    w.close()


def test_log_handler_reports_once_not_a_traceback_per_record(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "gcs.log"
    disk = Disk(path)
    monkeypatch.setattr(storage, "_os_write", disk)
    said, report = reports()
    handler = AppendLogHandler(AppendLog(path, "log", report=report, retry_s=3600))
    logger = logging.getLogger("test.storage.handler")
    logger.addHandler(handler)
    logger.propagate = False
    try:
        disk.full = True
        for i in range(100):
            logger.error("line %d", i)
    finally:
        logger.removeHandler(handler)
        logger.propagate = True
    assert "Traceback" not in capsys.readouterr().err
    assert len(said) == 1 and handler.file.held == 100
    disk.full = False
    handler.close()
    assert len(lines(path)) == 100


def test_atomic_write_leaves_old_file_and_no_temporary_on_failure(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "metrics.json"
    atomic_write_text(path, '{"old": 1}\n')

    def fill(fh: object) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with pytest.raises(StorageError) as info:
        atomic_write_with(path, fill)
    message = str(info.value)
    assert "\n" not in message and str(path) in message and "No space left" in message
    assert path.read_text() == '{"old": 1}\n'
    assert os.listdir(tmp_path) == ["metrics.json"]
    atomic_write_bytes(path, b"new")
    assert path.read_bytes() == b"new" and os.listdir(tmp_path) == ["metrics.json"]


def test_atomic_write_of_a_secret_is_0600_from_creation(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    modes: list[int] = []
    real_open = os.open

    def spy(path: str, flags: int, mode: int = 0o777, **kw: object) -> int:
        fd = real_open(path, flags, mode)
        if flags & os.O_CREAT:
            modes.append(stat.S_IMODE(os.fstat(fd).st_mode))
        return fd

    monkeypatch.setattr(storage.os, "open", spy)
    path = tmp_path / "control.json"
    atomic_write_text(path, "{}", mode=0o600)
    assert modes == [0o600]
    assert stat.S_IMODE(path.stat().st_mode) == 0o600


def test_check_writable_refuses_dev_full_and_bad_places(tmp_path: Path) -> None:
    if os.path.exists("/dev/full"):
        with pytest.raises(StorageError, match=r"^journal: cannot write /dev/full: No space"):
            check_writable("/dev/full", "journal")
    check_writable("/dev/null", "journal")
    check_writable(tmp_path / "new" / "journal.jsonl", "journal")
    check_writable(tmp_path / "runs", "run_dir", folder=True)
    assert (tmp_path / "runs").is_dir() and os.listdir(tmp_path / "runs") == []
    with pytest.raises(StorageError, match="it is a folder"):
        check_writable(tmp_path, "journal")
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(StorageError, match=r"^run_dir: cannot write .*file/sub"):
        check_writable(blocker / "sub", "run_dir", folder=True)


def test_check_writable_refuses_a_full_disk(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def full(fd: int, data: bytes) -> int:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(storage, "_os_write", full)
    with pytest.raises(StorageError, match="No space left on device"):
        check_writable(tmp_path / "runs", "run_dir", folder=True)
    assert os.listdir(tmp_path / "runs") == []  # the probe file was removed
