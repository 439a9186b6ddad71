"""Evidence rules: no single frame may remove or redirect a vehicle.

Each rule is a small pure class fed one observation at a time with the mission time it
arrived; it answers whether the evidence is now sufficient. The thresholds are named
parameters with defaults chosen for ~1 Hz HEARTBEAT / SYS_STATUS / MISSION_CURRENT streams
(ArduPlane's defaults; floe asks for 2 Hz of position):

* :class:`Sustained` - a condition holds on ``min_frames`` consecutive frames spanning at
  least ``min_span_s``; one contrary frame starts the count again. Used for mode changes,
  disarm, landed and "flying".
* :class:`RebootEvidence` - ``time_boot_ms`` going back is a reboot, and one jumping
  ahead of the receive clock is the timeline, only when the frames after it keep to the
  new timeline (or, for a reboot, the autopilot says it is booting).
* :class:`BatteryEvidence` - low readings sustained *and* confirmed by the autopilot
  (HEARTBEAT ``system_status`` CRITICAL, or its own RTL), or low for much longer.
* :class:`LoiterEndEvidence` - a mission item's end needs agreeing signals over time.
* :class:`NewSystemEvidence` - a system id becomes a vehicle (a session) only after
  consistent autopilot HEARTBEATs from one place over time, and, unless it is an expected
  vehicle, while its link has made fewer than a few new vehicles in the last minute;
  the others are summarised, one line per burst.
* :class:`WindEvidence` - the vehicle's wind estimate is the median of its last WIND frames,
  and exists only after several of them over time.
"""

from __future__ import annotations

import statistics
from collections import deque
from collections.abc import Hashable, Iterable
from dataclasses import dataclass, field
from typing import Any

from groundstation.mavlink.codec import mavlink2

__all__ = [
    "MAV_STATE_BOOT",
    "MAV_STATE_CRITICAL",
    "MAV_STATE_EMERGENCY",
    "BatteryEvidence",
    "LoiterEndEvidence",
    "NewSystemEvidence",
    "RebootEvidence",
    "Sustained",
    "WindEvidence",
    "is_autopilot_heartbeat",
]

MAV_STATE_BOOT = 1
MAV_STATE_CRITICAL = 5
MAV_STATE_EMERGENCY = 6


class Sustained:
    """True once a condition held on ``min_frames`` consecutive observations whose times
    span at least ``min_span_s`` (first to last); any observation where it does not hold
    resets it. ``observe`` returns the verdict after the observation."""

    def __init__(self, min_frames: int = 3, min_span_s: float = 2.0) -> None:
        self.min_frames = min_frames
        self.min_span_s = min_span_s
        self._since_s: float | None = None
        self._last_s = 0.0
        self._frames = 0

    @property
    def holding(self) -> bool:
        """The condition held on the last observation (confirmed or not yet)."""
        return self._frames > 0

    @property
    def confirmed(self) -> bool:
        return self._frames >= self.min_frames and self._span_ok

    @property
    def since_s(self) -> float | None:
        """When the current run of agreeing observations began."""
        return self._since_s

    def observe(self, holds: bool, t_s: float) -> bool:
        if not holds:
            self.reset()
            return False
        if self._since_s is None:
            self._since_s = t_s
        self._frames += 1
        self._last_s = t_s
        return self.confirmed

    def reset(self) -> None:
        self._since_s = None
        self._frames = 0

    @property
    def _span_ok(self) -> bool:
        return self._since_s is not None and self._last_s - self._since_s >= self.min_span_s - 1e-9


@dataclass
class _Timeline:
    """A run of frames off the accepted timeline that may be a new one: its first and
    latest boot times, when it began, how many frames, and its own receive-clock anchor."""

    first_ms: int
    latest_ms: int
    since_s: float
    frames: int
    anchor: tuple[int, float]


