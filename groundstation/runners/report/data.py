"""What a flight report shows, gathered from a run folder, a journal or a bare tlog.

Sources, in order of preference for each item:

* ``gcs simulate`` folders: ``journal.jsonl`` (inputs, decisions, ``track``, ``truth``,
  ``boat``, ``detection``, ``loiter_end``, scripted events) and ``metrics.json``.
  Vehicle tracks come from the journalled ``Telemetry``/``VehicleJoined`` inputs.
* ``gcs run`` folders: ``journal.jsonl`` (``track``, ``plan``, ``fly``, ``upload``,
  ``link_lost``/``link_restored``, ``override``/``resume``, ``mode``, ``release``...) and
  ``flight.tlog``: vehicle tracks from GLOBAL_POSITION_INT, in the local frame of the
  journal's ``origin`` (else the start record's, else the first position).
* a bare tlog (any tool's): vehicle tracks and modes only.

Wind: the core's estimate over time from the ``wind`` lines (a meaningful change each; the
start is the fallback of the ``start`` record's core configuration), each vehicle's own
reports from the ``WindReport`` inputs, and the ``wind_outlier`` notes.

Tracker: ``track`` lines with a ``status``, ``search`` lines and the ``track_*`` notes
(:mod:`~groundstation.runners.report.track_data`); tentative tracks are left out of the
per-target estimates (the map and uncertainty figures) and drawn in the tracking figure.

Times are mission seconds for journals; for a bare tlog, seconds since its first record.
"""

from __future__ import annotations

import json
import math
import statistics
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from domain.errors import DataError
from groundstation.runners.replay.journal import (
    JournalError,
    LoadedJournal,
    load_journal,
    skipped_summary,
)
from groundstation.runners.replay.tlog import TlogError, TlogSummary, read_tlog
from groundstation.runners.report.track_data import TrackingData, tracking_of

__all__ = ["ReportError", "RunData", "load_run_data"]

Row = tuple[float, ...]


class ReportError(DataError):
    """Nothing to report on; one-line message."""


@dataclass
class RunData:
    """Everything the report draws (see the module docstring)."""

    source: str
    path: Path
    title: str = ""
    vehicle_tracks: dict[str, list[Row]] = field(default_factory=dict)  # (t, x, y)
    target_truth: dict[str, list[Row]] = field(default_factory=dict)  # (t, x, y)
    target_estimates: dict[str, list[Row]] = field(default_factory=dict)  # (t, x, y, sigma)
    boat: list[Row] = field(default_factory=list)
    fly: list[dict[str, Any]] = field(default_factory=list)
    plans: list[dict[str, Any]] = field(default_factory=list)
    uploads: list[dict[str, Any]] = field(default_factory=list)
    link_events: list[dict[str, Any]] = field(default_factory=list)
    overrides: list[dict[str, Any]] = field(default_factory=list)
    loiter_ends: list[dict[str, Any]] = field(default_factory=list)
    detections: list[Row] = field(default_factory=list)  # (t, x, y)
    modes: dict[str, list[tuple[float, str]]] = field(default_factory=dict)
    wind: list[dict[str, Any]] = field(default_factory=list)  # the core's wind lines
    wind_reports: dict[str, list[Row]] = field(default_factory=dict)  # (t, wx, wy)
    wind_outliers: list[dict[str, Any]] = field(default_factory=list)
    metrics: dict[str, Any] | None = None
    start: dict[str, Any] | None = None
    tlog: TlogSummary | None = None
    warnings: list[str] = field(default_factory=list)
    end_t_s: float = 0.0
    tracking: TrackingData = field(default_factory=TrackingData)
    """The multi-target tracker's lines (empty for journals from before it)."""
    vehicle_files: list[tuple[str, str, Path]] = field(default_factory=list)
    """A ``gcs run`` folder's per-vehicle files: (vehicle, "mission" | "parameters", path),
    the QGC WPL 110 missions in upload order, then the ``.parm`` snapshots."""

    def mean_uncertainty(self) -> list[tuple[float, float]]:
        """[t, mean sigma over the targets estimated at t] (metrics' series if present)."""
        if self.metrics and self.metrics.get("uncertainty_series"):
            return [(float(t), float(s)) for t, s in self.metrics["uncertainty_series"]]
        by_t: dict[float, list[float]] = defaultdict(list)
        for rows in self.target_estimates.values():
            for row in rows:
                if math.isfinite(row[3]):
                    by_t[round(row[0], 3)].append(row[3])
        return [(t, sum(v) / len(v)) for t, v in sorted(by_t.items())]

    def vehicles(self) -> list[str]:
        names = set(self.vehicle_tracks) | {str(f["vehicle"]) for f in self.fly}
        names |= set(self.modes)
        return sorted(names, key=_natural)


