"""The simulated vehicle's geofence, enforced as ArduPlane 4.x enforces it (sans-IO).

What is fenced: the items of the FENCE store (:mod:`sitl.geo_items`) when ``FENCE_TYPE`` has
bit 2 (4, AC_FENCE_TYPE_POLYGON: every inclusion and exclusion item). Inclusion circles
(``MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION``, param1 the radius) and inclusion polygons (runs of
``..._POLYGON_VERTEX_INCLUSION``, param1 the vertex count) must contain the vehicle;
exclusion circles and polygons must not. The fence is *present* with such items and
*enabled* while ``FENCE_ENABLE`` is 1 (set by PARAM_SET or ``MAV_CMD_DO_FENCE_ENABLE``).

Rules (Plane::fence_check, restated):

* a *new* breach (outside an inclusion, inside an exclusion, after none) of an armed,
  enabled fence: STATUSTEXT ``Fence breached: Polygon`` and ``FENCE_ACTION``: 0 report
  only; 1 (RTL) RTL; 6/7 (GUIDED) GUIDED to the return point
  (``MAV_CMD_NAV_FENCE_RETURN_POINT``; home without one) at the RTL altitude. The mode
  change is the fence's ("in fence recovery");
* no new action while in fence recovery, and none for a breach that lasts: a pilot who
  changes mode after the fence acted keeps the vehicle (the breach is no longer new);
* back inside: ``Fence breach cleared``; a later breach acts again;
* ``FENCE_STATUS`` (breach_status, breach_count, breach_type 3 = boundary, breach_time ms
  since boot, breach_mitigation) is sent with SYS_STATUS while the fence is enabled, and
  SYS_STATUS reports the geofence present / enabled / healthy (healthy unless enabled and
  breached) as GCS_MAVLINK does.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

from domain.geodesy import GeoOrigin
from domain.modes import ArduPlaneMode
from groundstation.mavlink.codec import mavlink2
from sitl.mission_store import StoredItem

__all__ = ["FENCE_BREACH_TEXT", "FENCE_CLEARED_TEXT", "SimFence"]

M = mavlink2
FENCE_TYPE_POLYGON = 4
ACTION_REPORT_ONLY, ACTION_RTL, ACTION_GUIDED, ACTION_GUIDED_THR = 0, 1, 6, 7
FENCE_BREACH_TEXT = "Fence breached: Polygon"
FENCE_CLEARED_TEXT = "Fence breach cleared"

Area = tuple[str, bool, list[tuple[float, float]], float]
"""("circle" | "polygon", inclusion, local points (m), radius_m)."""


def _inside_polygon(x_m: float, y_m: float, points: Sequence[tuple[float, float]]) -> bool:
    """Even-odd rule: a ray to +x crosses the boundary an odd number of times."""
    inside = False
    n = len(points)
    for i in range(n):
        (x1, y1), (x2, y2) = points[i], points[(i + 1) % n]
        if (y1 > y_m) != (y2 > y_m):
            x_cross = x1 + (y_m - y1) * (x2 - x1) / (y2 - y1)
            if x_m < x_cross:
                inside = not inside
    return inside


def _outside(x_m: float, y_m: float, areas: list[Area]) -> bool:
    """Whether (x_m, y_m) breaks one of ``areas``."""
    for kind, inclusion, points, radius_m in areas:
        if kind == "circle":
            cx, cy = points[0]
            inside = math.hypot(x_m - cx, y_m - cy) <= radius_m
        else:
            inside = len(points) >= 3 and _inside_polygon(x_m, y_m, points)
        if inside != inclusion:
            return True
    return False


class SimFence:
    """The fence state of one vehicle (module docstring). ``store`` gives the FENCE items
    now, ``param`` reads a parameter."""

    def __init__(self, origin: GeoOrigin, store: Callable[[], list[StoredItem]],
                 param: Callable[[str], float]) -> None:
        self.origin = origin
        self._store = store
        self._param = param
        self._cached: tuple[list[StoredItem], list[Area], tuple[float, float] | None] | None = None
        self.breached = False
        self.breach_count = 0
        self.breach_time_ms = 0
        self.recovery_mode: int | None = None
        """The mode the fence put the vehicle in, while it stays in it (None: none)."""

    # ------------------------------------------------------------------ reading
    def _areas(self) -> tuple[list[Area], tuple[float, float] | None]:
        """The stored items as local areas, and the return point (cached while the items
        are the same: compared by value, so a store cleared or refilled in place, or a new
        list that reuses a freed one's id, is read again)."""
        items = self._store()
        if self._cached is not None and self._cached[0] == items:
            return self._cached[1], self._cached[2]
        areas: list[Area] = []
        ret: tuple[float, float] | None = None
        i = 0
        while i < len(items):
            item = items[i]
            x_m, y_m, _ = self.origin.to_local(item.lat_deg, item.lon_deg)
            cmd = item.command
            if cmd in (M.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION, M.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION):
                areas.append(("circle", cmd == M.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION,
                              [(x_m, y_m)], item.param1))
            elif cmd in (M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                         M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION):
                count = max(1, int(item.param1)) if math.isfinite(item.param1) else 1
                run = items[i:i + count]
                points = [self.origin.to_local(p.lat_deg, p.lon_deg)[:2] for p in run]
                areas.append(("polygon", cmd == M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                              points, 0.0))
                i += len(run)
                continue
            elif cmd == M.MAV_CMD_NAV_FENCE_RETURN_POINT:
                ret = (x_m, y_m)
            i += 1
        self._cached = (list(items), areas, ret)
        return areas, ret

    @property
    def present(self) -> bool:
        return self._present(self._areas()[0])

    def _present(self, areas: list[Area]) -> bool:
        """Present: FENCE_TYPE has the polygon bit and there are ``areas``."""
        return bool(int(self._param("FENCE_TYPE")) & FENCE_TYPE_POLYGON) and bool(areas)

    @property
    def enabled(self) -> bool:
        return int(self._param("FENCE_ENABLE")) == 1

    def outside(self, x_m: float, y_m: float) -> bool:
        """Whether (x_m, y_m) breaks an area of the fence."""
        return _outside(x_m, y_m, self._areas()[0])

    def return_point(self) -> tuple[float, float] | None:
        return self._areas()[1]

    # ------------------------------------------------------------------ the check
    def check(
        self, x_m: float, y_m: float, *, armed: bool, mode: int,
        time_boot_ms: Callable[[], int],
    ) -> tuple[int | None, list[str]]:
        """One check (ArduPlane runs it at 10 Hz): the mode to enter (None: none) and the
        STATUSTEXTs to send (NOTICE). ``time_boot_ms`` is read at a new breach only."""
        if self.recovery_mode is not None and mode != self.recovery_mode:
            self.recovery_mode = None  # someone else changed the mode: no longer the fence's
        if not self.enabled:  # (then the stored items are not even read)
            self.breached = False
            return None, []
        areas = self._areas()[0]
        if not self._present(areas):
            self.breached = False
            return None, []
        outside = _outside(x_m, y_m, areas)
        if not outside:
            if self.breached:
                self.breached = False
                return None, [FENCE_CLEARED_TEXT]
            return None, []
        if self.breached:
            return None, []  # not a new breach: nothing more is done
        self.breached = True
        self.breach_count += 1
        self.breach_time_ms = time_boot_ms()
        if not armed or self.recovery_mode is not None:
            return None, [FENCE_BREACH_TEXT] if armed else []
        action = int(self._param("FENCE_ACTION"))
        target: int | None = None
        if action == ACTION_RTL:
            target = ArduPlaneMode.RTL
        elif action in (ACTION_GUIDED, ACTION_GUIDED_THR):
            target = ArduPlaneMode.GUIDED
        if target is not None:
            self.recovery_mode = target
        return target, [FENCE_BREACH_TEXT]

    def status_bits(self) -> tuple[int, int, int]:
        """SYS_STATUS geofence bits: (present, enabled, health)."""
        bit = M.MAV_SYS_STATUS_GEOFENCE
        present = bit if self.present else 0
        enabled = bit if self.enabled and self.present else 0
        healthy = 0 if enabled and self.breached else bit
        return present, enabled, healthy

    def status_message(self) -> Any:
        """FENCE_STATUS now."""
        return M.MAVLink_fence_status_message(
            1 if self.breached else 0, min(self.breach_count, 65535),
            M.FENCE_BREACH_BOUNDARY if self.breach_count else M.FENCE_BREACH_NONE,
            self.breach_time_ms & 0xFFFFFFFF, M.FENCE_MITIGATE_UNKNOWN,
        )
