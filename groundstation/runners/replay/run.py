"""Replay: a recorded run's inputs through today's decision core, decision by decision.

The journal holds every input the core saw (``{"event": "input", "kind": ...}``, exact
floats) and every decision it made. :func:`replay_journal` builds a fresh
:class:`DecisionCore` from the ``start`` record's configuration (optionally changed, for a
what-if) and feeds it the inputs in order, at their recorded mission times. The decisions
journalled after input *i* (up to input *i + 1*) are what the recorded core answered to
input *i*; the replayed core's answer to the same input is compared with them
(:mod:`~groundstation.runners.replay.compare`).

Planning is checked in three steps, because solving is the frontend's job:

1. when the replayed core asks for a plan, its problem is compared with the recorded
   problem of the same request (vehicles, poses, targets, sigmas at 1e-9 relative);
2. the replayed problem is re-solved with one worker, seed 0 and a deterministic time
   limit, and its objective compared with the recorded result at 1e-6 relative (never the
   routes: equal-cost routes differ). A recorded solve that hit its deadline, or a
   fallback plan, is *not comparable*, not a difference;
3. the *recorded* ``PlanSolved`` (it is one of the inputs) is fed as recorded, so the run
   stays in step with the journal even where today's solver would choose another tie.

Nothing here reads a clock: pacing (``--speed K``) is a callable the caller passes, called
with each input's mission time before it is fed.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from groundstation.core import events as core_events
from groundstation.core.commands import SolveRequest
from groundstation.core.config import CoreConfig, config_to_dict
from groundstation.core.decision import DecisionCore
from groundstation.core.records import (
    RecordError,
    command_to_record,
    record_to_event,
    result_from_record,
)
from groundstation.core.views import CoreView
from groundstation.runners.replay.compare import (
    Decision,
    compare_decisions,
    compare_problems,
    decision_of_record,
    describe,
)
from groundstation.runners.replay.journal import LoadedJournal, skipped_summary
from planner import problem_to_dict, solve_plan

_WARN_LINES = 5  # per-line warnings shown for skipped lines; the rest are only counted

__all__ = ["Difference", "ReplayReport", "config_changes", "replay_journal"]

OBJECTIVE_REL_TOL = 1e-6
TRACK_XY_TOL_M = 0.06
"""Track positions closer than this are the same (``gcs run`` journals them to 0.1 m)."""
TRACK_SIGMA_TOL = 6e-4
"""Sigmas closer than this (m^2) are the same (``gcs run`` journals them to 0.001)."""


@dataclass(frozen=True)
class Difference:
    """One place where today's core decides differently from the recording."""

    t_s: float
    kind: str
    recorded: str
    now: str
    line: int | None = None

    def as_dict(self) -> dict[str, Any]:
        return {
            "t": self.t_s,
            "kind": self.kind,
            "recorded": self.recorded,
            "now": self.now,
            "line": self.line,
        }

    def text(self) -> str:
        where = f" (journal line {self.line})" if self.line else ""
        return (
            f"t={self.t_s:9.3f}  {self.kind:<10} recorded: {self.recorded}  |  now: "
            f"{self.now}{where}"
        )


