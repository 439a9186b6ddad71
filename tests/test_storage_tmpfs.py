"""A really full filesystem: a 256 KiB tmpfs mounted for the test (needs root and mount
rights, as CI's container has; skipped elsewhere, where the fault-injection tests in
test_storage.py and test_daemon_disk.py cover the same rules)."""

from __future__ import annotations

import json
import logging
import os
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
from environment import need

from groundstation.daemon import journal as journal_module
from groundstation.daemon.journal import Journal, read_journal
from groundstation.storage import StorageError, atomic_write_text, check_writable

SIZE = 256 * 1024


@pytest.fixture
def small_fs(tmp_path: Path) -> Iterator[Path]:
    mount = tmp_path / "fs"
    mount.mkdir()
    need(os.geteuid() == 0 and shutil.which("mount") is not None, "mounting a tmpfs needs root")
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={SIZE}", "tmpfs", str(mount)],
        capture_output=True,
        timeout=10,
        check=False,
    )
    if done.returncode != 0:
        # Deliberately a skip even in CI: a container may be root without the right to mount.
        # The full-disk paths are also checked through /dev/full (test_daemon_disk,
        # test_link_tlog), which CI must provide.
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.decode().strip()}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], capture_output=True, timeout=10, check=False)


def fill(folder: Path) -> Path:
    """Fill the filesystem to the last byte; returns the filler file."""
    filler = folder / "filler"
    with filler.open("wb", buffering=0) as fh:
        chunk = b"\0" * 4096
        try:
            while True:
                fh.write(chunk)
        except OSError:
            pass
        try:
            while True:
                fh.write(b"\0")
        except OSError:
            pass
    return filler


def test_journal_on_a_really_full_filesystem(small_fs: Path) -> None:
    t = [0.0]
    journal = Journal(small_fs / "journal.jsonl", lambda: t[0], lambda: 1.7e9, retry_s=0.0)
    journal.write("start")
    filler = fill(small_fs)
    assert journal.file is not None
    for i in range(200):
        t[0] = i * 0.1
        journal.write("track", target="A", sigma=float(i), pad="x" * 50)
    assert journal.file.failing and journal.file.held > 0
    # every line in the file is whole, even with the disk full
    text = (small_fs / "journal.jsonl").read_text()
    assert text.endswith("\n")
    assert all(json.loads(line) for line in text.splitlines())
    with pytest.raises(StorageError, match="No space left on device"):
        check_writable(small_fs, "run_dir", folder=True)
    with pytest.raises(StorageError):
        atomic_write_text(small_fs / "metrics.json", json.dumps({"x": "y" * 10_000}))
    assert not (small_fs / "metrics.json").exists()
    assert sorted(p.name for p in small_fs.iterdir()) == ["filler", "journal.jsonl"]
    filler.unlink()
    journal.write("stop")
    journal.close()
    got = read_journal(small_fs / "journal.jsonl")
    assert [e["event"] for e in got] == ["start", *["track"] * 200, "stop"]
    assert [e["sigma"] for e in got if e["event"] == "track"] == [float(i) for i in range(200)]


def test_a_filesystem_still_full_at_exit_keeps_the_stop_line(
        small_fs: Path, monkeypatch: pytest.MonkeyPatch,
        caplog: pytest.LogCaptureFixture) -> None:
    """Filled to the last byte and never emptied: at close the journal's reserve (allocated
    when it opened) is released, the stop line is written first, then the held lines in
    order while they fit, and one line says how many were not written."""
    monkeypatch.setattr(journal_module, "RESERVE_BYTES", 32 * 1024, raising=False)
    t = [0.0]
    journal = Journal(small_fs / "journal.jsonl", lambda: t[0], lambda: 1.7e9, retry_s=0.0)
    journal.write("start")
    filler = fill(small_fs)
    for i in range(600):  # ~60 kB held: more than the reserve
        t[0] = i * 0.1
        journal.write("track", target="A", sigma=float(i), pad="x" * 50)
    t[0] = 60.0
    journal.write("stop", reason="duration", mission_s=60.0, plans=3)
    with caplog.at_level(logging.WARNING, logger="groundstation.storage"):
        journal.close()
    got = read_journal(small_fs / "journal.jsonl")
    events = [e["event"] for e in got]
    assert events.count("stop") == 1 and got[events.index("stop")]["plans"] == 3
    stop_at = events.index("stop")  # after the lines that fitted before the disk refused
    assert events[0] == "start" and set(events[1:stop_at]) <= {"track"}
    sigmas = [e["sigma"] for e in got if e["event"] == "track"]
    assert sigmas == [float(i) for i in range(len(sigmas))]  # in order, none skipped
    held_written = len(got) - stop_at - 1
    assert held_written > 0 and len(sigmas) < 600
    said = [r.getMessage() for r in caplog.records if "at exit" in r.getMessage()]
    assert len(said) == 1 and f"{600 - len(sigmas)} records not written" in said[0]
    assert f"then {held_written} of {600 - (stop_at - 1)} held records" in said[0]
    assert sorted(p.name for p in small_fs.iterdir()) == ["filler", "journal.jsonl"]
    assert filler.exists()
