"""The schedule for playing a tlog's vehicles back as live MAVLink sources (sans-IO).

:func:`serving_schedule` turns a tlog into :class:`ServedFrame` values: each vehicle frame
exactly as recorded (so its own system id, component id, sequence number and signature go
out unchanged) and the wall-clock offset, from the start of serving, at which to send it::

    at_s(k) = sum over j <= k of min(t(j) - t(j - 1), max_gap_s)^+ / speed

Recorded pauses longer than ``max_gap_s`` (a log holding two flights an hour apart) are
shortened to ``max_gap_s``; timestamps that go backwards (a log merged from several links)
count as no pause. Frames of ground stations (and floe's own commands to the vehicles) are
left out. Sending is the caller's job (``gcs replay --serve``, composition layer).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from groundstation.link.tlog import TlogReader
from groundstation.runners.replay_tlog import TlogSummary, read_tlog

__all__ = ["DEFAULT_MAX_GAP_S", "ServedFrame", "serving_schedule"]

DEFAULT_MAX_GAP_S = 5.0


@dataclass(frozen=True, slots=True)
class ServedFrame:
    """One frame to send ``at_s`` wall seconds after serving starts."""

    at_s: float
    t_unix_s: float
    system_id: int
    raw: bytes


def serving_schedule(
    path: Path,
    speed: float = 1.0,
    *,
    max_gap_s: float = DEFAULT_MAX_GAP_S,
    systems: set[int] | None = None,
) -> tuple[TlogSummary, Iterator[ServedFrame]]:
    """The tlog's summary, and an iterator over the frames to serve (module docstring).

    ``systems`` restricts serving to those system ids (default: every vehicle).
    Raises :class:`~groundstation.runners.replay_tlog.TlogError` for an unusable tlog.
    """
    if not speed > 0:
        raise ValueError("speed must be > 0")
    summary = read_tlog(path)
    wanted = set(summary.vehicles) if systems is None else set(systems)

    def frames() -> Iterator[ServedFrame]:
        at_s = 0.0
        previous: float | None = None
        for record in TlogReader(summary.path):
            sysid = int(record.message.get_srcSystem())
            if sysid not in wanted:
                continue
            if previous is not None:
                at_s += min(max(record.t_unix_s - previous, 0.0), max_gap_s) / speed
            previous = record.t_unix_s
            yield ServedFrame(at_s, record.t_unix_s, sysid, record.raw)

    return summary, frames()