def _natural(text: str) -> tuple[int, str]:
    return (int(text), "") if text.isdigit() else (1 << 30, text)


def _num(value: Any, default: float = math.nan) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return default
    return out


_OVERRIDE_EVENTS = (
    "override",
    "resume",
    "release",
    "send_home",
    "battery_low",
    "reboot",
    "vehicle_lost",
    "vehicle_returned",
    "vehicle_rebooted",
)


def _from_journal(data: RunData, journal: LoadedJournal) -> None:
    data.warnings += journal.warnings(first=5)
    skipped = skipped_summary(journal.lines_total, [line for line, _ in journal.damaged])
    if skipped:
        data.warnings.append(f"{journal.path}: {skipped}")
    data.start = journal.start
    seen_release: set[tuple[float, str, str]] = set()
    solved: dict[str, dict[str, Any]] = {}  # PlanSolved inputs: the full result
    for r in journal.records:
        event = r.get("event")
        t = _num(r.get("t"), 0.0)
        data.end_t_s = max(data.end_t_s, t)
        vehicle = None if r.get("vehicle") is None else str(r.get("vehicle"))
        if event == "input":
            kind = r.get("kind")
            if kind in ("Telemetry", "VehicleJoined") and vehicle is not None:
                data.vehicle_tracks.setdefault(vehicle, []).append(
                    (t, _num(r.get("x_m")), _num(r.get("y_m")))
                )
            elif kind == "PlanSolved" and isinstance(r.get("result"), dict):
                solved[str(r.get("request_id"))] = r["result"]
            elif kind == "WindReport" and vehicle is not None:
                data.wind_reports.setdefault(vehicle, []).append(
                    (t, _num(r.get("wx_m_s")), _num(r.get("wy_m_s")))
                )
            continue
        if event == "track" and r.get("target") is not None:
            if r.get("status") == "tentative":  # the tracking figure draws those
                continue
            data.target_estimates.setdefault(str(r["target"]), []).append(
                (t, _num(r.get("x_m")), _num(r.get("y_m")), _num(r.get("sigma")))
            )
        elif event == "truth" and r.get("target") is not None:
            data.target_truth.setdefault(str(r["target"]), []).append(
                (t, _num(r.get("x_m")), _num(r.get("y_m")))
            )
        elif event == "boat":
            data.boat.append((t, _num(r.get("x_m")), _num(r.get("y_m"))))
        elif event == "fly" and vehicle is not None:
            data.fly.append(
                {
                    "t": t,
                    "vehicle": vehicle,
                    "target": r.get("target"),
                    "x_m": _num(r.get("x_m")),
                    "y_m": _num(r.get("y_m")),
                    "loiter_s": _num(r.get("loiter_s"), 0.0),
                    "loiter_radius_m": _num(r.get("loiter_radius_m")),
                }
            )
        elif event == "plan":
            raw_result = r.get("result")
            result: dict[str, Any] = raw_result if isinstance(raw_result, dict) else {}
            data.plans.append(
                {
                    "t": t,
                    "request": r.get("request_id", r.get("request")),
                    "status": r.get("status", result.get("status")),
                    "solve_time_s": _num(r.get("solve_time_s", result.get("solve_time_s"))),
                    "hit_time_limit": bool(result.get("hit_time_limit", False)),
                    "objective": _num(r.get("objective", result.get("objective"))),
                }
            )
        elif event == "upload":
            data.uploads.append(
                {
                    "t": t,
                    "vehicle": vehicle,
                    "ok": bool(r.get("ok")),
                    "retries": int(_num(r.get("retries"), 0.0)),
                    "purpose": r.get("purpose"),
                    "error": r.get("error"),
                }
            )
        elif event in ("link_lost", "link_restored"):
            data.link_events.append({"t": t, "vehicle": vehicle, "event": event})
        elif event in _OVERRIDE_EVENTS:
            key = (round(t, 3), str(event), str(vehicle))
            if key in seen_release:  # gcs simulate journals a release twice
                continue
            seen_release.add(key)
            data.overrides.append(
                {"t": t, "vehicle": vehicle, "event": event, "reason": r.get("reason")}
            )
        elif event == "loiter_end":
            data.loiter_ends.append({"t": t, "vehicle": vehicle})
        elif event == "detection":
            data.detections.append((t, _num(r.get("x_m")), _num(r.get("y_m"))))
        elif event == "mode" and vehicle is not None:
            data.modes.setdefault(vehicle, []).append((t, str(r.get("mode"))))
        elif event == "wind":
            data.wind.append({"t": t, "speed_m_s": _num(r.get("speed_m_s")),
                              "from_deg": _num(r.get("from_deg")),
                              "source": str(r.get("source", "?")),
                              "vehicles": [str(v) for v in r.get("vehicles") or []]})
        elif event == "wind_outlier":
            data.wind_outliers.append({"t": t, "vehicle": vehicle, "detail": r.get("detail")})
    data.tracking = tracking_of(journal.records)
    if data.tracking.skipped:
        data.warnings.append(f"{journal.path}: {data.tracking.skipped} malformed tracker "
                             "entries (track, search or track_* lines) skipped")
    for plan in data.plans:  # gcs run's plan lines lack hit_time_limit; the inputs have it
        full = solved.get(str(plan["request"]))
        if full is not None and full.get("hit_time_limit"):
            plan["hit_time_limit"] = True


