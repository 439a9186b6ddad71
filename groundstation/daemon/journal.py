"""The run's JSON-lines journal: one object a line, in the OS as soon as it is written.

Every line has ``t`` (mission seconds), ``unix_s`` (wall clock) and ``event``; ``vehicle``
and ``target`` where they apply. Lines go through a :class:`groundstation.storage.AppendLog`
(one ``os.write`` each), so a crash loses at most the line being written, and a full disk
(ENOSPC, EIO, EDQUOT) never stops the daemon: one error line, the lines are held in memory
(at most :data:`groundstation.storage.DEFAULT_CAP_BYTES`) and written in order when the
disk has room again, with one line saying so. Over the cap, telemetry-type lines
(:data:`TELEMETRY_EVENTS`, inputs of kind :data:`TELEMETRY_INPUTS`) are dropped first,
oldest first; decisions last. The file never holds half a line in the middle.

The ``stop`` line (with the run's summary) is the most valuable line: it is never dropped,
and a reserve of :data:`RESERVE_BYTES` is allocated beside the journal at start
(``.journal.jsonl.reserve``) and released at the end if lines are still held. Then, if the
held lines fit in the room made, they are written in order; else the ``stop`` line goes
first and the held lines follow it in order as far as space allows (their ``t`` is earlier
than the stop line's). One console line says what was written and how many lines were not
(docs/daemon.md, A full disk).

Live subscribers (the control API's event stream) get every line through a bounded queue;
a slow subscriber loses lines, never blocks the daemon.
"""

from __future__ import annotations

import asyncio
import collections
import json
import logging
import math
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any

from groundstation.storage import DEFAULT_CAP_BYTES, DEFAULT_RETRY_S, AppendLog

__all__ = ["TELEMETRY_EVENTS", "TELEMETRY_INPUTS", "Journal", "is_telemetry", "read_journal"]

log = logging.getLogger(__name__)

#: Bytes set aside beside the journal for its last lines on a full disk (1 MiB: a stop line
#: with its summary is a few kB, tens of kB after hours of many vehicles).
RESERVE_BYTES = 1024 * 1024
#: Events written first at the end of a run on a full disk (never dropped).
VITAL_EVENTS = frozenset({"stop"})

_ENCODE = json.JSONEncoder(separators=(",", ":")).encode
"""One compact encoder for every line (``json.dumps`` with separators builds one a call)."""

_RECENT = 200
_SUBSCRIBER_QUEUE = 1000
#: Journal events dropped first when held lines exceed the cap (periodic, re-derivable).
TELEMETRY_EVENTS = frozenset({"track", "truth", "detection", "statustext", "search"})
#: Core inputs (``event: input``) of these kinds count as telemetry too.
TELEMETRY_INPUTS = frozenset({"Telemetry", "Tick", "Detection", "BoatPosition"})


def is_telemetry(line: dict[str, Any]) -> bool:
    """True for a telemetry-type line (dropped first on a long disk outage)."""
    event = line.get("event")
    if event == "input":
        return line.get("kind") in TELEMETRY_INPUTS
    return event in TELEMETRY_EVENTS


def _clean(value: Any) -> Any:
    """JSON-safe: NaN/inf -> None, tuples -> lists, unknown objects -> str."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple | set | frozenset):
        return [_clean(v) for v in value]
    if value is None or isinstance(value, bool | int | str):
        return value
    return str(value)


class Journal:
    """Append-only JSON-lines writer with live subscribers."""

    def __init__(
        self,
        path: str | Path | None,
        now_s: Callable[[], float],
        unix_s: Callable[[], float],
        *,
        cap_bytes: int = DEFAULT_CAP_BYTES,
        retry_s: float = DEFAULT_RETRY_S,
        reserve_bytes: int | None = None,
    ) -> None:
        self.path = Path(path) if path is not None else None
        self._now_s = now_s
        self._unix_s = unix_s
        self.file: AppendLog | None = None
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.file = AppendLog(
                self.path, "journal", cap_bytes=cap_bytes, retry_s=retry_s,
                reserve_bytes=RESERVE_BYTES if reserve_bytes is None else reserve_bytes,
                vital_label="the stop line and summary")
        self.recent: collections.deque[dict[str, Any]] = collections.deque(maxlen=_RECENT)
        self.counts: collections.Counter[str] = collections.Counter()
        self._subscribers: list[asyncio.Queue[dict[str, Any] | None]] = []
        self.lines = 0

    def write(self, event: str, **fields: Any) -> dict[str, Any]:
        """Journal one event now; returns the line as written."""
        return self.write_at(self._now_s(), event, fields)

    def write_at(self, at_s: float, event: str, fields: dict[str, Any]) -> dict[str, Any]:
        """Journal one event stamped ``at_s`` (mission s): a report made as of a time the
        caller read from this journal's clock just before, so the journal stays in time
        order. Returns the line as written."""
        line: dict[str, Any] = {
            "t": round(at_s, 3),
            "unix_s": round(self._unix_s(), 3),
            "event": event,
        }
        for key, value in fields.items():
            if value is not None:
                line[key] = _clean(value)
        self.counts[event] += 1
        self.lines += 1
        self._append(line)
        self.recent.append(line)
        for queue in self._subscribers:
            if not queue.full():
                queue.put_nowait(line)
        return line

    def write_record(self, record: dict[str, Any]) -> None:
        """Journal a ready-made record (a core input from ``core.records``): its ``t`` is
        kept exact, ``unix_s`` is added; not sent to live subscribers (high rate)."""
        line = {"t": record.get("t"), "unix_s": round(self._unix_s(), 3)}
        line.update({k: _clean(v) for k, v in record.items() if k != "t"})
        self.counts[str(record.get("event"))] += 1
        self.lines += 1
        self._append(line)

    def _append(self, line: dict[str, Any]) -> None:
        if self.file is None:
            return
        try:
            data = (_ENCODE(line) + "\n").encode("utf-8")
        except (TypeError, ValueError) as exc:  # cannot happen after _clean; never fatal
            log.error("journal: line not written: %s", exc)
            return
        self.file.append(data, keep=not is_telemetry(line),
                         vital=line.get("event") in VITAL_EVENTS)

    async def subscribe(self) -> AsyncIterator[dict[str, Any]]:
        """Every line written from now on, until :meth:`close`."""
        queue: asyncio.Queue[dict[str, Any] | None] = asyncio.Queue(_SUBSCRIBER_QUEUE)
        self._subscribers.append(queue)
        try:
            while True:
                item = await queue.get()
                if item is None:
                    return
                yield item
        finally:
            if queue in self._subscribers:
                self._subscribers.remove(queue)

    def close(self) -> None:
        for queue in self._subscribers:
            if queue.full():
                queue.get_nowait()
            queue.put_nowait(None)
        if self.file is not None:
            self.file.close()


def read_journal(path: str | Path) -> list[dict[str, Any]]:
    """Every complete line of a journal (a truncated last line is skipped)."""
    out: list[dict[str, Any]] = []
    with Path(path).open(encoding="utf-8") as fh:
        for text in fh:
            try:
                out.append(json.loads(text))
            except json.JSONDecodeError:
                continue
    return out
