"""Routing between the daemon, its vehicle links and its ``--out`` links.

* Vehicle links (``--vehicles``): a vehicle's system id is **bound** to the link its
  autopilot HEARTBEAT was first heard on (``groundstation.link.binding``; the link itself
  binds it to a UDP address or TCP client). Every valid frame is recorded in the tlog and
  copied unchanged to every out link; it is handed to ``on_vehicle_frame`` unless it is
  **foreign** (its system id is bound to another link, or to another peer of this link),
  which is counted in that link's ``counters.foreign`` instead. A binding moves only on
  the vehicle's own evidence (the bound link silent for ``rules.rebind_after_s``, and
  consistent autopilot heartbeats on the new link); a move is logged and reported through
  ``on_notice("link_rebound", ...)``. A link that reconnects is the same link object and
  keeps its bindings.
* Out links (``--out``: QGroundControl, MAVProxy): every valid frame is recorded, passed
  through to the vehicle its ``target_system`` names (0 or absent or not yet heard: to all
  vehicle links), and handed to ``on_out_frame`` so the daemon can notice another ground
  station's commands (a mission upload is an operator override).
* The tlog gets every frame; the two lowest timestamp bits say where it went (see
  ``groundstation.link.tlog``): 0..2 the vehicle link it came from, 3 sent to vehicles.
* The daemon's own frames: :meth:`Router.send_to` (one system id, only ever on its bound
  link) and :meth:`Router.broadcast` (every vehicle link and peer: the GCS heartbeat);
  recorded too.

Time for the binding rules comes from ``now_s`` (the daemon passes its mission clock).

A radio's own reports (RADIO_STATUS, RADIO: ``groundstation.link.radio``) are recorded and
forwarded like every frame, then kept as the link's ``radio``, counted (``radio_frames``)
and handed to ``on_radio`` (the link's traffic budget); they never reach the binding table
or ``on_vehicle_frame``: they describe the radio, not a vehicle, so they bind no system id
and keep none alive.

The router decides nothing about the vehicles; it only moves frames. Two optional hooks
let MAVLink 2 signing sit at its edge (``groundstation.daemon.signing_gate``): ``admit``
sees every vehicle frame first and may refuse it (then it is counted in ``refused`` and goes
nowhere: not routed, recorded, forwarded or delivered), and ``sign`` rewrites each frame the
daemon sends (``send_to``/``broadcast``) for the vehicle link it goes out on.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from groundstation.link.base import Link, ReceiveCallback, Received
from groundstation.link.binding import Binder, BindingRules, BindingVerdict
from groundstation.link.radio import is_radio_message, radio_report
from groundstation.link.tlog import TlogWriter
from groundstation.mavlink.evidence import is_autopilot_heartbeat

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
    foreign: int = 0
    rebinds: int = 0
    radio: int = 0


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
        *,
        rules: BindingRules | None = None,
        now_s: Callable[[], float] = time.monotonic,
        on_notice: Callable[[str, dict[str, Any]], None] | None = None,
        admit: Callable[[Link, int, Received], bool] | None = None,
        sign: Callable[[int | None, int, bytes], bytes] | None = None,
        on_radio: Callable[[Link, Received], None] | None = None,
    ) -> None:
        self.on_vehicle_frame = on_vehicle_frame
        self.on_out_frame = on_out_frame
        self.tlog = tlog
        self.now_s = now_s
        self.on_notice = on_notice
        self.vehicle_links: list[Link] = []
        self._indices: dict[int, int] = {}  # id(link) -> its place among the vehicle links
        self.out_links: list[Link] = []
        self.binder: Binder[Link] = Binder(rules)
        self.counters = RouterCounters()
        self.admit = admit
        """Signing check: (link, vehicle link index, frame) -> let it through?"""
        self.sign = sign
        """Signing: (system id or None for broadcast, vehicle link index, frame) -> frame."""
        self.on_radio = on_radio
        """A radio's report on a vehicle link (the link's traffic budget hears it)."""

    @property
    def routes(self) -> dict[int, Link]:
        """System id -> the vehicle link it is bound to."""
        return self.binder.bound()

    def link_stats(self) -> dict[str, dict[str, int]]:
        """Per link id: received, dropped, bad, foreign, overflow (see ``LinkCounters``)."""
        return {link.link_id: link.counters.receive_summary() for link in self.links}

    # -- set-up ----------------------------------------------------------------------
    def add_vehicle_link(self, link: Link) -> None:
        """Add a link to vehicles (its receive callback becomes the router's)."""
        index = len(self.vehicle_links)
        self._indices[id(link)] = index
        link.on_receive = lambda rx: self._from_vehicle(link, index, rx)
        link.now_s = lambda: self.now_s()
        link.on_notice = self._notice
        self.vehicle_links.append(link)

    def add_out_link(self, link: Link) -> None:
        """Add a link to another ground station."""
        link.on_receive = lambda rx: self._from_out(rx)
        link.now_s = lambda: self.now_s()
        link.on_notice = self._notice
        self.out_links.append(link)

    def _notice(self, event: str, fields: dict[str, Any]) -> None:
        if self.on_notice is not None:
            try:
                self.on_notice(event, fields)
            except Exception:
                log.exception("router: notice callback failed")

    @property
    def links(self) -> list[Link]:
        """Every link, vehicle links first."""
        return [*self.vehicle_links, *self.out_links]

    async def start(self, group: asyncio.TaskGroup | None = None) -> None:
        """Start every link (background tasks in ``group`` if given); if one cannot start,
        stop those started and re-raise."""
        started: list[Link] = []
        try:
            for link in self.links:
                await link.start(group)
                started.append(link)
        except BaseException:
            for link in reversed(started):
                with contextlib.suppress(Exception):
                    await link.stop()
            raise

    async def serve(self, ready: asyncio.Future[None]) -> None:
        """Start every link with its background tasks (drain, reconnect) in a task group of
        this coroutine's own, tell ``ready`` (or hand it the start error), and run until
        cancelled; then stop the links. The daemon runs this in its root task group."""
        async with asyncio.TaskGroup() as group:
            try:
                await self.start(group)
            except Exception as exc:
                if ready.done():  # a restart by the supervisor: its error is the task's
                    raise
                ready.set_exception(exc)
                return
            if not ready.done():
                ready.set_result(None)
            try:
                await asyncio.Event().wait()
            finally:
                await self.stop()

    def begin_close(self) -> None:
        """The daemon is shutting down: peers closing from now on are not lost links."""
        for link in self.links:
            link.begin_close()

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
        """The vehicle link ``system_id`` is bound to, if any."""
        return self.binder.place_of(system_id)

    def send_to(self, system_id: int, frame: bytes) -> bool:
        """Send the daemon's ``frame`` to one vehicle, on its bound link only; False if
        its autopilot was never heard."""
        link = self.binder.place_of(system_id)
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
        return self._indices.get(id(link), 0)

    # -- receiving -------------------------------------------------------------------
    def _record(self, frame: bytes, t_unix_s: float | None, link_number: int) -> None:
        if self.tlog is not None:
            self.tlog.write(frame, t_unix_s, link_number)

    def _from_vehicle(self, link: Link, index: int, rx: Received) -> None:
        if self.admit is not None and not self.admit(link, index, rx):
            self.counters.refused += 1
            return
        self.counters.from_vehicles += 1
        self._record(rx.raw, rx.t_unix_s, min(index, 2))
        for out in self.out_links:
            if out.send(rx.raw, None):
                self.counters.forwarded_to_out += 1
        if is_radio_message(rx.message):  # the radio's, not a vehicle's: recorded, kept
            link.counters.radio_frames += 1
            self.counters.radio += 1
            link.radio = radio_report(rx.message, rx.t_unix_s) or link.radio
            if self.on_radio is not None:
                self.on_radio(link, rx)
            return
        if rx.foreign:  # bound to another peer of this link: the link counted it
            self.counters.foreign += 1
            return
        previous = self.binder.place_of(rx.system_id)
        verdict = self.binder.observe(
            rx.system_id, link, is_autopilot_heartbeat(rx.message), self.now_s()
        )
        if verdict is BindingVerdict.FOREIGN:
            link.counters.foreign += 1
            self.counters.foreign += 1
            return
        if verdict is BindingVerdict.BOUND:
            log.info("system %d bound to link %s", rx.system_id, link.link_id)
        elif verdict is BindingVerdict.REBOUND:
            self.counters.rebinds += 1
            old = previous.link_id if previous is not None else None
            # told by the daemon's journal line (one console line per problem)
            log.debug("system %d re-bound from link %s to %s", rx.system_id, old, link.link_id)
            self._notice(
                "link_rebound", {"system_id": rx.system_id, "link": link.link_id, "previous": old}
            )
        if self.on_vehicle_frame is not None:
            self.on_vehicle_frame(rx)

    def _from_out(self, rx: Received) -> None:
        self.counters.from_out += 1
        self._record(rx.raw, rx.t_unix_s, SENT_LINK_NUMBER)
        target = target_system_of(rx)
        link = self.binder.place_of(target) if target else None
        if link is not None:
            passed = link.send(rx.raw, target)
        else:
            passed = any([v.send(rx.raw, target or None) for v in self.vehicle_links])
        if passed:
            self.counters.passed_to_vehicles += 1
        if self.on_out_frame is not None:
            self.on_out_frame(rx)
