"""Telemetry logs (``.tlog``), the format MAVProxy, QGroundControl and pymavlink read.

A tlog is a plain sequence of records, nothing before, between or after them::

    record = uint64 big-endian microseconds since the Unix epoch (the reception time)
             + one raw MAVLink frame (v1 or v2, as it was on the wire, signature included)

MAVProxy stores a link number in the two lowest bits of the timestamp (3 for frames it
sent); :meth:`TlogWriter.write` can do the same, and floe's router does: 0, 1, 2 for frames
received on vehicle link 0, 1, 2 or later, 3 for frames sent towards the vehicles.

A frame's length is in its header: v1 ``6 + len + 2``, v2 ``10 + len + 2`` plus 13 if the
signed flag (incompat_flags bit 0) is set.

:class:`TlogWriter` writes each record with one unbuffered ``os.write`` call (through
:class:`groundstation.storage.AppendLog`): once ``write`` returns True the record is in the
operating system, so a crash of the process loses at most the record being written. A
small write to the page cache takes microseconds, far below what the event loop notices at
MAVLink rates (hundreds of frames per second). A full disk (ENOSPC, EIO, EDQUOT) is never
raised into the link layer: one error line, records held in memory (at most
:data:`groundstation.storage.DEFAULT_CAP_BYTES`, the oldest dropped and counted beyond it)
and written in order once the disk has room, with one line saying so; a record cut short
by the full disk is cut off the file, so the file stays a clean sequence of records.

:class:`TlogReader` yields ``(t_unix_s, message, raw)`` records. It accepts a record only
if its timestamp is plausible (years 2000 to 2100), its frame has a MAVLink start marker
and complete length, and pymavlink decodes it (CRC checked for known messages). Anything
else is damage: the reader moves on byte by byte until a valid record starts again and
reports each skipped ``[start, end)`` byte range in :attr:`TlogReader.skipped` (a
truncated last record is one such range, ending at the end of the file).
"""

from __future__ import annotations

import logging
import mmap
import os
import struct
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from groundstation.link.base import MavMessage
from groundstation.mavlink.codec import mavlink2
from groundstation.storage import DEFAULT_CAP_BYTES, DEFAULT_RETRY_S, AppendLog

__all__ = ["TlogReader", "TlogRecord", "TlogWriter"]

log = logging.getLogger(__name__)

_TS = struct.Struct(">Q")
_MIN_US = 946_684_800 * 1_000_000  # 2000-01-01
_MAX_US = 4_102_444_800 * 1_000_000  # 2100-01-01
_V1, _V2 = 0xFE, 0xFD
_SIGNATURE_LEN = 13


class TlogWriter:
    """Append-only tlog writer (see the module docstring for the guarantees)."""

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        append: bool = False,
        cap_bytes: int = DEFAULT_CAP_BYTES,
        retry_s: float = DEFAULT_RETRY_S,
    ) -> None:
        self.path = os.fspath(path)
        self._file: AppendLog | None = AppendLog(
            self.path, "tlog", truncate=not append, cap_bytes=cap_bytes, retry_s=retry_s
        )

    @property
    def records(self) -> int:
        """Records in the file."""
        return self._file.records if self._file is not None else self._closed[0]

    @property
    def bytes_written(self) -> int:
        return self._file.bytes_written if self._file is not None else self._closed[1]

    @property
    def write_errors(self) -> int:
        """Failed write attempts (one per retry while the disk stays full)."""
        return self._file.write_errors if self._file is not None else self._closed[2]

    @property
    def held(self) -> int:
        """Records waiting in memory for the disk to have room."""
        return self._file.held if self._file is not None else 0

    @property
    def dropped(self) -> int:
        """Records dropped because the held records exceeded the cap."""
        return self._file.dropped if self._file is not None else self._closed[3]

    _closed: tuple[int, int, int, int] = (0, 0, 0, 0)

    def write(
        self, frame: bytes, t_unix_s: float | None = None, link_number: int | None = None
    ) -> bool:
        """Append one record stamped ``t_unix_s`` (default: now). False if not written now
        (held in memory while the disk is full, or the writer is closed).

        ``link_number`` (0..3), if given, replaces the two lowest bits of the microsecond
        timestamp, as MAVProxy does (it marks the frames it sent with 3); pymavlink's reader
        exposes them as ``msg._link``.
        """
        if self._file is None:
            return False
        if t_unix_s is None:
            t_unix_s = time.time()
        t_us = max(0, round(t_unix_s * 1e6))
        if link_number is not None:
            t_us = (t_us & ~3) | (link_number & 3)
        return self._file.append(_TS.pack(t_us) + bytes(frame))

    def flush(self, *, durable: bool = False) -> None:
        """Records are already in the OS (held ones are retried here); ``durable=True``
        also asks the disk (fsync), which may block: call it from a worker thread if at
        all. Never raises."""
        if self._file is None:
            return
        self._file.retry()
        if durable and self._file.fd is not None:
            try:
                os.fsync(self._file.fd)
            except OSError as exc:
                log.error("tlog %s: fsync failed (%s)", self.path, exc)

    def close(self) -> None:
        """Write what is held if possible, then close the file. Idempotent."""
        f, self._file = self._file, None
        if f is not None:
            f.close()
            self._closed = (f.records, f.bytes_written, f.write_errors, f.dropped)

    def __enter__(self) -> TlogWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass(frozen=True, slots=True)
