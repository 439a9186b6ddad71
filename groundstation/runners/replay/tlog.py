"""What a tlog holds, vehicle by vehicle: for serving it back and for reports.

Any tool's tlog (floe's ``flight.tlog``, MAVProxy, QGroundControl, pymavlink's logger) is
read with :class:`~groundstation.link.tlog.TlogReader`, which resynchronises past damage
and lists the skipped byte ranges. Frames are grouped by MAVLink source system id:

* a **vehicle** is a system id that sent a HEARTBEAT which is not a ground station's
  (type GCS, or autopilot INVALID), or any GLOBAL_POSITION_INT;
* the others (ground stations, floe's own commands to the vehicles) are kept apart, so
  serving plays only the vehicles back.

Positions come from GLOBAL_POSITION_INT (lat/lon 1e-7 deg, relative altitude mm, heading
cdeg), modes from HEARTBEAT ``custom_mode`` (ArduPlane's names), texts from STATUSTEXT.
"""

from __future__ import annotations

import collections
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pymap3d

from domain.errors import DataError
from groundstation.link.tlog import TlogReader
from groundstation.mavlink.telemetry_events import mode_name

__all__ = ["TlogError", "TlogSummary", "VehicleLog", "read_tlog", "tlog_of"]

_MAV_TYPE_GCS = 6
_MAV_AUTOPILOT_INVALID = 8


class TlogError(DataError):
    """A tlog that cannot be used; one-line message."""


@dataclass
class VehicleLog:
    """One system id's traffic."""

    system_id: int
    messages: collections.Counter[str] = field(default_factory=collections.Counter)
    # (t_unix_s, lat_deg, lon_deg, relative_alt_m, heading_deg or nan)
    positions: list[tuple[float, float, float, float, float]] = field(default_factory=list)
    modes: list[tuple[float, str]] = field(default_factory=list)
    texts: list[tuple[float, str]] = field(default_factory=list)
    heartbeat_types: set[int] = field(default_factory=set)
    autopilots: set[int] = field(default_factory=set)
    first_t_s: float | None = None
    last_t_s: float | None = None

    @property
    def frames(self) -> int:
        return sum(self.messages.values())

    @property
    def is_vehicle(self) -> bool:
        if self.messages.get("GLOBAL_POSITION_INT"):
            return True
        ground = {_MAV_TYPE_GCS} & self.heartbeat_types or (
            self.autopilots and self.autopilots <= {_MAV_AUTOPILOT_INVALID}
        )
        return bool(self.heartbeat_types) and not ground


@dataclass
class TlogSummary:
    """A whole tlog (see the module docstring)."""

    path: Path
    size_bytes: int
    records: int = 0
    skipped: list[tuple[int, int]] = field(default_factory=list)
    systems: dict[int, VehicleLog] = field(default_factory=dict)
    first_t_s: float | None = None
    last_t_s: float | None = None

    @property
    def vehicles(self) -> dict[int, VehicleLog]:
        return {k: v for k, v in sorted(self.systems.items()) if v.is_vehicle}

    @property
    def skipped_bytes(self) -> int:
        return sum(b - a for a, b in self.skipped)

    def origin(self) -> tuple[float, float] | None:
        """The first valid vehicle position (lat, lon): a local frame for maps."""
        best: tuple[float, float, float] | None = None
        for v in self.vehicles.values():
            for t, lat, lon, _alt, _hdg in v.positions:
                if lat or lon:
                    if best is None or t < best[0]:
                        best = (t, lat, lon)
                    break
        return (best[1], best[2]) if best else None

    def local_tracks(self, origin: tuple[float, float] | None = None) -> dict[int, np.ndarray]:
        """Each vehicle's track as an array of rows (t_unix_s, east_m, north_m)."""
        origin = origin or self.origin()
        out: dict[int, np.ndarray] = {}
        if origin is None:
            return out
        for sysid, v in self.vehicles.items():
            rows = np.array([p[:3] for p in v.positions if p[1] or p[2]], dtype=float)
            if rows.size == 0:
                continue
            e, n, _u = pymap3d.geodetic2enu(rows[:, 1], rows[:, 2], 0.0, origin[0], origin[1], 0.0)
            out[sysid] = np.column_stack([rows[:, 0], np.asarray(e), np.asarray(n)])
        return out

    def skipped_text(self) -> list[str]:
        return [f"skipped damaged bytes {a}..{b} ({b - a} bytes)" for a, b in self.skipped]


def tlog_of(path: Path) -> Path:
    """``RUN_DIR`` -> ``RUN_DIR/flight.tlog``; a file is the tlog itself."""
    if path.is_dir():
        candidate = path / "flight.tlog"
        if not candidate.is_file():
            raise TlogError(f"{path}: no flight.tlog in this folder")
        return candidate
    if not path.is_file():
        raise TlogError(f"{path}: no such file")
    return path


def read_tlog(path: Path) -> TlogSummary:
    """Read a whole tlog (run folder or file) into a :class:`TlogSummary`."""
    tlog = tlog_of(path)
    try:
        size = tlog.stat().st_size
        reader = TlogReader(tlog)
        summary = TlogSummary(tlog, size)
        for record in reader:
            _add(summary, record.t_unix_s, record.message)
    except OSError as exc:
        raise TlogError(f"{tlog}: cannot read: {exc.strerror or exc}") from None
    summary.records = reader.records
    summary.skipped = list(reader.skipped)
    if summary.records == 0:
        raise TlogError(f"{tlog}: no valid MAVLink record in {size} bytes")
    return summary


def _add(summary: TlogSummary, t_s: float, msg: Any) -> None:
    kind = str(msg.get_type())
    sysid = int(msg.get_srcSystem())
    v = summary.systems.get(sysid)
    if v is None:
        v = summary.systems[sysid] = VehicleLog(sysid)
    v.messages[kind] += 1
    if v.first_t_s is None:
        v.first_t_s = t_s
    v.last_t_s = t_s
    if summary.first_t_s is None:
        summary.first_t_s = t_s
    summary.last_t_s = t_s
    if kind == "GLOBAL_POSITION_INT":
        hdg = float(msg.hdg)
        v.positions.append(
            (
                t_s,
                msg.lat / 1e7,
                msg.lon / 1e7,
                msg.relative_alt / 1000.0,
                hdg / 100.0 if hdg != 65535 else float("nan"),
            )
        )
    elif kind == "HEARTBEAT":
        v.heartbeat_types.add(int(msg.type))
        v.autopilots.add(int(msg.autopilot))
        if int(msg.type) != _MAV_TYPE_GCS:
            name = mode_name(int(msg.custom_mode))
            if not v.modes or v.modes[-1][1] != name:
                v.modes.append((t_s, name))
    elif kind == "STATUSTEXT":
        text = msg.text
        if isinstance(text, bytes):
            text = text.decode("utf-8", "replace")
        v.texts.append((t_s, str(text).rstrip("\x00")))