def _origin_of(journal: LoadedJournal | None) -> tuple[float, float] | None:
    if journal is None:
        return None
    for r in journal.records:
        if r.get("event") == "origin" and r.get("lat_deg") is not None:
            return _num(r["lat_deg"]), _num(r["lon_deg"])
    start = journal.start or {}
    origin = start.get("origin")
    if isinstance(origin, dict) and origin.get("lat_deg") is not None:
        return _num(origin["lat_deg"]), _num(origin["lon_deg"])
    return None


def _vehicle_name(journal: LoadedJournal | None, sysid: int) -> str:
    if journal is not None:
        for r in journal.records:
            if (
                r.get("event") in ("vehicle_seen", "vehicle_joined")
                and r.get("system_id") == sysid
                and r.get("vehicle") is not None
            ):
                return str(r["vehicle"])
    return str(sysid)


def _from_tlog(data: RunData, tlog: TlogSummary, journal: LoadedJournal | None) -> None:
    data.tlog = tlog
    data.warnings += [f"{tlog.path}: {text}" for text in tlog.skipped_text()]
    origin = _origin_of(journal) or tlog.origin()
    tracks = tlog.local_tracks(origin)
    # Mission time of a journalled run: interpolated between the journal lines' two clocks
    # (``t`` mission, ``unix_s`` wall), which is right under any speed-up; a bare tlog (or
    # a journal without ``unix_s``) counts from its first record.
    pairs = sorted(
        (_num(r["unix_s"]), _num(r.get("t")))
        for r in (journal.records if journal else [])
        if r.get("unix_s") is not None and r.get("t") is not None
    )
    pairs = [p for p in pairs if math.isfinite(p[0]) and math.isfinite(p[1])]
    first_unix = tlog.first_t_s or 0.0
    unix_axis = np.array([p[0] for p in pairs])
    mission_axis = np.array([p[1] for p in pairs])

    def mission(t_unix: float) -> float:
        if len(pairs) < 2:
            return t_unix - first_unix
        return float(np.interp(t_unix, unix_axis, mission_axis))

    have_tracks = bool(data.vehicle_tracks)
    for sysid, v in tlog.vehicles.items():
        name = _vehicle_name(journal, sysid)
        if not have_tracks and sysid in tracks:
            data.vehicle_tracks[name] = [(mission(t), x, y) for t, x, y in tracks[sysid]]
        if name not in data.modes and v.modes:
            data.modes[name] = [(mission(t), mode) for t, mode in v.modes]
        if v.last_t_s is not None:
            data.end_t_s = max(data.end_t_s, mission(v.last_t_s))


