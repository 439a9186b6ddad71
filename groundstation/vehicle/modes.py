"""ArduPlane flight modes (HEARTBEAT ``custom_mode``) and the ones floe commands in."""

from __future__ import annotations

import enum

__all__ = ["TAKEN_MODES", "PlaneMode", "plane_mode_name"]


class PlaneMode(enum.IntEnum):
    """ArduPlane's ``custom_mode`` numbering (ArduPlane ``mode.h``)."""

    MANUAL = 0
    CIRCLE = 1
    STABILIZE = 2
    TRAINING = 3
    ACRO = 4
    FBWA = 5
    FBWB = 6
    CRUISE = 7
    AUTOTUNE = 8
    AUTO = 10
    RTL = 11
    LOITER = 12
    TAKEOFF = 13
    AVOID_ADSB = 14
    GUIDED = 15
    INITIALISING = 16
    QSTABILIZE = 17
    QHOVER = 18
    QLOITER = 19
    QLAND = 20
    QRTL = 21
    QAUTOTUNE = 22
    QACRO = 23
    THERMAL = 24
    LOITER_ALT_QLAND = 25
    AUTOLAND = 26


TAKEN_MODES = frozenset({PlaneMode.AUTO, PlaneMode.GUIDED})
"""Modes in which floe takes (or takes back) a flying vehicle."""


def plane_mode_name(custom_mode: int) -> str:
    """The mode's name (``MODE_<n>`` if ArduPlane has no such mode)."""
    try:
        return PlaneMode(custom_mode).name
    except ValueError:
        return f"MODE_{custom_mode}"
