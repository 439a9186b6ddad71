"""The controller's typed inputs and outputs.

In: :class:`AutopilotFrame` (one message from the vehicle's autopilot, reduced),
:class:`TimePassed` (the daemon's tick: silence, progress, deadlines), :class:`ExchangeDone`
(the result of the exchange the controller asked for), :class:`Fly` / :class:`Release`
(the decision core's commands), :class:`NewHome` (its SetHome), :class:`LaunchWanted` (its
LaunchVehicle), :class:`ForeignFrame` (a frame of another component,
counted) and :class:`Stop`. Operator requests (launch, resume, override) are the
controller's methods of those names.

The exchange requests are named verb first (``SetCurrent``, ``SetParam``...); the
``groundstation.mavlink`` machines that carry them out are named after the protocol
(``MissionSetCurrent``, ``ParamSet``...).

Out: exchange requests (:data:`Exchange`: one at a time, answered by ``ExchangeDone``),
fire-and-forget :class:`RequestRates`, :class:`CancelExchange`, :class:`NotifyRebooted`,
:class:`CoreEvent` (for the decision core), :class:`JournalLine` and :class:`Warn`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from groundstation.core import events as ev
from groundstation.core.commands import FlyToTarget
from groundstation.mavlink.fence_items import FenceCircle
from groundstation.mavlink.mission_items import MissionStep
from groundstation.mavlink.telemetry_events import TelemetryEvent, VehicleSnapshot

__all__ = [
    "Arm",
    "AutopilotFrame",
    "CancelExchange",
    "CoreEvent",
    "Download",
    "Exchange",
    "ExchangeDone",
    "FenceParam",
    "FenceWanted",
    "Fly",
    "ForeignFrame",
    "HomeOutcome",
    "Input",
    "JournalLine",
    "LaunchWanted",
    "MoveHome",
    "NewHome",
    "NotifyRebooted",
    "Output",
    "ParamsRead",
    "ReadAllParams",
    "ReadParam",
    "Release",
    "RequestRates",
    "SetCurrent",
    "SetMode",
    "SetParam",
    "Stop",
    "TimePassed",
    "UploadFence",
    "UploadMission",
    "UploadOutcome",
    "Warn",
]


# ------------------------------------------------------------------ inputs
@dataclass(frozen=True)
class AutopilotFrame:
    """One message of the vehicle's own autopilot component: its MAVLink type, the
    reducer's snapshot after it and the events it caused."""

    t_s: float
    kind: str
    snapshot: VehicleSnapshot
    events: tuple[TelemetryEvent, ...] = ()
    time_boot_ms: int | None = None
    """The frame's own ``time_boot_ms``, if it carries one (its telemetry age)."""


@dataclass(frozen=True)
class ForeignFrame:
    """A message of the vehicle's system from another component: ignored, counted."""

    t_s: float
    kind: str
    component_id: int


@dataclass(frozen=True)
class TimePassed:
    t_s: float


@dataclass(frozen=True)
class Fly:
    """The core's FlyToTarget, with the aim point clipped into the operating area."""

    t_s: float
    command: FlyToTarget
    x_m: float
    y_m: float
    clipped: bool = False


@dataclass(frozen=True)
class Release:
    """The core's ReleaseVehicle (``home`` False) or SendHome (``home`` True)."""

    t_s: float
    reason: str
    home: bool = False


@dataclass(frozen=True)
class NewHome:
    """The core's SetHome: move the vehicle's home to (x_m, y_m) (local ENU, m)."""

    t_s: float
    x_m: float
    y_m: float


@dataclass(frozen=True)
class LaunchWanted:
    """The core's LaunchVehicle: launch this spare (``reason``; ``relieves`` the vehicle it
    relieves, if any). With ``--launch`` floe launches it; otherwise it asks the operator."""

    t_s: float
    reason: str
    relieves: str | None = None


@dataclass(frozen=True)
class FenceWanted:
    """The fence the vehicle should hold: the operating area's (``fence_items.py``), sent
    at join and whenever the area moved; None: no area, nothing fenced."""

    t_s: float
    fence: FenceCircle | None


@dataclass(frozen=True)
class Stop:
    t_s: float


@dataclass(frozen=True)
class UploadOutcome:
    """A verified upload: uploaded, read back and compared (``ok``), or why not."""

    ok: bool
    retries: int = 0
    error: str | None = None
    items: int = 0
    took_s: float | None = None
    """Mission seconds from the first MISSION_COUNT to the verdict (None: not timed)."""


