"""How many pytest-xdist workers run the suite (pyproject's ``addopts`` asks ``-n auto``).

The suite waits more than it computes: most of its wall time is end-to-end runs of
``gcs run`` against the built-in simulator in (sped-up) real time. It runs on
``SUITE_WORKERS`` workers, chosen by measurement on the shared 2-core machine (see
docs/contributing.md): 2 beat 4 and 6, which starve the simulators on a busy host. A run
of one test file (or of node ids in one file) runs in this process, without workers: no
start-up of workers that would each collect it again, and ``-s``/``--pdb`` work as usual.
``-n N`` on the command line, or ``PYTEST_XDIST_AUTO_NUM_WORKERS=N``, overrides both.

A suite started in the background of a non-interactive shell (``nohup bash -c ... &``)
inherits SIGINT ignored, and so would every ``gcs`` process a test starts: its Ctrl-C
tests would wait for nothing. :func:`pytest_configure` gives the suite (and so its
children) the default Ctrl-C back.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

SUITE_WORKERS = 2


def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """``SUITE_WORKERS``, or 0 (no workers) when the arguments name a single test file."""
    given = os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS")
    if given:
        return int(given)
    files = {arg.split("::", 1)[0] for arg in config.args}
    if len(files) == 1 and Path(next(iter(files))).is_file():
        return 0
    return SUITE_WORKERS


def pytest_configure(config: pytest.Config) -> None:
    """SIGINT back to Python's default when it came ignored (module docstring)."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
