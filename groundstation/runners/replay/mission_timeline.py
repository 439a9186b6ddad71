"""Mission time of a recorded run, as a function of the tlog's reception times.

A tlog stamps frames with the wall clock (Unix seconds). A run recorded at a speed-up K
(``gcs run --vehicles sim:N`` runs at 50x) went through K mission seconds per wall second,
and not quite steadily (a loaded host slows the simulator down). Serving it back "at the
mission's pace" (``gcs replay --serve --pace K``) needs the mission time of every frame.
:func:`mission_timeline` finds anchors, pairs ``(unix_s, mission_s)``, from the best
source there is:

1. ``journal.jsonl`` beside the tlog (a ``gcs run`` folder): every record holds its
   mission time ``t`` and its ``unix_s``;
2. otherwise the vehicles' own clock: ``time_boot_ms`` of the first vehicle's messages
   (it runs on simulated time; a reboot, where it goes back, continues from where it was).
   A frame whose clock leaps (back more than 1 s, or ahead faster than
   :data:`MAX_CLOCK_RATE` times the tlog's time since the last, plus 1 s) counts only once
   the vehicle's next frame goes on from it: one stray or forged frame moves nothing;
3. otherwise none: mission time is taken to be the tlog's own time (K = 1).

Between anchors mission time is linear in Unix time; outside them it is extrapolated at
the mean rate of all anchors. Mission time never decreases (anchors that would make it go
back are dropped).
"""

from __future__ import annotations

import bisect
import json
import math
from dataclasses import dataclass
from pathlib import Path

from groundstation.link.tlog import TlogReader

__all__ = ["MissionTimeline", "mission_timeline"]

ANCHOR_SPACING_S = 0.1
"""At most one anchor per this much wall time: a long recording keeps anchors to its end
(the drift of a loaded host late in a run counts as much as early on) in bounded memory."""


def _add_anchor(anchors: list[tuple[float, float]], unix_s: float, t_s: float) -> None:
    """Append (unix_s, t_s) unless the previous anchor is less than ANCHOR_SPACING_S older."""
    if not anchors or unix_s - anchors[-1][0] >= ANCHOR_SPACING_S:
        anchors.append((unix_s, t_s))


@dataclass(frozen=True)
class MissionTimeline:
    """Piecewise-linear ``unix_s -> mission_s``; ``source`` says where it came from."""

    unix_s: tuple[float, ...]
    mission_s: tuple[float, ...]
    source: str

    @classmethod
    def from_anchors(cls, anchors: list[tuple[float, float]], source: str) -> MissionTimeline:
        """Sort by Unix time, keep mission time non-decreasing and Unix time increasing."""
        unix: list[float] = []
        mission: list[float] = []
        for u, m in sorted(anchors):
            if not (math.isfinite(u) and math.isfinite(m)):
                continue
            if unix and (u <= unix[-1] or m < mission[-1]):
                continue
            unix.append(u)
            mission.append(m)
        return cls(tuple(unix), tuple(mission), source if unix else "tlog time (K = 1)")

    @property
    def rate(self) -> float:
        """Mean mission seconds per Unix second (the recorded speed-up; 1 without anchors)."""
        if len(self.unix_s) < 2 or self.unix_s[-1] <= self.unix_s[0]:
            return 1.0
        return (self.mission_s[-1] - self.mission_s[0]) / (self.unix_s[-1] - self.unix_s[0])

    def at(self, unix_s: float) -> float:
        """Mission time at ``unix_s``."""
        if not self.unix_s:
            return unix_s
        u, m = self.unix_s, self.mission_s
        k = bisect.bisect_right(u, unix_s)
        if k == 0:
            return m[0] - (u[0] - unix_s) * self.rate
        if k == len(u):
            return m[-1] + (unix_s - u[-1]) * self.rate
        fraction = (unix_s - u[k - 1]) / (u[k] - u[k - 1])
        return m[k - 1] + fraction * (m[k] - m[k - 1])


def _journal_anchors(journal: Path) -> list[tuple[float, float]]:
    anchors: list[tuple[float, float]] = []
    try:
        with journal.open(encoding="utf-8", errors="replace") as f:
            for line in f:
                try:
                    record = json.loads(line)
                except ValueError:
                    continue
                if not isinstance(record, dict):
                    continue
                t, unix = record.get("t"), record.get("unix_s")
                if isinstance(t, int | float) and isinstance(unix, int | float):
                    _add_anchor(anchors, float(unix), float(t))
    except OSError:
        return []
    return anchors


MAX_CLOCK_RATE = 1000.0
"""The fastest a vehicle's clock can run against the tlog's (floe's top speed-up)."""


def _follows(boot_s: float, unix_s: float, prev_boot_s: float, prev_unix_s: float) -> bool:
    """Whether a clock reading goes on from the previous one: not back by more than 1 s,
    ahead by at most ``MAX_CLOCK_RATE`` times the tlog time between them, plus 1 s."""
    ahead_s = boot_s - prev_boot_s
    return -1.0 <= ahead_s <= MAX_CLOCK_RATE * max(0.0, unix_s - prev_unix_s) + 1.0


def _boot_anchors(tlog: Path, system_id: int) -> list[tuple[float, float]]:
    """(unix_s, seconds of the vehicle's clock), continued across reboots; a leap counts
    once the next frame confirms it (module docstring)."""
    anchors: list[tuple[float, float]] = []
    offset_s = 0.0
    last: tuple[float, float] | None = None  # (boot_s, unix_s) of the clock as accepted
    leap: tuple[float, float] | None = None  # a reading that leapt, awaiting the next
    for record in TlogReader(tlog):
        msg = record.message
        if int(msg.get_srcSystem()) != system_id:
            continue
        boot_ms = getattr(msg, "time_boot_ms", None)
        if not isinstance(boot_ms, int) or isinstance(boot_ms, bool):
            continue
        reading = (boot_ms / 1000.0, record.t_unix_s)
        if last is not None and not _follows(*reading, *last):
            if leap is None or not _follows(*reading, *leap):
                leap = reading  # a stray frame, or the first of a new clock: wait
                continue
            # the leap confirmed (a reboot): mission time goes on from where it was
            offset_s += last[0] - leap[0]
            _add_anchor(anchors, leap[1], leap[0] + offset_s)
        leap = None
        last = reading
        _add_anchor(anchors, reading[1], reading[0] + offset_s)
    return anchors


def mission_timeline(tlog: Path, vehicles: list[int]) -> MissionTimeline:
    """The mission timeline of ``tlog`` (module docstring); ``vehicles``: its vehicles'
    system ids, lowest first."""
    journal = tlog.parent / "journal.jsonl"
    if journal.is_file():
        anchors = _journal_anchors(journal)
        if len(anchors) >= 2:
            return MissionTimeline.from_anchors(anchors, f"mission time from {journal}")
    for system_id in vehicles[:1]:
        anchors = _boot_anchors(tlog, system_id)
        if len(anchors) >= 2:
            return MissionTimeline.from_anchors(
                anchors, f"mission time from system {system_id}'s time_boot_ms"
            )
    return MissionTimeline.from_anchors([], "")
