"""Per-vehicle files in the run folder that other ground stations open.

* ``missions/<vehicle>/<NNN>-<purpose>.waypoints``: every mission floe uploaded and verified
  by read-back, numbered from 001 in upload order, as QGC WPL 110
  (:func:`~groundstation.mavlink.mission_files.wpl_text`; MAVProxy's ``wp load FILE`` and
  QGroundControl's plan import read it);
* ``params/<vehicle>.parm``: the vehicle's parameters read at join, in MAVProxy's ``param
  save`` form (``param load FILE``, ``param diff``).

Each file is written atomically (:func:`groundstation.storage.atomic_write_text`). A write
that fails (a full disk, a read-only folder) is one ``file_write_failed`` journal line, a
logged fault the operator sees once per kind of file until a write of it succeeds again;
the daemon carries on: these files are copies of what the journal and the tlog hold.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from groundstation.mavlink.mission_files import parm_text, wpl_text
from groundstation.mavlink.mission_items import MissionItem
from groundstation.storage import StorageError, atomic_write_text

__all__ = ["VehicleFiles"]

_UNSAFE = re.compile(r"[^A-Za-z0-9_.-]")


def _safe(name: str) -> str:
    """A vehicle name as a file name: anything but letters, digits, ``_.-`` becomes ``_``."""
    cleaned = _UNSAFE.sub("_", name).lstrip(".")
    return cleaned or "_"


class VehicleFiles:
    """Writes the files of the module docstring under ``run_dir``; ``journal(event,
    logged=..., **fields)`` records a failed write."""

    def __init__(self, run_dir: Path, journal: Callable[..., None]) -> None:
        self.run_dir = run_dir
        self._journal = journal
        self._missions: dict[str, int] = {}
        self._failing: set[str] = set()
        self.written: list[Path] = []
        """Every file written, in order (``gcs report`` lists the run folder's)."""

    def mission(self, vehicle: str, purpose: str, items: Sequence[MissionItem]) -> Path | None:
        """Write one verified mission; the path, or None when the write failed."""
        number = self._missions.get(vehicle, 0) + 1
        self._missions[vehicle] = number
        path = (self.run_dir / "missions" / _safe(vehicle)
                / f"{number:03d}-{_safe(purpose)}.waypoints")
        return self._write("mission", path, wpl_text(items), vehicle=vehicle)

    def params(self, vehicle: str, params: Mapping[str, float]) -> Path | None:
        """Write the vehicle's parameter snapshot; the path, or None when it failed."""
        path = self.run_dir / "params" / f"{_safe(vehicle)}.parm"
        return self._write("params", path, parm_text(params), vehicle=vehicle,
                           count=len(params))

    def _write(self, kind: str, path: Path, text: str, **fields: Any) -> Path | None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_text(path, text)
        except (StorageError, OSError) as exc:
            first = kind not in self._failing
            self._failing.add(kind)
            # the first failure of a kind is told; the next ones only journalled
            self._journal("file_write_failed", logged=not first, kind=kind, path=str(path),
                          error=str(exc), **fields)
            return None
        self._failing.discard(kind)
        self.written.append(path)
        return path
