"""Track-quality measures of a run: GOSPA, confirmed fraction, time to confirm, false tracks
and id switches (:class:`TrackQualityRecorder`). Pure: no I/O, no clock; time is an argument.

The caller reports every camera frame (:meth:`TrackQualityRecorder.frame`) and, every
second of mission time, the confirmed tracks and the true icebergs in the operating area
(:meth:`TrackQualityRecorder.sample`). Each sample computes GOSPA (``c``, ``p``, ``alpha =
2``; :mod:`observer.gospa`) between the confirmed tracks and the true icebergs; its optimal
assignment, restricted to pairs closer than ``c``, is *the* assignment every other measure
uses: a true iceberg "has a confirmed track" at a sample when the assignment gives it one.

Definitions (:meth:`TrackQualityRecorder.to_dict`):

- ``gospa_mean_m``: the mean GOSPA distance over the samples.
- ``true_confirmed_fraction``: at the last sample, the assigned true icebergs over the true
  icebergs in the area (``None`` without samples or without a true iceberg then).
- ``time_to_confirm_s`` ``{median, max}``: per true iceberg, ``t_a - t_f`` where ``t_f`` is
  the time of the first frame whose footprint disc (``|p - c_fp| <= r``) covers it and
  ``t_a`` the first sample at or after ``t_f`` where it is assigned; over the icebergs for
  which both exist (``None`` when none). An iceberg already tracked before any camera saw it
  (a known target) gets the gap between ``t_f`` and the next sample.
- ``false_tracks_per_hour``: confirmed track ids never assigned to a true iceberg in any
  sample where they were confirmed, per hour of ``duration_s``. A track on a real iceberg
  outside the area is not false: the tracks the area's assignment leaves over are assigned
  (pairs closer than ``c``) to the true icebergs outside the area, when the caller gives
  them; they count for nothing else.
- ``id_switches``: over true icebergs and consecutive samples in which the iceberg is
  assigned in both, the number of times its assigned track id differs. A track lost and
  later replaced (a gap in between) is a fragmentation, not a switch, and is not counted.

Beside ``to_dict`` (not in ``metrics.json``): :attr:`TrackQualityRecorder.truth_changes`,
the track-side view: the number of times a confirmed track is assigned to a true iceberg
other than the last one it was assigned to (gaps allowed), e.g. a stale track that takes
over another iceberg's detections; and :attr:`TrackQualityRecorder.identity_errors`, the
*identity errors*: the number of confirmed track ids assigned, over the run, to more than one
true iceberg (a track counts once however often it changes).
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Mapping

from observer.checks import finite_number
from observer.gospa import GospaResult, Point, gospa


def _point(name: str, value: object) -> Point:
    x: object
    y: object
    try:
        x, y = value  # type: ignore[misc]
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an (x, y) pair, got {value!r}") from None
    return (finite_number(name, x), finite_number(name, y))


def _points(name: str, points: Mapping[str, Point]) -> dict[str, Point]:
    """Validated copy, ordered by id so results never depend on the caller's order."""
    if not isinstance(points, Mapping):
        raise ValueError(f"{name} must be a mapping id -> (x, y), got {type(points).__name__}")
    return {str(k): _point(f"{name}[{k!r}]", points[k]) for k in sorted(points, key=str)}


