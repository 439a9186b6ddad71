"""ArduPlane's flight modes (HEARTBEAT ``custom_mode``), as an :class:`enum.IntEnum`.

Numbers are ArduPlane's ``Mode::Number``; ``INITIALISING`` (16) is reported while the
autopilot boots. The Q modes are QuadPlane's. A number floe does not know is shown as
``MODE_<n>`` (:func:`mode_name`).
"""

from __future__ import annotations

import enum

__all__ = ["ARDUPLANE_MODES", "TAKEN_MODES", "ArduPlaneMode", "mode_name"]


class ArduPlaneMode(enum.IntEnum):
    """ArduPlane's ``custom_mode`` numbers."""

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


ARDUPLANE_MODES: dict[int, str] = {int(mode): mode.name for mode in ArduPlaneMode}
"""Number -> name, for tables and journal lines."""

TAKEN_MODES = frozenset({ArduPlaneMode.AUTO, ArduPlaneMode.GUIDED})
"""The modes in which floe commands a vehicle; any other is someone else's."""


def mode_name(custom_mode: int) -> str:
    """The mode's name, ``MODE_<n>`` for a number ArduPlane does not define."""
    try:
        return ArduPlaneMode(custom_mode).name
    except ValueError:
        return f"MODE_{custom_mode}"