@dataclass
class ReplayReport:
    """What a replay found."""

    journal: str
    inputs: int = 0
    decisions_recorded: int = 0
    decisions_replayed: int = 0
    solves: int = 0
    problems_equal: int = 0
    objectives_compared: int = 0
    objectives_equal: int = 0
    routes_changed: int = 0
    """Re-solved plans whose routes differ from the recorded plan's (any vehicle's
    sequence); out of ``objectives_compared``. Without ``--set`` equal-cost ties can differ
    too; with it, this says whether a setting changed what would have been flown."""
    track_samples_compared: int = 0
    track_samples_differing: int = 0
    not_comparable: list[str] = field(default_factory=list)
    differences: list[Difference] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    config_changes: list[str] = field(default_factory=list)
    lines_total: int = 0
    skipped_lines: list[int] = field(default_factory=list)  # damaged or bad input lines
    first_t_s: float | None = None
    last_t_s: float | None = None

    @property
    def identical(self) -> bool:
        return not self.differences

    def as_dict(self) -> dict[str, Any]:
        return {
            "journal": self.journal,
            "identical": self.identical,
            "inputs": self.inputs,
            "decisions_recorded": self.decisions_recorded,
            "decisions_replayed": self.decisions_replayed,
            "solves": self.solves,
            "problems_equal": self.problems_equal,
            "objectives_compared": self.objectives_compared,
            "objectives_equal": self.objectives_equal,
            "routes_changed": self.routes_changed,
            "track_samples_compared": self.track_samples_compared,
            "track_samples_differing": self.track_samples_differing,
            "not_comparable": self.not_comparable,
            "differences": [d.as_dict() for d in self.differences],
            "warnings": self.warnings,
            "config_changes": self.config_changes,
            "mission_time_s": [self.first_t_s, self.last_t_s],
            "lines_total": self.lines_total,
            "skipped_lines": sorted(self.skipped_lines),
        }

    def skipped(self) -> str | None:
        """``skipped N of M journal lines: a, b, c...`` or None."""
        return skipped_summary(self.lines_total, self.skipped_lines)

    def summary(self) -> str:
        span = ""
        if self.first_t_s is not None and self.last_t_s is not None:
            span = f" over {self.first_t_s:.1f}..{self.last_t_s:.1f} s"
        verdict = "IDENTICAL" if self.identical else f"{len(self.differences)} DIFFERENCE(S)"
        return (
            f"replay {verdict}: {self.inputs} inputs{span}; decisions recorded "
            f"{self.decisions_recorded}, replayed {self.decisions_replayed}; plans requested "
            f"{self.solves}, problems equal {self.problems_equal}; objectives equal "
            f"{self.objectives_equal}/{self.objectives_compared} (not comparable: "
            f"{len(self.not_comparable)}); track samples differing "
            f"{self.track_samples_differing}/{self.track_samples_compared}"
        ) + (f"; routes changed: {self.routes_changed} of {self.objectives_compared} "
             "re-solved plans" if self.config_changes else "")


def config_changes(recorded: CoreConfig, now: CoreConfig) -> list[str]:
    """``key recorded -> now`` for every setting that differs (flattened)."""

    def flat(data: dict[str, Any], prefix: str = "") -> dict[str, Any]:
        out: dict[str, Any] = {}
        for k, v in data.items():
            if isinstance(v, dict):
                out.update(flat(v, f"{prefix}{k}."))
            else:
                out[f"{prefix}{k}"] = v
        return out

    a, b = flat(config_to_dict(recorded)), flat(config_to_dict(now))
    return [f"{k} {a.get(k)!r} -> {b.get(k)!r}" for k in sorted(a) if a.get(k) != b.get(k)]


