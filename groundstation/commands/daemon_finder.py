"""Which running daemon ``gcs target`` / ``gcs vehicle`` talk to, and with which token.

Every ``gcs run`` with its control API on writes ``RUN_DIR/<run>/control.json`` (mode 0600):
``{"url": "http://127.0.0.1:PORT", "token": "..."}``. The API is chosen in this order:

1. ``--api URL``, else ``$FLOE_API``: that daemon. Its token: ``--token``, else
   ``$FLOE_TOKEN``, else the token of a ``control.json`` (under ``--run-dir``) naming the
   same URL.
2. Otherwise the newest **live** daemon among the ``control.json`` files of
   ``--run-dir`` (default ``runs``): the files are taken newest first (modification time),
   at most :data:`MAX_PROBED` of them, and each URL is asked ``GET /api/server`` (a stale
   file of a daemon that ended, or a port now used by something else, is skipped). Its
   token: ``--token``, else the file's (``$FLOE_TOKEN`` may belong to another run).
   The choice is said on stderr, with the number of live daemons when there are several.
3. None live: a one-line error naming the folder searched and the ways to choose.
"""

from __future__ import annotations

import json
import os
import urllib.parse
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

__all__ = ["DEFAULT_RUN_DIR", "MAX_PROBED", "ControlFile", "FoundDaemon", "find_daemon"]

DEFAULT_RUN_DIR = "runs"
MAX_PROBED = 20


@dataclass(frozen=True, slots=True)
class ControlFile:
    """One ``control.json``: where it is, the URL and the token it holds."""

    path: Path
    url: str
    token: str | None
    mtime_s: float


@dataclass(frozen=True, slots=True)
class FoundDaemon:
    """The chosen API, its token (None: none known) and what to tell the user (None:
    nothing, the user chose it)."""

    url: str
    token: str | None
    note: str | None = None


def _same_url(a: str, b: str) -> bool:
    pa, pb = urllib.parse.urlsplit(a.rstrip("/")), urllib.parse.urlsplit(b.rstrip("/"))
    try:
        return (pa.scheme, pa.hostname, pa.port) == (pb.scheme, pb.hostname, pb.port)
    except ValueError:
        return False


def control_files(run_dir: Path) -> list[ControlFile]:
    """The readable ``control.json`` files directly under ``run_dir``'s run folders,
    newest first; unreadable or malformed ones are skipped."""
    found: list[ControlFile] = []
    try:
        folders = list(run_dir.iterdir())
    except OSError:
        return []
    for folder in folders:
        path = folder / "control.json"
        try:
            mtime_s = path.stat().st_mtime
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if not isinstance(data, dict) or not isinstance(data.get("url"), str):
            continue
        token = data.get("token")
        found.append(
            ControlFile(path, data["url"], token if isinstance(token, str) else None, mtime_s)
        )
    found.sort(key=lambda c: (c.mtime_s, str(c.path)), reverse=True)
    return found


def find_daemon(
    api: str | None,
    token: str | None,
    run_dir: str | None,
    is_live: Callable[[str], bool],
    environ: dict[str, str] | None = None,
) -> FoundDaemon:
    """The daemon to talk to (module docstring). ``is_live(url)`` probes one API;
    raises ``LookupError`` (one line) when no daemon can be found."""
    env = os.environ if environ is None else environ
    folder = Path(run_dir or DEFAULT_RUN_DIR)
    chosen = api or env.get("FLOE_API")
    if chosen:
        key = token or env.get("FLOE_TOKEN")
        if key is None:
            key = next((c.token for c in control_files(folder) if _same_url(c.url, chosen)), None)
        return FoundDaemon(chosen, key)
    files = control_files(folder)
    if not files:
        raise LookupError(
            f"no running daemon found: no control.json under {folder}/ (start 'gcs run', "
            "or give --api URL (or FLOE_API), or --run-dir DIR where gcs run writes its runs)"
        )
    live = [c for c in files[:MAX_PROBED] if is_live(c.url)]
    if not live:
        raise LookupError(
            f"no running daemon found: the {min(len(files), MAX_PROBED)} newest control.json "
            f"under {folder}/ belong to daemons that stopped (start 'gcs run', or give "
            "--api URL, or --run-dir DIR)"
        )
    best = live[0]
    others = f"; newest of {len(live)} running, --api URL to choose" if len(live) > 1 else ""
    note = f"using the daemon at {best.url} ({best.path}{others})"
    return FoundDaemon(best.url, token or best.token, note)
