"""Writing files so that a full disk never crashes floe, floods the console or leaves half
a file behind.

Three tools, used for every file floe writes:

* :func:`atomic_write_bytes` / :func:`atomic_write_text` / :func:`atomic_write_with`: whole
  files (metrics, reports, plots, ``config.yaml``, ``control.json``). Rule: write a
  temporary file in the same folder, ``fsync`` it, ``os.replace`` it onto the name, then
  ``fsync`` the folder. Readers see the old file or the new one, never a part. Any failure
  removes the temporary file and raises :class:`StorageError` with a one-line message that
  names the path; the caller prints it (exit status non-zero), never a traceback.
* :func:`check_writable`: the start-up probe. It writes and ``fsync``s a small probe (into
  the folder, or into the file itself when it is a device such as ``/dev/full``), so a full
  disk, a read-only folder or ``/dev/full`` is refused before the run begins.
* :class:`AppendLog`: an append-only record file (the journal, the tlog, ``gcs.log``) that
  survives ENOSPC, EIO and EDQUOT during a run; see its docstring for the rules.
"""

from __future__ import annotations

import collections
import contextlib
import errno
import logging
import os
import stat
import time
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

__all__ = [
    "DEFAULT_CAP_BYTES",
    "AppendLog",
    "AppendLogHandler",
    "StorageError",
    "atomic_write_bytes",
    "atomic_write_text",
    "atomic_write_with",
    "check_writable",
    "describe_os_error",
]

log = logging.getLogger(__name__)

#: Bytes an :class:`AppendLog` holds in memory while its file cannot be written (32 MiB:
#: about half an hour of a busy journal). Beyond it the oldest droppable records go first.
DEFAULT_CAP_BYTES = 32 * 1024 * 1024
#: Seconds between two attempts to write held records.
DEFAULT_RETRY_S = 1.0
_PROBE = b"floe write probe\n"

# the one place records reach the OS; tests replace it to simulate a full disk
_os_write: Callable[[int, bytes], int] = os.write
# where a reserve is allocated and released; tests replace them with their simulated disk
_os_allocate: Callable[[int, int, int], None] = os.posix_fallocate
_os_unlink: Callable[[str], None] = os.unlink


class StorageError(Exception):
    """A file cannot be written; the message is one line and names the path."""


def describe_os_error(exc: BaseException) -> str:
    """``strerror`` of an OSError (``No space left on device``), else ``str(exc)``."""
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return str(exc) or type(exc).__name__


