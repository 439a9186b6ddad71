"""The daemon's side of the control contract (``contract.DaemonControl``).

The HTTP control API and the live page call these methods; every write answers
``{"ok": bool, "error": str | None, ...}`` and never raises on bad requests.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import AsyncIterator, Mapping
from typing import TYPE_CHECKING, Any, Protocol

from groundstation.core import events as ev
from groundstation.daemon.control.contract import FLEET_ACTIONS, VEHICLE_ACTIONS
from groundstation.daemon.fence_view import fence_dict, holds_fence
from groundstation.daemon.hosts import CoreHost, FleetHost
from groundstation.daemon.link_budgets import LinkBudgets
from groundstation.daemon.log_lines import is_operator_event
from groundstation.daemon.track_views import search_dicts, track_counts, track_dicts
from groundstation.daemon.vehicle_view import vehicle_panel
from groundstation.daemon.watch_lines import watch_dict
from groundstation.daemon.wind_view import vehicle_wind, wind_summary

if TYPE_CHECKING:
    from domain.geodesy import GeoOrigin
    from groundstation.core.config import CoreConfig
    from groundstation.daemon.config import DaemonConfig
    from groundstation.daemon.journal import Journal
    from groundstation.daemon.session import VehicleSession
    from groundstation.mavlink.fence_items import FenceCircle

__all__ = ["ControllerHost", "DaemonController"]


class ControllerHost(FleetHost, CoreHost, Protocol):
    """What the control API reads of the daemon and asks it to do."""

    @property
    def config(self) -> DaemonConfig: ...
    @property
    def core_config(self) -> CoreConfig: ...
    @property
    def journal_file(self) -> Journal: ...
    @property
    def origin_or_none(self) -> GeoOrigin | None: ...
    @property
    def origin(self) -> GeoOrigin: ...
    @property
    def by_name(self) -> Mapping[str, VehicleSession]: ...
    @property
    def boat_xy_m(self) -> tuple[float, float] | None: ...
    @property
    def last_plan(self) -> Mapping[str, Any] | None: ...
    @property
    def wind_fallback_source(self) -> str: ...
    @property
    def budgets(self) -> LinkBudgets: ...

    def add_detection(self, event: ev.Detection) -> None: ...
    def area_center(self) -> tuple[float, float]: ...
    def fence(self) -> FenceCircle | None: ...


def _refuse(error: str) -> dict[str, Any]:
    return {"ok": False, "error": error}


class DaemonController:
    """Implements :class:`~groundstation.daemon.control.contract.DaemonControl`."""

    def __init__(self, daemon: ControllerHost) -> None:
        self.daemon = daemon
        self._names = itertools.count(1)

    # ------------------------------------------------------------------ reads
    def state(self) -> dict[str, Any]:
        d = self.daemon
        t = d.clock.now_s()
        origin = d.origin_or_none
        view = d.core.view()
        fence = d.fence()
        vehicles = []
        for s in sorted(d.sessions.values(), key=lambda s: s.system_id):
            snap = s.snapshot
            fly = s.shown_fly
            vehicles.append(
                {
                    "id": s.id,
                    "name": s.id,
                    "system_id": s.system_id,
                    "x_m": snap.x_m,
                    "y_m": snap.y_m,
                    "alt_m": snap.alt_m,
                    "heading_rad": snap.heading_rad,
                    "speed_m_s": snap.airspeed_m_s or snap.speed_m_s,
                    "mode": snap.mode_name,
                    "armed": snap.armed,
                    "status": s.status,
                    "launch_held": s.launch_held,
                    "launch_wanted": s.launch_wanted,
                    "home": (list(s.controller.home_xy_m)
                             if s.controller.home_xy_m is not None else None),
                    "link": s.link,
                    "telemetry_age_s": s.telemetry_age_s,
                    "lagging": s.lagging,
                    "prediction": s.prediction(),
                    "battery_pct": snap.battery_remaining_pct,
                    # floe's mission only while floe flies it (not once released,
                    # taken over or sent home)
                    "target": fly.target if fly else None,
                    "route": list(fly.route) if fly else [],
                    "aim": [fly.x_m, fly.y_m] if fly else None,
                    "track": [list(p) for p in s.track],
                    "wind": vehicle_wind(snap.wind_xy_m_s),
                    "fence_verified": holds_fence(fence, s.controller.fence_held),
                    **vehicle_panel(snap, s.fly, d.core_config.loiter_radius_m,
                                    s.link, s.telemetry_age_s,
                                    d.budgets.for_system(s.system_id)),
                }
            )
        targets = [
            {
                "id": tr.id,
                "x_m": tr.x_m,
                "y_m": tr.y_m,
                "vx_m_s": tr.vx_m_s,
                "vy_m_s": tr.vy_m_s,
                "sigma": tr.sigma,
                "cov_xy": list(tr.cov_xy),
                "lost": tr.lost,
                "last_seen_s": tr.last_seen_s,
                "status": tr.status,
            }
            for tr in view.tracks
        ]
        tracks = track_dicts(view.tracks)
        return {
            "t": t,
            "unix_s": d.clock.unix_s(),
            "speedup": d.clock.speedup,
            "advisory": d.config.advisory,
            "origin": {"lat_deg": origin.lat_deg, "lon_deg": origin.lon_deg} if origin else None,
            "operating_radius_m": d.config.mission.operating_radius_m,
            "operating_center_m": list(d.area_center()),
            "fence": fence_dict(fence),
            "vehicles": vehicles,
            "targets": targets,
            "tracks": tracks,
            "track_counts": track_counts(tracks),
            "search_cells": search_dicts(view.search_cells),
            "boat": {"x_m": d.boat_xy_m[0], "y_m": d.boat_xy_m[1]} if d.boat_xy_m else None,
            "watch": watch_dict(view.watch) if view.watch is not None else None,
            "fov_radius_m": d.core_config.observer.fov_radius_m,
            "plan": d.last_plan,
            "wind": wind_summary(view.wind, d.wind_fallback_source,
                                 d.core_config.wind_aware),
            "events": [line for line in d.journal_file.recent if is_operator_event(line)][-50:],
        }

    def subscribe(self) -> AsyncIterator[dict[str, Any]]:
        return self.daemon.journal_file.subscribe()

    # ------------------------------------------------------------------ writes
    def _position(
        self, x_m: float | None, y_m: float | None, lat_deg: float | None, lon_deg: float | None
    ) -> tuple[float, float] | str:
        if x_m is not None and y_m is not None:
            x, y = float(x_m), float(y_m)
        elif lat_deg is not None and lon_deg is not None:
            if self.daemon.origin_or_none is None:
                return "no mission origin yet (no vehicle position heard)"
            if not (-90 <= lat_deg <= 90 and -180 <= lon_deg <= 180):
                return "lat_deg/lon_deg out of range"
            x, y, _ = self.daemon.origin.to_local(float(lat_deg), float(lon_deg))
        else:
            return "give x_m and y_m, or lat_deg and lon_deg"
        if not (math.isfinite(x) and math.isfinite(y)):
            return "position must be finite"
        if not self.daemon.inside_area(x, y):
            return (
                f"position ({x:.0f}, {y:.0f}) m is outside the operating area "
                f"({self.daemon.config.mission.operating_radius_m:g} m)"
            )
        return x, y

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
        d = self.daemon
        pos = self._position(x_m, y_m, lat_deg, lon_deg)
        if isinstance(pos, str):
            return _refuse(pos)
        known = d.core.view().target_ids
        if target_id is None:
            target_id = next(f"U{k}" for k in self._names if f"U{k}" not in known)
        if not isinstance(target_id, str) or not target_id:
            return _refuse("target id must be a non-empty string")
        if target_id in known:
            return _refuse(f"target {target_id!r} already exists")
        if sigma0 is not None and not (math.isfinite(sigma0) and sigma0 >= 0):
            return _refuse("sigma0 must be >= 0")
        if not (math.isfinite(vx_m_s) and math.isfinite(vy_m_s)):
            return _refuse("velocity must be finite")
        t = d.clock.now_s()
        d.journal(
            "target_added",
            target=target_id,
            x_m=pos[0],
            y_m=pos[1],
            vx_m_s=vx_m_s,
            vy_m_s=vy_m_s,
            sigma0=sigma0,
            source="api",
        )
        d.core_event(ev.TargetAdded(t, target_id, pos[0], pos[1], vx_m_s, vy_m_s, sigma0))
        return {"ok": True, "error": None, "target": target_id}

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
        """An operator's fix: the track is re-seated at the position with ``sigma0`` (m^2;
        default ``2 r_m2``, one camera fix) as a ``TargetFixed`` core input, never gated
        like a measurement. The answer is the track as it is after the fix."""
        d = self.daemon
        if target_id not in d.core.view().target_ids:
            return _refuse(f"unknown target {target_id!r}")
        pos = self._position(x_m, y_m, lat_deg, lon_deg)
        if isinstance(pos, str):
            return _refuse(pos)
        if sigma0 is None:
            sigma0 = 2.0 * d.core_config.observer.r_m2
        if not (math.isfinite(sigma0) and sigma0 >= 0):
            return _refuse("sigma0 must be >= 0")
        t = d.clock.now_s()
        d.journal("target_fixed", target=target_id, x_m=pos[0], y_m=pos[1],
                  sigma0=sigma0, source="api")
        d.core_event(ev.TargetFixed(t, target_id, pos[0], pos[1], float(sigma0)))
        track = next((tr for tr in d.core.view().tracks if tr.id == target_id), None)
        if track is None or math.hypot(track.x_m - pos[0], track.y_m - pos[1]) > 1e-6:
            return _refuse(f"target {target_id!r} was not moved (the run is over, or it "
                           "was removed)")
        return {"ok": True, "error": None, "target": target_id, "x_m": track.x_m,
                "y_m": track.y_m, "sigma": track.sigma}

    async def remove_target(self, target_id: str) -> dict[str, Any]:
        d = self.daemon
        if target_id not in d.core.view().target_ids:
            return _refuse(f"unknown target {target_id!r}")
        d.journal("target_removed", target=target_id, source="api")
        d.core_event(ev.TargetRemoved(d.clock.now_s(), target_id))
        return {"ok": True, "error": None, "target": target_id}

    async def vehicle_action(self, vehicle_id: str, action: str) -> dict[str, Any]:
        d = self.daemon
        if action not in VEHICLE_ACTIONS:
            return _refuse(f"unknown action {action!r}; use {', '.join(VEHICLE_ACTIONS)}")
        session = d.by_name.get(vehicle_id)
        if session is None and vehicle_id.isdigit():
            session = d.sessions.get(int(vehicle_id))
        if session is None:
            return _refuse(f"unknown vehicle {vehicle_id!r}")
        return self._act(session, action)

    def _act(self, session: VehicleSession, action: str) -> dict[str, Any]:
        """One vehicle's action and its answer (``contract.DaemonControl.vehicle_action``)."""
        d = self.daemon
        if action == "launch":
            if d.config.advisory:
                return {**_refuse("advisory mode: floe commands no vehicle"),
                        "vehicle": session.id, "status": session.status}
            ok, error = session.request_launch()
            what = (f"vehicle {session.id}: launch requested (arm when the pre-arm checks "
                    "pass, take off, hand over to floe)") if ok else None
        else:
            ok, text = session.operator_action(d.clock.now_s(), action)
            what, error = (text, "") if ok else (None, text)
        return {"ok": ok, "error": error or None, "vehicle": session.id,
                "status": session.status, **({"what": what} if ok else {})}

    async def fleet_action(self, action: str) -> dict[str, Any]:
        d = self.daemon
        if action not in FLEET_ACTIONS:
            return _refuse(f"unknown fleet action {action!r}; use {', '.join(FLEET_ACTIONS)}")
        results = []
        for session in sorted(d.sessions.values(), key=lambda s: s.system_id):
            reply = self._act(session, action)
            results.append({k: v for k, v in reply.items() if v is not None})
        done = sum(1 for r in results if r["ok"])
        return {"ok": True, "error": None, "action": action, "results": results,
                "done": done, "refused": len(results) - done}
