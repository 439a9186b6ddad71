"""``gcs report``: a self-contained HTML report of a flight.

    gcs report runs/20260101T120000Z --out report/    # gcs run folder (journal + tlog)
    gcs report out/sim --out report/                  # gcs simulate folder
    gcs report flight.tlog --out report/              # any tool's tlog: map and modes

Writes ``OUT/report.html`` (PNGs embedded) plus the PNGs and ``figures.json``.
Exit status: 0 written, 2 bad input (an empty or garbage journal: no readable record or no
``start`` record, and no tlog beside it; output not writable). Every file is written
atomically.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["run"]

_PROG = "gcs report"


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        allow_abbrev=False,
        prog=_PROG,
        description="Write a self-contained HTML report (map, uncertainty, plan timeline, "
        "solve times, uploads, link losses, overrides, summary) of a gcs run folder, a "
        "gcs simulate folder, a journal.jsonl or a tlog.",
    )
    parser.add_argument(
        "run", type=Path, metavar="RUN_DIR|FILE", help="run folder, journal.jsonl or .tlog"
    )
    parser.add_argument(
        "--out",
        type=Path,
        required=True,
        metavar="DIR",
        help="output folder (report.html and the PNGs)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")
    return parser


def run(argv: list[str]) -> int:
    args = _parser().parse_args(argv)
    from groundstation.runners.report.data import ReportError
    from groundstation.runners.report.page import build_report
    from groundstation.storage import StorageError

    def say(text: str) -> None:
        if not args.quiet:
            print(f"{_PROG}: {text}", file=sys.stderr, flush=True)

    try:
        result = build_report(args.run, args.out, say)
    except ReportError as exc:
        print(f"{_PROG}: error: {exc}", file=sys.stderr)
        return 2
    except StorageError as exc:
        print(f"{_PROG}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # reading the input failed half-way (it vanished, I/O error)
        print(f"{_PROG}: error: {args.run}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    data = result.data
    if data is not None:
        for warning in data.warnings[:20]:
            say(f"warning: {warning}")
    print(f"{result.html_path} ({len(result.figures)} figures)")
    return 0
