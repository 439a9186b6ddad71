"""The controller's settings: one frozen dataclass, built from the daemon's configuration
in one place (:func:`groundstation.daemon.config.controller_settings`)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ControllerSettings"]


@dataclass(frozen=True)
class ControllerSettings:
    """Everything one vehicle's controller is told (mission seconds, metres, percent).

    Flying (needed to join or rejoin): armed, ``alt_m > flying_alt_m`` above home,
    groundspeed ``> flying_speed_m_s``, and not MAV_LANDED_STATE_ON_GROUND where the
    autopilot reports a landed state, on ``evidence_frames`` position frames over
    ``evidence_span_s``. The same counts apply to a mode change, a disarm and a landing
    before they take a vehicle out. ``progress_timeout_s``: an active vehicle that gets no
    nearer its aim point by ``progress_min_m`` (and is not loitering within
    ``loiter_radius_m + progress_margin_m`` of it, and advances no mission item) for this
    long leaves the plan. ``restore_settle_s``: after a link restore, how long (and
    ``evidence_frames`` heartbeats) the vehicle is watched before floe commands it again.
    ``wind_report_min_s``: an active vehicle's accepted wind estimate goes to the core at
    most once per this many mission seconds (ArduPlane's 1 Hz WIND, with arrival jitter,
    passes whole; a faster stream is thinned to ~1 Hz), and only after it has been active
    and reporting for ``wind_settle_s`` (an autopilot's wind estimate starts from zero and
    converges in flight: a vehicle just launched or taken over under-reports at first).
    ``speed_m_s``: the configured airspeed (the vehicle's own setting, else the core's),
    planned with only when the vehicle's cruise airspeed parameter cannot be read.

    ``lag_threshold_s``: a vehicle whose newest position is older than this (against its
    own clock) while its frames keep arriving is *lagging* (:mod:`.freshness`): the core is
    given a prediction instead of the stale fix, at most every ``lag_pose_every_s``.

    The ship watch (docs/ship.md): ``battery_report_s`` / ``battery_report_pct``:
    a ``BatteryReport`` goes to the core at most every this many mission seconds, or at once
    when the remaining charge moved by this many points. ``ready_pct``: the watch's
    ``ready_pct`` (None: no watch), the charge a spare on deck needs to be ready, and the
    watch's recovery rule (a vehicle that came down in an RTL and rebooted with this much
    is a fresh spare again). ``launch_on_order``: a watch with ``on_station`` is
    configured, so ``launch`` (``--launch``) launches only what the core's LaunchVehicle
    (or the operator) names, never every vehicle found on the ground.
    """

    altitude_m: float = 100.0
    loiter_radius_m: float | None = None
    speed_m_s: float | None = None
    launch: bool = False
    advisory: bool = False
    lost_after_s: float = 5.0
    override_grace_s: float = 2.0
    battery_low_pct: float = 25.0
    telemetry_rate_hz: float = 2.0
    progress_timeout_s: float = 120.0
    progress_min_m: float = 20.0
    progress_margin_m: float = 60.0
    flying_alt_m: float = 10.0
    flying_speed_m_s: float = 5.0
    evidence_frames: int = 3
    evidence_span_s: float = 2.0
    battery_alone_span_s: float = 20.0
    restore_settle_s: float = 2.0
    rates_every_s: float = 30.0
    retry_pause_s: float = 1.0
    retry_assess_s: float = 5.0
    fence_retry_s: float = 30.0
    """Mission seconds before a geofence that could not be set is tried again."""
    params_snapshot: bool = False
    """Read every parameter once (the run folder's ``.parm``; the daemon sets it)."""
    expect_mode_s: float = 15.0
    launch_timeout_s: float = 180.0
    clock_check_s: float = 30.0
    default_loiter_radius_m: float = 120.0
    wind_report_min_s: float = 0.8
    wind_settle_s: float = 10.0
    battery_report_s: float = 5.0
    battery_report_pct: float = 1.0
    ready_pct: float | None = None
    launch_on_order: bool = False
    lag_threshold_s: float = 2.0
    lag_pose_every_s: float = 1.0
