"""Verify a downloaded mission against the uploaded one.

:func:`compare_missions` compares a read-back mission with what was uploaded, after
predicting what the autopilot returns (:func:`arduplane_readback`, from AP_Mission's
``mavlink_int_to_mission_cmd`` / ``mission_cmd_to_mavlink_int``):

* lat/lon: integers, tolerance 1 unit (1e-7 deg, ~1 cm);
* altitude: ArduPilot stores int32 centimetres (truncated), so tolerance 0.015 m;
* params: float32 on the wire, compared after rounding to float32 (relative 1e-6); NaN equals
  NaN;
* frames compared by class (``GLOBAL_RELATIVE_ALT`` == ``GLOBAL_RELATIVE_ALT_INT``: ArduPilot
  reads back the non-INT frame), and only for items that carry a position;
* item 0 (home) is skipped by default: ArduPilot reads it back as its own home.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any, Literal

from groundstation.mavlink.mission_items import (
    CMD_DO_CHANGE_SPEED,
    CMD_NAV_LOITER_TIME,
    CMD_NAV_LOITER_UNLIM,
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    LOCATION_COMMANDS,
    MissionItem,
    f32,
)

__all__ = ["ItemMismatch", "arduplane_readback", "compare_missions"]

_UINT16_MAX = 65535
# Frame classes: a frame and its _INT twin mean the same thing.
FRAME_CLASS = {0: 0, 5: 0, 3: 3, 6: 3, 10: 10, 11: 10}


def _uint(value: float, high: int) -> int:
    """C float -> unsigned conversion as ArduPilot effectively does (NaN/negative -> 0)."""
    if not math.isfinite(value) or value <= 0.0:
        return 0
    return min(int(value), high)


def arduplane_readback(item: MissionItem) -> MissionItem:
    """What ArduPlane returns on download for an uploaded ``item``.

    From AP_Mission: NAV_WAYPOINT keeps param2/param3 as bytes (param1 hold time and param4
    dropped); NAV_LOITER_UNLIM keeps |param3| as uint16 with its sign; NAV_LOITER_TIME keeps
    param1 as uint16 seconds, param3 only as its sign (+-1), param4 as (param4 > 0);
    NAV_TAKEOFF keeps param1 (pitch); DO_CHANGE_SPEED keeps param1 (uint8), param2, param3.
    Positions come back in the non-INT frame with z truncated to centimetres; non-positional
    items come back with frame, x, y, z = 0. ``current`` is 0, ``autocontinue`` 1.
    """
    out = replace(item, current=0, autocontinue=1)
    p1, p2, p3, p4 = item.param1, item.param2, item.param3, item.param4
    if item.command == CMD_NAV_WAYPOINT:
        out = replace(
            out, param1=0.0, param2=float(_uint(p2, 255)), param3=float(_uint(p3, 255)), param4=0.0
        )
    elif item.command == CMD_NAV_LOITER_UNLIM:
        radius = float(_uint(abs(p3) if math.isfinite(p3) else 0.0, _UINT16_MAX))
        out = replace(out, param1=0.0, param2=0.0, param3=-radius if p3 < 0 else radius, param4=0.0)
    elif item.command == CMD_NAV_LOITER_TIME:
        out = replace(
            out,
            param1=float(_uint(p1, _UINT16_MAX)),
            param2=0.0,
            param3=-1.0 if p3 < 0 else 1.0,
            param4=1.0 if p4 > 0 else 0.0,
        )
    elif item.command == CMD_NAV_TAKEOFF:
        out = replace(out, param1=float(_uint(p1, _UINT16_MAX)), param2=0.0, param3=0.0, param4=0.0)
    elif item.command == CMD_DO_CHANGE_SPEED:
        out = replace(out, param1=float(_uint(p1, 255)), param4=0.0)
    if item.command in LOCATION_COMMANDS:
        z_m = math.trunc(item.z * 100.0) / 100.0 if math.isfinite(item.z) else item.z
        out = replace(out, frame={5: 0, 6: 3, 11: 10}.get(item.frame, item.frame), z=z_m)
    else:
        out = replace(out, frame=0, x=0, y=0, z=0.0)
    return out


@dataclass(frozen=True)
class ItemMismatch:
    """One difference between the expected and the downloaded mission (seq -1: count)."""

    seq: int
    field: str
    expected: Any
    actual: Any

    def __str__(self) -> str:
        return f"item {self.seq}: {self.field} expected {self.expected!r}, got {self.actual!r}"


def _param_equal(expected: float, actual: float) -> bool:
    if math.isnan(expected) or math.isnan(actual):
        return math.isnan(expected) and math.isnan(actual)
    return math.isclose(f32(expected), f32(actual), rel_tol=1e-6, abs_tol=1e-6)


def compare_missions(
    uploaded: Sequence[MissionItem],
    downloaded: Sequence[MissionItem],
    *,
    skip_home: bool = True,
    autopilot: Literal["arduplane", "exact"] = "arduplane",
    latlon_tolerance_e7: int = 1,
    alt_tolerance_m: float = 0.015,
) -> list[ItemMismatch]:
    """Differences between what was uploaded and what was read back; empty means verified.

    With ``autopilot="arduplane"`` each uploaded item is first mapped through
    :func:`arduplane_readback`; with ``"exact"`` the vehicle must echo the items (frames
    still compared by class). ``skip_home`` ignores item 0, which ArduPilot replaces by its
    own home position.
    """
    mismatches: list[ItemMismatch] = []
    if len(uploaded) != len(downloaded):
        mismatches.append(ItemMismatch(-1, "count", len(uploaded), len(downloaded)))
    for sent, got in zip(uploaded, downloaded, strict=False):
        if skip_home and sent.seq == 0:
            continue
        want = arduplane_readback(sent) if autopilot == "arduplane" else sent
        seq = sent.seq

        def differ(field: str, expected: Any, actual: Any, seq: int = seq) -> None:
            mismatches.append(ItemMismatch(seq, field, expected, actual))

        if got.seq != want.seq:
            differ("seq", want.seq, got.seq)
        if got.command != want.command:
            differ("command", want.command, got.command)
            continue
        if got.mission_type != want.mission_type:
            differ("mission_type", want.mission_type, got.mission_type)
        if autopilot == "exact" and got.autocontinue != want.autocontinue:
            differ("autocontinue", want.autocontinue, got.autocontinue)
        for name in ("param1", "param2", "param3", "param4"):
            if not _param_equal(getattr(want, name), getattr(got, name)):
                differ(name, getattr(want, name), getattr(got, name))
        if want.command not in LOCATION_COMMANDS:
            continue
        if FRAME_CLASS.get(want.frame, want.frame) != FRAME_CLASS.get(got.frame, got.frame):
            differ("frame", want.frame, got.frame)
        for name in ("x", "y"):
            if abs(getattr(want, name) - getattr(got, name)) > latlon_tolerance_e7:
                differ(name, getattr(want, name), getattr(got, name))
        if not (math.isfinite(got.z) and abs(want.z - got.z) <= alt_tolerance_m):
            differ("z", want.z, got.z)
    return mismatches
