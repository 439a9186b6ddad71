"""Sans-IO: how old a vehicle's telemetry is, measured against the vehicle's own clock.

Every frame of the autopilot that carries ``time_boot_ms`` (the autopilot's clock, ms since
it booted) is a sample: the vehicle's time ``b = time_boot_ms / 1000`` and the mission time
``t`` at which floe applied it. Its *offset* is ``o = t - b``. The vehicle's clock runs at
the mission clock's rate (the controller's clock check says so, within 20 %), so the offset
of a frame is a constant (where the two clocks start) plus the delay the frame took to reach
floe. The least delay is the freshest frame: as NTP does, the estimator keeps the **lowest
offset seen** as the baseline, and a frame's age is its offset above it:

    baseline(t) = min over accepted samples i of [o_i + creep_s_per_s * (t - t_i)]
    age(b, t)   = t - (b + baseline(t)) + nominal_latency_s      (never below 0)

``creep_s_per_s`` (1 % by default) lets the baseline follow clocks that drift apart (a
crystal's 0.01 %, a simulator that runs slightly slower than its speed-up): a lag of A s
is still seen as ``A - creep * (time since the last fresh frame)``.

Guards, so that neither a stale backlog nor one forged frame can move the baseline:

* A frame *older* than the baseline (a backlog) only measures its own age; it never raises
  the baseline (only the creep does, slowly).
* A frame *fresher* than the baseline by more than ``tolerance_s`` (jitter) lowers it only
  when ``corroborate_frames`` frames (the first included), whose offsets agree within
  ``tolerance_s``, span ``corroborate_span_s`` of mission time: a link that was lagging when
  floe first heard it is corrected within about a second, a single forged large
  ``time_boot_ms`` changes nothing (its frame is judged fresh, age 0, and forgotten as
  soon as a frame keeps to the baseline).
  Smaller improvements (within the jitter) lower it at once.
* A **reboot** (the reducer's ``Rebooted``: the clock restarted) or a new session:
  :meth:`reset`; the next frame starts a new baseline.
* A **trend that stays**: when for ``resync_after_s`` of mission time frames kept arriving
  regularly (no gap over ``regular_gap_s``) with offsets on one straight line (within
  ``tolerance_s``) above the baseline, level or rising, that is the clock, not a backlog:
  a step (a reboot during a silence longer than the previous uptime, which the reducer
  cannot see) or a vehicle clock slower than the mission clock (a simulator that cannot
  keep its speed-up, a wrong ``--speedup``). The baseline follows it and the creep takes
  its slope. A flood holds the vehicle's frames back (gaps), a drain brings them faster
  than they were made (falling offsets): neither resyncs. A lag that stays level, or grows
  steadily while frames keep arriving regularly, for that long is forgotten.

No clock is read and nothing raises: times are given by the caller, in mission seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["TelemetryAge", "TelemetryAgeSettings"]


@dataclass(frozen=True)
class TelemetryAgeSettings:
    """The estimator's rules (see the module docstring); mission seconds."""

    creep_s_per_s: float = 0.01
    tolerance_s: float = 0.5
    corroborate_frames: int = 3
    corroborate_span_s: float = 1.0
    resync_after_s: float = 30.0
    regular_gap_s: float = 2.0
    nominal_latency_s: float = 0.0


