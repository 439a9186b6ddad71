"""What the operator sees of ``gcs run``: ``gcs run`` as a subprocess on a pseudo-terminal
(``os.openpty``) for the live table and on pipes for the log lines, bounded in time.

* the table keeps the live-map URL in its header through its redraws, its recent pane holds
  operator events only (no ``truth``/``track``/``detection`` lines), plans as routes;
* an unreachable ``tcp:127.0.0.1:<closed port>``: its warnings on the console during the run
  (table and log modes), a clear error line and exit status 1 at the end;
* no escape codes on a pipe or a dumb terminal.
"""

from __future__ import annotations

import fcntl
import os
import re
import select
import socket
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

import pytest

from groundstation.commands.run import EXIT_NO_VEHICLE

ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")
STATE_UPDATES = ("truth", "track", "detection", "input")


def closed_port() -> int:
    """A TCP port on 127.0.0.1 nothing listens on (bound, then closed)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _env(term: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if k not in ("NO_COLOR", "FORCE_COLOR", "COLUMNS", "LINES", "TTY_COMPATIBLE")}
    env.update(TERM=term, PYTHONWARNINGS="ignore")
    return env


def gcs_run_pty(args: list[str], cwd: Path, *, term: str = "xterm-256color",
                timeout_s: float = 90.0) -> tuple[int, str]:
    """``gcs run ARGS`` with stdin/stdout/stderr on a 160x60 pseudo-terminal; its exit
    status and everything it wrote."""
    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 60, 160, 0, 0))
    proc = subprocess.Popen([sys.executable, "-m", "groundstation.cli", "run", *args],
                            stdin=slave, stdout=slave, stderr=slave, cwd=cwd,
                            env=_env(term), close_fds=True)
    os.close(slave)
    chunks: list[bytes] = []
    end = time.monotonic() + timeout_s
    try:
        while time.monotonic() < end:
            ready, _, _ = select.select([master], [], [], 0.2)
            if ready:
                try:
                    data = os.read(master, 65536)
                except OSError:  # EIO: the child closed the terminal
                    break
                if not data:
                    break
                chunks.append(data)
            elif proc.poll() is not None:
                break
        code = proc.wait(timeout=max(1.0, end - time.monotonic()))
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(master)
    return code, b"".join(chunks).decode("utf-8", "replace")


def gcs_run_pipe(args: list[str], cwd: Path, timeout_s: float = 90.0
                 ) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "groundstation.cli", "run", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=timeout_s, env=_env("xterm"))


def frames(text: str) -> list[str]:
    """The table's redraws (escape codes removed), each from its title line on."""
    plain = ANSI.sub("", text).replace("\r", "")
    return ["floe gcs run" + part for part in plain.split("floe gcs run")[1:]]


def recent_pane(frame: str) -> list[str]:
    """The lines under ``recent:`` of one frame (up to the console's next own line)."""
    lines = frame.split("recent:", 1)[1].splitlines()[1:]
    return [line for line in lines if line.startswith("  t=")]


@pytest.mark.timeout(120)
def test_table_keeps_the_live_map_url_and_shows_operator_events(tmp_path: Path) -> None:
    code, out = gcs_run_pty(
        ["--vehicles", "sim:2", "--scenario", "paper-boat", "--speedup", "10",
         "--duration", "45", "--http", "127.0.0.1:0", "--detections", "off",
         "--run-dir", str(tmp_path)], tmp_path)  # fmt: skip
    assert code == 0, out[-3000:]
    assert "\x1b[" in out  # a colour terminal: rich draws with escape codes
    url = re.search(r"live map (http://127\.0\.0\.1:\d+)/", ANSI.sub("", out))
    assert url is not None, out[:2000]
    drawn = frames(out)
    assert len(drawn) >= 3, f"{len(drawn)} frames"
    for frame in drawn:  # the first draw and every redraw keep the URL and the token's place
        header = frame.split("vehicle", 1)[0]
        assert f"live map {url.group(1)}/" in header
        assert "control.json" in header
    last = drawn[-1]
    assert re.search(r"plan t=\s*[\d.]+: 1 -> .*\| 2 -> ", last), last[:1500]
    panes = [line for frame in drawn for line in recent_pane(frame)]
    assert any(" plan " in line for line in panes) and any(" upload " in line for line in panes)
    for line in panes:
        assert line.split()[1] not in STATE_UPDATES, line
    journal = (next(tmp_path.glob("2*")) / "journal.jsonl").read_text()
    assert '"event":"truth"' in journal  # there were truth lines to leave out
    # the embedded vehicles closing their TCP ports as the run ends is no lost link
    assert "lost TCP" not in ANSI.sub("", out)


