"""Documented limits of what floe accepts from files and flags (docs/limits in README).

Each limit is far above any real use and far below what would exhaust memory or time:
beyond them a file or flag gets a one-line error naming the field, never a MemoryError,
RecursionError or a run that cannot finish. The daemon's control API has limits of its own
(docs/control.md).
"""

from __future__ import annotations

__all__ = [
    "MAX_COORDINATE_M",
    "MAX_DURATION_S",
    "MAX_FILE_BYTES",
    "MAX_FLEET",
    "MAX_SPEED_M_S",
    "MAX_TARGETS",
    "MAX_WIND_M_S",
    "MAX_YAML_DEPTH",
    "MAX_YAML_NODES",
]

MAX_FLEET = 50
"""UAVs in a scenario, ``--uavs`` or ``sim:N`` (the planner's problem grows as N^2)."""
MAX_TARGETS = 500
"""Targets in a scenario (listed plus random) or a ``--targets`` file."""
MAX_SPEED_M_S = 100.0
"""|velocity| of a target or the boat, and a UAV's airspeed (icebergs drift < 3 m/s)."""
MAX_WIND_M_S = 60.0
"""The strongest mean wind or gust std floe accepts (m/s); above any flyable weather."""
MAX_COORDINATE_M = 1.0e6
"""|x|, |y| of anything in the local frame (1 000 km from the origin)."""
MAX_DURATION_S = 30 * 86400.0
"""A scenario's or run's duration, and a scripted event's time (30 days)."""
MAX_FILE_BYTES = 16 * 1024 * 1024
"""A YAML file (config, scenario, targets)."""
MAX_YAML_DEPTH = 32
"""Nesting of mappings/lists in a YAML file."""
MAX_YAML_NODES = 200_000
"""Values in a YAML file, counting every use of an alias (so an alias bomb is refused)."""
