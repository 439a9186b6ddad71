"""``gcs replay``: a recorded run through today's decision core, or its vehicles back on air.

    gcs replay runs/20260101T120000Z                  # regression check, exit 0/1/2
    gcs replay out/sim --set planner.tau=0.9          # what-if: shows the differences
    gcs replay runs/X --serve udp:127.0.0.1:14550 --pace 1     # the vehicles, in mission time
    gcs replay runs/X --serve udp:127.0.0.1:14550 --speed 5    # 5x the recorded wall pace
    gcs replay flight.tlog --detections det.jsonl     # the core on a bare tlog

Exit status: 0 the replayed decisions are the recorded ones (or serving ended), 1 they
differ, 2 bad input (missing or unreadable journal or tlog, bad option), 130 interrupted.
"""

from __future__ import annotations

import argparse
import asyncio
import collections
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from groundstation.commands.argtypes import positive_float
from groundstation.commands.async_main import run_async
from groundstation.commands.progress_bars import ProgressBars, TaskUpdate

__all__ = ["run"]

_PROG = "gcs replay"


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        allow_abbrev=False,
        prog=_PROG,
        description="Feed a recorded run (RUN_DIR/journal.jsonl) through today's decision "
        "core and report, event by event, where it decides differently (exit 0 identical, "
        "1 differences, 2 bad input); or, with --serve, play the recorded vehicles "
        "(RUN_DIR/flight.tlog or FILE.tlog) back as live MAVLink sources.",
    )
    parser.add_argument(
        "run",
        type=Path,
        metavar="RUN_DIR|FILE",
        help="a run folder (gcs run / gcs simulate), a journal.jsonl or a .tlog",
    )
    pace = parser.add_mutually_exclusive_group()
    pace.add_argument(
        "--speed",
        type=positive_float,
        default=None,
        metavar="K",
        help="pace inputs (or served frames) at K times the recorded pace "
        "(default: as fast as possible for a regression check; 1 for --serve)",
    )
    pace.add_argument(
        "--pace",
        type=positive_float,
        default=None,
        metavar="K",
        help="pace by mission time: K mission seconds per second, whatever the recording's "
        "speed-up (a 50x run at --pace 1 is watched in real mission time; mission time from "
        "the run's journal, else the vehicles' time_boot_ms)",
    )
    pace.add_argument(
        "--as-fast-as-possible", action="store_true", help="no pacing (the default without --serve)"
    )
    parser.add_argument(
        "--serve",
        metavar="URL",
        default=None,
        help="send the recorded vehicles' frames to URL (udpout:HOST:PORT, "
        "udp:HOST:PORT, tcp:HOST:PORT, tcpin:HOST:PORT, udpin:HOST:PORT)",
    )
    parser.add_argument(
        "--detections",
        type=Path,
        default=None,
        metavar="FILE",
        help="detection feed JSON lines, to replay the core on a bare tlog",
    )
    parser.add_argument(
        "--set",
        "--override",
        dest="settings",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="change a core setting for a what-if replay (tau=0.9, "
        "planner.tau=0.9, policy.commit=false, observer.q_per_s=0.2); "
        "repeatable",
    )
    parser.add_argument(
        "--no-resolve",
        action="store_true",
        help="do not re-solve the recorded plans (faster; problems are still compared)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--max-lines",
        type=int,
        default=200,
        metavar="N",
        help="print at most N differences (default 200; --json prints all)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")
    return parser


def _error(message: str) -> int:
    print(f"{_PROG}: error: {message}", file=sys.stderr)
    return 2


def make_pace(speed: float) -> Callable[[float], None]:
    """Sleep so that mission time ``t`` is reached at wall time ``(t - t0) / speed``."""
    state: dict[str, float] = {}

    def pace(t_s: float) -> None:
        if not state:
            state["wall0"], state["t0"] = time.monotonic(), t_s
            return
        delay = state["wall0"] + (t_s - state["t0"]) / speed - time.monotonic()
        if delay > 0:
            time.sleep(delay)

    return pace


def _is_tlog(path: Path) -> bool:
    if path.is_dir():
        return not (path / "journal.jsonl").exists() and (path / "flight.tlog").exists()
    return path.suffix.lower() == ".tlog"


def run(argv: list[str]) -> int:
    args = _parser().parse_args(argv)
    if args.serve is not None:
        speed = 1e9 if args.as_fast_as_possible else (args.speed or 1.0)
        return _serve_command(
            args.run, args.serve, speed, quiet=args.quiet, as_json=args.json, pace=args.pace
        )
    if args.pace is not None:  # a journal's inputs are paced by mission time already
        args.speed = args.pace
    if _is_tlog(args.run):
        if args.detections is None:
            return _error(
                f"{args.run}: a tlog holds no core inputs; give --detections FILE "
                "to replay the decision core on it, or --serve URL to play it back"
            )
        return _tlog_core_command(args.run, args.detections, args.settings, as_json=args.json)
    if args.detections is not None:
        return _error("--detections is for a bare tlog; a journal already holds its detections")
    return _journal_replay(args)


