"""The ship's NMEA 0183 feed (``gcs run --ship URL``) -> the core's ``BoatPosition`` s.

Bytes come from a :class:`~groundstation.link.nmea_source.NmeaSource`, fixes out of the
sans-IO :class:`~groundstation.link.nmea.NmeaReader`; each fix becomes one
:class:`~groundstation.core.events.BoatPosition` (:func:`boat_position`) stamped with the
mission clock at reception, handed to ``ShipFeedHost.ship_fix``. When ``--ship`` is given
it is the core's only source of the ship: the scenario's boat and the detection feed's
``boat`` lines no longer reach the core (the simulator still flies its own boat, the truth
of its metrics). docs/ship.md.

**Conversion.** Position: ``GeoOrigin.to_local`` (WGS-84 -> local ENU). Velocity from
course over ground ``c`` (degrees true, clockwise from north) and speed ``s`` (m/s):
``vx = s sin c`` (east), ``vy = s cos c`` (north); a speed of 0 without a course is
(0, 0); no speed, or a non-zero speed without a course, is unknown (None). Heading: HDT's
true heading ``h`` -> ``heading_rad = pi/2 - radians(h)`` wrapped to [-pi, pi) (CCW from
east). ``sigma_m = HDOP x UERE_M`` (:data:`UERE_M`, 5 m: a plain GPS's user range error),
None without an HDOP.

**Silence.** No fix for ``silent_after_s`` mission seconds (from the start, or the last
fix) is one console warning and a ``ship_feed_silent`` journal line saying how many
sentences arrived meanwhile and how many were valid (a stream of garbage is silent too);
the next fix is a ``ship_feed_restored`` line. A fix without a mission origin yet is
dropped and counted (``no_origin``). The reader's counters are journalled at the end of
the run (``ship_feed_summary``).
"""

from __future__ import annotations

import asyncio
import logging
import math
from typing import TYPE_CHECKING, Any, Protocol

from domain.geodesy import enu_rad_from_compass_deg
from groundstation.core import events as ev
from groundstation.daemon.hosts import FleetHost
from groundstation.link.nmea import DEFAULT_MAX_AGE_S, NmeaReader, ShipFix
from groundstation.link.nmea_source import NmeaSource

if TYPE_CHECKING:
    from domain.geodesy import GeoOrigin
    from groundstation.link.url import LinkSpec

__all__ = ["DEFAULT_SILENT_AFTER_S", "UERE_M", "ShipFeed", "ShipFeedHost", "boat_position"]

log = logging.getLogger(__name__)

UERE_M = 5.0
"""User equivalent range error (m): a fix's 1-sigma horizontal error is HDOP x UERE_M."""
DEFAULT_SILENT_AFTER_S = 10.0
WATCH_PERIOD_S = 0.5
"""How often (mission s) the feed checks for silence."""
MIN_WATCH_WALL_S = 0.02


class ShipFeedHost(FleetHost, Protocol):
    """What the ship feed needs of the daemon: the clock, the origin, the journal, and the
    way into the core for a ship fix."""

    @property
    def origin_or_none(self) -> GeoOrigin | None: ...

    def ship_fix(self, event: ev.BoatPosition) -> None: ...
    def journal(self, event: str, *, logged: bool = False, **fields: Any) -> None: ...


def boat_position(fix: ShipFix, origin: GeoOrigin) -> ev.BoatPosition:
    """One NMEA fix as the core's :class:`BoatPosition` (see the module docstring)."""
    x_m, y_m, _ = origin.to_local(fix.lat_deg, fix.lon_deg)
    vx_m_s = vy_m_s = None
    if fix.speed_m_s is not None:
        if fix.course_deg is not None:
            course_rad = math.radians(fix.course_deg)
            vx_m_s = fix.speed_m_s * math.sin(course_rad)
            vy_m_s = fix.speed_m_s * math.cos(course_rad)
        elif fix.speed_m_s == 0.0:
            vx_m_s = vy_m_s = 0.0
    heading_rad = (None if fix.heading_deg is None
                   else enu_rad_from_compass_deg(fix.heading_deg))
    sigma_m = None if fix.hdop is None else fix.hdop * UERE_M
    return ev.BoatPosition(fix.t_s, x_m, y_m, vx_m_s, vy_m_s, heading_rad, sigma_m,
                           source="nmea")