class RebootEvidence:
    """Which ``time_boot_ms`` values are the autopilot's timeline, and when it restarted.

    Two kinds of frame are held back (not accepted; :meth:`observe` says why) until the
    frames after them show a consistent new timeline:

    * **a step back**: ``boot_ms`` more than ``backstep_ms`` below the accepted value (the
      highest accepted so far). It is a *reboot* when ``min_frames`` frames (the first
      included) keep to the new timeline over at least ``min_span_s``, or at once when the
      autopilot says it is booting (:meth:`booting`: HEARTBEAT ``system_status``
      MAV_STATE_BOOT or mode INITIALISING). ``"suspect"`` while it is not confirmed.
    * **a jump ahead**: ``boot_ms`` beyond what the receive clock allows since the
      accepted frames. With ``(b_a, t_a)`` the *anchor* (the accepted frame that arrived
      latest relative to its own clock: the least of ``b_i - 1000 t_i`` over the accepted
      frames ``i``, so late frames of a backlog only lower it and no frame can raise it),
      a frame at receive time ``t`` may carry at most::

          b_max(t) = b_a + 1000 (t - t_a) + min(drift 1000 (t - t_a), drift_cap_ms) + ahead_ms

      (``ahead_ms`` covers latency that shrinks again after a backlog or a stall,
      ``drift`` a vehicle clock a little faster than the receive clock). A frame beyond
      it is ``"ahead"``: held back, never the timeline on its own. When ``min_frames``
      such frames keep to one new timeline (never back by more than ``jitter_ms``, never
      ahead of their own ``b_max``) over ``min_span_s`` it is ``"resync"``: the vehicle's
      clock really moved on (a mission clock that paused, a backlog drained at once); the
      caller accepts it, and nothing else changes (no reboot).

    Anything else is ``"ok"`` (accept the value; the anchor may move down). A frame that
    is neither back nor ahead clears both suspicions (counted in ``rejected``). So one
    forged frame with a small or a large ``time_boot_ms`` changes nothing: it is held
    back, and the next real frame clears it. An accepted value is at most ``ahead_ms +
    drift_cap_ms`` ahead of the real timeline, which is less than ``backstep_ms``: the real
    frames after it never look like a step back (the way a forged large frame used to be
    accepted, and the real frames then "confirmed" a reboot).
    """

    def __init__(
        self,
        backstep_ms: int = 3000,
        min_frames: int = 3,
        min_span_s: float = 1.0,
        jitter_ms: int = 500,
        ahead_ms: int = 2000,
        drift: float = 0.05,
        drift_cap_ms: int = 500,
    ) -> None:
        if ahead_ms + drift_cap_ms >= backstep_ms:
            raise ValueError(
                f"ahead_ms + drift_cap_ms ({ahead_ms + drift_cap_ms}) must be below "
                f"backstep_ms ({backstep_ms}): an accepted frame ahead of the real timeline "
                "would make the real frames look like a reboot"
            )
        self.backstep_ms = backstep_ms
        self.min_frames = min_frames
        self.min_span_s = min_span_s
        self.jitter_ms = jitter_ms
        self.ahead_ms = ahead_ms
        self.drift = drift
        self.drift_cap_ms = drift_cap_ms
        self.rejected = 0
        """Suspicions (back or ahead) cleared by a frame on the accepted timeline."""
        self.held_ahead = 0
        """Frames held back as ahead of the receive clock."""
        self.resyncs = 0
        """New timelines ahead of the old one accepted (no reboot)."""
        self._anchor: tuple[int, float] | None = None
        self._back: _Timeline | None = None
        self._ahead: _Timeline | None = None

    @property
    def suspected(self) -> bool:
        """A step back (a possible reboot) is pending."""
        return self._back is not None

    @property
    def ahead_suspected(self) -> bool:
        """A jump ahead of the receive clock is pending."""
        return self._ahead is not None

    def limit_ms(self, t_s: float) -> int | None:
        """``b_max(t)`` of the accepted timeline (None before its first frame)."""
        return None if self._anchor is None else self._limit(self._anchor, t_s)

    def observe(self, accepted_ms: int | None, boot_ms: int, t_s: float) -> str:
        """One frame's ``boot_ms`` received at ``t_s``, against ``accepted_ms`` (the highest
        value accepted so far, None before the first): ``"ok"``, ``"suspect"``,
        ``"reboot"``, ``"ahead"`` or ``"resync"`` (see the class docstring)."""
        if accepted_ms is None:
            self._restart((boot_ms, t_s))
            return "ok"
        if boot_ms < accepted_ms - self.backstep_ms:
            self._back = self._extend(self._back, boot_ms, t_s)
            if self._confirmed(self._back, t_s):
                self._restart(self._back.anchor)
                return "reboot"
            return "suspect"
        if self._anchor is not None and boot_ms > self._limit(self._anchor, t_s):
            self.held_ahead += 1
            self._ahead = self._extend(self._ahead, boot_ms, t_s)
            if self._confirmed(self._ahead, t_s):
                self.resyncs += 1
                self._restart(self._ahead.anchor)
                return "resync"
            return "ahead"
        if self._back is not None or self._ahead is not None:
            self.rejected += 1
            self._back = self._ahead = None
        self._anchor = (boot_ms, t_s) if self._anchor is None else _lower(
            self._anchor, boot_ms, t_s)
        return "ok"

    def booting(self) -> bool:
        """The autopilot says it is booting: a pending step back is confirmed (True)."""
        if self._back is None:
            return False
        self._restart(self._back.anchor)
        return True

    def latest_ms(self) -> int | None:
        """The latest boot time of the pending step back, if any."""
        return None if self._back is None else self._back.latest_ms

    def _limit(self, anchor: tuple[int, float], t_s: float) -> int:
        boot_ms, at_s = anchor
        elapsed_ms = max(0.0, t_s - at_s) * 1000.0
        return int(boot_ms + elapsed_ms + min(self.drift * elapsed_ms, self.drift_cap_ms)
                   + self.ahead_ms)

    def _extend(self, run: _Timeline | None, boot_ms: int, t_s: float) -> _Timeline:
        """``run`` with this frame if it keeps to it (not back by more than ``jitter_ms``,
        not ahead of the run's own ``b_max``), else a new run from this frame."""
        if (
            run is None
            or boot_ms < run.latest_ms - self.jitter_ms
            or boot_ms > self._limit(run.anchor, t_s)
        ):
            return _Timeline(boot_ms, boot_ms, t_s, 1, (boot_ms, t_s))
        run.latest_ms = max(run.latest_ms, boot_ms)
        run.frames += 1
        run.anchor = _lower(run.anchor, boot_ms, t_s)
        return run

    def _confirmed(self, run: _Timeline, t_s: float) -> bool:
        return run.frames >= self.min_frames and t_s - run.since_s >= self.min_span_s - 1e-9

    def _restart(self, anchor: tuple[int, float]) -> None:
        self._anchor = anchor
        self._back = self._ahead = None