@pytest.mark.timeout(120)
@pytest.mark.parametrize("mode", ["table", "log"])
def test_unreachable_tcp_on_a_terminal_warns_and_exits_1(tmp_path: Path, mode: str) -> None:
    port = closed_port()
    code, out = gcs_run_pty(
        # the silence is counted on the link's clock (wall s): 2 s after its start
        # (--link-silent-after), seen at the alerts' next look (at most a wall second
        # later); the run ends at 6 s
        ["--vehicles", f"tcp:127.0.0.1:{port}", "--speedup", "1", "--duration", "6",
         "--link-silent-after", "2",
         "--http", "127.0.0.1:0", "--detections", "off", "--status", mode,
         "--run-dir", str(tmp_path)], tmp_path)  # fmt: skip
    plain = ANSI.sub("", out).replace("\r", "")
    assert code == EXIT_NO_VEHICLE, plain[-2000:]
    stopped = plain.index("gcs run: stopped")
    during = plain[:stopped]
    assert f"gcs run: link vehicles0: cannot open TCP 127.0.0.1:{port}" in during
    assert f"gcs run: link vehicles0 (tcp:127.0.0.1:{port}): no vehicle heard in" in during
    if mode == "table":  # in the table's header too
        assert any(f"link vehicles0 (tcp:127.0.0.1:{port}): no vehicle heard (never "
                   "connected)" in frame for frame in frames(during))
    else:
        assert not frames(plain)  # no table drawn
        assert "\x1b[33m" in out  # the warnings in yellow on a colour terminal
    assert re.search(r"gcs run: error: no vehicle was heard in [\d.]+ mission s "
                     rf"\(tcp:127\.0\.0\.1:{port}: never connected\)", plain[stopped:])
    assert "Traceback" not in plain


@pytest.mark.timeout(120)
def test_unreachable_tcp_in_log_mode_on_a_pipe(tmp_path: Path) -> None:
    port = closed_port()
    result = gcs_run_pipe(
        # the silence is counted on the link's clock (wall s): 2 s after its start
        # (--link-silent-after), seen at the alerts' next look (at most a wall second
        # later); the run ends at 6 s
        ["--vehicles", f"tcp:127.0.0.1:{port}", "--speedup", "1", "--duration", "6",
         "--link-silent-after", "2", "--http", "off", "--detections", "off",
         "--run-dir", str(tmp_path)], tmp_path)
    out, err = result.stdout, result.stderr
    assert result.returncode == EXIT_NO_VEHICLE, out + err
    assert "\x1b" not in out + err  # no colour or cursor codes on a pipe
    lines = out.splitlines()
    stopped = next(i for i, line in enumerate(lines) if line.startswith("gcs run: stopped"))
    cannot = [i for i, line in enumerate(lines)
              if line.startswith(f"gcs run: link vehicles0: cannot open TCP 127.0.0.1:{port}")]
    silent = [i for i, line in enumerate(lines) if "no vehicle heard in" in line]
    assert cannot and cannot[0] < stopped
    assert silent and silent[0] < stopped
    assert err.strip().splitlines()[-1].startswith("gcs run: error: no vehicle was heard in")
    assert "Traceback" not in out + err


@pytest.mark.timeout(120)
def test_dumb_terminal_gets_log_lines_without_escape_codes(tmp_path: Path) -> None:
    code, out = gcs_run_pty(
        ["--vehicles", "sim:1", "--scenario", "none", "--sim-airborne", "--speedup", "20",
         "--duration", "30", "--http", "off", "--detections", "off",
         "--run-dir", str(tmp_path)], tmp_path, term="dumb")  # fmt: skip
    assert code == 0, out[-2000:]
    assert "\x1b" not in out
    assert "floe gcs run" not in out  # no table to redraw: log lines instead
    assert re.search(r"gcs run: t=[\d.]+ vehicle_joined vehicle=1", out), out[-2000:]