class _Replayer:
    def __init__(
        self,
        journal: LoadedJournal,
        config: CoreConfig,
        pace: Callable[[float], None] | None,
        progress: Callable[[int, int], None] | None,
        resolve: bool,
    ) -> None:
        self.journal = journal
        self.core = DecisionCore(config)
        self.pace = pace
        self.progress = progress
        self.resolve = resolve
        self.report = ReplayReport(str(journal.path))
        self.report.warnings += journal.warnings(first=_WARN_LINES)
        self.report.lines_total = journal.lines_total
        self.report.skipped_lines = [line for line, _ in journal.damaged]
        self.bad_inputs = 0
        self.track_reported: set[str] = set()
        records = journal.records
        self.has_solve_records = any(r.get("event") == "solve_request" for r in records)
        self.recorded_problem: dict[str, dict[str, Any]] = {}
        self.recorded_result: dict[str, dict[str, Any]] = {}
        for r in records:
            event = r.get("event")
            rid = str(r.get("request_id", r.get("request")))
            if event == "solve_request" and isinstance(r.get("problem"), dict):
                self.recorded_problem.setdefault(rid, r["problem"])
            elif event == "plan":
                if isinstance(r.get("problem"), dict):
                    self.recorded_problem.setdefault(rid, r["problem"])
                if isinstance(r.get("result"), dict):
                    self.recorded_result.setdefault(rid, r["result"])
            elif (
                event == "input"
                and r.get("kind") == "PlanSolved"
                and isinstance(r.get("result"), dict)
            ):
                self.recorded_result[rid] = r["result"]

    def differ(self, t_s: float, kind: str, recorded: str, now: str, line: int | None) -> None:
        self.report.differences.append(Difference(t_s, kind, recorded, now, line))

    def run(self) -> ReplayReport:
        records = self.journal.records
        lines = self.journal.line_numbers
        inputs = [k for k, r in enumerate(records) if r.get("event") == "input"]
        boat_inputs = any(records[k].get("kind") == "BoatPosition" for k in inputs)
        use_boat_samples = self.core.config.priority_gain > 0 and not boat_inputs
        if use_boat_samples:
            self.report.warnings.append(
                "priority_gain > 0 but the journal has no BoatPosition inputs: replay uses "
                "its 1 s boat samples, so small differences are possible"
            )
        for n, k in enumerate(inputs):
            end = inputs[n + 1] if n + 1 < len(inputs) else len(records)
            group = records[k + 1 : end]
            for r in group:
                if r.get("event") == "boat" and use_boat_samples:
                    self.core.set_boat(float(r["x_m"]), float(r["y_m"]))
            self.feed(records[k], lines[k], group)
            if self.progress is not None and n % 500 == 0:
                self.progress(n, len(inputs))
        if self.progress is not None:
            self.progress(len(inputs), len(inputs))
        return self.report

    def feed(self, record: dict[str, Any], line: int, group: list[dict[str, Any]]) -> None:
        try:
            event = record_to_event(_with_nones(record))
        except RecordError as exc:
            self.report.skipped_lines.append(line)
            self.bad_inputs += 1
            if self.bad_inputs <= _WARN_LINES:
                self.report.warnings.append(f"line {line}: bad input record: {exc} (skipped)")
            return
        report = self.report
        report.inputs += 1
        if report.first_t_s is None:
            report.first_t_s = event.t_s
        report.last_t_s = event.t_s
        if self.pace is not None:
            self.pace(event.t_s)
        commands = self.core.handle(event)
        recorded = [d for d in (decision_of_record(r) for r in group) if d is not None]
        now = [
            d for d in (decision_of_record(command_to_record(c)) for c in commands) if d is not None
        ]
        report.decisions_recorded += len({(d.kind, d.key) for d in recorded})
        report.decisions_replayed += len({(d.kind, d.key) for d in now})
        skip = frozenset() if self.has_solve_records else frozenset({"solve"})
        for kind, a, b in compare_decisions(recorded, now, skip_kinds=skip):
            t_s = (a or b or Decision(event.t_s, kind, "")).t_s
            self.differ(t_s, kind, describe(a), describe(b), line)
        for command in commands:
            if isinstance(command, SolveRequest):
                self.check_solve(command, line)
        tracks = [r for r in group if r.get("event") == "track" and r.get("target") is not None]
        view = self.core.view() if tracks else None
        for r in tracks:
            self.check_track(r, line, view)

    def check_track(self, record: dict[str, Any], line: int, view: CoreView | None) -> None:
        """A journalled track estimate against the replayed observer's, at the same point
        of the input stream (first difference per target listed, the rest counted)."""
        report = self.report
        report.track_samples_compared += 1
        target = str(record["target"])
        t_s = float(record.get("t", 0.0))
        now = view.track(target) if view is not None else None
        if now is None:
            differs, text = True, "no such track"
        else:
            pairs = [
                ("x_m", now.x_m, TRACK_XY_TOL_M),
                ("y_m", now.y_m, TRACK_XY_TOL_M),
                ("sigma", now.sigma, TRACK_SIGMA_TOL),
            ]
            bad = [
                (name, float(record[name]), value)
                for name, value, tol in pairs
                if isinstance(record.get(name), int | float)
                and not math.isclose(float(record[name]), value, rel_tol=1e-9, abs_tol=tol)
            ]
            differs = bool(bad)
            text = "; ".join(f"{n} {a:.6g} vs {b:.6g}" for n, a, b in bad)
        if not differs:
            return
        report.track_samples_differing += 1
        if target not in self.track_reported:
            self.track_reported.add(target)
            self.differ(t_s, "track", f"{target} (first differing sample)", text, line)

    def check_solve(self, request: SolveRequest, line: int) -> None:
        report = self.report
        report.solves += 1
        rid = str(request.request_id)
        problem_now = problem_to_dict(request.problem)
        recorded = self.recorded_problem.get(rid)
        if recorded is None:
            report.not_comparable.append(f"t={request.t_s:.3f} request #{rid}: no recorded problem")
        else:
            diffs = compare_problems(recorded, problem_now)
            for what, a, b in diffs:
                self.differ(request.t_s, "problem", f"#{rid} {what} {a}", f"{what} {b}", line)
            if not diffs:
                report.problems_equal += 1
        if not self.resolve:
            return
        result_record = self.recorded_result.get(rid)
        if result_record is None:
            report.not_comparable.append(
                f"t={request.t_s:.3f} request #{rid}: no recorded result (cancelled?)"
            )
            return
        try:
            recorded_result = result_from_record(result_record)
        except RecordError as exc:
            report.not_comparable.append(f"t={request.t_s:.3f} request #{rid}: {exc}")
            return
        if recorded_result.hit_time_limit or recorded_result.status == "fallback":
            why = "hit its deadline" if recorded_result.hit_time_limit else "was a fallback"
            report.not_comparable.append(
                f"t={request.t_s:.3f} request #{rid}: the recorded solve {why}"
            )
            return
        result = solve_plan(
            request.problem, request.hint, num_workers=1, random_seed=0, deterministic=True
        )
        if result.hit_time_limit or result.status == "fallback":
            report.not_comparable.append(
                f"t={request.t_s:.3f} request #{rid}: the re-solve hit its deterministic limit"
            )
            return
        report.objectives_compared += 1
        if _routes(result.routes) != _routes(recorded_result.routes):
            report.routes_changed += 1
        if math.isclose(
            result.objective, recorded_result.objective, rel_tol=OBJECTIVE_REL_TOL, abs_tol=1e-9
        ):
            report.objectives_equal += 1
        else:
            self.differ(
                request.t_s,
                "objective",
                f"#{rid} {recorded_result.objective:.9g}",
                f"{result.objective:.9g} ({result.status})",
                line,
            )