def _lower(anchor: tuple[int, float], boot_ms: int, t_s: float) -> tuple[int, float]:
    """The anchor that arrived latest relative to its own clock: the frame with the least
    ``boot_ms - 1000 t_s``."""
    if boot_ms - 1000.0 * t_s < anchor[0] - 1000.0 * anchor[1]:
        return (boot_ms, t_s)
    return anchor


class BatteryEvidence:
    """A battery failsafe that floe acts on.

    Low means ``remaining_pct < low_pct``. Confirmed when low readings are sustained over
    ``min_frames`` frames and ``min_span_s`` *and* the autopilot agrees (``confirm``: its
    HEARTBEAT ``system_status`` is CRITICAL/EMERGENCY, or it switched to RTL by itself), or
    when low readings alone are sustained over ``alone_span_s`` (an autopilot whose own
    failsafe is off). One reading at or above ``low_pct`` starts again.
    """

    def __init__(
        self,
        low_pct: float = 25.0,
        min_frames: int = 3,
        min_span_s: float = 2.0,
        alone_span_s: float = 20.0,
    ) -> None:
        self.low_pct = low_pct
        self.alone_span_s = alone_span_s
        self._low = Sustained(min_frames, min_span_s)
        self._confirmed_by_autopilot = False

    def reading(self, remaining_pct: float | None, t_s: float) -> None:
        if remaining_pct is None:
            return
        self._low.observe(remaining_pct < self.low_pct, t_s)
        if not self._low.holding:
            self._confirmed_by_autopilot = False

    def autopilot_agrees(self) -> None:
        """The autopilot reports a failsafe state (CRITICAL) or flew home by itself."""
        if self._low.holding:
            self._confirmed_by_autopilot = True

    @property
    def low_readings(self) -> bool:
        return self._low.holding

    def confirmed(self, t_s: float) -> bool:
        if not self._low.confirmed:
            return False
        since = self._low.since_s
        long_enough = since is not None and t_s - since >= self.alone_span_s
        return self._confirmed_by_autopilot or long_enough

    def reset(self) -> None:
        self._low.reset()
        self._confirmed_by_autopilot = False


