"""The run folder's files: probed at start, opened so a full disk never stops the daemon.

``runs/<UTC timestamp>/`` holds ``journal.jsonl`` (or ``--journal FILE``), ``flight.tlog``,
``config.yaml``, ``gcs.log`` and, at the end, ``metrics.json`` (and ``control.json``, mode
0600, when the control API is on).

Rules:

* Before anything is written, the run folder (``--run-dir``) and an explicit ``--journal``
  are probed with :func:`groundstation.storage.check_writable` (a probe written and
  fsynced), so a full disk, a read-only folder or ``--journal /dev/full`` is refused with
  one line naming the path.
* The journal, the tlog and ``gcs.log`` are :class:`~groundstation.storage.AppendLog` s:
  a full disk during the run is one line on stderr (and one when it recovers), records
  held in memory and written later. The storage errors are printed on stderr whatever the
  status display (``--status quiet`` included).
* ``config.yaml`` is written atomically.
"""

from __future__ import annotations

import datetime
import logging
import sys
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from groundstation.daemon.clock import MissionClock
from groundstation.daemon.config import DaemonConfig
from groundstation.daemon.journal import Journal
from groundstation.link import TlogWriter
from groundstation.storage import (
    AppendLog,
    AppendLogHandler,
    StorageError,
    atomic_write_text,
    check_writable,
    describe_os_error,
)

__all__ = ["RunFiles", "make_run_dir", "open_run_files"]


def make_run_dir(base: str) -> Path:
    """``base/<UTC timestamp>`` (``-2``, ``-3``... if taken), created."""
    stamp = datetime.datetime.now(datetime.UTC).strftime("%Y%m%dT%H%M%SZ")
    root = Path(base)
    path = root / stamp
    k = 1
    while True:  # mkdir decides: another gcs run may take the same name at the same time
        try:
            path.mkdir(parents=True)
            return path
        except FileExistsError:
            k += 1
            path = root / f"{stamp}-{k}"
        except OSError as exc:
            raise StorageError(
                f"run_dir: cannot create {path}: {describe_os_error(exc)}"
            ) from None


def _stderr_report(level: int, message: str) -> None:
    print(f"gcs run: {message}", file=sys.stderr, flush=True)


@dataclass
class RunFiles:
    """The open files of one run; :meth:`close` closes them all (idempotent)."""

    run_dir: Path
    journal: Journal
    tlog: TlogWriter
    effective: dict[str, object]
    handlers: list[tuple[logging.Logger, logging.Handler]] = field(default_factory=list)

    def close(self) -> None:
        self.journal.close()
        self.tlog.close()
        for logger, handler in self.handlers:
            logger.removeHandler(handler)
            handler.close()
        self.handlers.clear()


def _setup_logging(run_dir: Path) -> list[tuple[logging.Logger, logging.Handler]]:
    """``gcs.log`` for everything at INFO and up; storage errors also on stderr."""
    handler = AppendLogHandler(AppendLog(run_dir / "gcs.log", "log", report=_stderr_report))
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    root = logging.getLogger()
    root.addHandler(handler)
    if root.level > logging.INFO or root.level == logging.NOTSET:
        root.setLevel(logging.INFO)
    console = logging.StreamHandler(sys.stderr)
    console.setFormatter(logging.Formatter("gcs run: %(message)s"))
    console.setLevel(logging.WARNING)
    storage_log = logging.getLogger("groundstation.storage")
    storage_log.addHandler(console)
    return [(root, handler), (storage_log, console)]


def open_run_files(config: DaemonConfig, clock: MissionClock) -> RunFiles:
    """Probe, create the run folder, open the journal, tlog and log, write config.yaml.
    Raises :class:`StorageError` (one line naming the path); nothing is left open then."""
    records = config.records
    check_writable(records.run_dir, "run_dir", folder=True)
    if records.journal:
        check_writable(records.journal, "journal")
    run_dir = make_run_dir(records.run_dir)
    journal_path = Path(records.journal) if records.journal else run_dir / "journal.jsonl"
    try:
        journal = Journal(journal_path, clock.now_s, clock.unix_s)
    except OSError as exc:
        raise StorageError(
            f"journal: cannot write {journal_path}: {describe_os_error(exc)}"
        ) from None
    try:
        tlog = TlogWriter(run_dir / "flight.tlog")
    except OSError as exc:
        journal.close()
        raise StorageError(
            f"tlog: cannot write {run_dir / 'flight.tlog'}: {describe_os_error(exc)}"
        ) from None
    files = RunFiles(run_dir, journal, tlog, config.to_dict())
    try:
        files.handlers = _setup_logging(run_dir)
        atomic_write_text(run_dir / "config.yaml", yaml.safe_dump(files.effective, sort_keys=False))
    except (StorageError, OSError) as exc:
        files.close()
        raise StorageError(f"config.yaml: {exc}") from None
    return files
