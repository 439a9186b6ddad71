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

The fence is the area plus :data:`FENCE_MARGIN_M`: floe clips its waypoints onto the area's
edge and a loiter there circles up to its radius outside it; a fence on the edge itself would
send a vehicle floe sent there home. :func:`fence_circle` states the rule.
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
    "CMD_FENCE_CIRCLE_INCLUSION",
    "CMD_FENCE_RETURN_POINT",
    "FENCE_ACTION_REPORT_ONLY",
    "FENCE_ACTION_RTL",
    "FENCE_MARGIN_M",
    "FENCE_MOVE_M",
    "FENCE_TYPE_POLYGON",
    "FenceCircle",
    "build_fence_items",
    "compare_fence",
    "fence_circle",
]

M = mavlink2
CMD_FENCE_RETURN_POINT = M.MAV_CMD_NAV_FENCE_RETURN_POINT  # 5000
CMD_FENCE_CIRCLE_INCLUSION = M.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION  # 5003
FENCE_TYPE_POLYGON = 4
"""FENCE_TYPE bit for the inclusion/exclusion items (AC_FENCE_TYPE_POLYGON)."""
FENCE_ACTION_REPORT_ONLY = 0
FENCE_ACTION_RTL = 1
"""ArduPlane's FENCE_ACTION values: 0 report only, 1 RTL, 6 GUIDED, 7 GUIDED_THR_PASS."""
FENCE_MARGIN_M = 300.0
"""Fence radius beyond the area's (m): a loiter clipped onto the edge (WP_LOITER_RAD, 60 m by
default, floe's loiters up to ~200 m) plus its overshoot stays inside the fence."""
FENCE_MOVE_M = 100.0
"""An area that moves with the boat is uploaded again once its centre moved this far from
the fence's (m): the fence lags the area by less than this, inside the margin."""
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


def fence_circle(center_xy_m: tuple[float, float], area_radius_m: float | None
                 ) -> FenceCircle | None:
    """The fence for an area of ``area_radius_m`` around ``center_xy_m``: the same centre,
    radius ``round(area_radius_m + FENCE_MARGIN_M)``; None without an area (nothing is
    fenced) or when that radius does not fit ArduPlane's uint16 metres."""
    if area_radius_m is None or not math.isfinite(area_radius_m) or area_radius_m <= 0:
        return None
    radius_m = round(area_radius_m + FENCE_MARGIN_M)
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
