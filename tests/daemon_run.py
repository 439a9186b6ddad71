"""Shared helpers of the daemon tests: run ``gcs run`` in this process, read its journal."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

from groundstation.commands.run import build_config, run_daemon
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.journal import read_journal

Journal = list[dict[str, Any]]


def run_gcs(tmp_path: Path, *args: str, timeout_s: float = 70.0) -> tuple[Daemon, Journal]:
    """Run the daemon (no control API, no detection feed, quiet) until ``--duration``;
    return it and its journal. ``timeout_s`` (wall) bounds a run that would not stop."""
    config = build_config([*args, "--run-dir", str(tmp_path), "--http", "off",
                           "--detections", "off", "--status", "quiet"])
    daemon = asyncio.run(asyncio.wait_for(
        run_daemon(config, print_fn=lambda _: None, install_signals=False), timeout_s))
    return daemon, read_journal(daemon.run_dir / "journal.jsonl")


def events(journal: Journal, name: str, **match: Any) -> Journal:
    """The journal lines of event ``name`` whose fields equal ``match``."""
    return [
        e for e in journal if e["event"] == name and all(e.get(k) == v for k, v in match.items())
    ]


def after(items: Journal, t: float) -> Journal:
    return [e for e in items if e["t"] > t]