def test_a_problem_that_warned_itself_reaches_the_console_once(tmp_path: Path) -> None:
    """task_error, link_rebound and no_progress: one console line each (the journal line's
    log, or the site's own words with ``Daemon.journal(..., logged=True)``)."""
    import asyncio
    import logging
    from types import SimpleNamespace

    from test_vehicle_controller import active_rig

    from groundstation.core.config import CoreConfig
    from groundstation.daemon.clock import MissionClock
    from groundstation.daemon.config_parse import parse_config
    from groundstation.daemon.daemon import Daemon
    from groundstation.daemon.journal import Journal, read_journal
    from groundstation.daemon.session import VehicleSession
    from groundstation.vehicle import controller_io as vio

    records: list[logging.LogRecord] = []

    class Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            records.append(record)

    def said(word: str) -> list[str]:
        return [r.getMessage() for r in records if word in r.getMessage()]

    async def main() -> Daemon:
        t = [0.0]
        config = parse_config({"vehicles": ["udpin:127.0.0.1:0"]}, {})
        journal = Journal(tmp_path / "journal.jsonl", lambda: t[0], lambda: 1.7e9)
        daemon = Daemon(config, CoreConfig(), MissionClock(1.0, source=lambda: t[0]),
                        tmp_path, None, journal, None)
        failed: list[int] = []

        async def flaky() -> None:
            if not failed:
                failed.append(1)
                raise ConnectionResetError("peer went away")

        await daemon.supervisor.supervise("flaky", flaky)
        assert daemon.router.on_notice is not None
        daemon.router.on_notice("link_rebound", {"system_id": 1, "link": "vehicles1",
                                                 "previous": "vehicles0"})
        rig = active_rig(progress_timeout_s=60.0)
        rig.fly("A", x_m=3000.0)
        rig.run(65.0)  # circling far away: no progress
        host = SimpleNamespace(host=daemon, id="v1")
        VehicleSession._carry_out(host, [o for o in rig.out  # type: ignore[arg-type]
                                         if isinstance(o, vio.JournalLine | vio.Warn)])
        daemon.journal_file.close()
        return daemon

    keep = Keep(logging.INFO)
    logger = logging.getLogger("groundstation")
    level = logger.level
    logger.addHandler(keep)
    logger.setLevel(logging.INFO)
    try:
        asyncio.run(main())
    finally:
        logger.removeHandler(keep)
        logger.setLevel(level)
    journal = [e["event"] for e in read_journal(tmp_path / "journal.jsonl")]
    for event in ("task_error", "link_rebound", "no_progress"):
        assert event in journal, journal
    assert len(said("flaky")) == 1, said("flaky")
    assert len(said("re-bound") + said("link_rebound")) == 1, records
    assert len(said("no progress") + said("no_progress")) == 1, said("progress")


@pytest.mark.timeout(120)
def test_log_mode_says_nothing_of_the_links_as_the_run_shuts_down(tmp_path: Path) -> None:
    """The embedded vehicles stop with the run: no lost link, no reconnect attempt."""
    result = gcs_run_pipe(
        ["--vehicles", "sim:1", "--scenario", "none", "--sim-airborne", "--speedup", "20",
         "--duration", "20", "--http", "off", "--detections", "off", "--status", "log",
         "--run-dir", str(tmp_path)], tmp_path)  # fmt: skip
    out = result.stdout + result.stderr
    assert result.returncode == 0, out[-2000:]
    assert "connected to" in out  # link state changes are shown in log mode
    assert re.search(r"gcs run: t=[\d.]+ stop reason=duration", out), out[-2000:]
    assert "lost TCP" not in out and "cannot open" not in out, out[-2000:]
    assert "reconnecting" not in out


def test_a_start_that_fails_leaves_no_console_handler(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """A failure once the console is installed (here: building the signing gate) detaches
    it, so a later run in the same process prints each line once."""
    import asyncio
    import logging

    from groundstation.commands.run import build_config, run_daemon
    from groundstation.daemon import startup
    from groundstation.daemon.console import FLOE_LOGGERS, ConsoleHandler

    def boom(*args: object) -> None:
        raise RuntimeError("signing gate failed")

    monkeypatch.setattr(startup, "SigningGate", boom)
    phrase = tmp_path / "phrase.txt"
    phrase.write_text("correct horse battery staple\n")
    config = build_config(["--vehicles", f"tcp:127.0.0.1:{closed_port()}", "--http", "off",
                           "--detections", "off", "--status", "log", "--duration", "1",
                           "--signing-passphrase-file", str(phrase),
                           "--run-dir", str(tmp_path)])
    with pytest.raises(RuntimeError, match="signing gate failed"):
        asyncio.run(run_daemon(config, print_fn=lambda _: None, install_signals=False))
    for name in FLOE_LOGGERS:
        handlers = logging.getLogger(name).handlers
        assert not [h for h in handlers if isinstance(h, ConsoleHandler)], name
