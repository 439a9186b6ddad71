"""In-memory ground-station link to a :class:`SimVehicle` in virtual time (tests, benches).

Every message in either direction goes through the real MAVLink 2 codec (encode, then
decode), so a test sees exactly what a socket peer would.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder
from sitl.vehicle import SimVehicle

__all__ = ["Loopback", "MemoryClient"]


class Loopback:
    """A ground station (``gcs_sysid``/``gcs_compid``) wired straight to one vehicle."""

    def __init__(self, vehicle: SimVehicle, gcs_sysid: int = 255, gcs_compid: int = 190) -> None:
        self.vehicle = vehicle
        self.t_s = vehicle.t_s
        self._gcs = MavlinkEncoder(gcs_sysid, gcs_compid)
        self._veh = MavlinkEncoder(vehicle.system_id, vehicle.config.component_id)
        self._up = MavlinkDecoder()
        self._down = MavlinkDecoder()
        self.inbox: list[Any] = []

    @property
    def mav(self) -> Any:
        """The ground station's pymavlink MAVLink object (for ``*_encode`` helpers)."""
        return self._gcs.mav

    def _deliver(self, out: list[Any]) -> list[Any]:
        got: list[Any] = []
        for msg in out:
            got += self._down.feed(self._veh.encode(msg))
        self.inbox += got
        return got

    def send(self, msg: Any) -> list[Any]:
        """Send ``msg`` to the vehicle now; returns (and queues) the immediate answers."""
        decoded = self._up.feed(self._gcs.encode(msg))
        got: list[Any] = []
        for m in decoded:
            got += self._deliver(self.vehicle.receive(m, self.t_s))
        return got

    def send_raw(self, data: bytes) -> list[Any]:
        """Send raw bytes (garbage, bad CRC) through the decoder."""
        got: list[Any] = []
        for m in self._up.feed(data):
            got += self._deliver(self.vehicle.receive(m, self.t_s))
        return got

    def advance(self, dt_s: float, step_s: float = 0.1) -> list[Any]:
        """Run the vehicle ``dt_s`` simulated seconds; returns what it sent."""
        got: list[Any] = []
        end = self.t_s + dt_s
        while self.t_s < end - 1e-9:
            self.t_s = min(end, self.t_s + step_s)
            got += self._deliver(self.vehicle.step(self.t_s))
        return got

    def run_until(
        self, predicate: Callable[[Any], bool], timeout_s: float, step_s: float = 0.1
    ) -> Any | None:
        """Advance until a sent message satisfies ``predicate``; return it (None: timeout)."""
        end = self.t_s + timeout_s
        while self.t_s < end:
            for msg in self.advance(step_s, step_s):
                if predicate(msg):
                    return msg
        return None

    def take(self, kind: str) -> list[Any]:
        """Remove and return the queued messages of one type."""
        hit = [m for m in self.inbox if m.get_type() == kind]
        self.inbox = [m for m in self.inbox if m.get_type() != kind]
        return hit

    def texts(self) -> list[str]:
        """Texts of the queued STATUSTEXTs (not removed)."""
        return [m.text for m in self.inbox if m.get_type() == "STATUSTEXT"]


class MemoryClient:
    """A TCP client of a :class:`~sitl.server.SitlServer` held in memory (tests, benches):
    the writer the server sees (add it to a slot's ``clients``), keeping what it was sent,
    decoded, in :attr:`msgs`."""

    def __init__(self) -> None:
        self.decoder = MavlinkDecoder()
        self.msgs: list[Any] = []
        self.transport = self

    def get_write_buffer_size(self) -> int:
        return 0

    def is_closing(self) -> bool:
        return False

    def write(self, data: bytes) -> None:
        self.msgs += self.decoder.feed(data)

    def close(self) -> None:
        pass