@dataclass(frozen=True)
class HomeOutcome:
    """A home set: confirmed by HOME_POSITION (``ok``; ``x_m, y_m`` where the vehicle says
    its home now is, ``error_m`` from the request), or why not (``error``)."""

    ok: bool
    x_m: float | None = None
    y_m: float | None = None
    error_m: float | None = None
    retries: int = 0
    error: str | None = None


@dataclass(frozen=True)
class ExchangeDone:
    """The answer to ``request``: an :class:`UploadOutcome` (UploadMission), a
    ``TransferResult`` (Download, SetCurrent), a MAV_RESULT or None on silence (SetMode,
    Arm), a bool (SetParam), the value read, None on silence (ReadParam), or a
    :class:`HomeOutcome` (MoveHome)."""

    t_s: float
    request: Exchange
    result: Any


Input = (
    AutopilotFrame | ForeignFrame | TimePassed | Fly | Release | Stop | ExchangeDone | NewHome
    | LaunchWanted | FenceWanted
)


# ------------------------------------------------------------------ outputs
@dataclass(frozen=True, eq=False)
class UploadMission:
    """Upload ``steps`` (the driver prepends home and builds the items), read them back
    and compare; retried up to the transfer retries."""

    steps: tuple[MissionStep, ...]
    purpose: str
    target: str | None = None


@dataclass(frozen=True, eq=False)
class UploadFence:
    """Upload ``fence`` as fence items (mission type FENCE), read them back and compare;
    retried up to the transfer retries, as a mission is: an :class:`UploadOutcome`."""

    fence: FenceCircle


@dataclass(frozen=True, eq=False)
class Download:
    purpose: str = "check"


@dataclass(frozen=True, eq=False)
class SetCurrent:
    """Make ``seq`` current (``known_current_seq``: the item the vehicle was last seen on)."""

    seq: int
    known_current_seq: int | None


@dataclass(frozen=True, eq=False)
class SetMode:
    mode: int


@dataclass(frozen=True, eq=False)
class Arm:
    pass


@dataclass(frozen=True, eq=False)
class SetParam:
    name: str
    value: float


@dataclass(frozen=True, eq=False)
class FenceParam(SetParam):
    """A SetParam of the fence's (FENCE_TYPE, FENCE_ACTION, FENCE_ENABLE): it commands the
    vehicle's behaviour, so it waits, as an upload does, while a mode change is not yet
    attributed, and is never sent to a vehicle its pilot took over."""


@dataclass(frozen=True, eq=False)
class ReadParam:
    """Read parameter ``name`` (PARAM_REQUEST_READ by name; the driver retries a silence a
    bounded number of times): the value, or None when the vehicle does not answer."""

    name: str


@dataclass(frozen=True, eq=False)
class ReadAllParams:
    """Read every parameter (the ``.parm`` snapshot): a ``(values, TransferResult)``."""


@dataclass(frozen=True, eq=False)
class MoveHome:
    """Move the home to (x_m, y_m) (local ENU; the driver converts with the mission origin
    and keeps the home's altitude), verified by HOME_POSITION: a :class:`HomeOutcome`."""

    x_m: float
    y_m: float


Exchange = (
    UploadMission | UploadFence | Download | SetCurrent | SetMode | Arm | SetParam | ReadParam
    | MoveHome | ReadAllParams
)


@dataclass(frozen=True)
class RequestRates:
    position_hz: float


@dataclass(frozen=True)
class ParamsRead:
    """The vehicle's parameters were read (all of them): the driver writes the snapshot."""

    values: dict[str, float]


@dataclass(frozen=True)
class CancelExchange:
    """Forget the running exchange: its result will be ignored."""


@dataclass(frozen=True)
class NotifyRebooted:
    """The vehicle rebooted: end any transfer in progress (``port.notify_rebooted``)."""


@dataclass(frozen=True)
class CoreEvent:
    event: ev.Event


@dataclass(frozen=True)
class JournalLine:
    event: str
    fields: dict[str, Any] = field(default_factory=dict)
    logged: bool = False
    """A :class:`Warn` of the same step tells the operator (the line is not logged again)."""


@dataclass(frozen=True)
class Warn:
    """An operator warning (the console, ``log.warning``)."""

    text: str


Output = (
    Exchange | RequestRates | CancelExchange | NotifyRebooted | CoreEvent | JournalLine | Warn
    | ParamsRead
)
