"""Problems no single journal line reports, told to the operator while the run goes on.

* **A link that has heard no vehicle.** A vehicle link none of whose frames ever made a
  vehicle (a session bound to it) after ``SILENT_AFTER_S`` mission seconds says so, and again
  every ``SILENT_REPEAT_S`` while it stays so: one ``link_silent`` journal line (``link``,
  ``url``, ``silent_s``, ``connected``, ``received``) and one warning on the console naming
  what to check. A wrong address, a missing serial device, an unroutable ``udpout:`` or a
  TCP port another client holds all look like this.
* **Detections dropped.** At most every ``DROPS_REPORT_S`` mission seconds, when the number
  of dropped detections grew: one ``detections_dropped`` line (``new``, ``total`` and the
  counts by reason: ``no_origin``, ``outside_area`` (camera or feed), ``malformed``,
  ``out_of_order``, ``late`` (feed)) and one console warning.

:meth:`OperatorAlerts.check` reads only what the daemon already counts (sessions, link
counters, dropped detections) and reports what is due; the daemon's task
(:meth:`OperatorAlerts.run`) calls it once a mission second until the run stops.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Protocol

from groundstation.daemon.hosts import FleetHost
from groundstation.link.url import LinkKind

if TYPE_CHECKING:
    from groundstation.link.base import Link
    from groundstation.link.router import Router

__all__ = [
    "DROPS_REPORT_S",
    "SILENT_AFTER_S",
    "SILENT_REPEAT_S",
    "AlertsHost",
    "OperatorAlerts",
    "never_heard",
]

log = logging.getLogger(__name__)

SILENT_AFTER_S = 10.0
SILENT_REPEAT_S = 30.0
DROPS_REPORT_S = 10.0
_FEED_REASONS = ("malformed", "out_of_order", "late")


class AlertsHost(FleetHost, Protocol):
    """What the alerts read of the daemon (and its journal)."""

    @property
    def router(self) -> Router: ...
    @property
    def stopping(self) -> bool: ...
    @property
    def detections_dropped(self) -> int: ...
    @property
    def detections_no_origin(self) -> int: ...

    def journal(self, event: str, *, logged: bool = False, **fields: Any) -> None: ...


class OperatorAlerts:
    """See the module docstring."""

    def __init__(
        self, daemon: AlertsHost, feed_counters: Callable[[], Mapping[str, int]] | None = None
    ) -> None:
        self.daemon = daemon
        self.feed_counters = feed_counters
        """The detection feed's counters (None without a feed)."""
        self.heard: set[str] = set()
        """Vehicle links a vehicle was ever bound to."""
        self.silent: set[str] = set()
        """Vehicle links reported silent (until a vehicle is heard on one)."""
        self._next_silent_s: dict[str, float] = {}
        self._next_drops_s = DROPS_REPORT_S
        self._drops_reported = 0

    # ------------------------------------------------------------------ figures
    def drops(self) -> dict[str, int]:
        """Dropped detections by reason (see the module docstring)."""
        d = self.daemon
        out = {"no_origin": d.detections_no_origin, "outside_area": d.detections_dropped}
        if self.feed_counters is not None:
            counters = self.feed_counters()
            for reason in _FEED_REASONS:
                out[reason] = int(counters.get(reason, 0))
        return out

    def link_state(self, link: Link) -> str:
        """What an operator can tell of a vehicle link: heard, connected, frames in."""
        if link.link_id in self.heard:
            return "vehicle heard"
        return _unheard_state(link)

    def silent_links(self) -> list[Link]:
        """The vehicle links reported silent, in the router's order."""
        return [x for x in self.daemon.router.vehicle_links if x.link_id in self.silent]

    # ------------------------------------------------------------------ checks
    def check(self, now_s: float) -> None:
        """Report what is due at mission time ``now_s`` (nothing once the run is stopping)."""
        if self.daemon.stopping:
            return
        self._check_links(now_s)
        if now_s >= self._next_drops_s:
            self._next_drops_s = now_s + DROPS_REPORT_S
            self._check_drops()

    def _check_links(self, now_s: float) -> None:
        router = self.daemon.router
        for sysid in self.daemon.sessions:
            link = router.link_for(sysid)
            if link is not None:
                self.heard.add(link.link_id)
                self.silent.discard(link.link_id)
        for link in router.vehicle_links:
            link_id = link.link_id
            if link_id in self.heard or now_s < self._next_silent_s.get(link_id, SILENT_AFTER_S):
                continue
            self._next_silent_s[link_id] = now_s + SILENT_REPEAT_S
            self.silent.add(link_id)
            url = link.spec.url
            state = self.link_state(link)
            self.daemon.journal(
                "link_silent", link=link_id, url=url, silent_s=round(now_s, 1),
                connected=link.connected, received=link.counters.frames_in, logged=True,
            )  # fmt: skip
            log.warning("link %s (%s): no vehicle heard in %.0f s (%s); %s", link_id, url,
                        now_s, state, _advice(link))

    def _check_drops(self) -> None:
        drops = self.drops()
        total = sum(drops.values())
        new = total - self._drops_reported
        if new <= 0:
            return
        self._drops_reported = total
        reasons = {k: v for k, v in drops.items() if v}
        self.daemon.journal("detections_dropped", new=new, total=total, logged=True,
                            **reasons)
        text = ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in reasons.items())
        log.warning("detections: %d dropped in the last %.0f s (%d in all: %s)", new,
                    DROPS_REPORT_S, total, text)

    async def run(self) -> None:
        """Check once a mission second (at least every 0.05 wall s) until cancelled."""
        clock = self.daemon.clock
        while True:
            self.check(clock.now_s())
            await asyncio.sleep(max(0.05, clock.wall_s(1.0)))


