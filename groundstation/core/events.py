"""Inputs of the decision core.

Every event carries the mission time ``t_s`` at which it happened. Frontends (the daemon,
the offline runner, replay) translate what they observe into these plain values; the core
never sees a socket, a clock or a MAVLink message.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from planner import PlanResult

__all__ = [
    "BatteryLow",
    "BatteryReport",
    "BoatPosition",
    "CameraFrame",
    "Detection",
    "Event",
    "LoiterEnded",
    "OperatorOverride",
    "OperatorResume",
    "PlanSolved",
    "TargetAdded",
    "TargetFixed",
    "TargetRemoved",
    "Telemetry",
    "Tick",
    "VehicleJoined",
    "VehicleLanded",
    "VehicleLost",
    "VehicleOnDeck",
    "VehicleRebooted",
    "VehicleReturned",
    "WindReport",
    "WindWithdrawn",
]


@dataclass(frozen=True)
class Tick:
    """Time passes (drives periodic replanning and the observer's prediction)."""

    t_s: float


@dataclass(frozen=True, init=False)
class Telemetry:
    """A vehicle's planar pose and airspeed (local ENU, heading CCW from east).

    ``fix_age_s``: None for a fix (fresh telemetry); for a vehicle whose telemetry lags,
    the age of the fix this pose was predicted from, with ``sigma_m`` its uncertainty
    (``groundstation/vehicle/freshness.py``). Journals written before have neither.

    The commonest input (one per vehicle and tick: 6 000 in a 3-UAV paper-boat run), so
    its ``__init__`` is written out: it fills the instance's ``__dict__`` at once, where
    the one a frozen dataclass generates sets each field through ``object.__setattr__``
    (0.6 us against 1.3 us). The value is the same (fields, defaults, equality, hash,
    repr) and as frozen: assigning a field raises ``FrozenInstanceError``
    (tests/test_core_fast_paths.py checks it against the generated one)."""

    t_s: float
    vehicle: str
    x_m: float
    y_m: float
    heading_rad: float
    speed_m_s: float
    fix_age_s: float | None = None
    sigma_m: float | None = None

    def __init__(self, t_s: float, vehicle: str, x_m: float, y_m: float, heading_rad: float,
                 speed_m_s: float, fix_age_s: float | None = None,
                 sigma_m: float | None = None) -> None:
        self.__dict__.update(t_s=t_s, vehicle=vehicle, x_m=x_m, y_m=y_m,
                             heading_rad=heading_rad, speed_m_s=speed_m_s,
                             fix_age_s=fix_age_s, sigma_m=sigma_m)


@dataclass(frozen=True)
class CameraFrame:
    """A vehicle's camera took a frame whose footprint is the disc of ``radius_m`` around
    (x_m, y_m): the icebergs inside it could have been seen (evidence of absence for the
    tracks inside it that no detection of the frame confirms; search cells inside it are
    covered). The frame's detections carry the same ``t_s`` and ``vehicle``."""

    t_s: float
    vehicle: str
    x_m: float
    y_m: float
    radius_m: float


@dataclass(frozen=True)
class Detection:
    """A camera measurement of a target's position (``target`` None: an unlabelled
    detection, buffered with the other detections of its frame (same ``t_s`` and
    ``vehicle``) and handed to the tracker as one scan at the next ``Tick``)."""

    t_s: float
    vehicle: str | None
    target: str | None
    x_m: float
    y_m: float
    r_m2: float | None = None


class PriorListing(Protocol):
    """What announcing a listed iceberg needs (``world.discovery_spec.PriorEntry`` has it)."""

    @property
    def id(self) -> str: ...
    @property
    def x_m(self) -> float: ...
    @property
    def y_m(self) -> float: ...
    @property
    def variance_m2(self) -> float: ...


@dataclass(frozen=True)
class TargetAdded:
    """A target the ground station must keep track of from now on."""

    t_s: float
    target: str
    x_m: float
    y_m: float
    vx_m_s: float = 0.0
    vy_m_s: float = 0.0
    sigma0: float | None = None
    q_per_s: float | None = None
    prior: bool = False
    """A listed, unverified iceberg (e.g. a satellite pass): tracked and planned, deleted
    when a camera looks where it should be and does not see it."""

    @classmethod
    def listed(cls, t_s: float, entry: PriorListing) -> TargetAdded:
        """A prior listing announced at ``t_s``: at its position, velocity 0, ``sigma0 =
        2 variance_m2`` (``variance_m2`` per axis, e.g. ``world``'s ``PriorEntry``)."""
        return cls(t_s, entry.id, entry.x_m, entry.y_m, sigma0=2.0 * entry.variance_m2,
                   prior=True)


@dataclass(frozen=True)
class TargetFixed:
    """An operator's fix: ``target`` is at (x_m, y_m) now, with position uncertainty
    ``sigma0`` (m^2, the trace of the position covariance). Not a measurement: it is not
    gated; the track is re-seated there (it keeps its velocity estimate) and confirmed."""

    t_s: float
    target: str
    x_m: float
    y_m: float
    sigma0: float


@dataclass(frozen=True)
class TargetRemoved:
    t_s: float
    target: str


@dataclass(frozen=True)
class LoiterEnded:
    """A vehicle finished the timed loiter (or the pass) over its target."""

    t_s: float
    vehicle: str


@dataclass(frozen=True)
class VehicleJoined:
    """A vehicle is flying and available to the plan (launched or taken over)."""

    t_s: float
    vehicle: str
    x_m: float
    y_m: float
    heading_rad: float
    speed_m_s: float


@dataclass(frozen=True)
class VehicleLost:
    """The link to a vehicle has been silent for too long; it leaves the plan."""

    t_s: float
    vehicle: str


@dataclass(frozen=True)
class VehicleReturned:
    """A lost vehicle is heard again and is taken back into the plan."""

    t_s: float
    vehicle: str


@dataclass(frozen=True)
class VehicleRebooted:
    """A vehicle's autopilot rebooted: its stored mission is gone."""

    t_s: float
    vehicle: str


@dataclass(frozen=True)
class OperatorOverride:
    """Someone else took the vehicle (mode switch, another GCS's upload): stop commanding."""

    t_s: float
    vehicle: str


@dataclass(frozen=True)
class OperatorResume:
    """An operator gave the vehicle back to floe."""

    t_s: float
    vehicle: str


@dataclass(frozen=True)
class BatteryLow:
    t_s: float
    vehicle: str


@dataclass(frozen=True)
class BoatPosition:
    """A fix of the ship (the paper's boat): where it is, and where known its velocity over
    ground and heading. It drives the priority knob (process noise rising near the boat)
    and the ship's track (``core/ship.py``), which predicts the ship between fixes: homes
    move with it, returns are planned to it.

    ``vx_m_s, vy_m_s``: velocity over ground (ENU m/s; NMEA RMC/VTG course and speed), None
    when the source does not say. ``heading_rad``: the bow's heading (CCW from east; NMEA
    HDT), None when unknown. ``sigma_m``: the fix's 1-sigma horizontal error (m), None for
    the source's default. ``source``: where the fix came from (``scenario``, ``feed``,
    ``nmea``). Journals written before these fields existed read with them all None."""

    t_s: float
    x_m: float
    y_m: float
    vx_m_s: float | None = None
    vy_m_s: float | None = None
    heading_rad: float | None = None
    sigma_m: float | None = None
    source: str = ""


@dataclass(frozen=True)
class BatteryReport:
    """A vehicle's battery as its autopilot reports it (``BATTERY_STATUS``/``SYS_STATUS``;
    the simulators' battery model): ``remaining_pct`` 0-100, ``current_a``, ``voltage_v``;
    None where the vehicle reports nothing (ArduPilot's -1 / UINT16_MAX). Frontends send one
    at most every few seconds, or when the remaining charge moved by a percent: the core's
    energy model (``core/energy.py``) learns the vehicle's consumption from them."""

    t_s: float
    vehicle: str
    remaining_pct: float | None
    current_a: float | None = None
    voltage_v: float | None = None


@dataclass(frozen=True)
class VehicleOnDeck:
    """A vehicle stands on the ship, disarmed: a spare. ``ready`` when it may be launched
    (a fresh boot and a full battery, ``battery_pct``); a recovered vehicle waiting for
    its battery swap is on deck but not ready. Frontends send it when it changes."""

    t_s: float
    vehicle: str
    ready: bool
    battery_pct: float | None = None


@dataclass(frozen=True)
class VehicleLanded:
    """A vehicle that flew is on the ground (landed, recovered, or fell) at (x_m, y_m).
    The core calls it recovered when it came down within the watch's recovery radius of
    the ship's predicted position (``WatchConfig.recovery_radius_m``), else down."""

    t_s: float
    vehicle: str
    x_m: float
    y_m: float


@dataclass(frozen=True)
class PlanSolved:
    """The frontend finished solving the request ``request_id``."""

    t_s: float
    request_id: int
    result: PlanResult


@dataclass(frozen=True)
class WindReport:
    """One vehicle's own wind estimate (its autopilot's WIND message, accepted on the
    telemetry reducer's evidence): the ENU vector the air moves *towards*, m/s
    (``domain.wind_triangle.wind_vector_m_s``)."""

    t_s: float
    vehicle: str
    wx_m_s: float
    wy_m_s: float


@dataclass(frozen=True)
class WindWithdrawn:
    """A vehicle's wind estimate is not to be believed any more (its autopilot disabled a
    failed airspeed sensor, ``reason``): its reports so far are forgotten at once, so the
    fleet's estimate no longer counts them; its next ``WindReport`` counts again."""

    t_s: float
    vehicle: str
    reason: str


Event = (
    Tick
    | Telemetry
    | Detection
    | CameraFrame
    | TargetAdded
    | TargetFixed
    | TargetRemoved
    | LoiterEnded
    | VehicleJoined
    | VehicleLost
    | VehicleReturned
    | VehicleRebooted
    | OperatorOverride
    | OperatorResume
    | BatteryLow
    | BatteryReport
    | BoatPosition
    | VehicleOnDeck
    | VehicleLanded
    | PlanSolved
    | WindReport
    | WindWithdrawn
)
