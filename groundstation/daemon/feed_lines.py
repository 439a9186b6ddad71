"""The detection feed's accepted lines (``groundstation.link.detection_feed``) -> the daemon.

* ``boat``: where the boat is (``Daemon.set_boat``).
* ``frame``: the camera of vehicle ``vehicle`` (system id) took a frame whose footprint is
  the disc of ``radius_m`` around (``lat_deg``, ``lon_deg``) -> ``CameraFrame(t_s,
  vehicle, x_m, y_m, radius_m)`` for the core (absence of evidence in view is evidence of
  absence: the tracker lowers the existence of tracks in it that were not seen). A frame
  from a system id floe has no session for is dropped and counted (``frames_unknown``):
  the core would have no vehicle to tie it to.
* ``detection``: ``Detection(t_s, vehicle, target, x_m, y_m, r_m2)`` with ``target`` None
  when the line says null (the tracker associates it), ``r_m2 = sigma_m ** 2`` (None when
  ``sigma_m`` is 0: the core's default).

Positions go from lat/lon to the mission's local ENU frame (``GeoOrigin.to_local``); with
no mission origin yet a line is dropped and counted (``FeedHost.no_origin``).

**One scan, one time.** ``t_s`` is the daemon's mission clock when the line is handled
(the sender's ``time_s`` is only checked for order and delay by the feed). The core groups
a scan by (``t_s``, ``vehicle``), so the detections of a frame must carry the frame's
``t_s`` exactly, though the clock moves on between lines: a detection line whose vehicle
and sender ``time_s`` equal those of that vehicle's last frame line gets that frame's
mission time.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Protocol

from groundstation.core import events as ev
from groundstation.daemon.hosts import FleetHost

if TYPE_CHECKING:
    from domain.geodesy import GeoOrigin
    from groundstation.daemon.world_feed import WorldFeed

__all__ = ["FeedHost", "FeedLines"]


class FeedHost(FleetHost, Protocol):
    """What the feed's lines need of the daemon."""

    @property
    def origin_or_none(self) -> GeoOrigin | None: ...
    @property
    def feed(self) -> WorldFeed: ...

    def no_origin(self) -> None:
        """Count a line dropped for want of a mission origin."""

    def set_boat(self, x_m: float, y_m: float) -> None: ...
    def add_detection(self, event: ev.Detection) -> None: ...


def _field(item: Any, name: str) -> Any:
    return item.get(name) if isinstance(item, dict) else getattr(item, name, None)


class FeedLines:
    """Callable for ``DetectionFeed(on_detection=...)``; see the module docstring."""

    def __init__(self, daemon: FeedHost) -> None:
        self.daemon = daemon
        self.frames = 0
        """Frame lines handed to the core."""
        self.frames_unknown = 0
        """Frame lines of system ids without a session (dropped)."""
        self._last_frame: dict[int, tuple[float, float]] = {}
        """System id -> (sender's time_s, mission t_s) of its last frame line."""

    def __call__(self, item: Any) -> None:
        daemon = self.daemon
        lat, lon = _field(item, "lat_deg"), _field(item, "lon_deg")
        if daemon.origin_or_none is None or lat is None or lon is None:
            daemon.no_origin()
            return
        x, y, _ = daemon.origin_or_none.to_local(float(lat), float(lon))
        t = daemon.clock.now_s()
        kind = _field(item, "kind")
        if kind == "boat":
            daemon.set_boat(x, y)
            return
        sysid = _field(item, "vehicle")
        sysid = sysid if isinstance(sysid, int) and not isinstance(sysid, bool) else None
        session = daemon.sessions.get(sysid) if sysid is not None else None
        sent_s = _field(item, "time_s")
        if kind == "frame":
            radius = _field(item, "radius_m")
            if session is None or sysid is None or not isinstance(radius, int | float):
                self.frames_unknown += 1
                return
            if isinstance(sent_s, int | float):
                self._last_frame[sysid] = (float(sent_s), t)
            self.frames += 1
            daemon.feed.frame(ev.CameraFrame(t, session.id, x, y, float(radius)))
            return
        if sysid is not None and isinstance(sent_s, int | float):
            last = self._last_frame.get(sysid)
            if last is not None and last[0] == float(sent_s):
                t = last[1]  # the frame's scan
        sigma = _field(item, "sigma_m")
        r = (float(sigma) ** 2 if isinstance(sigma, int | float) and math.isfinite(sigma)
             and sigma > 0 else None)
        target = _field(item, "target")
        daemon.add_detection(
            ev.Detection(t, session.id if session else None,
                         str(target) if target is not None else None, x, y, r)
        )
