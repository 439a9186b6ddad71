"""What ``gcs campaign`` shows while and after it runs.

Progress goes to stderr: on a terminal a ``rich`` bar (runs done of to do, rate, elapsed,
ETA); otherwise one plain line at every 10 % (no escape codes in a log); nothing with
``--quiet``. The summary table (one row per grid cell: runs, mean sigma with its 95 %
t-interval, the growth over the second half of the cell's mean curve with its 95 %
bootstrap interval, runs with trend <= 0.5, visits, lost targets) goes to stdout, as a
``rich`` table.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from types import TracebackType
from typing import IO, Any

from groundstation.runners.campaign.summary import CellMeans

__all__ = ["CampaignProgress", "format_duration", "print_summary"]


def format_duration(seconds: float) -> str:
    """``1h02m``, ``3m07s``, ``12s``."""
    seconds = max(0, round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    if hours:
        return f"{hours}h{minutes:02d}m"
    return f"{minutes}m{secs:02d}s" if minutes else f"{secs}s"


class CampaignProgress:
    """``with CampaignProgress(todo) as progress: progress.update(finished, failed)``."""

    def __init__(self, todo: int, *, quiet: bool = False, stream: IO[str] | None = None):
        self.todo = todo
        self.quiet = quiet
        self.stream: IO[str] = stream if stream is not None else sys.stderr
        isatty = getattr(self.stream, "isatty", None)
        self.tty = bool(isatty()) if callable(isatty) else False
        self.started_s = time.monotonic()
        self.next_mark = 0.1
        self._rich: Any = None
        self._task: Any = None

    def __enter__(self) -> CampaignProgress:
        if self.tty and not self.quiet and self.todo > 0:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self._rich = Progress(
                TextColumn("runs"), BarColumn(), MofNCompleteColumn(),
                TextColumn("{task.fields[rate]}"), TimeElapsedColumn(),
                TextColumn("ETA"), TimeRemainingColumn(),
                console=Console(file=self.stream, force_terminal=True), transient=True,
            )
            self._rich.start()
            self._task = self._rich.add_task("runs", total=self.todo, rate="")
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._rich is not None:
            self._rich.stop()
            self._rich = None

    def rate(self, ended: int) -> float:
        elapsed_s = time.monotonic() - self.started_s
        return ended / elapsed_s if elapsed_s > 0 else 0.0

    def update(self, finished: int, failed: int) -> None:
        """After each run: ``finished`` stored, ``failed`` given up, this session."""
        if self.quiet or self.todo <= 0:
            return
        ended = finished + failed
        rate = self.rate(ended)
        if self._rich is not None:
            text = f"{rate:.1f} runs/s" + (f", {failed} failed" if failed else "")
            self._rich.update(self._task, completed=ended, rate=text)
            return
        fraction = ended / self.todo
        if fraction + 1e-9 < self.next_mark:
            return
        while self.next_mark <= fraction + 1e-9:
            self.next_mark += 0.1
        eta = (self.todo - ended) / rate if rate > 0 else 0.0
        failures = f", {failed} failed" if failed else ""
        print(f"gcs campaign: {ended}/{self.todo} runs ({100 * fraction:.0f} %){failures}, "
              f"{rate:.1f} runs/s, ETA {format_duration(eta)}", file=self.stream, flush=True)


def _figure(summary: CellMeans, name: str, digits: int) -> str:
    if name not in summary.figures:
        return "-"
    mean, half = summary.figures[name]
    if half is None:
        return f"{mean:,.{digits}f}"
    return f"{mean:,.{digits}f} ± {half:,.{digits}f}"


def print_summary(keys: Sequence[str], cells: Sequence[CellMeans],
                  stream: IO[str] | None = None) -> None:
    """The per-cell table (module docstring) on ``stream`` (stdout)."""
    from rich.console import Console
    from rich.table import Table

    out = stream if stream is not None else sys.stdout
    table = Table(title="mean and 95 % t-interval per grid cell", title_justify="left",
                  box=None, header_style="bold")
    for key in keys:
        table.add_column(key)
    for name in ("runs", "mean sigma m^2", "final sigma m^2",
                 "growth 2nd half [95 % CI]", "trend <= 0.5", "visits", "lost"):
        table.add_column(name, justify="right")
    for summary in cells:
        bounded = f"{summary.bounded}/{summary.bounded_of}" if summary.bounded_of else "-"
        growth = summary.growth.text() if summary.growth is not None else "-"
        table.add_row(
            *(str(summary.cell[k]) for k in keys), str(summary.runs),
            _figure(summary, "mean_uncertainty", 0), _figure(summary, "final_uncertainty", 0),
            growth, bounded, _figure(summary, "visits", 1), _figure(summary, "lost_targets", 1),
        )
    Console(file=out, width=200 if not out.isatty() else None).print(table)
