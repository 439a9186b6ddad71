"""The tracker's state as the operator views show it: the status JSON's ``tracks``,
``track_counts`` and ``search_cells``, the console's counts line, and which track notes
are worth an operator's attention.

**Views.** The decision core's ``track_views()`` (every track: ``id``, ``status``
``tentative|confirmed|prior``, position ``x_m, y_m``, ``sigma_m2`` = trace of the position
covariance, ``existence`` in [0, 1], ``t_s`` of the estimate) and ``search_view()`` (every
search cell: centre ``x_m, y_m``, side ``size_m``, ``value_m2`` and ``last_covered_s``,
None if never covered; empty when search is off) become plain JSON-able dicts here,
rounded for the page (0.1 m, 0.001 existence). Non-finite numbers become None.

**Notes.** The core journals ``track_born``, ``track_confirmed`` and ``track_deleted``
notes. With clutter (0.1 false alarm per frame, three vehicles at 2 Hz) a tentative track
is born and deleted about every two mission seconds, which would bury everything else in
the operator's panes, so :class:`TrackNotes` marks each ``track_deleted`` line with
``confirmed``: whether the track had been confirmed or announced as a prior entry.
:func:`groundstation.daemon.log_lines.is_operator_event` shows confirmations and the
deletion of confirmed/prior tracks; births and the deletion of never-confirmed tentative
tracks are state updates (the map draws them, the counts count them, the journal keeps
them all).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

from groundstation.core.views import SearchCellView, TrackView

__all__ = [
    "TrackNotes",
    "count_line",
    "search_dicts",
    "track_counts",
    "track_dicts",
]

STATUSES = ("confirmed", "tentative", "prior")


def _round(value: float | None, digits: int) -> float | None:
    if value is None or not math.isfinite(value):
        return None
    return round(float(value), digits)


def track_dicts(views: Iterable[TrackView]) -> list[dict[str, Any]]:
    """The status JSON's ``tracks`` (see the module docstring)."""
    return [
        {
            "id": str(v.id),
            "status": str(v.status),
            "x_m": _round(v.x_m, 1),
            "y_m": _round(v.y_m, 1),
            "sigma_m2": _round(v.sigma_m2, 1),
            "existence": _round(v.existence, 3),
            "t_s": _round(v.t_s, 3),
        }
        for v in views
    ]


def search_dicts(cells: Iterable[SearchCellView]) -> list[dict[str, Any]]:
    """The status JSON's ``search_cells``."""
    return [
        {
            "id": str(c.id),
            "x_m": _round(c.x_m, 1),
            "y_m": _round(c.y_m, 1),
            "size_m": _round(c.size_m, 1),
            "value_m2": _round(c.value_m2, 1),
            "last_covered_s": _round(c.last_covered_s, 1),
        }
        for c in cells
    ]


def track_counts(tracks: Iterable[dict[str, Any]]) -> dict[str, int]:
    """``{"confirmed": n, "tentative": n, "prior": n}`` of :func:`track_dicts`' output."""
    counts = dict.fromkeys(STATUSES, 0)
    for t in tracks:
        status = t.get("status")
        if status in counts:
            counts[status] += 1
    return counts


def count_line(counts: dict[str, int], search_cells: int) -> str:
    """``tracks: 9 confirmed, 3 tentative, 1 prior; 100 search cells`` (the console)."""
    text = "tracks: " + ", ".join(f"{counts.get(s, 0)} {s}" for s in STATUSES)
    return text + (f"; {search_cells} search cells" if search_cells else "")


class TrackNotes:
    """Remembers which tracks were confirmed (or announced as prior entries), so a
    ``track_deleted`` line can say whether the operator ever relied on that track."""

    def __init__(self) -> None:
        self._trusted: set[str] = set()

    def prior(self, track_id: str) -> None:
        """A prior entry was announced (``TargetAdded(prior=True)``)."""
        self._trusted.add(track_id)

    def fields(self, kind: str, track_id: str | None) -> dict[str, Any]:
        """Extra fields for the note's journal line (``{}`` for other notes)."""
        if track_id is None:
            return {}
        if kind == "track_confirmed":
            self._trusted.add(track_id)
        elif kind == "track_deleted":
            trusted = track_id in self._trusted
            self._trusted.discard(track_id)
            return {"confirmed": trusted}
        return {}
