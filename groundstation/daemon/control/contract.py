"""The contract between the running daemon and its control surfaces (HTTP API, live page).

The daemon implements :class:`DaemonControl`; the HTTP server (``server.py``) only
calls it. Positions are local ENU metres around the mission origin (``x_m`` east, ``y_m``
north) or WGS-84 degrees; the daemon converts. Every write returns a JSON-able reply
``{"ok": bool, "error": str | None, ...}``; a refused request (unknown id, position outside
the operating area, vehicle not in a state to be launched...) is ``ok: false`` with a
one-line reason, never an exception.

State snapshot (``state()``), JSON-able, the same document the live page draws::

    {
      "t": mission time (s), "unix_s": float, "speedup": float, "advisory": bool,
      "origin": {"lat_deg", "lon_deg"}, "operating_radius_m": float | None,
      "operating_center_m": [x_m, y_m] (home or the boat),
      "vehicles": [{"id", "name", "system_id", "x_m", "y_m", "alt_m", "heading_rad",
                    "speed_m_s", "mode", "armed", "status" (active|overridden|released|lost|
                    home|on_ground|joining), "launch_held" (why floe will not launch it on
                    its own: it came down after it flew; None), "launch_wanted"
                    ({"reason", "relieves"}: the core asks for this spare's launch, until
                    it flies; None), "home" ([x_m, y_m]: the home it confirmed after
                    floe moved it to the ship; None), "link" (ok|degraded|lost),
                    "battery_pct",
                    "target", "route": [ids], "aim": [x_m, y_m] | None (floe's mission:
                    only while floe flies it, active or joining),
                    "track": [[x_m, y_m], ...] (recent positions),
                    "wind": {"wx_m_s", "wy_m_s", "speed_m_s", "from_deg"} | None (its own
                    accepted WIND estimate)}],
      "targets": [{"id", "x_m", "y_m", "vx_m_s", "vy_m_s", "sigma", "cov_xy": [pxx, pxy, pyy],
                   "lost", "last_seen_s", "status"}] (every track the observer holds,
                  tentative ones included),
      "tracks": [{"id", "status" (tentative|confirmed|prior), "x_m", "y_m", "sigma_m2",
                  "existence" (0..1), "t_s"}] (the tracker's view of the same tracks),
      "track_counts": {"confirmed", "tentative", "prior"},
      "search_cells": [{"id", "x_m", "y_m", "size_m", "value_m2", "last_covered_s"}]
                      ([] when the core does not search),
      "boat": {"x_m", "y_m"} | None,
      "fov_radius_m": float,
      "plan": {"t", "routes", "status", "solve_time_s"} | None,
      "wind": {"wx_m_s", "wy_m_s" (ENU, where the air moves), "speed_m_s", "from_deg"
               (compass, where it blows from), "source" (vehicles|config|scenario|none),
               "vehicles": [ids used], "label" ("12.0 m/s from 270° (vehicles 1,2)"),
               "planning" (the planner uses it: wind_aware)},
      "events": [recent journal lines, newest last]
    }
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from typing import Any, Protocol

__all__ = ["FLEET_ACTIONS", "VEHICLE_ACTIONS", "DaemonControl"]

VEHICLE_ACTIONS = ("launch", "resume", "release", "rtl")
FLEET_ACTIONS = ("release", "rtl", "resume")
"""Actions on every vehicle at once: each vehicle as its own ``vehicle_action``."""


class DaemonControl(Protocol):
    """What a control surface may ask of the daemon."""

    def state(self) -> dict[str, Any]:
        """The live state document (see module docstring)."""
        ...

    def subscribe(self) -> AsyncIterator[dict[str, Any]]:
        """Journal events as they happen (for pushing to pages); ends when the daemon stops."""
        ...

    async def add_target(
        self,
        target_id: str | None,
        *,
        x_m: float | None = None,
        y_m: float | None = None,
        lat_deg: float | None = None,
        lon_deg: float | None = None,
        vx_m_s: float = 0.0,
        vy_m_s: float = 0.0,
        sigma0: float | None = None,
    ) -> dict[str, Any]:
        """Add a target (``target_id`` None: the daemon names it). Reply has ``target``."""
        ...

    async def move_target(
        self,
        target_id: str,
        *,
        x_m: float | None = None,
        y_m: float | None = None,
        lat_deg: float | None = None,
        lon_deg: float | None = None,
        sigma0: float | None = None,
    ) -> dict[str, Any]:
        """An operator's fix: the track is re-seated there with ``sigma0`` (m^2), not gated
        as a measurement. Reply has ``target``, ``x_m``, ``y_m``, ``sigma``."""
        ...

    async def remove_target(self, target_id: str) -> dict[str, Any]: ...

    async def vehicle_action(self, vehicle_id: str, action: str) -> dict[str, Any]:
        """``launch``, ``resume`` (give back to floe), ``release`` (stop commanding) or
        ``rtl`` (send home). Reply has ``vehicle``, ``status`` (after the action) and
        ``what`` (what happened, one line); a refusal's ``error`` says why."""
        ...

    async def fleet_action(self, action: str) -> dict[str, Any]:
        """One of :data:`FLEET_ACTIONS` on every vehicle, each exactly as
        :meth:`vehicle_action`. Reply: ``{"ok": True, "action", "results": [{"vehicle",
        "ok", "what" | "error", "status"}], "done": n, "refused": n}``."""
        ...
