"""The operating area as an ArduPlane geofence: its fence items and their check on read-back.

floe's operating area is a circle (``core/area.py``): ``radius_m`` around home or the boat.
It goes to the vehicle through the mission protocol with ``mission_type =
MAV_MISSION_TYPE_FENCE`` as two items, the form ArduPlane 4.x stores (AC_PolyFence_loader):

* item 0: ``MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION`` (5003), param1 = radius (whole metres:
  ArduPlane keeps the radius as an integer), x/y = the centre (degE7);
* item 1: ``MAV_CMD_NAV_FENCE_RETURN_POINT`` (5000) at the centre: where ArduPlane flies on
  a breach when ``FENCE_ACTION`` is GUIDED (6/7); with RTL (1) it returns home or to a
  rally point.

Both in ``MAV_FRAME_GLOBAL_INT``, z = 0 (ArduPlane reads them back with z = 0). A circle is
the area itself, exactly, in one item; a polygon would only approximate it.

ArduPlane acts on the fence when ``FENCE_TYPE`` has bit 2 (4, "polygon": every inclusion and
exclusion item, circles included) and the fence is enabled (``MAV_CMD_DO_FENCE_ENABLE``
param1 = 1, or ``FENCE_ENABLE`` = 1), with ``FENCE_ACTION`` not 0 (report only).

The fence is the operating area itself (:func:`fence_circle`: its centre, its radius in
whole metres), so what a vehicle reads back equals the area. floe keeps its own waypoints
:func:`keep_in_m` inside that edge (``core/area.py`` clips onto the smaller circle): a loiter
there circles its radius around it, plus the overshoot of capturing the circle, and an area
that moves with the boat is uploaded again only once its centre moved :data:`FENCE_MOVE_M`,
so the fence the vehicle holds lags the area by up to that much. With ``r`` the area's
radius, ``l`` the loiter radius plus overshoot and ``m`` the move allowance (0 for an area
around home), a waypoint lies within ``r - l - m`` of the area's centre, which is within
``m`` of the fence's: its loiter stays within ``r - l - m + m + l = r`` of the fence's
centre, inside the fence.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from domain.errors import LocalProtocolError
from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import mavlink2
from groundstation.mavlink.mission_items import MissionItem, f32
from groundstation.mavlink.mission_verify import ItemMismatch

__all__ = [
    "CAPTURE_OVERSHOOT_M",
    "CMD_FENCE_CIRCLE_INCLUSION",
    "CMD_FENCE_RETURN_POINT",
    "FENCE_ACTION_REPORT_ONLY",
    "FENCE_ACTION_RTL",
    "FENCE_MOVE_M",
    "FENCE_TYPE_POLYGON",
    "MIN_OPERATING_RADIUS_M",
    "FenceCircle",
    "build_fence_items",
    "compare_fence",
    "fence_circle",
    "keep_in_m",
]

M = mavlink2
CMD_FENCE_RETURN_POINT = M.MAV_CMD_NAV_FENCE_RETURN_POINT  # 5000
CMD_FENCE_CIRCLE_INCLUSION = M.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION  # 5003
FENCE_TYPE_POLYGON = 4
"""FENCE_TYPE bit for the inclusion/exclusion items (AC_FENCE_TYPE_POLYGON)."""
FENCE_ACTION_REPORT_ONLY = 0
FENCE_ACTION_RTL = 1
"""ArduPlane's FENCE_ACTION values: 0 report only, 1 RTL, 6 GUIDED, 7 GUIDED_THR_PASS."""
CAPTURE_OVERSHOOT_M = 100.0
"""How far beyond its loiter circle a fixed wing strays while capturing it (m)."""
FENCE_MOVE_M = 250.0
"""An area that moves with the boat is uploaded again once its centre moved this far from
the fence's (m): at the ship's 10 m/s, one fence transfer per flying vehicle every 25 s (a
two-item upload and its read-back, 13 frames and ~350 bytes: ~14 B/s, under 0.3 % of a
57 600-baud radio; measured in docs/daemon.md, "Geofence")."""
MIN_OPERATING_RADIUS_M = 1000.0
"""The smallest operating area floe accepts (m): room for a route inside the keep-in band
(:func:`keep_in_m`: 220 m around home and 470 m around a boat with 120 m loiters)."""
_UINT16_MAX = 65535