class TlogRecord:
    """One record of a tlog: reception time, decoded message, exact frame, file offset."""

    t_unix_s: float
    message: MavMessage
    raw: bytes
    offset: int

    @property
    def link_number(self) -> int:
        """The two lowest bits of the microsecond timestamp (MAVProxy's link number)."""
        return round(self.t_unix_s * 1e6) & 3


class TlogReader:
    """Iterate a tlog robustly; :attr:`skipped` lists damaged byte ranges found so far."""

    def __init__(self, source: str | os.PathLike[str] | bytes) -> None:
        self.path: str | None = None if isinstance(source, bytes) else os.fspath(source)
        self._data = source if isinstance(source, bytes) else None
        self.skipped: list[tuple[int, int]] = []
        self.records = 0
        self._mav: Any = mavlink2.MAVLink(None)

    @property
    def skipped_bytes(self) -> int:
        """Total bytes in :attr:`skipped`."""
        return sum(end - start for start, end in self.skipped)

    def __iter__(self) -> Iterator[TlogRecord]:
        if self._data is not None:
            yield from self._scan(self._data)
            return
        assert self.path is not None
        with open(self.path, "rb") as f:
            if os.fstat(f.fileno()).st_size == 0:
                return
            with mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
                yield from self._scan(buf)

    def _scan(self, buf: bytes | mmap.mmap) -> Iterator[TlogRecord]:
        n = len(buf)
        pos = 0
        damage_start: int | None = None
        while pos < n:
            found = self._record_at(buf, pos)
            if found is None:
                if damage_start is None:
                    damage_start = pos
                pos = self._next_candidate(buf, pos + 1)
                continue
            record, end = found
            if damage_start is not None:
                self._skip(damage_start, pos)
                damage_start = None
            self.records += 1
            yield record
            pos = end
        if damage_start is not None:
            self._skip(damage_start, n)

    def _skip(self, start: int, end: int) -> None:
        self.skipped.append((start, end))
        log.debug("tlog %s: skipped damaged bytes %d..%d", self.path or "<bytes>", start, end)

    @staticmethod
    def _next_candidate(buf: bytes | mmap.mmap, pos: int) -> int:
        """The next position whose 9th byte is a MAVLink start marker (or the end)."""
        best = len(buf)
        for marker in (b"\xfd", b"\xfe"):
            i = buf.find(marker, pos + 8)
            if i >= 0:
                best = min(best, i - 8)
        return best

    @staticmethod
    def _frame_length(buf: bytes | mmap.mmap, at: int) -> int | None:
        n = len(buf)
        if at + 3 > n:
            return None
        magic, plen, incompat = buf[at], buf[at + 1], buf[at + 2]
        if magic == _V1:
            return 6 + plen + 2
        if magic == _V2:
            if incompat & ~1:
                return None
            return 10 + plen + 2 + (_SIGNATURE_LEN if incompat & 1 else 0)
        return None

    def _plausible_start(self, buf: bytes | mmap.mmap, pos: int) -> bool:
        if pos + 9 > len(buf):
            return False
        (t_us,) = _TS.unpack_from(buf, pos)
        return _MIN_US <= t_us <= _MAX_US and buf[pos + 8] in (_V1, _V2)

    def _record_at(self, buf: bytes | mmap.mmap, pos: int) -> tuple[TlogRecord, int] | None:
        if not self._plausible_start(buf, pos):
            return None
        length = self._frame_length(buf, pos + 8)
        end = pos + 8 + (length or 0)
        if length is None or end > len(buf):
            return None
        raw = bytes(buf[pos + 8 : end])
        try:
            msg = self._mav.decode(bytearray(raw))
        except Exception:  # bad CRC, bad length, unpack errors: all damage
            return None
        if msg.get_type().startswith("UNKNOWN") and not (
            end == len(buf) or self._plausible_start(buf, end)
        ):
            return None  # an unknown id has no CRC to check: want a sane next record
        (t_us,) = _TS.unpack_from(buf, pos)
        return TlogRecord(t_us / 1e6, msg, raw, pos), end