def load_run_data(path: Path, say: Callable[[str], None] | None = None) -> RunData:
    """Gather a report's data from a run folder, a journal file or a tlog."""
    note = say or (lambda text: None)
    if not path.exists():
        raise ReportError(f"{path}: no such file or folder")
    journal: LoadedJournal | None = None
    tlog: TlogSummary | None = None
    if path.is_file() and path.suffix.lower() == ".tlog":
        tlog_path: Path | None = path
        journal_path: Path | None = None
    elif path.is_file():
        journal_path, tlog_path = path, None
    else:
        journal_path = path / "journal.jsonl" if (path / "journal.jsonl").is_file() else None
        tlog_path = path / "flight.tlog" if (path / "flight.tlog").is_file() else None
        if journal_path is None and tlog_path is None:
            raise ReportError(f"{path}: neither journal.jsonl nor flight.tlog in this folder")
    if journal_path is not None:
        note(f"reading {journal_path}")
        try:
            journal = load_journal(journal_path)
            if journal.start is None:
                raise JournalError(f"{journal.path}: no 'start' record (is this a floe journal?)")
        except JournalError as exc:
            journal = None
            if tlog_path is None:
                raise ReportError(str(exc)) from None
            note(f"warning: {exc}; reporting the tlog only")
    source = "tlog"
    if journal is not None:
        start = journal.start or {}
        source = str(start.get("frontend") or ("run" if "config" in start else "journal"))
    data = RunData(source, path)
    if journal is not None:
        _from_journal(data, journal)
    if tlog_path is not None:
        note(f"reading {tlog_path}")
        try:
            tlog = read_tlog(tlog_path)
        except TlogError as exc:
            if journal is None:
                raise ReportError(str(exc)) from None
            data.warnings.append(str(exc))
        if tlog is not None:
            _from_tlog(data, tlog, journal)
    if path.is_dir():
        data.vehicle_files = vehicle_files(path)
    metrics_path = path / "metrics.json" if path.is_dir() else None
    if metrics_path is not None and metrics_path.is_file():
        try:
            data.metrics = json.loads(metrics_path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            data.warnings.append(f"{metrics_path}: unreadable ({exc}); not used")
    data.title = _title(data)
    return data


def vehicle_files(run_dir: Path) -> list[tuple[str, str, Path]]:
    """The run folder's ``missions/<vehicle>/NNN-<purpose>.waypoints`` and
    ``params/<vehicle>.parm`` (``daemon/vehicle_files.py``), vehicles in natural order."""
    found: list[tuple[str, str, Path]] = []
    missions = run_dir / "missions"
    if missions.is_dir():
        for folder in sorted((p for p in missions.iterdir() if p.is_dir()),
                             key=lambda p: _natural(p.name)):
            found += [(folder.name, "mission", f) for f in sorted(folder.glob("*.waypoints"))]
    params = run_dir / "params"
    if params.is_dir():
        found += [(f.stem, "parameters", f)
                  for f in sorted(params.glob("*.parm"), key=lambda p: _natural(p.stem))]
    return found


_SOURCE_TITLES = {"run": "gcs run", "simulate": "gcs simulate", "tlog": "tlog"}


def _title(data: RunData) -> str:
    """``<what wrote it> <folder or file name>, scenario S, seed N, K vehicle(s)``, e.g.
    ``gcs run 20261121T071106Z, scenario paper-boat, 3 vehicle(s)``."""
    start = data.start or {}
    name = data.path.name or str(data.path)
    parts = [f"{_SOURCE_TITLES.get(data.source, data.source)} {name}"]
    if start.get("scenario"):
        parts.append(f"scenario {start['scenario']}")
    if start.get("seed") is not None and data.source == "simulate":
        parts.append(f"seed {start['seed']}")
    parts.append(f"{len(data.vehicles())} vehicle(s)")
    return ", ".join(parts)


def fallback_wind_of(data: RunData) -> tuple[float, float]:
    """The core's fallback wind from the ``start`` record (ENU m/s; calm if none)."""
    start = data.start or {}
    core = start.get("core_config", start.get("core"))
    wind = core.get("wind_xy_m_s") if isinstance(core, dict) else None
    if isinstance(wind, list) and len(wind) == 2:
        x, y = _num(wind[0], 0.0), _num(wind[1], 0.0)
        if math.isfinite(x) and math.isfinite(y):
            return x, y
    return 0.0, 0.0


def wind_summary(data: RunData) -> str:
    """``3 changes; last 12.0 m/s from 270 deg (vehicles 1, 2) at t=61 s; ...``."""
    parts = []
    wx, wy = fallback_wind_of(data)
    parts.append(f"fallback {math.hypot(wx, wy):.1f} m/s")
    if data.wind:
        last = data.wind[-1]
        who = last["source"] + (" " + ", ".join(last["vehicles"]) if last["vehicles"] else "")
        parts.append(f"{len(data.wind)} change(s); last {last['speed_m_s']:.1f} m/s from "
                     f"{last['from_deg']:.0f} deg ({who}) at t={last['t']:.0f} s")
    if data.wind_reports:
        count = sum(len(v) for v in data.wind_reports.values())
        parts.append(f"{count} report(s) from vehicle(s) "
                     + ", ".join(sorted(data.wind_reports, key=_natural)))
    if data.wind_outliers:
        flagged = sorted({str(o["vehicle"]) for o in data.wind_outliers}, key=_natural)
        parts.append("outliers flagged: " + ", ".join(flagged))
    return "; ".join(parts)


def summary_rows(data: RunData) -> list[tuple[str, str]]:
    """The summary table: (quantity, value) pairs."""
    rows: list[tuple[str, str]] = [("source", f"{data.source}: {data.path}")]
    rows.append(("mission time", f"{data.end_t_s:.1f} s"))
    rows.append(("vehicles", ", ".join(data.vehicles()) or "none"))
    targets = sorted(set(data.target_estimates) | set(data.target_truth), key=_natural)
    rows.append(("targets", ", ".join(targets) or "none known"))
    mean = data.mean_uncertainty()
    if mean:
        values = [s for _t, s in mean]
        rows.append(
            (
                "uncertainty (mean sigma, m^2)",
                f"mean {statistics.fmean(values):.1f}, max {max(values):.1f}, "
                f"final {values[-1]:.1f}",
            )
        )
    lost = sorted(
        {
            k
            for k, rows_ in data.target_estimates.items()
            for r in rows_
            if len(r) > 3 and r[3] > 150.0**2
        }
    )
    if data.metrics and "lost_targets" in data.metrics:
        lost = list(data.metrics["lost_targets"])
    if data.target_estimates or data.metrics:
        rows.append(("targets ever lost", ", ".join(map(str, lost)) or "none"))
    if data.metrics and "visits" in data.metrics:
        rows.append(("visits", str(len(data.metrics["visits"]))))
    if data.plans:
        times = [p["solve_time_s"] for p in data.plans if math.isfinite(p["solve_time_s"])]
        limited = sum(1 for p in data.plans if p["hit_time_limit"])
        fallback = sum(1 for p in data.plans if p["status"] == "fallback")
        text = f"{len(data.plans)}"
        if times:
            text += f"; solve time median {statistics.median(times):.3f} s, max {max(times):.3f} s"
        text += f"; hit the time limit {limited}, fallback {fallback}"
        rows.append(("plans", text))
    rows.append(("fly commands", str(len(data.fly))))
    if data.uploads:
        failed = sum(1 for u in data.uploads if not u["ok"])
        retries = sum(u["retries"] for u in data.uploads)
        rows.append(("uploads", f"{len(data.uploads)} ({failed} failed, {retries} retries)"))
    if data.link_events or data.source != "simulate":
        lost_links = sum(1 for e in data.link_events if e["event"] == "link_lost")
        rows.append(("link losses", str(lost_links)))
    rows.append(("overrides and releases", str(len(data.overrides))))
    if data.wind or data.wind_reports:
        rows.append(("wind", wind_summary(data)))
    if data.tracking.present():
        c = data.tracking.counts()
        rows.append(("tracker", f"{c['born']} born, {c['confirmed']} confirmed, "
                     f"{c['deleted']} deleted; at the end {c.get('final_confirmed', 0)} "
                     f"confirmed, {c.get('final_tentative', 0)} tentative, "
                     f"{c.get('final_prior', 0)} prior"))
    if data.tlog is not None:
        tl = data.tlog
        ids = ", ".join(f"{k} ({v.frames} frames)" for k, v in tl.systems.items())
        rows.append(("tlog", f"{tl.path}: {tl.records} records, system ids {ids}"))
        rows.append(
            (
                "tlog damage",
                f"{len(tl.skipped)} range(s), {tl.skipped_bytes} bytes "
                "skipped"
                + (": " + "; ".join(f"{a}..{b}" for a, b in tl.skipped[:10]) if tl.skipped else ""),
            )
        )
    return rows