@dataclass(frozen=True)
class FenceCircle:
    """An inclusion circle: centre (local ENU m) and radius (whole metres)."""

    x_m: float
    y_m: float
    radius_m: float

    def moved(self, other: FenceCircle | None) -> bool:
        """Whether ``other`` (the fence the vehicle has) no longer stands for this one: none,
        another radius, or a centre more than :data:`FENCE_MOVE_M` away."""
        if other is None or other.radius_m != self.radius_m:
            return True
        return math.hypot(self.x_m - other.x_m, self.y_m - other.y_m) > FENCE_MOVE_M


def keep_in_m(loiter_radius_m: float, around_boat: bool) -> float:
    """How far inside the fence floe keeps a waypoint it loiters at (m; module docstring):
    the loiter radius plus :data:`CAPTURE_OVERSHOOT_M`, plus :data:`FENCE_MOVE_M` for an
    area that moves with the boat (the fence the vehicle holds lags the area by up to that
    much)."""
    return loiter_radius_m + CAPTURE_OVERSHOOT_M + (FENCE_MOVE_M if around_boat else 0.0)


def fence_circle(center_xy_m: tuple[float, float], area_radius_m: float | None
                 ) -> FenceCircle | None:
    """The fence for an area of ``area_radius_m`` around ``center_xy_m``: the area itself,
    radius ``round(area_radius_m)`` (ArduPlane keeps whole metres); None without an area
    (nothing is fenced) or when that radius does not fit ArduPlane's uint16 metres."""
    if area_radius_m is None or not math.isfinite(area_radius_m) or area_radius_m <= 0:
        return None
    radius_m = round(area_radius_m)
    if radius_m > _UINT16_MAX:
        return None
    return FenceCircle(float(center_xy_m[0]), float(center_xy_m[1]), float(radius_m))


def build_fence_items(fence: FenceCircle, origin: GeoOrigin) -> list[MissionItem]:
    """The two fence items (module docstring) for ``fence``; raises
    :class:`~domain.errors.LocalProtocolError` for a centre without a valid lat/lon."""
    lat_deg, lon_deg, _ = origin.to_geodetic(fence.x_m, fence.y_m, 0.0)
    if not (math.isfinite(lat_deg) and math.isfinite(lon_deg) and abs(lat_deg) <= 90.0):
        raise LocalProtocolError(f"fence centre ({fence.x_m}, {fence.y_m}) m has no lat/lon")
    lat_e7 = round(lat_deg * 1e7)
    lon_e7 = round(((lon_deg + 180.0) % 360.0 - 180.0) * 1e7)
    base = {"frame": M.MAV_FRAME_GLOBAL_INT, "x": lat_e7, "y": lon_e7,
            "mission_type": M.MAV_MISSION_TYPE_FENCE}
    return [
        MissionItem(seq=0, command=CMD_FENCE_CIRCLE_INCLUSION, param1=fence.radius_m, **base),
        MissionItem(seq=1, command=CMD_FENCE_RETURN_POINT, **base),
    ]


_FRAME_CLASS = {0: 0, 5: 0, 3: 3, 6: 3}


def compare_fence(
    uploaded: Sequence[MissionItem], downloaded: Sequence[MissionItem]
) -> list[ItemMismatch]:
    """Differences between the fence uploaded and the one read back; empty means verified.

    Every item counts (a fence has no home item): command, mission type, param1 (the radius
    or the vertex count, float32), frame by class (GLOBAL == GLOBAL_INT), x/y within 1 degE7.
    """
    out: list[ItemMismatch] = []
    if len(uploaded) != len(downloaded):
        out.append(ItemMismatch(-1, "count", len(uploaded), len(downloaded)))
    for sent, got in zip(uploaded, downloaded, strict=False):
        seq = sent.seq
        if got.seq != seq:
            out.append(ItemMismatch(seq, "seq", seq, got.seq))
        if got.command != sent.command:
            out.append(ItemMismatch(seq, "command", sent.command, got.command))
            continue
        if got.mission_type != sent.mission_type:
            out.append(ItemMismatch(seq, "mission_type", sent.mission_type, got.mission_type))
        if not math.isclose(f32(sent.param1), f32(got.param1), rel_tol=1e-6, abs_tol=1e-6):
            out.append(ItemMismatch(seq, "param1", sent.param1, got.param1))
        if _FRAME_CLASS.get(sent.frame, sent.frame) != _FRAME_CLASS.get(got.frame, got.frame):
            out.append(ItemMismatch(seq, "frame", sent.frame, got.frame))
        for name in ("x", "y"):
            if abs(getattr(sent, name) - getattr(got, name)) > 1:
                out.append(ItemMismatch(seq, name, getattr(sent, name), getattr(got, name)))
    return out
