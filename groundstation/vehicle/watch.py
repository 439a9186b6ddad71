"""What the controller keeps watching about its vehicle, frame by frame (pure).

:class:`Watch` holds the evidence (:mod:`.evidence`) and answers the controller's
questions: does it fly, is it on the ground, has a mode change out of AUTO/GUIDED lasted
(and whose was it), is the battery low, does it make progress to its aim point, does its
clock run at the mission clock's rate. It decides nothing itself.
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass

from domain.modes import TAKEN_MODES, ArduPlaneMode
from groundstation.mavlink.evidence import (
    MAV_STATE_CRITICAL,
    MAV_STATE_EMERGENCY,
    BatteryEvidence,
    Sustained,
)
from groundstation.mavlink.telemetry_events import VehicleSnapshot
from groundstation.vehicle.settings import ControllerSettings

__all__ = ["MAV_LANDED_STATE_ON_GROUND", "ModeChange", "Watch"]

MAV_LANDED_STATE_ON_GROUND = 1
MISSION_STATE_COMPLETE = 5  # MAVLink MISSION_STATE_COMPLETE: every item executed
TEXT_LOOKBACK_S = 3.0
CLOCK_TOLERANCE = 0.2


@dataclass(frozen=True)
class ModeChange:
    """A sustained mode change out of AUTO/GUIDED and what it was: ``kind`` is
    ``battery`` (the autopilot's battery failsafe), ``mission_end`` (its RTL at the end of
    a mission) or ``override`` (an operator's, or a failsafe floe cannot tell from one);
    ``reason`` as journalled; ``evidence`` what decided a battery failsafe or a mission
    end (None for an override: the default needs none)."""

    since_s: float
    mode: int
    name: str
    kind: str
    reason: str
    evidence: str | None = None


class Watch:
    """See the module docstring."""

    def __init__(self, settings: ControllerSettings) -> None:
        self.s = settings
        frames, span = settings.evidence_frames, settings.evidence_span_s
        self.flying = Sustained(frames, span)
        self.grounded = Sustained(frames, span)
        self.taken = Sustained(frames, span)
        self._mode = Sustained(frames, span)
        self._change: tuple[float, int, str] | None = None
        self.battery = BatteryEvidence(
            settings.battery_low_pct, frames, span, settings.battery_alone_span_s
        )
        self.texts: collections.deque[tuple[float, str]] = collections.deque(maxlen=20)
        self.progress: tuple[float, float] | None = None  # (best distance m, since_s)
        self._last_seq: int | None = None
        self._reached: tuple[float, int] | None = None  # the last MISSION_ITEM_REACHED
        self._complete_frames = 0  # MISSION_CURRENTs in a row that said COMPLETE
        self._clock_ref: tuple[float, int] | None = None
        self.clock_checked = False

    # ------------------------------------------------------------------ flight
    def flight(self, s: VehicleSnapshot, t_s: float) -> bool:
        """Feed one HEARTBEAT / position / EXTENDED_SYS_STATE frame; True when being on the
        ground is confirmed (disarmed, the autopilot's landed state, or low and slow)."""
        on_ground_reported = s.landed_state == MAV_LANDED_STATE_ON_GROUND
        fast = s.speed_m_s is not None and s.speed_m_s > self.s.flying_speed_m_s
        high = s.alt_m is not None and s.alt_m > self.s.flying_alt_m
        self.flying.observe(s.armed is True and high and fast and not on_ground_reported, t_s)
        grounded = s.armed is False or on_ground_reported or (
            s.alt_m is not None and not high and not fast
        )
        return self.grounded.observe(grounded, t_s)

    # ------------------------------------------------------------------ modes
    def heartbeat(self, s: VehicleSnapshot, t_s: float, ours: bool, in_hand: bool) -> bool:
        """Feed one HEARTBEAT: the autopilot's failsafe signals, the mode evidence. Returns
        True when a taken mode (AUTO/GUIDED) that is not floe's own has lasted."""
        mode = s.mode
        if s.system_status in (MAV_STATE_CRITICAL, MAV_STATE_EMERGENCY):
            self.battery.autopilot_agrees()
        if mode is None:
            return False
        if mode == ArduPlaneMode.RTL and not ours:
            self.battery.autopilot_agrees()
        taken = mode in TAKEN_MODES
        if in_hand and not taken and not ours:
            if self._change is None or self._change[1] != mode:
                self._change = (t_s, mode, s.mode_name or str(mode))
                self._mode.reset()
            self._mode.observe(True, t_s)
        else:
            self.forget_mode_change()
        return self.taken.observe(taken and not ours, t_s)

    @property
    def mode_change_pending(self) -> bool:
        """A mode out of AUTO/GUIDED that is not floe's was seen while floe had the vehicle,
        and whose it was is not decided yet (:meth:`mode_change`)."""
        return self._change is not None

    def forget_mode_change(self) -> None:
        self._change = None
        self._mode.reset()

    def mode_change(self, s: VehicleSnapshot, t_s: float, active: bool) -> ModeChange | None:
        """A mode change that lasted ``override_grace_s``, attributed on ArduPilot's signals
        (design.md; docs/daemon.md "Whose mode change it was"):

        * **battery failsafe**: RTL with low battery readings, or the autopilot CRITICAL
          and a battery STATUSTEXT;
        * **mission end**: RTL of an active vehicle whose mission really ended
          (:meth:`mission_ended`);
        * anything else is the **operator's** (``reason`` ``failsafe`` when the autopilot
          is CRITICAL or said "failsafe": floe cannot tell such a failsafe from a pilot's
          switch, and treats both alike). Unsure is the operator's.
        """
        change = self._change
        if change is None or not self._mode.confirmed or t_s - change[0] < self.s.override_grace_s:
            return None
        self.forget_mode_change()
        since, mode, name = change
        texts = " | ".join(
            text.lower() for tt, text in self.texts if tt >= since - TEXT_LOOKBACK_S
        )
        critical = s.system_status in (MAV_STATE_CRITICAL, MAV_STATE_EMERGENCY)
        rtl = mode == ArduPlaneMode.RTL
        if rtl and self.battery.low_readings:
            return ModeChange(since, mode, name, "battery", "battery failsafe", "low readings")
        if rtl and critical and "batt" in texts:
            return ModeChange(
                since, mode, name, "battery", "battery failsafe", "CRITICAL and battery text"
            )
        ended = self.mission_ended(s, since)
        if rtl and active and ended is not None:
            return ModeChange(since, mode, name, "mission_end", "mission end", ended)
        reason = "failsafe" if critical or "failsafe" in texts else f"mode {name}"
        return ModeChange(since, mode, name, "override", reason)

    def mission_ended(self, s: VehicleSnapshot, since_s: float) -> str | None:
        """What shows that the autopilot ran off the end of its mission around ``since_s``
        (the mode change), or None. ArduPilot's MISSION_CURRENT counts the items without
        home (item 0): ``total`` is the number of items after home, so the last item has
        ``seq == total`` (MAVLink's definition). Its own end of a mission is one of:

        * its STATUSTEXT "Mission complete" (ArduPlane: "Mission complete, changing mode to
          RTL") within ``TEXT_LOOKBACK_S`` before the change, or after it;
        * MISSION_ITEM_REACHED of the last item (``seq >= total``) in that window;
        * two MISSION_CURRENTs in a row with ``mission_state`` MISSION_STATE_COMPLETE.

        Flying the last item is not its end: floe's missions end in an unlimited loiter,
        which ArduPilot never completes, so an RTL there is somebody's switch. A vehicle that
        reports ``mission_state`` and says anything but COMPLETE (PAUSED after a pilot's
        switch) did not end its mission, whatever the other signals say."""
        if s.mission_state is not None and s.mission_state != MISSION_STATE_COMPLETE:
            return None
        if self._complete_frames >= 2:
            return "mission_state COMPLETE"
        after = since_s - TEXT_LOOKBACK_S
        if any(tt >= after and "mission complete" in text.lower() for tt, text in self.texts):
            return "Mission complete"
        total = s.mission_total
        if self._reached is None or total is None or total < 1:
            return None
        reached_s, seq = self._reached
        if reached_s >= after and seq >= total:
            return f"last item {seq} of {total} reached"
        return None

    # ------------------------------------------------------------------ progress
    def reset_progress(self) -> None:
        self.progress = None

    def mission_current(self, seq: int, state: int | None) -> None:
        """A MISSION_CURRENT frame: an advance to a later item is progress; its
        ``mission_state`` is evidence of a mission's end (:meth:`mission_ended`)."""
        if self._last_seq is not None and seq > self._last_seq:
            self.progress = None
        self._last_seq = seq
        self._complete_frames = self._complete_frames + 1 if state == MISSION_STATE_COMPLETE else 0

    def item_reached(self, seq: int, t_s: float) -> None:
        """A MISSION_ITEM_REACHED (evidence of a mission's end when it is the last item)."""
        self._reached = (t_s, seq)

    def position(self, s: VehicleSnapshot, aim_xy_m: tuple[float, float], near_m: float,
                 t_s: float) -> None:  # fmt: skip
        """A position while flying to ``aim_xy_m``: progress is getting ``progress_min_m``
        nearer than the best so far, or being within ``near_m`` of it (loitering there)."""
        if s.x_m is None or s.y_m is None:
            return
        d = math.hypot(s.x_m - aim_xy_m[0], s.y_m - aim_xy_m[1])
        best = self.progress
        if best is None or d <= near_m or d < best[0] - self.s.progress_min_m:
            self.progress = (d, t_s)

    def stalled(self, t_s: float) -> tuple[float, float] | None:
        """(best distance, since) when no progress was made for ``progress_timeout_s``."""
        p = self.progress
        if p is not None and t_s - p[1] > self.s.progress_timeout_s:
            return p
        return None

    # ------------------------------------------------------------------ clock
    def reset_clock(self) -> None:
        self._clock_ref = None

    def clock(self, s: VehicleSnapshot, t_s: float) -> tuple[float, bool] | None:
        """Once, after ``clock_check_s``: (vehicle s per mission s, within 20 %). The mission
        clock must run at the rate of the vehicle's ``time_boot_ms`` (design.md)."""
        boot_ms = s.time_boot_ms
        if boot_ms is None or self.clock_checked:
            return None
        if self._clock_ref is None or boot_ms < self._clock_ref[1]:
            self._clock_ref = (t_s, boot_ms)
            return None
        dt = t_s - self._clock_ref[0]
        if dt < self.s.clock_check_s:
            return None
        ratio = (boot_ms - self._clock_ref[1]) / 1000.0 / dt
        self.clock_checked = True
        return ratio, abs(ratio - 1.0) <= CLOCK_TOLERANCE
