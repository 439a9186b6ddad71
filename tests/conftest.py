"""How many pytest-xdist workers run the suite (pyproject's ``addopts`` asks ``-n auto``).

The suite waits more than it computes: most of its wall time is end-to-end runs of
``gcs run`` against the built-in simulator in (sped-up) real time, at a small fraction of a
core each. So it runs on more workers than the machine has cores: ``SUITE_WORKERS`` (see
docs/contributing.md for the measurement behind the figure). A run of one test file (or of
node ids in one file) runs in this process, without workers: no start-up of workers that
would each collect it again, and ``-s``/``--pdb`` work as usual. ``-n N`` on the command
line, or ``PYTEST_XDIST_AUTO_NUM_WORKERS=N``, overrides both.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

SUITE_WORKERS = 4


def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """``SUITE_WORKERS``, or 0 (no workers) when the arguments name a single test file."""
    given = os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS")
    if given:
        return int(given)
    files = {arg.split("::", 1)[0] for arg in config.args}
    if len(files) == 1 and Path(next(iter(files))).is_file():
        return 0
    return SUITE_WORKERS