class TelemetryAge:
    """One vehicle's clock offset and the age of its frames (see the module docstring)."""

    def __init__(self, settings: TelemetryAgeSettings | None = None) -> None:
        self.s = settings or TelemetryAgeSettings()
        self._base_offset_s: float | None = None
        self._base_t_s = 0.0
        self._candidates: list[tuple[float, float]] = []  # (t_s, offset_s) fresher than base
        self._step: tuple[float, float, float, float] | None = None
        """A trend of offsets: (first t_s, its offset, last t_s, its offset)."""
        self.creep_s_per_s = self.s.creep_s_per_s
        """The creep in use: the setting's, or a trend's slope (a slower vehicle clock)."""
        self.samples = 0
        self.resyncs = 0
        """Times the baseline followed a trend that stayed (``resync_after_s``)."""

    @property
    def known(self) -> bool:
        """Whether a baseline exists (a frame with the vehicle's clock was seen)."""
        return self._base_offset_s is not None

    def reset(self) -> None:
        """Forget the baseline: the vehicle's clock restarted (a reboot)."""
        self._base_offset_s = None
        self._candidates.clear()
        self._step = None

    def baseline_s(self, t_s: float) -> float | None:
        """The freshest offset (mission s minus vehicle s) as of ``t_s``, with the creep."""
        base = self._base_offset_s
        if base is None:
            return None
        return base + self.creep_s_per_s * max(0.0, t_s - self._base_t_s)

    def produced_s(self, boot_ms: int, t_s: float) -> float | None:
        """The mission time at which the vehicle made a frame stamped ``boot_ms`` (the
        freshest frames reach floe at once), as of ``t_s``; None without a baseline."""
        base = self.baseline_s(t_s)
        return None if base is None else boot_ms / 1000.0 + base

    def age_s(self, boot_ms: int, now_s: float) -> float | None:
        """How old, at ``now_s``, the vehicle's state stamped ``boot_ms`` is (>= 0)."""
        produced = self.produced_s(boot_ms, now_s)
        if produced is None:
            return None
        return max(0.0, now_s - produced + self.s.nominal_latency_s)

    def observe(self, boot_ms: int, t_s: float) -> float | None:
        """A frame stamped ``boot_ms`` applied at ``t_s``: update the baseline; the
        frame's age then (None if ``boot_ms`` is not a clock reading)."""
        if isinstance(boot_ms, bool) or not isinstance(boot_ms, int) or boot_ms < 0:
            return None
        offset = t_s - boot_ms / 1000.0
        if not math.isfinite(offset):
            return None
        self.samples += 1
        base = self.baseline_s(t_s)
        tol = self.s.tolerance_s
        if base is None:
            self._set_base(offset, t_s)
        elif offset < base - tol:
            self._fresher(offset, t_s)
        else:
            if offset < base:
                self._set_base(offset, t_s)
            else:
                self._watch_step(offset, base, t_s)
        return self.age_s(boot_ms, t_s)

    # ------------------------------------------------------------------ internals
    def _set_base(self, offset: float, t_s: float) -> None:
        self._base_offset_s, self._base_t_s = offset, t_s
        self._candidates.clear()
        self._step = None

    def _fresher(self, offset: float, t_s: float) -> None:
        """A frame fresher than the baseline by more than the jitter: corroborated or not."""
        tol = self.s.tolerance_s
        kept = [(t, o) for t, o in self._candidates if abs(o - offset) <= tol]
        kept.append((t_s, offset))
        self._candidates = kept
        span = kept[-1][0] - kept[0][0]
        if len(kept) >= self.s.corroborate_frames and span >= self.s.corroborate_span_s - 1e-9:
            self._set_base(min(o for _, o in kept), t_s)

    def _watch_step(self, offset: float, base: float, t_s: float) -> None:
        """A frame at or above the baseline: part of a trend that stays, or not. A trend
        is a run of frames arriving regularly (no gap over ``regular_gap_s``) whose offsets
        keep to one straight line (within ``tolerance_s``): level (a clock step) or rising
        (a clock slower than the mission clock). Held for ``resync_after_s`` it is the
        clock, not a backlog: the baseline follows it, and the creep takes its slope."""
        tol = self.s.tolerance_s
        if offset - base <= tol:
            self._step = None  # keeps to the baseline: no trend, and no fresher claim stands
            self._candidates.clear()
            return
        step = self._step
        if step is not None:
            t0, o0, t_prev, o_prev = step
            slope = (o_prev - o0) / (t_prev - t0) if t_prev > t0 else 0.0
            on_line = abs(offset - (o0 + slope * (t_s - t0))) <= tol
            if t_s - t_prev <= self.s.regular_gap_s and on_line and slope >= -1e-9:
                self._step = (t0, o0, t_s, offset)
                if t_s - t0 >= self.s.resync_after_s:
                    self.resyncs += 1
                    self.creep_s_per_s = max(self.creep_s_per_s, slope)
                    self._set_base(offset, t_s)
                return
        self._step = (t_s, offset, t_s, offset)