def _journal_replay(args: argparse.Namespace) -> int:
    from groundstation.runners.replay.journal import (
        JournalError,
        apply_overrides,
        core_config_of,
        load_journal,
    )
    from groundstation.runners.replay.run import replay_journal

    try:
        journal = load_journal(args.run)
        recorded = core_config_of(journal)
        config = apply_overrides(recorded, args.settings)
    except (JournalError, ValueError) as exc:
        return _error(str(exc))
    if not any(r.get("event") == "input" for r in journal.records):
        return _error(
            f"{journal.path}: no core inputs ('input' records) to replay: the frontend that "
            "wrote it did not journal the decision core's inputs"
        )
    quiet = args.quiet or args.json
    pace = make_pace(args.speed) if args.speed is not None else None
    with ProgressBars(quiet=quiet, plain_lines=False) as bars:
        updates: list[TaskUpdate] = []

        def progress(done: int, total: int) -> None:
            if not updates:
                updates.append(bars.task(f"{_PROG} {journal.path.parent.name}", total, " inputs"))
            updates[0](done)

        report = replay_journal(
            journal,
            config,
            recorded_config=recorded,
            pace=pace,
            progress=progress,
            resolve=not args.no_resolve,
        )
    skipped = report.skipped()
    if report.inputs == 0:
        where = f" ({skipped})" if skipped else ""
        return _error(f"{journal.path}: nothing replayable: no input record could be read{where}")
    if args.json:
        print(json.dumps(report.as_dict(), indent=1))
    else:
        for warning in report.warnings:
            print(f"warning: {warning}")
        if skipped:
            print(f"warning: {journal.path}: {skipped}")
        for change in report.config_changes:
            print(f"setting changed: {change}")
        for diff in report.differences[: max(args.max_lines, 0)]:
            print(diff.text())
        hidden = len(report.differences) - max(args.max_lines, 0)
        if hidden > 0:
            print(f"... {hidden} more difference(s) (--max-lines, --json)")
        for item in report.not_comparable[:20]:
            print(f"not comparable: {item}")
        print(report.summary())
    return 0 if report.identical else 1


# ----------------------------------------------------------------------------- --serve
_READY_TIMEOUT_S = 30.0


def serve_spec(url: str) -> Any:
    """The link for ``--serve URL``, read as ``gcs run --out`` (MAVProxy's ``--out``):
    ``udp:``/``udpout:`` send, ``udpin:`` listens, ``tcpin:`` serves, ``tcp:`` connects."""
    from groundstation.link import parse_out_url

    return parse_out_url(url)


async def serve_frames(
    spec: Any,
    frames: Any,
    *,
    ready_timeout_s: float = _READY_TIMEOUT_S,
    say: Callable[[str], None] | None = None,
    progress: Callable[[int], None] | None = None,
) -> dict[str, Any]:
    """Send each :class:`ServedFrame` at its time on a link to ``spec``; returns counters.

    Waits (at most ``ready_timeout_s``) for a TCP connection, or for a peer of a listening
    link; raises ``LinkError`` if none comes. ``progress(frames)`` is told every 256
    frames. Cancellation (Ctrl-C) stops at once; the link is always closed.
    """
    from groundstation.link import LinkError, open_link

    link = open_link(spec, link_id="serve")
    await link.start()
    sent: collections.Counter[int] = collections.Counter()
    failed = 0
    try:
        loop = asyncio.get_running_loop()
        deadline = loop.time() + ready_timeout_s
        if not link.connected and say is not None:
            say(f"waiting for a peer on {spec.canonical} (up to {ready_timeout_s:.0f} s)")
        while not link.connected:
            if loop.time() > deadline:
                raise LinkError(f"{spec.canonical}: no peer within {ready_timeout_s:.0f} s")
            await asyncio.sleep(0.05)
        start = loop.time()
        for n, frame in enumerate(frames):
            delay = start + frame.at_s - loop.time()
            if delay > 0:
                await asyncio.sleep(delay)
            elif n % 64 == 0:
                await asyncio.sleep(0)  # let the transport drain when behind schedule
            if link.send(frame.raw):
                sent[frame.system_id] += 1
            else:
                failed += 1
            if progress is not None and n % 256 == 0:
                progress(n + 1)
        if progress is not None:
            progress(sum(sent.values()) + failed)
        await asyncio.sleep(0.05)  # the last datagrams leave before the socket closes
        wall = loop.time() - start
    finally:
        await link.stop()
    return {
        "frames_sent": sum(sent.values()),
        "by_system": dict(sorted(sent.items())),
        "send_failures": failed,
        "wall_s": round(wall, 3),
    }


