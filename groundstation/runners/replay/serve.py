"""The schedule for playing a tlog's vehicles back as live MAVLink sources (sans-IO).

:func:`serving_schedule` turns a tlog into :class:`ServedFrame` values: each vehicle frame
exactly as recorded (so its own system id, component id, sequence number and signature go
out unchanged) and the wall-clock offset, from the start of serving, at which to send it::

    at_s(k) = sum over j <= k of min(t(j) - t(j - 1), max_gap_s)^+ / speed

Recorded pauses longer than ``max_gap_s`` (a log holding two flights an hour apart) are
shortened to ``max_gap_s``; timestamps that go backwards (a log merged from several links)
count as no pause.

With ``pace`` K instead of ``speed``, frames are spaced by **mission time** instead:
``t(j)`` above is the frame's mission time (:mod:`.mission_timeline`:
from the run's journal, else the vehicles' ``time_boot_ms``) and the divisor is K, so a run
recorded at 50x is watched at K x mission time whatever its recording speed-up (10 mission
seconds at ``--pace 10`` take 1 s); ``max_gap_s`` is then in mission seconds.

Frames of ground stations (and floe's own commands to the vehicles) are
left out. Sending is the caller's job (``gcs replay --serve``, composition layer).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from groundstation.link.tlog import TlogReader
from groundstation.runners.replay.mission_timeline import mission_timeline
from groundstation.runners.replay.tlog import TlogSummary, read_tlog

__all__ = ["DEFAULT_MAX_GAP_S", "ServedFrame", "serving_schedule"]

Timeline = Callable[[float], float]

DEFAULT_MAX_GAP_S = 5.0


@dataclass(frozen=True, slots=True)
class ServedFrame:
    """One frame to send ``at_s`` wall seconds after serving starts; ``t_s`` is its time on
    the schedule's clock (Unix time, or mission time with ``pace``)."""

    at_s: float
    t_unix_s: float
    system_id: int
    raw: bytes
    t_s: float = 0.0


def serving_schedule(
    path: Path,
    speed: float = 1.0,
    *,
    max_gap_s: float = DEFAULT_MAX_GAP_S,
    systems: set[int] | None = None,
    pace: float | None = None,
    timeline: Timeline | None = None,
    summary: TlogSummary | None = None,
) -> tuple[TlogSummary, Iterator[ServedFrame]]:
    """The tlog's summary, and an iterator over the frames to serve (module docstring).

    ``systems`` restricts serving to those system ids (default: every vehicle). With
    ``pace`` the frames are spaced by mission time / ``pace``; ``timeline`` maps a Unix
    time to mission time (default: :func:`mission_timeline` of the tlog). ``summary``: the
    tlog's :func:`read_tlog` if the caller has it already (read once).
    Raises :class:`~groundstation.runners.replay.tlog.TlogError` for an unusable tlog.
    """
    if not speed > 0:
        raise ValueError("speed must be > 0")
    if pace is not None and not pace > 0:
        raise ValueError("pace must be > 0")
    if summary is None:
        summary = read_tlog(path)
    wanted = set(summary.vehicles) if systems is None else set(systems)
    clock: Timeline = lambda unix_s: unix_s  # noqa: E731
    divisor = speed
    if pace is not None:
        clock = timeline or mission_timeline(summary.path, sorted(summary.vehicles)).at
        divisor = pace

    def frames() -> Iterator[ServedFrame]:
        at_s = 0.0
        previous: float | None = None
        for record in TlogReader(summary.path):
            sysid = int(record.message.get_srcSystem())
            if sysid not in wanted:
                continue
            t_s = clock(record.t_unix_s)
            if previous is not None:
                at_s += min(max(t_s - previous, 0.0), max_gap_s) / divisor
            previous = t_s
            yield ServedFrame(at_s, record.t_unix_s, sysid, record.raw, t_s)

    return summary, frames()
