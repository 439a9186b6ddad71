"""The controller's multi-step exchanges, written as generators.

A job yields exchange requests (:data:`~groundstation.vehicle.controller_io.Exchange`) or a
:class:`Pause` and is sent each request's result; it returns when done. Jobs hold no I/O and
read no clock: the controller steps them as results and ticks come in. Every job here
works on a :class:`JobHost` (the controller) for the state it reads and changes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import Any, Protocol

from domain.modes import ArduPlaneMode
from groundstation.core.mission import target_mission
from groundstation.mavlink.codec import mavlink2
from groundstation.mavlink.fence_items import (
    FENCE_ACTION_REPORT_ONLY,
    FENCE_ACTION_RTL,
    FENCE_TYPE_POLYGON,
    FenceCircle,
)
from groundstation.mavlink.mission_items import (
    LoiterTime,
    LoiterUnlimited,
    MissionStep,
    Takeoff,
    Waypoint,
)
from groundstation.vehicle.controller_io import (
    Arm,
    Download,
    Exchange,
    FenceParam,
    Fly,
    HomeOutcome,
    MoveHome,
    ReadAllParams,
    ReadParam,
    SetCurrent,
    SetMode,
    SetParam,
    UploadFence,
    UploadMission,
    UploadOutcome,
)

__all__ = [
    "CRUISE_MAX_M_S",
    "CRUISE_MIN_M_S",
    "CRUISE_PARAMS",
    "Job",
    "JobHost",
    "JobRunner",
    "Pause",
    "cruise_job",
    "fence_job",
    "home_job",
    "launch_job",
    "params_job",
    "park_job",
    "set_home_job",
    "target_job",
]

M = mavlink2
LAUNCH_AHEAD_M = 400.0
CRUISE_PARAMS: tuple[tuple[str, float], ...] = (
    ("AIRSPEED_CRUISE", 1.0),  # ArduPlane 4.5 and later: m/s
    ("TRIM_ARSPD_CM", 0.01),  # before 4.5: cm/s
)
"""The parameters that hold ArduPlane's cruise airspeed, in the order asked, and the factor
to m/s."""
CRUISE_MIN_M_S = 5.0
CRUISE_MAX_M_S = 100.0
"""A cruise airspeed read outside [min, max] m/s is not believed (``domain.limits``'
MAX_SPEED_M_S; no fixed-wing UAV cruises below 5 m/s)."""


@dataclass(frozen=True)
class Pause:
    """Resume the job no earlier than ``until_s`` (mission time)."""

    until_s: float


Job = Generator[Exchange | Pause, Any, Any]


class JobHost(Protocol):
    """What jobs read and change on the controller."""

    t_s: float
    alt_m: float
    wp_loiter_rad_m: float | None
    retry_pause_s: float

    def mission_seq(self) -> int | None: ...
    def mode(self) -> int | None: ...
    def position(self) -> tuple[float, float, float]: ...
    def loiter_radius_m(self, fallback_m: float | None = None) -> float: ...
    def journal(self, event: str, **fields: Any) -> None: ...
    def count_retries(self, retries: int) -> None: ...
    def upload_done(self, ok: bool, took_s: float | None) -> None: ...
    def expect_mode(self, mode: int) -> None: ...
    def arm_loiter_end(self, seq: int) -> None: ...
    def disarm_loiter_end(self) -> None: ...
    def joined(self, how: str) -> None: ...
    def park_failed(self) -> None: ...
    def launch_failed(self) -> None: ...
    def launched(self) -> None: ...
    def target_verified(self, fly: Fly) -> bool: ...
    def target_failed(self, fly: Fly) -> bool: ...
    def target_wanted(self) -> bool: ...
    def home_done(self, ok: bool) -> None: ...
    def cruise_known(self, speed_m_s: float | None, source: str) -> None: ...
    def home_moved(self, x_m: float, y_m: float, outcome: HomeOutcome) -> None: ...
    def fence_done(self, fence: FenceCircle, ok: bool) -> None: ...
    def params_read(self, values: dict[str, float] | None) -> None: ...


def mission_job(
    host: JobHost, steps: list[MissionStep], current: int | None, purpose: str,
    target: str | None = None, end_seq: int | None = None,
) -> Generator[Exchange | Pause, Any, bool]:
    """Upload ``steps`` verified; then set ``current`` and make sure of AUTO.

    The loiter end of a target mission (item ``end_seq``, by default ``current``: the
    last item a route flies through) is watched from the verified upload on. The
    set-current machine itself confirms a waypoint passed at once (MISSION_ITEM_REACHED of
    it after its ACK); its result decides, on its code, never on its message."""
    host.disarm_loiter_end()
    up: UploadOutcome = yield UploadMission(tuple(steps), purpose, target)
    ok, retries, error = up.ok, up.retries, up.error or ""
    if ok and current is not None:
        result = yield SetCurrent(current, host.mission_seq())
        retries += result.retries_used
        ok = result.ok
        error = "" if ok else f"set current {result.code.value}: {result.message}"
        if ok and purpose == "target":
            host.arm_loiter_end(current if end_seq is None else end_seq)
        if ok and host.mode() != ArduPlaneMode.AUTO:
            host.expect_mode(ArduPlaneMode.AUTO)
            answer = yield SetMode(ArduPlaneMode.AUTO)
            ok = answer == M.MAV_RESULT_ACCEPTED
            error = "" if ok else "mode AUTO refused"
        if not ok:
            host.disarm_loiter_end()
    host.count_retries(retries)
    host.upload_done(ok, up.took_s)
    host.journal(
        "upload", ok=ok, purpose=purpose, target=target, retries=retries, items=up.items,
        error=error or None, took_s=None if up.took_s is None else round(up.took_s, 3),
    )  # fmt: skip
    return ok


def park_job(host: JobHost) -> Job:
    """Join a vehicle flying in AUTO: at once if it holds an unlimited loiter as the last
    item of its mission, else park it on one where it is."""
    result = yield Download("park")
    items = result.items or ()
    seq = host.mission_seq()
    if (
        result.ok
        and seq is not None
        and 0 < seq < len(items)
        and items[seq].command == M.MAV_CMD_NAV_LOITER_UNLIM
        and seq == len(items) - 1
    ):
        host.joined("holding")
        return
    x_m, y_m, _ = host.position()
    steps: list[MissionStep] = [LoiterUnlimited(x_m, y_m, host.alt_m, host.loiter_radius_m())]
    ok = yield from mission_job(host, steps, 1, "park")
    if ok:
        host.joined("parked")
    else:
        host.park_failed()


def launch_job(host: JobHost, heading_rad: float) -> Job:
    """Upload [home, takeoff, unlimited loiter ahead], verified; arm; item 1; AUTO."""
    x0, y0, _ = host.position()
    steps: list[MissionStep] = [
        Takeoff(host.alt_m),
        LoiterUnlimited(
            x0 + LAUNCH_AHEAD_M * math.cos(heading_rad),
            y0 + LAUNCH_AHEAD_M * math.sin(heading_rad),
            host.alt_m,
            host.loiter_radius_m(),
        ),
    ]
    ok = yield from mission_job(host, steps, None, "takeoff")
    if ok:
        answer = yield Arm()
        ok = answer == M.MAV_RESULT_ACCEPTED
        if not ok:
            host.journal("arm", ok=False, result=answer)
    if ok:
        yield SetCurrent(1, host.mission_seq())
        host.expect_mode(ArduPlaneMode.AUTO)
        answer = yield SetMode(ArduPlaneMode.AUTO)
        ok = answer == M.MAV_RESULT_ACCEPTED
    if ok:
        host.launched()
    else:
        host.launch_failed()


def target_job(host: JobHost, fly: Fly) -> Job:
    """Fly to a target: [timed loiter (or a waypoint for a pass) at the aim point, a
    waypoint per point the pass flies through, unlimited loiter at the last point]
    (``core/mission.py``), WP_LOITER_RAD set first; retried until verified, or overtaken.
    The loiter end watched is the last item before the unlimited loiter."""
    command = fly.command
    radius = host.loiter_radius_m(command.loiter_radius_m)
    mission = target_mission(command, (fly.x_m, fly.y_m), radius)
    first: MissionStep
    if not mission.pass_over:
        first = LoiterTime(fly.x_m, fly.y_m, host.alt_m, mission.loiter_s)
        if host.wp_loiter_rad_m != radius:
            if (yield SetParam("WP_LOITER_RAD", radius)):
                host.wp_loiter_rad_m = radius
            else:
                host.journal("param_set", ok=False, name="WP_LOITER_RAD", value=radius)
    else:
        first = Waypoint(fly.x_m, fly.y_m, host.alt_m)
    steps: list[MissionStep] = [first]
    # a routing core sends a pass always route_cells points (the last one repeated), so
    # the mission's length never changes between uploads (core/route.py)
    steps += [Waypoint(x_m, y_m, host.alt_m) for x_m, y_m in mission.through]
    steps.append(LoiterUnlimited(*mission.end_xy_m, host.alt_m, radius))
    while True:
        ok = yield from mission_job(host, steps, 1, "target", command.target,
                                    end_seq=len(steps) - 1)
        if ok:
            host.target_verified(fly)
            return
        if not host.target_failed(fly):
            return
        yield Pause(host.t_s + host.retry_pause_s)
        if not host.target_wanted():  # overtaken while it paused: the newer one goes next
            return


def cruise_job(host: JobHost) -> Job:
    """Read the vehicle's cruise airspeed: ``AIRSPEED_CRUISE`` (m/s), else ``TRIM_ARSPD_CM``
    (cm/s, firmware before 4.5), each by name (the driver retries a silence a bounded number
    of times; ArduPilot does not answer a name it lacks). The first believable answer is
    the speed floe plans the vehicle with (``host.cruise_known(speed, name)``); with none,
    ``host.cruise_known(None, "config")``: the configured speed. A value outside
    [CRUISE_MIN_M_S, CRUISE_MAX_M_S] is journalled (``cruise_speed_refused``) and the next
    parameter asked."""
    for name, to_m_s in CRUISE_PARAMS:
        value = yield ReadParam(name)
        if value is None:
            continue
        speed_m_s = value * to_m_s
        if CRUISE_MIN_M_S <= speed_m_s <= CRUISE_MAX_M_S:
            host.cruise_known(speed_m_s, name)
            return
        host.journal("cruise_speed_refused", name=name, value=value)
    host.cruise_known(None, "config")


def home_job(host: JobHost) -> Job:
    """RTL, to the home the vehicle has now. ArduPlane fixes an RTL's target when the mode
    is entered and ignores a switch to the mode it is in, so a vehicle floe already sent
    home (a return re-aimed at where the ship will be, its home just moved) leaves RTL for
    LOITER and enters it again."""
    if host.mode() == ArduPlaneMode.RTL:
        host.expect_mode(ArduPlaneMode.LOITER)
        answer = yield SetMode(ArduPlaneMode.LOITER)
        if answer != M.MAV_RESULT_ACCEPTED:
            host.home_done(False)
            yield Pause(host.t_s + host.retry_pause_s)
            return
    host.expect_mode(ArduPlaneMode.RTL)
    answer = yield SetMode(ArduPlaneMode.RTL)
    ok = answer == M.MAV_RESULT_ACCEPTED
    host.home_done(ok)
    if not ok:
        yield Pause(host.t_s + host.retry_pause_s)


def set_home_job(host: JobHost, x_m: float, y_m: float) -> Job:
    """Move the vehicle's home to (x_m, y_m): one DO_SET_HOME, verified by the HOME_POSITION
    that follows (the driver resends on silence, a bounded number of times). It changes no
    mode and no mission; ``host.home_moved`` journals the outcome."""
    outcome = yield MoveHome(x_m, y_m)
    if not isinstance(outcome, HomeOutcome):  # the exchange ended without an answer
        outcome = HomeOutcome(False, error="no answer")
    host.home_moved(x_m, y_m, outcome)


def fence_job(host: JobHost, fence: FenceCircle) -> Job:
    """Give the vehicle ``fence`` and enable it, as ArduPlane expects (``fence_items.py``):

    1. ``FENCE_TYPE`` read; bit 2 (4: the inclusion/exclusion items) added when missing,
       the other bits (altitude, home circle) kept;
    2. ``FENCE_ACTION`` read; 0 (report only) becomes 1 (RTL), any other kept (the
       operator's GUIDED to the return point stays);
    3. the fence items uploaded (mission type FENCE) and read back until they match;
    4. ``FENCE_ENABLE`` = 1 (PARAM_SET, confirmed by its PARAM_VALUE echo; a parameter, so
       the fence stays enabled through a reboot).

    Each step must succeed for the next; ``host.fence_done(fence, ok)`` journals the
    outcome. Parameters are read before they are set, so nothing the vehicle already has
    right is written."""
    ok = True
    error = ""
    fence_type = yield ReadParam("FENCE_TYPE")
    if fence_type is None:
        ok, error = False, "FENCE_TYPE not read"
    elif not int(fence_type) & FENCE_TYPE_POLYGON:
        ok = bool((yield FenceParam("FENCE_TYPE", float(int(fence_type) | FENCE_TYPE_POLYGON))))
        error = "" if ok else "FENCE_TYPE not set"
    if ok:
        action = yield ReadParam("FENCE_ACTION")
        if action is None:
            ok, error = False, "FENCE_ACTION not read"
        elif int(action) == FENCE_ACTION_REPORT_ONLY:
            ok = bool((yield FenceParam("FENCE_ACTION", float(FENCE_ACTION_RTL))))
            error = "" if ok else "FENCE_ACTION not set"
    retries = 0
    if ok:
        up: UploadOutcome = yield UploadFence(fence)
        ok, retries = up.ok, up.retries
        error = "" if ok else f"fence upload: {up.error}"
    if ok:
        ok = bool((yield FenceParam("FENCE_ENABLE", 1.0)))
        error = "" if ok else "FENCE_ENABLE not set"
    host.count_retries(retries)
    host.journal("fence", ok=ok, x_m=round(fence.x_m, 1), y_m=round(fence.y_m, 1),
                 radius_m=fence.radius_m, retries=retries, error=error or None)
    host.fence_done(fence, ok)


def params_job(host: JobHost) -> Job:
    """Read every parameter once (the ``.parm`` snapshot): ``host.params_read(values)``
    with all of them, or None when the download did not complete (journalled)."""
    answer = yield ReadAllParams()
    values, result = answer if isinstance(answer, tuple) else ({}, None)
    ok = result is not None and result.ok
    host.journal("params_snapshot", ok=ok, count=len(values),
                 error=None if ok or result is None else result.message)
    host.params_read(values if ok else None)


class JobRunner:
    """Steps one job, with at most one exchange outstanding.

    ``hold(request)`` is asked first: while it says True the request waits (held, the job
    paused; e.g. while a reboot is suspected and not yet confirmed or cleared). Then
    ``guard(request)``; a refused request ends the job (``on_refused(request)``). A result
    that comes back for an aborted job's exchange only frees the runner."""

    def __init__(
        self,
        guard: Callable[[Exchange], bool],
        on_refused: Callable[[Exchange], None],
        hold: Callable[[Exchange], bool] | None = None,
    ) -> None:
        self.guard = guard
        self.on_refused = on_refused
        self.hold = hold
        self.job: Job | None = None
        self.running: Exchange | None = None
        self.held: Exchange | None = None
        self.pause_until_s: float | None = None

    @property
    def busy(self) -> bool:
        return self.job is not None or self.running is not None

    def start(self, job: Job) -> None:
        self.abort()
        self.job = job

    def abort(self) -> bool:
        """End the job; True if one of its exchanges is still running."""
        if self.job is not None:
            self.job.close()
            self.job = None
        self.pause_until_s = None
        self.held = None
        return self.running is not None

    def wants(self, request: Exchange) -> bool:
        """Whether ``request`` is still the live job's running exchange (an aborted job's
        exchange, queued or between retries, is not: its driver stops it)."""
        return self.job is not None and self.running is request

    def ready(self, t_s: float) -> bool:
        if self.job is None or self.running is not None:
            return False
        if self.held is not None:
            return self.hold is None or not self.hold(self.held)
        return self.pause_until_s is None or t_s >= self.pause_until_s

    def step(self, value: Any = None) -> Exchange | None:
        """Resume the job with ``value`` (or release the held request); the exchange to
        send, if any."""
        job = self.job
        assert job is not None
        if self.held is not None:
            request: Exchange | Pause = self.held
            self.held = None
        else:
            self.pause_until_s = None
            try:
                request = job.send(value)
            except StopIteration:
                self.job = None
                return None
        if isinstance(request, Pause):
            self.pause_until_s = request.until_s
            return None
        if self.hold is not None and self.hold(request):
            self.held = request
            return None
        if not self.guard(request):
            self.job = None
            job.close()
            self.on_refused(request)
            return None
        self.running = request
        return request

    def done(self, request: Exchange, result: Any, stopping: bool) -> Exchange | None:
        """The result of ``request``: step the job on (the next exchange, if any)."""
        if request is not self.running:
            return None
        self.running = None
        if self.job is None:
            return None
        if stopping:
            self.abort()
            return None
        return self.step(result)
