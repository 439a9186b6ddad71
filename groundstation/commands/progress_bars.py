"""Progress of long commands on stderr: ``rich`` bars on a terminal, plain lines otherwise.

Rules: progress goes to stderr only (stdout stays the command's result); on a terminal each
task is a ``rich`` bar (one per fleet size of ``gcs simulate --uavs 1,3,5``, one for a
``gcs replay``); when stderr is not a terminal (a pipe, a CI log) there are no escape codes:
one plain line per task at 25 %, 50 %, 75 % and 100 % (``plain_lines``, ``gcs simulate``'s
habit), or nothing (``gcs replay``, whose stderr in a pipe holds only warnings and errors).
``--quiet`` shows nothing.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from types import TracebackType
from typing import IO, Any

__all__ = ["ProgressBars", "TaskUpdate"]

TaskUpdate = Callable[[float], None]
"""Report a task's progress: the amount done so far, in the task's unit."""


class _PlainTask:
    """Quarter-mark lines for a non-terminal stream."""

    def __init__(self, stream: IO[str], label: str, total: float, unit: str) -> None:
        self.stream, self.label, self.total, self.unit = stream, label, total, unit
        self.next_mark = 0.25

    def __call__(self, done: float) -> None:
        if self.total <= 0:
            return
        fraction = done / self.total
        if fraction >= self.next_mark - 1e-9:
            print(
                f"{self.label}: {done:.0f} / {self.total:.0f}{self.unit}",
                file=self.stream,
                flush=True,
            )
            while self.next_mark <= fraction + 1e-9:
                self.next_mark += 0.25


class ProgressBars:
    """A context holding the progress tasks of one command (module docstring).

    ``with ProgressBars(quiet) as bars: update = bars.task("uavs=3", 200.0, " s")`` then
    ``update(t_s)`` as the work advances.
    """

    def __init__(
        self, quiet: bool = False, stream: IO[str] | None = None, *, plain_lines: bool = True
    ) -> None:
        self.stream: IO[str] = stream if stream is not None else sys.stderr
        self.quiet = quiet
        self.plain_lines = plain_lines
        isatty = getattr(self.stream, "isatty", None)
        self.tty = bool(isatty()) if callable(isatty) else False
        self._rich: Any = None

    def __enter__(self) -> ProgressBars:
        if self.tty and not self.quiet:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                Progress,
                TaskProgressColumn,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            console = Console(file=self.stream, force_terminal=True)
            self._rich = Progress(
                TextColumn("{task.description}"),
                BarColumn(),
                TaskProgressColumn(),
                TextColumn("{task.completed:.0f}/{task.total:.0f}{task.fields[unit]}"),
                TimeElapsedColumn(),
                TimeRemainingColumn(),
                console=console,
            )
            self._rich.start()
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

    def task(self, label: str, total: float, unit: str = "") -> TaskUpdate:
        """A new task of ``total`` units; returns its update function."""
        if self.quiet:
            return lambda done: None
        if self._rich is None:
            if not self.plain_lines:
                return lambda done: None
            return _PlainTask(self.stream, label, total, unit)
        bar = self._rich
        task_id = bar.add_task(label, total=max(total, 1e-9), unit=unit)

        def update(done: float) -> None:
            bar.update(task_id, completed=min(done, total))

        return update