def _fsync_dir(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass  # some filesystems cannot fsync a folder; the data itself is synced
    finally:
        os.close(fd)


def atomic_write_with(
    path: str | os.PathLike[str], fill: Callable[[BinaryIO], object], *, mode: int = 0o644
) -> None:
    """Write ``path`` atomically: ``fill`` writes the content into a binary file object.

    The temporary file ``.<name>.<pid>.tmp`` is created with ``mode`` from the start
    (``os.open(..., mode)``, so a secret is never readable by others, not even briefly).
    Raises :class:`StorageError`; on failure ``path`` is untouched and no temporary remains.
    """
    target = Path(path)
    folder = target.parent if str(target.parent) else Path(".")
    tmp = folder / f".{target.name}.{os.getpid()}.tmp"
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, mode)
    except OSError as exc:
        raise StorageError(f"cannot write {target}: {describe_os_error(exc)}") from None
    try:
        with os.fdopen(fd, "wb") as fh:
            fill(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except (OSError, ValueError) as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise StorageError(f"cannot write {target}: {describe_os_error(exc)}") from None
    _fsync_dir(folder)


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes, *, mode: int = 0o644) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_write_with`)."""
    atomic_write_with(path, lambda fh: fh.write(data), mode=mode)


def atomic_write_text(path: str | os.PathLike[str], text: str, *, mode: int = 0o644) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically (see :func:`atomic_write_with`)."""
    atomic_write_bytes(path, text.encode("utf-8"), mode=mode)


def _probe_fd(fd: int, *, device: bool = False) -> None:
    view = memoryview(_PROBE)
    while view:
        n = _os_write(fd, bytes(view))
        if n <= 0:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        view = view[n:]
    try:
        os.fsync(fd)
    except OSError as exc:
        if not device or exc.errno not in (errno.EINVAL, errno.EROFS, errno.ENOTSUP):
            raise  # a device such as /dev/null cannot be synced; a file must be


def check_writable(path: str | os.PathLike[str], what: str, *, folder: bool = False) -> None:
    """Refuse, with a :class:`StorageError` naming ``what`` and the path, a place floe
    could not write: ``folder=True`` for a folder (created if missing), else a file to
    create or append to.

    Rule: a probe is written and ``fsync``ed. For a folder or a regular file it goes into a
    temporary file in the folder, which is removed (an existing file is only opened for
    appending, never changed); for anything else (a device such as ``/dev/null`` or
    ``/dev/full``) it is written to the path itself, so ``/dev/full`` fails with ENOSPC.
    """
    target = Path(path)
    where = f"{what}: cannot write {target}"
    try:
        if folder:
            target.mkdir(parents=True, exist_ok=True)
            probe_dir = target
        else:
            try:
                st = os.stat(target)
            except FileNotFoundError:
                st = None
            if st is not None and stat.S_ISDIR(st.st_mode):
                raise StorageError(f"{where}: it is a folder")
            if st is not None and not stat.S_ISREG(st.st_mode):
                fd = os.open(target, os.O_WRONLY | os.O_APPEND | os.O_NONBLOCK)
                try:
                    _probe_fd(fd, device=True)
                finally:
                    os.close(fd)
                return
            if st is not None:
                os.close(os.open(target, os.O_WRONLY | os.O_APPEND))
            probe_dir = target.parent if str(target.parent) else Path(".")
            probe_dir.mkdir(parents=True, exist_ok=True)
        probe = probe_dir / f".floe-probe.{os.getpid()}.tmp"
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        try:
            _probe_fd(fd)
        finally:
            os.close(fd)
            with contextlib.suppress(OSError):
                os.unlink(probe)
    except OSError as exc:
        raise StorageError(f"{where}: {describe_os_error(exc)}") from None


Report = Callable[[int, str], None]


def _log_report(level: int, message: str) -> None:
    log.log(level, "%s", message)


class AppendLog:
    """An append-only file of records (bytes, e.g. journal lines) that survives a full disk.

    Rules:

    * Each record goes to the OS with ``os.write`` at once (no user-space buffer), so a
      crash loses nothing already appended.
    * When a write fails (ENOSPC, EIO, EDQUOT or any OSError) the log reports ONE error
      (``report(logging.ERROR, ...)``) and is then silent for this file; records are held
      in memory, in order, and written again every ``retry_s`` seconds (on the next
      :meth:`append` or :meth:`retry` after that). When writing works again it reports one
      line (``logging.WARNING``) saying how many held records were written and how many
      were dropped.
    * The file never keeps half a record: a short write at ENOSPC is cut back
      (``ftruncate``) to the end of the last whole record; if that is impossible (a device)
      the rest of the record is written first on recovery.
    * Held bytes are bounded by ``cap_bytes``: beyond it the oldest records appended with
      ``keep=False`` (telemetry) are dropped first and counted in :attr:`dropped`; records
      with ``keep=True`` (decisions) are dropped, oldest first, only when no other remains.
    * A **vital** record (``append(..., vital=True)``: the journal's ``stop`` line and
      summary) is never dropped by the cap.
    * ``reserve_bytes`` > 0 (a regular file): a reserve of that many bytes is allocated at
      once next to the file (``.NAME.reserve``, ``posix_fallocate``: real blocks), so a
      full disk still has room at the end; it is removed on :meth:`close`. No room for it
      is one warning, and the log goes on without.
    * :meth:`close` with records held (the disk was full at the last try): the reserve is
      released first. If the held records fit in it they are written in order; else the
      vital records are written first, then the held records in order as long as space
      allows. One line (:meth:`close_report`) says what was written and exactly how many
      records (and bytes) of which file were not, and are lost.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        name: str,
        *,
        truncate: bool = False,
        cap_bytes: int = DEFAULT_CAP_BYTES,
        retry_s: float = DEFAULT_RETRY_S,
        monotonic: Callable[[], float] = time.monotonic,
        report: Report = _log_report,
        reserve_bytes: int = 0,
        vital_label: str = "vital records",
    ) -> None:
        self.path = os.fspath(path)
        self.name = name
        self.cap_bytes = cap_bytes
        self.retry_s = retry_s
        self._monotonic = monotonic
        self._report = report
        flags = os.O_WRONLY | os.O_CREAT | os.O_APPEND | (os.O_TRUNC if truncate else 0)
        self._fd: int | None = os.open(self.path, flags, 0o644)
        st = os.fstat(self._fd)
        self._regular = stat.S_ISREG(st.st_mode)
        self._committed = st.st_size if self._regular else 0
        # pending records: (sequence number, data); two queues so telemetry drops first
        self._low: collections.deque[tuple[int, bytes]] = collections.deque()
        self._high: collections.deque[tuple[int, bytes]] = collections.deque()
        self._vital: collections.deque[tuple[int, bytes]] = collections.deque()
        self.vital_label = vital_label
        self._seq = 0
        self._head_done = 0  # bytes of the head record already in the file (a device)
        self.held_bytes = 0
        self.failing = False
        self._last_try_s = 0.0
        self._outage_held = 0
        self._outage_dropped = 0
        self.records = 0
        self.bytes_written = 0
        self.dropped = 0
        self.write_errors = 0
        self.last_error: str | None = None
        self._closing = False
        self.lost = 0
        """Records not written at :meth:`close` (the disk still full): lost."""
        self.reserve_path: str | None = None
        self.reserve_bytes = 0
        if reserve_bytes > 0 and self._regular:
            self._allocate_reserve(reserve_bytes)

    @property
    def held(self) -> int:
        """Records waiting in memory."""
        return len(self._low) + len(self._high) + len(self._vital)

    @property
    def closed(self) -> bool:
        return self._fd is None

    @property
    def fd(self) -> int | None:
        """The open file descriptor (None once closed)."""
        return self._fd

    def append(self, data: bytes, *, keep: bool = False, vital: bool = False) -> bool:
        """Append one record; True if it is in the file now, False if held or closed.
        ``keep``: dropped last over the cap; ``vital``: never dropped, and written first
        at :meth:`close` on a full disk."""
        if self._fd is None:
            return False
        self._seq += 1
        queue = self._vital if vital else self._high if keep else self._low
        if not (self.failing or self._low or self._high or self._vital):
            return self._write_now(queue, data)  # nothing held: the common case
        queue.append((self._seq, data))
        self.held_bytes += len(data)
        if self.failing:
            self._outage_held += 1
            self._enforce_cap()
            if self._monotonic() - self._last_try_s < self.retry_s:
                return False
        self._drain()
        return not self.failing and self.held == 0

    def retry(self) -> bool:
        """Try to write held records now; True if none is left."""
        if self._fd is not None and self.held:
            self._drain()
        return self.held == 0

    def close(self) -> None:
        """Write what is held if possible (the class docstring's order), then close and
        remove the reserve. Idempotent."""
        if self._fd is None:
            return
        if self.held:
            self._close_out()
        self._release_reserve()
        fd, self._fd = self._fd, None
        os.close(fd)

    def close_report(self, held: int, freed: int, vital_first: int) -> tuple[int, str]:
        """The one line of a close with ``held`` records held (``freed``: the reserve's
        bytes released; ``vital_first``: vital records written ahead of the others)."""
        where = f"{self.name} {self.path}"
        room = f"released its {freed}-byte reserve; " if freed else ""
        first = (f"{self.vital_label} written first, then " if vital_first else "")
        written = held - self.held - vital_first
        if not self.held:
            order = "in order" if not vital_first else "in order after them"
            return logging.WARNING, (f"{where}: the disk was full at exit ({self.last_error}); "
                                     f"{room}{first}all {written} held records written {order}")
        lost_bytes = self.held_bytes
        vital_lost = len(self._vital)
        what = (f"{vital_lost} of them {self.vital_label}, " if vital_lost else "")
        return logging.ERROR, (
            f"{where}: the disk is still full at exit ({self.last_error}); {room}{first}"
            f"{written} of {held - vital_first} held records written in order; {self.held} "
            f"records not written ({what}{lost_bytes} bytes): they are lost")

    # ------------------------------------------------------------------ internals
    def _close_out(self) -> None:
        """Records are held at close: the reserve, then vital first unless all fit."""
        held = self.held
        self._closing = True  # the one close line below says it all
        freed = self._release_reserve()
        if not self._vital or not self.failing or freed >= self.held_bytes:
            self._drain()  # in order: nothing vital, room after all, or the reserve is enough
        vital_first = 0
        if self.held and self._vital and not self._head_done:
            while self._vital and self._write_whole(self._vital[0][1]):
                _, data = self._vital.popleft()
                self.held_bytes -= len(data)
                vital_first += 1
            if not self._vital:
                self._drain()
        self.lost = self.held
        self._report(*self.close_report(held, freed, vital_first))
        if self.held:
            self._cut_back()

    def _write_whole(self, data: bytes) -> bool:
        """Write ``data`` now, whole or not at all (cut back on a regular file)."""
        assert self._fd is not None
        done = 0
        while done < len(data):
            try:
                n = _os_write(self._fd, data[done:])
                if n <= 0:
                    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            except OSError as exc:
                self.write_errors += 1
                self.last_error = describe_os_error(exc)
                if done and self._regular:
                    with contextlib.suppress(OSError):
                        os.ftruncate(self._fd, self._committed)
                return False
            done += n
        self._written(len(data))
        return True

    def _allocate_reserve(self, size: int) -> None:
        """``.NAME.reserve`` beside the file with ``size`` bytes of real blocks."""
        folder, name = os.path.split(self.path)
        path = os.path.join(folder, f".{name}.reserve")
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        except OSError as exc:
            self._report(logging.WARNING, f"{self.name} {self.path}: no reserve for a full "
                         f"disk ({describe_os_error(exc)})")
            return
        try:
            _os_allocate(fd, 0, size)
        except OSError as exc:
            with contextlib.suppress(OSError):
                os.unlink(path)
            self._report(logging.WARNING, f"{self.name} {self.path}: no room for its "
                         f"{size}-byte reserve ({describe_os_error(exc)}); going on without")
            return
        finally:
            os.close(fd)
        self.reserve_path, self.reserve_bytes = path, size

    def _release_reserve(self) -> int:
        """Remove the reserve; the bytes it freed (0 without one)."""
        path, size = self.reserve_path, self.reserve_bytes
        self.reserve_path, self.reserve_bytes = None, 0
        if path is None:
            return 0
        try:
            _os_unlink(path)
        except OSError:
            return 0
        return size

    def _written(self, size_bytes: int) -> None:
        """A whole record of ``size_bytes`` is in the file: counted, and the file's last
        whole record ends there."""
        self._committed += size_bytes
        self.records += 1
        self.bytes_written += size_bytes

    def _write_now(self, queue: collections.deque[tuple[int, bytes]], data: bytes) -> bool:
        """:meth:`append` with nothing held: one write, as :meth:`_drain` would make it, the
        record queued only when it did not go whole (held on an error, the rest written by
        :meth:`_drain` after a short write)."""
        assert self._fd is not None
        try:
            n = _os_write(self._fd, data)
            if n <= 0:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        except OSError as exc:
            queue.append((self._seq, data))
            self.held_bytes += len(data)
            self._last_try_s = self._monotonic()
            self._fail(exc)
            return False
        if n == len(data):
            self._written(n)
            return True
        queue.append((self._seq, data))  # a short write: _drain writes the rest or fails
        self.held_bytes += len(data)
        self._head_done = n
        self._drain()
        return not self.failing and self.held == 0

    def _head(self) -> collections.deque[tuple[int, bytes]] | None:
        queues = [q for q in (self._low, self._high, self._vital) if q]
        return min(queues, key=lambda q: q[0][0]) if queues else None

    def _drain(self) -> None:
        assert self._fd is not None
        self._last_try_s = self._monotonic()
        while (queue := self._head()) is not None:
            data = queue[0][1]
            try:
                n = _os_write(self._fd, data[self._head_done :] if self._head_done else data)
                if n <= 0:
                    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            except OSError as exc:
                self._fail(exc)
                return
            self._head_done += n
            if self._head_done < len(data):
                continue  # a short write: the next call writes the rest or fails
            queue.popleft()
            self._head_done = 0
            self.held_bytes -= len(data)
            self._written(len(data))
        if self.failing:
            self.failing = False
            if self._closing:
                return
            self._report(
                logging.WARNING,
                f"{self.name} {self.path}: writing again; "
                f"{self._outage_held - self._outage_dropped} held records written in order, "
                f"{self._outage_dropped} dropped",
            )

    def _fail(self, exc: OSError) -> None:
        self.write_errors += 1
        self.last_error = describe_os_error(exc)
        self._cut_back()
        first = not self.failing
        if first:
            self.failing = True
            self._outage_held = self.held
            self._outage_dropped = 0
        if first and not self._closing:
            self._report(
                logging.ERROR,
                f"{self.name} {self.path}: cannot write ({self.last_error}); holding records "
                f"in memory (up to {self.cap_bytes // (1024 * 1024)} MiB) and retrying every "
                f"{self.retry_s:g} s",
            )
        self._enforce_cap()

    def _cut_back(self) -> None:
        """Remove half a record from the end of the file (regular files only)."""
        if self._head_done and self._regular and self._fd is not None:
            try:
                os.ftruncate(self._fd, self._committed)
                self._head_done = 0
            except OSError:
                pass  # kept: the rest of the record is written first on recovery

    def _enforce_cap(self) -> None:
        while self.held_bytes > self.cap_bytes:
            head = self._head()
            victim = None
            for queue in (self._low, self._high):
                # never drop a record whose first bytes are already in the file
                start = 1 if (queue is head and self._head_done) else 0
                if len(queue) > start:
                    victim = (queue, start)
                    break
            if victim is None:
                return
            queue, index = victim
            if index == 0:
                _, data = queue.popleft()
            else:
                item = queue[index]
                del queue[index]
                data = item[1]
            self.held_bytes -= len(data)
            self.dropped += 1
            self._outage_dropped += 1


class AppendLogHandler(logging.Handler):
    """A logging handler writing through an :class:`AppendLog` (``gcs.log``): a full disk
    gives one report line and one on recovery, never a traceback per record (the standard
    ``FileHandler`` prints one through ``handleError`` for every record); records are held
    and written later like the journal's. Its AppendLog must report elsewhere than through
    logging (e.g. straight to stderr), or the report would come back here."""

    def __init__(self, file: AppendLog, level: int = logging.INFO) -> None:
        super().__init__(level)
        self.file = file

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = self.format(record) + "\n"
        except Exception:  # a caller's bad format arguments: not worth a traceback
            text = f"{record.levelname} {record.name}: {record.msg!r}\n"
        self.file.append(text.encode("utf-8", "replace"))

    def close(self) -> None:
        self.file.close()
        super().close()
