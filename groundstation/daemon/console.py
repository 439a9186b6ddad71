"""The operator's console of ``gcs run``: what reaches the terminal in each ``--status`` mode.

Every warning and error that floe logs (the loggers of ``groundstation``, ``sitl``,
``planner``, ``observer``, ``world`` and ``domain``) reaches the console in every mode, as one
line ``gcs run: ...`` (yellow for a warning, red for an error on a colour terminal):

=========  ===================================================================================
mode       the console
=========  ===================================================================================
``table``  the live table (``status.py``) on stdout, redrawn in place; warnings printed above
           it. On a file or a dumb terminal (``TERM=dumb``) there is nothing to redraw: log
           lines as ``log``, and the table printed once at the end.
``log``    one readable line per operator event (``log_lines``), link state changes
           (connected, bound) and every warning, on stdout; nothing of the links as the
           run shuts down
``auto``   ``table`` on an interactive terminal (not ``TERM=dumb``), else ``log``
``quiet``  warnings and errors only, on stderr
=========  ===================================================================================

Colours come from ``rich``, which writes none to a file, a pipe or a dumb terminal (and
honours ``NO_COLOR``). ``groundstation.storage`` errors are left to the run files' own
stderr line (one per file, whatever the mode).
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Callable
from typing import TextIO

from rich.console import Console
from rich.text import Text

from groundstation.daemon.config import StatusMode

__all__ = ["FLOE_LOGGERS", "ConsoleHandler", "OperatorConsole"]

FLOE_LOGGERS = ("groundstation", "sitl", "planner", "observer", "world", "domain")
_STYLES = {logging.WARNING: "yellow", logging.ERROR: "bold red", logging.CRITICAL: "bold red"}


class ConsoleHandler(logging.Handler):
    """Log records as ``gcs run: message`` lines through a ``rich`` console (above a live
    table when one is shown)."""

    def __init__(self, console: Console, level: int) -> None:
        super().__init__(level)
        self.console = console
        self.addFilter(lambda record: not record.name.startswith("groundstation.storage"))

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = "gcs run: " + record.getMessage()
            if record.exc_info and record.levelno >= logging.ERROR:
                exc = record.exc_info[1]
                text += f" ({type(exc).__name__}: {exc}; traceback in gcs.log)"
            style = _STYLES.get(record.levelno, "")
            self.console.print(Text(text, style=style), soft_wrap=True, highlight=False)
        except Exception:  # a console that cannot be written must never stop the daemon
            self.handleError(record)


class OperatorConsole:
    """The console of one run (see the module docstring)."""

    def __init__(self, mode: StatusMode, stdout: TextIO | None = None,
                 stderr: TextIO | None = None) -> None:
        self.mode = mode
        # the table wraps what is too wide itself (so a redraw knows its height); the log
        # lines are printed whole (soft_wrap) for the terminal to fold
        self.out = Console(file=stdout or sys.stdout, highlight=False)
        self.err = Console(file=stderr or sys.stderr, highlight=False)
        self.interactive = self.out.is_terminal and not self.out.is_dumb_terminal
        self.live_table = self.interactive and mode in (StatusMode.TABLE, StatusMode.AUTO)
        """Redraw the table in place."""
        self.final_table = mode == StatusMode.TABLE and not self.interactive
        """Print the table once at the end (a forced table on a file or dumb terminal)."""
        self.event_lines = mode == StatusMode.LOG or (
            mode != StatusMode.QUIET and not self.live_table
        )
        """One line per operator event (else warnings only)."""

    def install(self) -> Callable[[], None]:
        """Attach the console to floe's loggers; returns the function that detaches it."""
        console = self.err if self.mode == StatusMode.QUIET else self.out
        attached: list[tuple[logging.Logger, logging.Handler]] = []
        for name in FLOE_LOGGERS:
            level = logging.INFO if self.event_lines and name == "groundstation" else (
                logging.WARNING)
            handler = ConsoleHandler(console, level)
            logger = logging.getLogger(name)  # its level: gcs.log's (INFO, run_files)
            logger.addHandler(handler)
            attached.append((logger, handler))

        def detach() -> None:
            for logger, handler in attached:
                logger.removeHandler(handler)

        return detach