class LoiterEndEvidence:
    """The end of mission item ``seq`` (a timed loiter or a waypoint) of floe's mission.

    ArduPlane sends MISSION_ITEM_REACHED once and then streams MISSION_CURRENT (~1 Hz). A
    signal that the item is over is MISSION_ITEM_REACHED ``seq`` (or later), or a
    MISSION_CURRENT past ``seq``. The end is confirmed when such signals agree over time:

    * a run of them, with no MISSION_CURRENT at or before ``seq`` in between, holds at
      least ``min_frames`` signals, at least one of them a MISSION_CURRENT past ``seq``,
      and spans ``min_span_s`` or more of mission time (first signal to last).

    The span is what a burst cannot fake: any number of forged frames written at once
    arrive together, and the vehicle's own MISSION_CURRENT (at or before ``seq`` while it
    still loiters) cancels the run within one period. The default 0.8 s is below the 1 s
    period of MISSION_CURRENT, so the real end is confirmed by MISSION_ITEM_REACHED and the
    next MISSION_CURRENT 0.8 s or more later, or by two MISSION_CURRENTs past ``seq`` (one
    period apart) when MISSION_ITEM_REACHED was lost: 1-2 s after the end.

    Signals count only after a MISSION_CURRENT at or before ``seq`` was seen (before that
    a MISSION_CURRENT past ``seq`` is the previous mission's), except MISSION_ITEM_REACHED
    of ``seq`` itself. ``observe_*`` return True exactly once, when the end is confirmed;
    ``ended_by`` is ``"reached"`` if a MISSION_ITEM_REACHED is in the confirming run, else
    ``"mission_current"``.
    """

    def __init__(
        self,
        seq: int,
        *,
        current_seq: int | None = None,
        min_frames: int = 2,
        min_span_s: float = 0.8,
    ) -> None:
        self.seq = seq
        self.min_frames = min_frames
        self.min_span_s = min_span_s
        self.ended_by: str | None = None
        self._seen_at_or_before = current_seq is not None and current_seq <= seq
        self._run_since_s: float | None = None
        self._run_frames = 0
        self._run_reached = False
        self._run_past_current = False

    @property
    def ended(self) -> bool:
        return self.ended_by is not None

    def observe_reached(self, seq: int, t_s: float) -> bool:
        """One MISSION_ITEM_REACHED frame."""
        if self.ended:
            return False
        if seq == self.seq or (seq > self.seq and self._seen_at_or_before):
            self._run_reached = True
            return self._signal(t_s)
        return False

    def observe_current(self, seq: int, t_s: float) -> bool:
        """One MISSION_CURRENT frame (every frame, not only changes)."""
        if self.ended:
            return False
        if seq <= self.seq:
            self._seen_at_or_before = True
            self._reset_run()
            return False
        if not self._seen_at_or_before and not self._run_reached:
            return False
        self._run_past_current = True
        return self._signal(t_s)

    def _signal(self, t_s: float) -> bool:
        if self._run_since_s is None:
            self._run_since_s = t_s
        self._run_frames += 1
        if (
            self._run_past_current
            and self._run_frames >= self.min_frames
            and t_s - self._run_since_s >= self.min_span_s - 1e-9
        ):
            self.ended_by = "reached" if self._run_reached else "mission_current"
        return self.ended

    def _reset_run(self) -> None:
        self._run_since_s = None
        self._run_frames = 0
        self._run_reached = False
        self._run_past_current = False

    def rebooted(self) -> None:
        self._seen_at_or_before = False
        self._reset_run()