class TrackQualityRecorder:
    """Accumulates the track-quality measures of one run (see the module docstring).

    Args:
        c_m: GOSPA cut-off and assignment radius (m).
        p: GOSPA order.
    """

    def __init__(self, c_m: float = 150.0, p: float = 2.0) -> None:
        gospa([], [], c_m=c_m, p=p)  # validates c_m and p with gospa's own messages
        self.c_m = float(c_m)
        self.p = float(p)
        self._first_seen_s: dict[str, float] = {}
        self._confirm_delay_s: dict[str, float] = {}
        self._gospa_sum_m = 0.0
        self._samples = 0
        self._ever_matched: dict[str, bool] = {}
        self._previous: dict[str, str] = {}
        self._track_truth: dict[str, str] = {}
        self._track_truths: dict[str, set[str]] = {}
        self._truth_changes = 0
        self._id_switches = 0
        self._last_in_area = 0
        self._last_assigned = 0

    def frame(
        self, t_s: float, footprint_xy_r: tuple[float, float, float], truth_xy: Mapping[str, Point]
    ) -> None:
        """A camera frame at ``t_s`` with footprint ``(x_m, y_m, radius_m)``; ``truth_xy``:
        the true icebergs' positions then (any set that includes those in view)."""
        t = finite_number("t_s", t_s)
        try:
            fx, fy, fr = footprint_xy_r
        except (TypeError, ValueError):
            raise ValueError(
                f"footprint_xy_r must be (x_m, y_m, radius_m), got {footprint_xy_r!r}"
            ) from None
        cx, cy = finite_number("footprint_xy_r x_m", fx), finite_number("footprint_xy_r y_m", fy)
        r = finite_number("footprint_xy_r radius_m", fr)
        if r <= 0.0:
            raise ValueError(f"footprint_xy_r radius_m must be > 0, got {fr!r}")
        for truth_id, (x, y) in _points("truth_xy", truth_xy).items():
            if truth_id not in self._first_seen_s and math.hypot(x - cx, y - cy) <= r:
                self._first_seen_s[truth_id] = t

    def sample(
        self,
        t_s: float,
        confirmed: Mapping[str, Point],
        truth_in_area: Mapping[str, Point],
        truth_outside: Mapping[str, Point] | None = None,
    ) -> GospaResult:
        """One sample (every second of mission time); returns its GOSPA result (indices in
        the id-sorted order of ``confirmed`` and ``truth_in_area``). ``truth_outside``: the
        true icebergs outside the area; confirmed tracks the area's assignment leaves over
        are assigned to them alike (pairs closer than ``c``) only to tell a track on a real
        iceberg outside the area from a false one."""
        t = finite_number("t_s", t_s)
        tracks = _points("confirmed", confirmed)
        truth = _points("truth_in_area", truth_in_area)
        outside = _points("truth_outside", truth_outside or {})
        track_ids, truth_ids = list(tracks), list(truth)
        result = gospa(list(tracks.values()), list(truth.values()), c_m=self.c_m, p=self.p)
        self._gospa_sum_m += result.distance_m
        self._samples += 1
        assigned = {truth_ids[j]: track_ids[i] for i, j in result.matches}
        for track_id in track_ids:
            self._ever_matched.setdefault(track_id, False)
        self._match_outside(tracks, set(assigned.values()), outside)
        for truth_id, track_id in assigned.items():
            self._ever_matched[track_id] = True
            last_truth = self._track_truth.get(track_id)
            if last_truth is not None and last_truth != truth_id:
                self._truth_changes += 1
            self._track_truth[track_id] = truth_id
            self._track_truths.setdefault(track_id, set()).add(truth_id)
            seen = self._first_seen_s.get(truth_id)
            if seen is not None and truth_id not in self._confirm_delay_s and t >= seen:
                self._confirm_delay_s[truth_id] = t - seen
            before = self._previous.get(truth_id)
            if before is not None and before != track_id:
                self._id_switches += 1
        self._previous = assigned
        self._last_in_area = len(truth)
        self._last_assigned = len(assigned)
        return result

    def _match_outside(self, tracks: dict[str, Point], taken: set[str],
                       outside: dict[str, Point]) -> None:
        left = {k: xy for k, xy in tracks.items() if k not in taken}
        if not left or not outside:
            return
        left_ids = list(left)
        result = gospa(list(left.values()), list(outside.values()), c_m=self.c_m, p=self.p)
        for i, _ in result.matches:
            self._ever_matched[left_ids[i]] = True

    @property
    def first_seen_s(self) -> dict[str, float]:
        """True iceberg id -> time of the first frame that covered it."""
        return dict(self._first_seen_s)

    @property
    def time_to_confirm_s(self) -> dict[str, float]:
        """True iceberg id -> its time to confirm (only those with one)."""
        return dict(self._confirm_delay_s)

    @property
    def truth_changes(self) -> int:
        """Times a track was assigned to a true iceberg other than its last one."""
        return self._truth_changes

    @property
    def identity_errors(self) -> int:
        """Confirmed track ids assigned to more than one true iceberg over the run."""
        return sum(len(truths) > 1 for truths in self._track_truths.values())

    @property
    def false_track_ids(self) -> list[str]:
        """Confirmed track ids never assigned to a true iceberg (so far), sorted."""
        return sorted(k for k, matched in self._ever_matched.items() if not matched)

    def to_dict(self, duration_s: float) -> dict[str, object]:
        """The measures for ``metrics.json`` (JSON-plain; ``None`` where undefined)."""
        duration = finite_number("duration_s", duration_s)
        if duration <= 0.0:
            raise ValueError(f"duration_s must be > 0, got {duration_s!r}")
        delays = sorted(self._confirm_delay_s.values())
        return {
            "gospa_mean_m": self._gospa_sum_m / self._samples if self._samples else None,
            "true_confirmed_fraction": (
                self._last_assigned / self._last_in_area if self._last_in_area else None
            ),
            "time_to_confirm_s": {
                "median": statistics.median(delays) if delays else None,
                "max": delays[-1] if delays else None,
            },
            "false_tracks_per_hour": len(self.false_track_ids) * 3600.0 / duration,
            "id_switches": self._id_switches,
        }
