"""Files other ground stations open: a mission as QGC WPL 110, parameters as ``.parm``.

* :func:`wpl_text` -- the text MAVProxy's ``wp save`` writes and its ``wp load`` (pymavlink's
  ``MAVWPLoader.load``) and QGroundControl read: the line ``QGC WPL 110``, then one line per
  item, tab separated: ``seq current frame command param1 param2 param3 param4 x y z
  autocontinue``. x/y are degrees (``MISSION_ITEM``'s float form), written with 7 decimals so
  they give back the uploaded degE7 integers exactly; the ``_INT`` frames are written as
  their float twins (6 -> 3, 5 -> 0), as ArduPilot reads them back and ``wp save`` writes
  them; parameters and z with up to 9 significant digits (float32 survives).
* :func:`parm_text` -- MAVProxy's ``param save`` form: ``NAME value`` per line, names
  sorted, padded to 16 columns; ``param load`` (and Mission Planner) read it.

Both are pure (no I/O): the daemon writes them (``daemon/vehicle_files.py``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from groundstation.mavlink.mission_items import NON_GEO_XY_COMMANDS, MissionItem, f32

__all__ = ["WPL_HEADER", "parm_text", "wpl_text"]

WPL_HEADER = "QGC WPL 110"
_FLOAT_FRAME = {5: 0, 6: 3, 11: 10}
"""An ``_INT`` frame -> its float twin (GLOBAL, GLOBAL_RELATIVE_ALT, GLOBAL_TERRAIN_ALT)."""


def _number(value: float) -> str:
    """A float as text that reads back to the same float32: integral values without a
    fraction, NaN as ``nan`` (pymavlink's ``float()`` reads both)."""
    if math.isnan(value):
        return "nan"
    value = f32(value)
    if value.is_integer() and abs(value) < 1e15:
        return str(int(value))
    return f"{value:.9g}"


def wpl_text(items: Sequence[MissionItem]) -> str:
    """``items`` as a QGC WPL 110 file (module docstring)."""
    lines = [WPL_HEADER]
    for item in items:
        if item.command in NON_GEO_XY_COMMANDS:  # x/y no position: integers, as pymavlink
            x, y = str(item.x), str(item.y)
        else:
            x, y = f"{item.x / 1e7:.7f}", f"{item.y / 1e7:.7f}"
        fields = [
            str(item.seq), str(item.current), str(_FLOAT_FRAME.get(item.frame, item.frame)),
            str(item.command), _number(item.param1), _number(item.param2),
            _number(item.param3), _number(item.param4), x, y, _number(item.z),
            str(item.autocontinue),
        ]
        lines.append("\t".join(fields))
    return "\n".join(lines) + "\n"


def parm_text(params: Mapping[str, float]) -> str:
    """``params`` in MAVProxy's ``param save`` form (module docstring)."""
    return "".join(f"{name:<16.16s} {_number(params[name])}\n" for name in sorted(params))