@dataclass
class _Newcomer:
    place: Hashable
    signature: tuple[int, int]
    first_s: float
    last_s: float
    last_seq: int
    count: int = 1


@dataclass
class _Burst:
    """Unknown system ids heard on one link since ``first_s`` (a burst ends after
    ``quiet_s`` without any)."""

    first_s: float
    last_s: float
    reported_s: float
    ids: set[int] = field(default_factory=set)
    heartbeats: int = 0
    rate_limited: set[int] = field(default_factory=set)
    joined: int = 0


class NewSystemEvidence:
    """When an unknown system id is a vehicle: consistent autopilot HEARTBEATs, and room
    on its link for a new vehicle.

    Fed the autopilot HEARTBEATs (``type`` not GCS, ``autopilot`` not INVALID, component
    1: the caller filters) of system ids that have no session yet. A system id is
    **confirmed** when ``min_heartbeats`` of them, spanning at least ``min_span_s``,
    came from one place (link and peer) with the same ``(type, autopilot)`` and no gap
    longer than ``max_gap_s``; a heartbeat from another place, with another signature or
    after a longer gap starts the count again from it. A heartbeat with the same MAVLink
    sequence number as the last one counted is a duplicate (a radio's repeat, a replay)
    and adds nothing. A real autopilot (1 Hz, its sequence number counting every frame it
    sends) is confirmed 2-3 s after it is first heard; random system ids in noise or
    fuzzed frames, which rarely repeat a signature and never over seconds with fresh
    sequence numbers, are not.

    **Rate limit.** A confirmed system id that is not ``expected`` (the configured
    vehicles: ``sim:N``'s 1..N, ``vehicle_settings``' ids) is *admitted* only while its
    link admitted fewer than ``max_new_per_link`` unexpected system ids in the last
    ``new_window_s``; else it waits (counted in ``rate_limited``) and is admitted when
    the window frees, if its heartbeats go on. So one peer sending the heartbeats of 150
    system ids makes at most ``max_new_per_link`` vehicles a minute, and a real newcomer
    (one at a time) joins at once. :meth:`heartbeat` returns True while the system id is
    confirmed and admitted; the caller :meth:`forget` s it once it made a session.

    **Summary.** Unexpected system ids are gathered per link into *bursts*; a burst ends
    after ``quiet_s`` without a heartbeat of one, and :meth:`reports` then gives one line
    for it (``link``, ``systems``: how many ids never became vehicles, ``ids``: the first
    10 of them, ``heartbeats``, ``rate_limited``, ``joined``: ids of it that did, ``since_t``)
    - or every ``report_every_s`` while it lasts (``ongoing``). A burst whose every id
    became a vehicle (a real newcomer) gives none. Candidates silent for longer than
    ``max(max_gap_s, quiet_s)`` are dropped.

    Counters: ``heartbeats`` (fed), ``duplicates``, ``restarts`` (a candidate's count
    started again), ``rate_limited`` (confirmed heartbeats not admitted), ``admitted``.
    """

    SAMPLE_IDS = 10

    def __init__(
        self,
        min_heartbeats: int = 3,
        min_span_s: float = 2.0,
        max_gap_s: float = 5.0,
        *,
        expected: Iterable[int] = (),
        max_new_per_link: int = 4,
        new_window_s: float = 60.0,
        quiet_s: float = 10.0,
        report_every_s: float = 60.0,
    ) -> None:
        self.min_heartbeats = min_heartbeats
        self.min_span_s = min_span_s
        self.max_gap_s = max_gap_s
        self.expected = frozenset(expected)
        self.max_new_per_link = max_new_per_link
        self.new_window_s = new_window_s
        self.quiet_s = quiet_s
        self.report_every_s = report_every_s
        self.heartbeats = 0
        self.duplicates = 0
        self.restarts = 0
        self.rate_limited = 0
        self.admitted = 0
        self._candidates: dict[int, _Newcomer] = {}
        self._admitted_ids: set[int] = set()
        self._admissions: dict[Hashable, deque[float]] = {}
        self._bursts: dict[Hashable, _Burst] = {}

    @property
    def pending(self) -> int:
        """System ids heard but not (yet) confirmed."""
        return len(self._candidates)

    def heartbeat(
        self,
        system_id: int,
        place: Hashable,
        signature: tuple[int, int],
        seq: int,
        t_s: float,
        link: Hashable | None = None,
    ) -> bool:
        """One autopilot HEARTBEAT of ``system_id`` from ``place`` (on ``link``, default
        ``place``; ``signature``: its ``(type, autopilot)``, ``seq``: its MAVLink sequence
        number) at ``t_s``. True: confirmed and admitted (make the session)."""
        self.heartbeats += 1
        link = place if link is None else link
        expected = system_id in self.expected
        burst = None if expected else self._burst(link, system_id, t_s)
        if not self._confirmed(system_id, place, signature, seq, t_s):
            return False
        if expected or system_id in self._admitted_ids:
            return True
        if not self._admit(link, t_s):
            self.rate_limited += 1
            if burst is not None:
                burst.rate_limited.add(system_id)
            return False
        self.admitted += 1
        self._admitted_ids.add(system_id)
        if burst is not None:
            burst.ids.discard(system_id)
            burst.rate_limited.discard(system_id)
            burst.joined += 1
        return True

    def forget(self, system_id: int) -> None:
        self._candidates.pop(system_id, None)
        self._admitted_ids.discard(system_id)

    def reports(self, t_s: float) -> list[dict[str, Any]]:
        """The ``unknown_systems`` lines due at ``t_s`` (see the class docstring)."""
        out: list[dict[str, Any]] = []
        for link, burst in list(self._bursts.items()):
            if t_s - burst.last_s >= self.quiet_s:
                del self._bursts[link]
                if burst.ids:
                    out.append(self._line(link, burst, ongoing=False))
            elif t_s - burst.reported_s >= self.report_every_s and burst.ids:
                out.append(self._line(link, burst, ongoing=True))
                self._bursts[link] = _Burst(t_s, burst.last_s, t_s)
        stale_s = max(self.max_gap_s, self.quiet_s)
        for sysid in [k for k, c in self._candidates.items() if t_s - c.last_s > stale_s]:
            del self._candidates[sysid]
            self._admitted_ids.discard(sysid)
        return out

    def flush(self) -> list[dict[str, Any]]:
        """The lines of every burst still open (the run ends)."""
        out = [self._line(link, b, ongoing=True) for link, b in self._bursts.items() if b.ids]
        self._bursts.clear()
        return out

    def _line(self, link: Hashable, burst: _Burst, *, ongoing: bool) -> dict[str, Any]:
        ids = sorted(burst.ids)
        return {
            "link": link,
            "systems": len(ids),
            "ids": ids[: self.SAMPLE_IDS],
            "heartbeats": burst.heartbeats,
            "rate_limited": len(burst.rate_limited),
            "joined": burst.joined,
            "since_t": round(burst.first_s, 3),
            "ongoing": ongoing,
        }

    def _burst(self, link: Hashable, system_id: int, t_s: float) -> _Burst:
        burst = self._bursts.get(link)
        if burst is None:
            burst = self._bursts[link] = _Burst(t_s, t_s, t_s)
        burst.last_s = t_s
        burst.heartbeats += 1
        if system_id not in self._admitted_ids:
            burst.ids.add(system_id)
        return burst

    def _admit(self, link: Hashable, t_s: float) -> bool:
        times = self._admissions.setdefault(link, deque())
        while times and t_s - times[0] >= self.new_window_s:
            times.popleft()
        if len(times) >= self.max_new_per_link:
            return False
        times.append(t_s)
        return True

    def _confirmed(
        self, system_id: int, place: Hashable, signature: tuple[int, int], seq: int,
        t_s: float,
    ) -> bool:
        cand = self._candidates.get(system_id)
        if cand is not None and cand.place == place and cand.signature == signature:
            if seq == cand.last_seq:
                self.duplicates += 1
                return self._enough(cand)
            if t_s - cand.last_s <= self.max_gap_s:
                cand.count += 1
                cand.last_s = t_s
                cand.last_seq = seq
                return self._enough(cand)
        if cand is not None:
            self.restarts += 1
        self._candidates[system_id] = _Newcomer(place, signature, t_s, t_s, seq)
        return self.min_heartbeats <= 1 and self.min_span_s <= 0.0

    def _enough(self, cand: _Newcomer) -> bool:
        return (
            cand.count >= self.min_heartbeats
            and cand.last_s - cand.first_s >= self.min_span_s - 1e-9
        )


