"""What the daemon's helpers may use of it: narrow ``Protocol`` hosts, composed.

The control API (:class:`~groundstation.daemon.control.controller.ControllerHost`), the
detection feed's lines (:class:`~groundstation.daemon.feed_lines.FeedHost`), the operator
alerts (:class:`~groundstation.daemon.alerts.AlertsHost`) and the world feed
(:class:`~groundstation.daemon.world_feed.WorldFeedHost`) each declare what they use of the
:class:`~groundstation.daemon.daemon.Daemon`; the parts several of them share are declared
once here.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, Protocol

from groundstation.core import events as ev

if TYPE_CHECKING:
    from groundstation.core.commands import Verdict
    from groundstation.core.decision import DecisionCore
    from groundstation.daemon.clock import MissionClock
    from groundstation.daemon.session import VehicleSession

__all__ = ["CoreHost", "FleetHost"]


class FleetHost(Protocol):
    """The mission clock and the vehicle sessions by system id."""

    @property
    def clock(self) -> MissionClock: ...
    @property
    def sessions(self) -> Mapping[int, VehicleSession]: ...


class CoreHost(Protocol):
    """The decision core, the way into it (its verdicts back), the journal and the
    operating area."""

    @property
    def core(self) -> DecisionCore: ...

    def core_event(self, event: ev.Event) -> Sequence[Verdict]: ...
    def journal(self, event: str, *, logged: bool = False, **fields: Any) -> None: ...
    def inside_area(self, x_m: float, y_m: float) -> bool: ...