def _serve_command(
    path: Path, url: str, speed: float, *, quiet: bool, as_json: bool, pace: float | None = None
) -> int:
    from groundstation.link import LinkError, LinkUrlError
    from groundstation.runners.replay.mission_timeline import mission_timeline
    from groundstation.runners.replay.serve import serving_schedule
    from groundstation.runners.replay.tlog import TlogError, read_tlog

    timeline = None
    try:
        spec = serve_spec(url)
        recorded = read_tlog(path)
        if pace is not None:
            timeline = mission_timeline(recorded.path, sorted(recorded.vehicles))
        summary, frames = serving_schedule(
            path, speed, pace=pace, timeline=timeline.at if timeline else None, summary=recorded
        )
    except (LinkUrlError, TlogError, ValueError) as exc:
        return _error(str(exc))
    vehicles = summary.vehicles
    if not vehicles:
        return _error(
            f"{summary.path}: no vehicle frames to serve (system ids "
            f"{sorted(summary.systems)} are ground stations)"
        )
    say: Callable[[str], None] = (
        (lambda text: None)
        if (quiet or as_json)
        else (lambda text: print(f"{_PROG}: {text}", file=sys.stderr, flush=True))
    )
    for line in summary.skipped_text():
        say(f"warning: {summary.path}: {line}")
    span = (summary.last_t_s or 0.0) - (summary.first_t_s or 0.0)
    if timeline is not None:
        mission_s = timeline.at(summary.last_t_s or 0.0) - timeline.at(summary.first_t_s or 0.0)
        pacing = (
            f"{mission_s:.1f} mission s (recorded at {timeline.rate:.3g}x; "
            f"{timeline.source}) at --pace {pace:g}"
        )
    else:
        pacing = f"{span:.1f} s recorded, at {speed:g}x"
    total = sum(v.frames for v in vehicles.values())
    interrupted = False
    try:  # from here on, Ctrl-C (even before the loop starts) ends cleanly with 130
        say(
            f"serving {len(vehicles)} vehicle(s) (system ids {', '.join(map(str, vehicles))}) "
            f"from {summary.path} to {spec.canonical}: {pacing}"
        )
        with ProgressBars(quiet=quiet or as_json, plain_lines=False) as bars:
            update = bars.task(f"{_PROG} --serve", total, " frames")
            stats = run_async(lambda: serve_frames(spec, frames, say=say, progress=update))
    except LinkError as exc:
        return _error(str(exc))
    except KeyboardInterrupt:
        interrupted = True
        stats = {}
    result = {
        "tlog": str(summary.path),
        "url": spec.canonical,
        "speed": None if pace is not None else speed,
        "pace": pace,
        "clock": timeline.source if timeline is not None else "tlog time",
        "records": summary.records,
        "skipped": [list(r) for r in summary.skipped],
        "vehicles": list(vehicles),
        "interrupted": interrupted,
        **stats,
    }
    if as_json:
        print(json.dumps(result, indent=1))
    elif interrupted:
        print(f"{_PROG}: interrupted; link closed")
    else:
        per = ", ".join(f"{k}: {v}" for k, v in result["by_system"].items())
        print(
            f"served {result['frames_sent']} frames ({per}) in {result['wall_s']:.1f} s; "
            f"{len(summary.skipped)} damaged range(s) skipped"
        )
    return 130 if interrupted else 0


# ----------------------------------------------------------------------------- bare tlog
def _tlog_core_command(tlog: Path, detections: Path, settings: list[str], *, as_json: bool) -> int:
    from groundstation.runners.replay.journal import apply_overrides
    from groundstation.runners.replay.tlog import TlogError
    from groundstation.runners.replay.tlog_core import TLOG_DEFAULT_CONFIG, run_core_on_tlog

    try:
        config = apply_overrides(TLOG_DEFAULT_CONFIG, settings)
        result = run_core_on_tlog(tlog, detections, config)
    except (TlogError, ValueError) as exc:
        return _error(str(exc))
    except OSError as exc:
        return _error(f"{exc.filename or detections}: {exc.strerror or exc}")
    if as_json:
        print(
            json.dumps(
                {
                    "inputs": result.inputs,
                    "detections_used": result.detections_used,
                    "detections_skipped": result.detections_skipped,
                    "skipped": [list(r) for r in result.skipped_ranges],
                    "origin": result.origin,
                    "decisions": result.decisions,
                },
                indent=1,
            )
        )
        return 0
    for a, b in result.skipped_ranges:
        print(f"warning: {tlog}: skipped damaged bytes {a}..{b}")
    for line in result.detections_skipped[:20]:
        print(f"warning: {detections}: {line}")
    for d in result.decisions:
        if d["event"] == "fly":
            print(
                f"t={d['t']:9.3f}  fly        vehicle {d['vehicle']} -> {d['target']} "
                f"({d['x_m']:.1f}, {d['y_m']:.1f})"
            )
        elif d["event"] != "plan":
            print(f"t={d['t']:9.3f}  {d['event']:<10} vehicle {d['vehicle']}")
    plans = sum(1 for d in result.decisions if d["event"] == "plan")
    print(
        f"the core on {tlog}: {result.inputs} inputs, {result.detections_used} detections, "
        f"{plans} plans, {len(result.decisions) - plans} vehicle commands (nothing recorded "
        "to compare with)"
    )
    return 0