class WindEvidence:
    """The wind estimate of one vehicle that floe uses, from its WIND frames (~1 Hz).

    Fed every *valid* WIND frame (the reducer drops non-finite and absurd ones) as the ENU
    vector and its mission time. The estimate is the component-wise median of the last
    ``window`` frames::

        w = (median_k w_x,k, median_k w_y,k),   k over the last ``window`` frames

    and exists only once they are ``min_frames`` or more spanning at least ``min_span_s``
    (first to last), with no gap longer than ``max_gap_s`` between two of them (a longer
    silence starts again: old values are no evidence for new ones). So one stray frame
    among consistent ones never moves it (it is never the median of three), and a run of
    them does only after they outnumber the vehicle's own; ArduPlane's estimate is a
    filtered one that changes smoothly from frame to frame, so the median costs it one
    frame of lag at most. :meth:`observe` returns the estimate after the frame, or None.
    """

    def __init__(
        self, window: int = 3, min_frames: int = 3, min_span_s: float = 1.5,
        max_gap_s: float = 5.0,
    ) -> None:
        self.min_frames = min_frames
        self.min_span_s = min_span_s
        self.max_gap_s = max_gap_s
        self._frames: deque[tuple[float, float, float]] = deque(maxlen=window)
        self._since_s: float | None = None
        self._count = 0

    def observe(self, wx_m_s: float, wy_m_s: float, t_s: float) -> tuple[float, float] | None:
        frames = self._frames
        if frames and t_s - frames[-1][0] > self.max_gap_s:
            self.reset()
        if self._since_s is None:
            self._since_s = t_s
        frames.append((t_s, wx_m_s, wy_m_s))
        self._count += 1
        if self._count < self.min_frames or t_s - self._since_s < self.min_span_s - 1e-9:
            return None
        return (statistics.median(f[1] for f in frames),
                statistics.median(f[2] for f in frames))

    def reset(self) -> None:
        """Start again (a reboot, a long silence)."""
        self._frames.clear()
        self._since_s = None
        self._count = 0


def is_autopilot_heartbeat(message: Any) -> bool:
    """A HEARTBEAT of a vehicle's autopilot: from component 1 (MAV_COMP_ID_AUTOPILOT1), of a
    type that is not a ground station, naming a real autopilot. The one test every layer
    uses (link binding, new-vehicle evidence, signing setup)."""
    return (
        message.get_type() == "HEARTBEAT"
        and message.get_srcComponent() == mavlink2.MAV_COMP_ID_AUTOPILOT1
        and getattr(message, "type", mavlink2.MAV_TYPE_GCS) != mavlink2.MAV_TYPE_GCS
        and getattr(message, "autopilot", mavlink2.MAV_AUTOPILOT_INVALID)
        != mavlink2.MAV_AUTOPILOT_INVALID
    )
