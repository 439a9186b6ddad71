"""Routing between the daemon, its vehicle links and its ``--out`` links.

* Vehicle links (``--vehicles``): every valid frame teaches the router which link its
  system id was heard on (the link itself remembers the UDP address or TCP client), is
  recorded in the tlog, copied unchanged to every out link, and handed to
  ``on_vehicle_frame``.
* Out links (``--out``: QGroundControl, MAVProxy): every valid frame is recorded, passed
  through to the vehicle its ``target_system`` names (0 or absent or not yet heard: to all
  vehicle links), and handed to ``on_out_frame`` so the daemon can notice another ground
  station's commands (a mission upload is an operator override).
* The tlog gets every frame; the two lowest timestamp bits say where it went (see
  ``groundstation.link.tlog``): 0..2 the vehicle link it came from, 3 sent to vehicles.
* The daemon's own frames: :meth:`Router.send_to` (one system id) and
  :meth:`Router.broadcast` (every vehicle link and peer: the GCS heartbeat); recorded too.

The router decides nothing about the vehicles; it only moves frames. Two optional hooks
let MAVLink 2 signing sit at its edge (``groundstation.daemon.signing_gate``): ``admit``
sees every vehicle frame first and may refuse it (then it is counted in ``refused`` and goes
nowhere: not routed, recorded, forwarded or delivered), and ``sign`` rewrites each frame the
daemon sends (``send_to``/``broadcast``) for the vehicle link it goes out on.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable
from dataclasses import dataclass

from groundstation.link.base import Link, ReceiveCallback, Received
from groundstation.link.tlog import TlogWriter

__all__ = ["Router", "RouterCounters"]

log = logging.getLogger(__name__)

SENT_LINK_NUMBER = 3
"""Tlog link number of frames sent towards the vehicles (MAVProxy's convention)."""


@dataclass
class RouterCounters:
    """What the router did with frames (see the module docstring)."""

    from_vehicles: int = 0
    from_out: int = 0
    forwarded_to_out: int = 0
    passed_to_vehicles: int = 0
    sent: int = 0
    no_route: int = 0
    refused: int = 0


def target_system_of(rx: Received) -> int:
    """The ``target_system`` a frame is addressed to, 0 (broadcast) if it has none."""
    value = getattr(rx.message, "target_system", 0)
    return value if isinstance(value, int) else 0


class Router:
    """Several vehicle links, optional out links, one routing table."""

    def __init__(
        self,
        on_vehicle_frame: ReceiveCallback | None = None,
        on_out_frame: ReceiveCallback | None = None,
        tlog: TlogWriter | None = None,
    ) -> None:
        self.on_vehicle_frame = on_vehicle_frame
        self.on_out_frame = on_out_frame
        self.tlog = tlog
        self.vehicle_links: list[Link] = []
        self.out_links: list[Link] = []
        self.routes: dict[int, Link] = {}
        self.counters = RouterCounters()
        self.admit: Callable[[Link, int, Received], bool] | None = None
        """Signing check: (link, vehicle link index, frame) -> let it through?"""
        self.sign: Callable[[int | None, int, bytes], bytes] | None = None
        """Signing: (system id or None for broadcast, vehicle link index, frame) -> frame."""

    # -- set-up ----------------------------------------------------------------------
    def add_vehicle_link(self, link: Link) -> None:
        """Add a link to vehicles (its receive callback becomes the router's)."""
        link.on_receive = lambda rx: self._from_vehicle(link, rx)
        self.vehicle_links.append(link)

    def add_out_link(self, link: Link) -> None:
        """Add a link to another ground station."""
        link.on_receive = lambda rx: self._from_out(rx)
        self.out_links.append(link)

    @property
    def links(self) -> list[Link]:
        """Every link, vehicle links first."""
        return [*self.vehicle_links, *self.out_links]

    async def start(self) -> None:
        """Start every link; if one cannot start, stop those started and re-raise."""
        started: list[Link] = []
        try:
            for link in self.links:
                await link.start()
                started.append(link)
        except BaseException:
            for link in reversed(started):
                with contextlib.suppress(Exception):
                    await link.stop()
            raise

    async def stop(self) -> None:
        """Stop every link. Idempotent."""
        for link in reversed(self.links):
            with contextlib.suppress(Exception):
                await link.stop()

    async def __aenter__(self) -> Router:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    # -- sending ---------------------------------------------------------------------
    def link_for(self, system_id: int) -> Link | None:
        """The vehicle link ``system_id`` was last heard on, if any."""
        return self.routes.get(system_id)

    def send_to(self, system_id: int, frame: bytes) -> bool:
        """Send the daemon's ``frame`` to one vehicle; False if it was never heard."""
        link = self.routes.get(system_id)
        if link is None:
            self.counters.no_route += 1
            return False
        if self.sign is not None:
            frame = self.sign(system_id, self._index(link), frame)
        self._record(frame, None, SENT_LINK_NUMBER)
        self.counters.sent += 1
        return link.send(frame, system_id)

    def broadcast(self, frame: bytes) -> int:
        """Send the daemon's ``frame`` on every vehicle link to every peer; returns how
        many links took it (a listening link with no peer yet takes nothing)."""
        sign = self.sign
        if sign is None:
            self._record(frame, None, SENT_LINK_NUMBER)
            self.counters.sent += 1
            return sum(1 for link in self.vehicle_links if link.send(frame, None))
        taken = 0
        for index, link in enumerate(self.vehicle_links):
            signed = sign(None, index, frame)
            if index == 0:  # one record per broadcast, as without signing
                self._record(signed, None, SENT_LINK_NUMBER)
            taken += link.send(signed, None)
        self.counters.sent += 1
        return taken

    def _index(self, link: Link) -> int:
        return next((i for i, v in enumerate(self.vehicle_links) if v is link), 0)

    # -- receiving -------------------------------------------------------------------
    def _record(self, frame: bytes, t_unix_s: float | None, link_number: int) -> None:
        if self.tlog is not None:
            self.tlog.write(frame, t_unix_s, link_number)

    def _from_vehicle(self, link: Link, rx: Received) -> None:
        if self.admit is not None and not self.admit(link, self._index(link), rx):
            self.counters.refused += 1
            return
        self.counters.from_vehicles += 1
        previous = self.routes.get(rx.system_id)
        if previous is not link:
            if previous is not None:
                log.info(
                    "system %d moved from %s to %s", rx.system_id, previous.link_id, link.link_id
                )
            self.routes[rx.system_id] = link
        index = next(i for i, v in enumerate(self.vehicle_links) if v is link)
        self._record(rx.raw, rx.t_unix_s, min(index, 2))
        for out in self.out_links:
            if out.send(rx.raw, None):
                self.counters.forwarded_to_out += 1
        if self.on_vehicle_frame is not None:
            self.on_vehicle_frame(rx)

    def _from_out(self, rx: Received) -> None:
        self.counters.from_out += 1
        self._record(rx.raw, rx.t_unix_s, SENT_LINK_NUMBER)
        target = target_system_of(rx)
        link = self.routes.get(target) if target else None
        if link is not None:
            passed = link.send(rx.raw, target)
        else:
            passed = any([v.send(rx.raw, target or None) for v in self.vehicle_links])
        if passed:
            self.counters.passed_to_vehicles += 1
        if self.on_out_frame is not None:
            self.on_out_frame(rx)