class ShipFeed:
    """The ``--ship`` source, its reader, and the silence watch: a daemon service."""

    def __init__(self, host: ShipFeedHost, spec: LinkSpec, *,
                 silent_after_s: float = DEFAULT_SILENT_AFTER_S,
                 max_age_s: float = DEFAULT_MAX_AGE_S) -> None:
        if not (math.isfinite(silent_after_s) and silent_after_s > 0):
            raise ValueError(f"silent_after_s must be > 0, got {silent_after_s}")
        self.host = host
        self.spec = spec
        self.silent_after_s = silent_after_s
        self.reader = NmeaReader(max_age_s)
        self.source = NmeaSource(spec, self.on_bytes, self._on_state)
        self.no_origin = 0
        """Fixes dropped because the mission had no origin yet."""
        self.silent = False
        self._last_fix_s: float | None = None
        self._watch_from_s = 0.0
        self._at_fix = (0, 0, 0, 0)  # the reader's bytes, sentences, valid, dropped then
        self._link_state = ""

    @property
    def name(self) -> str:
        return "ship_feed"

    async def start(self) -> None:
        """Bind a UDP source (raises OSError: the composition root's one-line error)."""
        await self.source.start()

    async def stop(self) -> None:
        await self.source.stop()

    async def run(self) -> None:
        """Read the source and watch for silence, until cancelled."""
        self._watch_from_s = self.host.clock.now_s()
        async with asyncio.TaskGroup() as group:
            group.create_task(self.source.run(), name="ship_feed source")
            group.create_task(self._watch(), name="ship_feed watch")

    def on_bytes(self, data: bytes) -> None:
        """One read of the source (any chunking), at the mission clock's now."""
        now_s = self.host.clock.now_s()
        for fix in self.reader.feed(data, now_s):
            origin = self.host.origin_or_none
            if origin is None:
                self.no_origin += 1
                continue
            self.host.ship_fix(boat_position(fix, origin))
            self._fixed(now_s)

    def _fixed(self, now_s: float) -> None:
        self._last_fix_s = now_s
        self._at_fix = self._counts()
        if self.silent:
            self.silent = False
            log.warning("ship feed %s: fixes again", self.spec.url)
            self.host.journal("ship_feed_restored", logged=True, url=self.spec.url)

    def check_silence(self, now_s: float) -> bool:
        """Warn once if no fix came for ``silent_after_s``; True while silent."""
        since_s = self._last_fix_s if self._last_fix_s is not None else self._watch_from_s
        if self.silent or now_s - since_s < self.silent_after_s:
            return self.silent
        self.silent = True
        now = self._counts()
        received, sentences, valid, dropped = (a - b for a, b in zip(now, self._at_fix,
                                                                     strict=True))
        what = ("nothing received" if received == 0
                else f"{received} bytes, no sentence" if sentences == 0
                else f"{sentences} sentences, none valid" if valid == 0
                else f"{sentences} sentences, {valid} valid, no position")
        if self.no_origin and valid:
            what += f"; {self.no_origin} fixes without a mission origin"
        last = self.reader.last_drop if dropped else None
        log.warning("ship feed %s: no fix for %.0f mission s (%s%s)", self.spec.url,
                    now_s - since_s, what, f"; last dropped {last}" if last else "")
        self.host.journal("ship_feed_silent", logged=True, url=self.spec.url,
                          silent_s=round(now_s - since_s, 3), sentences=sentences,
                          valid=valid, detail=what, last_drop=last)
        return True

    def _counts(self) -> tuple[int, int, int, int]:
        c = self.reader.counters
        return c.bytes, c.sentences, c.valid, c.dropped_total

    def summary(self) -> dict[str, Any]:
        """The counters (journalled at the end: ``ship_feed_summary``)."""
        return {"url": self.spec.url, **self.reader.counters.as_dict(),
                "no_origin": self.no_origin, "connects": self.source.connects,
                "silent": self.silent}

    def journal_summary(self) -> None:
        self.host.journal("ship_feed_summary", **self.summary())

    async def _watch(self) -> None:
        clock = self.host.clock
        while True:
            await asyncio.sleep(max(MIN_WATCH_WALL_S, clock.wall_s(WATCH_PERIOD_S)))
            self.check_silence(clock.now_s())

    def _on_state(self, state: str, reason: str) -> None:
        repeated = state == self._link_state
        self._link_state = state
        if repeated:  # still down: told once, retried with back-off
            log.debug("ship feed %s: %s (%s)", self.spec.url, state, reason)
            return
        if state == "connected":
            log.info("ship feed %s: connected", self.spec.url)
            self.host.journal("ship_feed_link", logged=True, url=self.spec.url, state=state)
            return
        log.warning("ship feed %s: %s (%s); retrying", self.spec.url, state, reason)
        self.host.journal("ship_feed_link", logged=True, url=self.spec.url, state=state,
                          reason=reason)
