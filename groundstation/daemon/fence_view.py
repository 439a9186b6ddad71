"""The geofence in the control API's state document (docs/control.md), for the live map.

``fence`` is the operating area's geofence now, as :meth:`Daemon.fence
<groundstation.daemon.daemon.Daemon.fence>` gives it to every vehicle
(``mavlink/fence_items.py``): ``{"x_m", "y_m", "radius_m"}``, the inclusion circle's centre
in local ENU metres and its radius in whole metres; None without an operating area. Each
vehicle's ``fence_verified`` says whether it holds that fence: its controller's
``fence_held`` (the fence last read back equal and enabled, journalled ``fence`` with
``ok: true``) stands for it by :meth:`FenceCircle.moved
<groundstation.mavlink.fence_items.FenceCircle.moved>` (the same radius, a centre at most
``FENCE_MOVE_M`` away). False before its first verified fence, after a reboot, while a
moved fence is on its way, and when its uploads failed.
"""

from __future__ import annotations

from typing import Any

from groundstation.mavlink.fence_items import FenceCircle

__all__ = ["fence_dict", "holds_fence"]


def fence_dict(fence: FenceCircle | None) -> dict[str, Any] | None:
    """The state document's ``fence`` (module docstring)."""
    if fence is None:
        return None
    return {"x_m": fence.x_m, "y_m": fence.y_m, "radius_m": fence.radius_m}


def holds_fence(fence: FenceCircle | None, held: FenceCircle | None) -> bool:
    """A vehicle's ``fence_verified``: it holds ``fence``, verified (module docstring)."""
    return fence is not None and held is not None and not fence.moved(held)
