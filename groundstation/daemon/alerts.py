"""Problems no single journal line reports, told to the operator while the run goes on.

* **A link that has heard no vehicle.** Silence is counted on the link's own clock (wall
  seconds, whatever the mission's speed-up), from the link's own progress, never from the
  mission clock: from the daemon's start while it never connected, from its connect once
  it connected, from its first frame once frames arrive. A vehicle link none of whose
  frames made a vehicle (a session bound to it) ``silent_after_s`` seconds
  (``links.silent_after_s``, ``--link-silent-after``, default ``SILENT_AFTER_S``) after the latest
  of these (``NO_VEHICLE_AFTER_S`` after its first frame: frames arrive, the vehicle is
  not made yet) says so, and again every ``SILENT_REPEAT_S`` while it stays so: one
  ``link_silent`` journal line (``link``, ``url``, ``silent_s``: seconds since ``since``,
  ``since``: ``start``, ``connect`` or ``first frame``, ``connected``, ``received``) and one
  warning on the console naming what to check. A wrong address, a missing serial device,
  an unroutable ``udpout:`` or a TCP port another client holds all look like this; a link
  whose vehicle is still being heard in (3 heartbeats and a position, a second or two at
  any speed-up) does not. A link that connects again or flaps does not restart the count:
  only progress (never connected -> connected -> frames) does.
* **Detections dropped.** At most every ``DROPS_REPORT_S`` mission seconds, when the number
  of dropped detections grew: one ``detections_dropped`` line (``new``, ``total`` and the
  counts by reason: ``no_origin``, ``outside_area`` (camera or feed), ``malformed``,
  ``out_of_order``, ``late`` (feed)) and one console warning.

:meth:`OperatorAlerts.check` reads only what the daemon already counts (sessions, link
counters, dropped detections) and reports what is due; the daemon's task
(:meth:`OperatorAlerts.run`) calls it once a mission second (at least every 0.05 wall s,
at most every wall second) until the run stops.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Protocol

from groundstation.daemon.hosts import FleetHost
from groundstation.link.url import LinkKind

if TYPE_CHECKING:
    from groundstation.link.base import Link
    from groundstation.link.router import Router

__all__ = [
    "DROPS_REPORT_S",
    "NO_VEHICLE_AFTER_S",
    "SILENT_AFTER_S",
    "SILENT_REPEAT_S",
    "AlertsHost",
    "OperatorAlerts",
    "never_heard",
]

log = logging.getLogger(__name__)

SILENT_AFTER_S = 10.0
NO_VEHICLE_AFTER_S = 60.0
"""A link receiving frames that made no vehicle yet warns this long after its first frame:
a real autopilot may stream heartbeats for tens of seconds before it has the GPS position
a vehicle needs without ``--origin``."""
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
        self, daemon: AlertsHost, feed_counters: Callable[[], Mapping[str, int]] | None = None,
        wall_s: Callable[[], float] = time.monotonic, silent_after_s: float = SILENT_AFTER_S,
    ) -> None:
        self.daemon = daemon
        self.silent_after_s = silent_after_s
        """Wall seconds of silence after the start or connect (``links.silent_after_s``)."""
        self.feed_counters = feed_counters
        self.wall_s = wall_s
        """The links' own clock (wall seconds): silence is counted on it."""
        self._phase: dict[str, tuple[int, float]] = {}
        """Per link: its progress (0 never connected, 1 connected, 2 frames) and since when."""
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
        """Report what is due at mission time ``now_s`` (the links: at ``wall_s()``;
        nothing once the run is stopping)."""
        if self.daemon.stopping:
            return
        self._check_links(self.wall_s())
        if now_s >= self._next_drops_s:
            self._next_drops_s = now_s + DROPS_REPORT_S
            self._check_drops()

    def _progress(self, link: Link, wall_s: float) -> tuple[str, float]:
        """Where the link got to (``start``, ``connect``, ``first frame``) and since when
        (wall s): the count restarts only when it gets further."""
        if link.counters.frames_in:
            level = 2
        elif link.connected or link.counters.connects:
            level = 1
        else:
            level = 0
        seen = self._phase.get(link.link_id)
        if seen is None or level > seen[0]:
            seen = self._phase[link.link_id] = (level, wall_s)
        return ("start", "connect", "first frame")[seen[0]], seen[1]

    def _check_links(self, wall_s: float) -> None:
        router = self.daemon.router
        for sysid in self.daemon.sessions:
            link = router.link_for(sysid)
            if link is not None:
                self.heard.add(link.link_id)
                self.silent.discard(link.link_id)
        for link in router.vehicle_links:
            link_id = link.link_id
            if link_id in self.heard:
                continue
            since, since_s = self._progress(link, wall_s)
            silent_s = wall_s - since_s
            due = self._next_silent_s.get(link_id)
            after_s = NO_VEHICLE_AFTER_S if since == "first frame" else self.silent_after_s
            if silent_s < after_s or (due is not None and wall_s < due):
                continue
            self._next_silent_s[link_id] = wall_s + SILENT_REPEAT_S
            self.silent.add(link_id)
            url = link.spec.url
            state = self.link_state(link)
            self.daemon.journal(
                "link_silent", link=link_id, url=url, silent_s=round(silent_s, 1),
                since=since, connected=link.connected, received=link.counters.frames_in,
                logged=True,
            )  # fmt: skip
            after = "" if since == "start" else f" since its {since}"
            log.warning("link %s (%s): no vehicle heard in %.0f s%s (%s); %s", link_id, url,
                        silent_s, after, state, _advice(link))

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
        """Check once a mission second (at least every 0.05 wall s, at most every wall
        second) until cancelled."""
        clock = self.daemon.clock
        while True:
            self.check(clock.now_s())
            await asyncio.sleep(min(1.0, max(0.05, clock.wall_s(1.0))))


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
    if link.counters.frames_in:
        return ("frames arrive but none made a vehicle: check that an autopilot (not "
                "another ground station) sends heartbeats and a position here")
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

