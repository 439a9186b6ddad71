"""What the daemon needs of vehicles that run inside its own event loop (``sim:N``).

The daemon never imports the simulator: the command layer (``groundstation/commands``)
builds an :class:`EmbeddedVehicles` (the built-in ArduPlane-like vehicles) and hands
``run_daemon`` a factory for it. The daemon then talks to those vehicles over ordinary
``tcp:`` links, exactly as to ArduPilot SITL, follows their simulated clock (``now_s``) and
asks them where the airborne vehicles are (the scenario's camera sees from there).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from domain.geodesy import GeoOrigin
    from groundstation.daemon.config import DaemonConfig
    from world.scenario import Scenario
    from world.wind import WindSpec

__all__ = ["EmbeddedFactory", "EmbeddedService", "EmbeddedVehicles"]


class EmbeddedVehicles(Protocol):
    """Simulated vehicles served on 127.0.0.1 inside the daemon's process."""

    @property
    def origin(self) -> GeoOrigin:
        """The mission origin (the vehicles' home) the simulator was built around."""

    @property
    def fault_specs(self) -> list[str]:
        """The fault specs in force (journalled in the ``start`` line)."""

    def now_s(self) -> float:
        """Simulated seconds since the start: the daemon's mission clock."""

    def link_urls(self) -> list[str]:
        """One link URL per vehicle (valid after :meth:`start`)."""

    def airborne_positions(self) -> dict[int, tuple[float, float]]:
        """System id -> true local (x, y) m of every vehicle in the air."""

    def radio_stats(self) -> dict[int, dict[str, Any]]:
        """Each simulated radio's figures by system id (``--sim-radio``; {} without
        radios): at least ``air_pct``, the air time its two radios used, in % of the
        elapsed time."""

    async def start(self) -> None:
        """Open the vehicles' ports (OSError if one cannot be opened)."""

    async def run(self) -> None:
        """Fly the vehicles until :meth:`stop`."""

    def stop(self) -> None:
        """Ask :meth:`run` to return."""

    async def close(self) -> None:
        """Close every port."""


EmbeddedFactory = Callable[
    ["DaemonConfig", "Scenario | None", dict[int, bytes], "WindSpec"], EmbeddedVehicles
]
"""Builds the vehicles for ``config.sim_count`` with the MAVLink 2 signing key each system
id starts with, flying in the wind given (``--wind``, else the scenario's; raises
ConfigError on a bad setting)."""


class EmbeddedService:
    """The daemon's service that flies the embedded vehicles until it is cancelled."""

    name = "embedded vehicles"

    def __init__(self, vehicles: EmbeddedVehicles) -> None:
        self.vehicles = vehicles

    async def run(self) -> None:
        try:
            await self.vehicles.run()
        finally:
            self.vehicles.stop()