def _routes(routes: Mapping[str, Sequence[str]]) -> dict[str, list[str]]:
    """A plan's routes, comparable: each vehicle's sequence, empty ones left out."""
    return {str(v): [str(t) for t in seq] for v, seq in routes.items() if seq}


def _with_nones(record: dict[str, Any]) -> dict[str, Any]:
    """The record with its absent optional fields set to None: ``gcs run``'s journal leaves
    None values out (``Detection.target`` None: "let the observer associate it")."""
    cls = getattr(core_events, str(record.get("kind")), None)
    if not dataclasses.is_dataclass(cls):
        return record
    missing = {
        f.name: None
        for f in dataclasses.fields(cls)
        if f.name not in record and f.name != "t_s" and "None" in str(f.type)
    }
    return {**record, **missing} if missing else record


def replay_journal(
    journal: LoadedJournal,
    config: CoreConfig,
    *,
    recorded_config: CoreConfig | None = None,
    pace: Callable[[float], None] | None = None,
    progress: Callable[[int, int], None] | None = None,
    resolve: bool = True,
) -> ReplayReport:
    """Replay ``journal`` through a fresh core built from ``config`` (module docstring).

    ``recorded_config``, if given, is the journal's own configuration: the settings that
    differ from ``config`` are listed in the report. ``resolve=False`` skips re-solving.
    """
    replayer = _Replayer(journal, config, pace, progress, resolve)
    if recorded_config is not None:
        replayer.report.config_changes = config_changes(recorded_config, config)
    report = replayer.run()
    if report.inputs == 0:
        report.warnings.append("the journal holds no core inputs ('input' records)")
    return report
