"""Shared helpers of the daemon tests: run ``gcs run`` in this process, read its journal."""

from __future__ import annotations

import asyncio
import json
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from groundstation.commands.run import build_config, run_daemon
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.journal import read_journal

Journal = list[dict[str, Any]]


def run_gcs(
    tmp_path: Path,
    *args: str,
    timeout_s: float = 70.0,
    until: Callable[[Journal], bool] | None = None,
    embedded: Any = None,
) -> tuple[Daemon, Journal]:
    """Run the daemon (no control API, no detection feed, quiet) until ``--duration``, or
    with ``until`` as soon as its journal satisfies it (:func:`stop_when`); return it and
    its journal. ``timeout_s`` (wall) bounds a run that would not stop. ``embedded``:
    another factory of the ``sim:N`` vehicles than ``gcs run``'s (``build_embedded_sim``'s
    signature)."""
    config = build_config([*args, "--run-dir", str(tmp_path), "--http", "off",
                           "--detections", "off", "--status", "quiet"])

    async def main() -> Daemon:
        watchers: list[asyncio.Task[None]] = []

        def started(daemon: Daemon) -> None:
            if until is not None:
                watchers.append(asyncio.create_task(stop_when(daemon, until)))

        options: dict[str, Any] = dict(
            print_fn=lambda _: None, install_signals=False, on_started=started
        )
        try:
            if embedded is not None:
                from groundstation.daemon.startup import run_daemon as run_bare

                return await run_bare(config, embedded=embedded, **options)
            return await run_daemon(config, **options)
        finally:
            for watcher in watchers:
                watcher.cancel()

    daemon = asyncio.run(asyncio.wait_for(main(), timeout_s))
    return daemon, read_journal(daemon.run_dir / "journal.jsonl")


def events(journal: Journal, name: str, **match: Any) -> Journal:
    """The journal lines of event ``name`` whose fields equal ``match``."""
    return [
        e for e in journal if e["event"] == name and all(e.get(k) == v for k, v in match.items())
    ]


def after(items: Journal, t: float) -> Journal:
    return [e for e in items if e["t"] > t]


class JournalTail:
    """The complete lines a running daemon has appended to its journal, read incrementally
    (a line still being written is left for the next call)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.lines: Journal = []
        self._offset = 0
        self._partial = b""

    def poll(self) -> Journal:
        """Read what was appended since the last call; every line so far."""
        try:
            with self.path.open("rb") as fh:
                fh.seek(self._offset)
                data = fh.read()
        except FileNotFoundError:
            return self.lines
        self._offset += len(data)
        *whole, self._partial = (self._partial + data).split(b"\n")
        self.lines += [json.loads(line) for line in whole if line]
        return self.lines


async def stop_when(
    daemon: Daemon, done: Callable[[Journal], bool], poll_wall_s: float = 0.05
) -> None:
    """Ask ``daemon`` to stop as soon as its journal satisfies ``done``: a test then waits
    for the events it asserts on, in mission time, however slowly a loaded host runs them
    (its ``--duration`` is only the upper bound; a wall timeout only guards a hang)."""
    path = daemon.journal_file.path
    assert path is not None
    tail = JournalTail(path)
    while not done(tail.poll()):
        await asyncio.sleep(poll_wall_s)
    daemon.request_stop("test: awaited events seen")


def status_text(daemon: Daemon, width: int = 160) -> str:
    """The status table as ``gcs run`` draws it (its recent pane seeded from the journal's
    recent lines, as ``status_loop`` does), in plain text."""
    import io

    from rich.console import Console

    from groundstation.daemon.status import EventTally, render_status

    buffer = io.StringIO()
    console = Console(file=buffer, width=width, color_system=None, force_terminal=False,
                      highlight=False)
    console.print(render_status(daemon, EventTally.from_lines(daemon.journal_file.recent)))
    return buffer.getvalue()


def start_helper(cmd: list[str], pattern: str, count: int,
                 timeout_s: float) -> tuple[Any, list[str]]:
    """Start a helper process (``gcs sitl``, a flood proxy); read its stdout until ``count``
    lines hold ``pattern`` (or ``timeout_s``); the process and the lines read."""
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True)
    lines: list[str] = []
    end = time.monotonic() + timeout_s
    assert proc.stdout is not None
    while len([x for x in lines if pattern in x]) < count and time.monotonic() < end:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line.strip())
    return proc, lines