def _unheard_state(link: Link) -> str:
    received = link.counters.frames_in
    if received:
        return (f"{received} frames received, no vehicle yet: it needs 3 autopilot "
                "heartbeats and, without --origin, a position")
    kind = link.spec.kind
    if kind in (LinkKind.UDP_IN, LinkKind.UDP_OUT):  # datagrams: nothing to connect
        return "nothing received"
    if link.connected:
        return "connected, nothing received"
    if link.counters.connects:
        return "not connected"
    return "no client connected" if kind is LinkKind.TCP_SERVER else "never connected"


def never_heard(daemon: AlertsHost) -> str | None:
    """The end-of-run message when no vehicle was ever heard (None if one was):
    ``no vehicle was heard in 25.2 mission s (tcp:127.0.0.1:5999: never connected)``."""
    if daemon.sessions:
        return None
    states = "; ".join(f"{link.spec.url}: {_unheard_state(link)}"
                       for link in daemon.router.vehicle_links)
    return (f"no vehicle was heard in {daemon.clock.now_s():.1f} mission s"
            + (f" ({states})" if states else ""))


def _advice(link: Link) -> str:
    """What to check for a link that heard no vehicle (by the kind of link)."""
    match link.spec.kind:
        case LinkKind.TCP_SERVER:
            return "check that the vehicle or its bridge connects to this address and port"
        case LinkKind.TCP_CLIENT if not link.connected:
            return ("check the address, that the vehicle or SITL listens there and that no "
                    "other program holds its port")
        case LinkKind.TCP_CLIENT:
            return ("connected but silent: ArduPilot serves one client per TCP port, so "
                    "another ground station may hold it; else check that the vehicle sends "
                    "MAVLink here")
        case LinkKind.UDP_OUT:
            return "check the address and that the vehicle answers at it (udpout sends first)"
        case LinkKind.UDP_IN:
            return "check that the vehicle or its radio sends to this address and port"
        case _:
            return "check the device, its cable or radio, and the baud rate"

