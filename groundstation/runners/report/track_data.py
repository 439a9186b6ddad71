"""What a flight report shows of the multi-target tracker, gathered from journal records.

Three kinds of journal line feed it (a journal without any of them, from before the
tracker, gives an empty :class:`TrackingData` and the report is the one it always was):

* ``track`` lines with ``status`` (``tentative``, ``confirmed`` or ``prior``): where each
  track was and what it was, at every journalled sample;
* ``search`` lines, ``{"event": "search", "t": T, "cells": [[id, x_m, y_m, size_m,
  value_m2], ...]}``: the search cells and their values (the value of a cell grows with
  the time since a camera last covered it, weighted by the prior density of icebergs);
* the tracker's notes, ``track_born``, ``track_confirmed``, ``track_deleted`` (spelt as
  their own ``event``, or as ``{"event": "note", "kind": ...}``), ``target`` the track id
  and ``detail`` the reason.

Malformed entries (a cell that is not five values, a non-finite number) are skipped and
counted in :attr:`TrackingData.skipped`, never raised: a report reads what it can.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "LIFECYCLE_KINDS",
    "STATUSES",
    "Lifecycle",
    "SearchCellRecord",
    "TrackSample",
    "TrackingData",
    "tracking_of",
]

STATUSES = ("tentative", "confirmed", "prior")
LIFECYCLE_KINDS = {"track_born": "born", "track_confirmed": "confirmed",
                   "track_deleted": "deleted"}
"""The tracker's note kinds and the word the report uses for each."""


@dataclass(frozen=True)
class TrackSample:
    """One ``track`` line: mission time, position (m), ``sigma`` (m^2), ``status``."""

    t_s: float
    x_m: float
    y_m: float
    sigma_m2: float
    status: str


@dataclass(frozen=True)
class SearchCellRecord:
    """One cell of a ``search`` line: centre (m), side (m) and value (m^2)."""

    id: str
    x_m: float
    y_m: float
    size_m: float
    value_m2: float


@dataclass(frozen=True)
class Lifecycle:
    """A birth, confirmation or deletion of a track (``kind``: born|confirmed|deleted)."""

    t_s: float
    kind: str
    track: str
    detail: str


@dataclass
class TrackingData:
    """Every track's samples (by id), the search snapshots in time order, the lifecycle
    notes in journal order, and how many malformed entries were skipped."""

    tracks: dict[str, list[TrackSample]] = field(default_factory=dict)
    search: list[tuple[float, list[SearchCellRecord]]] = field(default_factory=list)
    lifecycle: list[Lifecycle] = field(default_factory=list)
    skipped: int = 0

    def present(self) -> bool:
        """True when the journal holds something of the tracker worth a figure: a tentative
        or prior track, a search line or a lifecycle note (a run whose every track was
        known and confirmed from the start gives the report it always gave)."""
        unusual = any(s.status != "confirmed" for rows in self.tracks.values() for s in rows)
        return unusual or bool(self.search) or bool(self.lifecycle)

    def final_status(self) -> dict[str, str]:
        """Each track's status in its last sample."""
        return {tid: rows[-1].status for tid, rows in self.tracks.items() if rows}

    def ever(self, status: str) -> set[str]:
        """The tracks that had ``status`` in some sample or (``confirmed``) a note."""
        out = {tid for tid, rows in self.tracks.items() if any(s.status == status for s in rows)}
        if status == "confirmed":
            out |= {e.track for e in self.lifecycle if e.kind == "confirmed"}
        return out

    def deleted(self) -> dict[str, float]:
        """Track id -> mission time of its deletion note."""
        return {e.track: e.t_s for e in self.lifecycle if e.kind == "deleted"}

    def counts(self) -> dict[str, int]:
        """Notes by kind and tracks by their final status (deleted ones excluded)."""
        out = {kind: 0 for kind in LIFECYCLE_KINDS.values()}
        for e in self.lifecycle:
            out[e.kind] += 1
        gone = self.deleted()
        for tid, status in self.final_status().items():
            if tid not in gone:
                key = f"final_{status}"
                out[key] = out.get(key, 0) + 1
        return out

    def last_search(self) -> list[SearchCellRecord]:
        """The cells of the newest ``search`` line (empty if none)."""
        return self.search[-1][1] if self.search else []


def _finite(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    number = float(value)
    return number if math.isfinite(number) else None


def _cell(raw: Any) -> SearchCellRecord | None:
    if not isinstance(raw, list | tuple) or len(raw) != 5:
        return None
    numbers = [_finite(v) for v in raw[1:]]
    if any(v is None for v in numbers) or not isinstance(raw[0], str | int):
        return None
    x, y, size, value = (float(v) for v in numbers if v is not None)
    if size <= 0:
        return None
    return SearchCellRecord(str(raw[0]), x, y, size, value)


def tracking_of(records: Iterable[Mapping[str, Any]]) -> TrackingData:
    """The tracker's part of a journal (see the module docstring)."""
    data = TrackingData()
    for r in records:
        event = r.get("event")
        t = _finite(r.get("t"))
        if event == "note":
            event = r.get("kind")
        if event == "track" and r.get("target") is not None:
            status = r.get("status")
            if status is None:  # an old journal's line: no tracker, nothing to add
                continue
            x, y, sigma = _finite(r.get("x_m")), _finite(r.get("y_m")), _finite(r.get("sigma"))
            if t is None or x is None or y is None or status not in STATUSES:
                data.skipped += 1
                continue
            data.tracks.setdefault(str(r["target"]), []).append(
                TrackSample(t, x, y, math.nan if sigma is None else sigma, str(status)))
        elif event == "search":
            cells_raw = r.get("cells")
            if t is None or not isinstance(cells_raw, list):
                data.skipped += 1
                continue
            cells = []
            for raw in cells_raw:
                cell = _cell(raw)
                if cell is None:
                    data.skipped += 1
                else:
                    cells.append(cell)
            data.search.append((t, cells))
        elif event in LIFECYCLE_KINDS:
            if t is None or r.get("target") is None:
                data.skipped += 1
                continue
            data.lifecycle.append(Lifecycle(t, LIFECYCLE_KINDS[str(event)], str(r["target"]),
                                            str(r.get("detail") or "")))
    data.search.sort(key=lambda snap: snap[0])
    return data
