"""How many pytest-xdist workers run the suite (pyproject's ``addopts`` asks ``-n auto``).

The suite waits more than it computes: most of its wall time is end-to-end runs of
``gcs run`` against the built-in simulator in (sped-up) real time. It runs on
``SUITE_WORKERS`` workers: two per core (at most 8), chosen by measurement on the shared
2-core machine (docs/contributing.md). Beside other work the workers' share of the CPU is
what bounds the suite: with two busy loops on two cores, 4 workers get about 4/6 of the
machine where 2 got 2/4, and the whole suite took 6 min 51 s to 7 min 49 s instead of
10 min 19 s; on an idle machine 4 workers keep both cores busy through the end-to-end
runs' waits. A run
of one test file (or of node ids in one file) runs in this process, without workers: no
start-up of workers that would each collect it again, and ``-s``/``--pdb`` work as usual.
``-n N`` on the command line, or ``PYTEST_XDIST_AUTO_NUM_WORKERS=N``, overrides both.

A suite started in the background of a non-interactive shell (``nohup bash -c ... &``)
inherits SIGINT ignored, and so would every ``gcs`` process a test starts: its Ctrl-C
tests would wait for nothing. :func:`pytest_configure` gives the suite (and so its
children) the default Ctrl-C back.

Every xdist worker collects every test module, and pytest's assertion rewriting of the
158 test modules (36 000 lines) is about 6 CPU-s of each worker's 16-21 CPU-s of collection
(measured in the controller). In a fresh checkout the workers would all rewrite the same
modules at once; :func:`pytest_sessionstart` rewrites
them once in the controller, before the workers start, into pytest's own cache (the same
files pytest would write), so each worker only reads them. With ``PYTHONDONTWRITEBYTECODE``
set (the team's shared machines set it) nothing is written, and every worker rewrites them
itself, as before.
"""

from __future__ import annotations

import fnmatch
import os
import signal
import sys
from pathlib import Path

import pytest

SUITE_WORKERS = min(8, 2 * (os.cpu_count() or 1))


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


@pytest.hookimpl(tryfirst=True)
def pytest_sessionstart(session: pytest.Session) -> None:
    """In xdist's controller, before its workers start (xdist starts them last): rewrite
    the test modules once into pytest's cache (module docstring)."""
    config = session.config
    if (not config.pluginmanager.has_plugin("dsession") or sys.dont_write_bytecode
            or config.getoption("assertmode") != "rewrite"):
        return
    _rewrite_test_modules_once(config, Path(__file__).resolve().parent)


def _rewrite_test_modules_once(config: pytest.Config, folder: Path) -> int:
    """Rewrite every test module of ``folder`` whose cached rewrite is missing or stale,
    as pytest's import hook would; the number rewritten. pytest's rewrite helpers are
    internal: if they change, nothing is rewritten here and the workers do it as before."""
    try:
        from _pytest.assertion import rewrite
    except ImportError:
        return 0
    patterns = [*config.getini("python_files"), "conftest.py"]
    done = 0
    for fn in sorted(folder.glob("*.py")):
        if not any(fnmatch.fnmatch(fn.name, pattern) for pattern in patterns):
            continue
        try:
            pyc = rewrite.get_cache_dir(fn) / (fn.name[:-3] + rewrite.PYC_TAIL)
            if rewrite._read_pyc(fn, pyc) is not None:
                continue
            source_hash, code = rewrite._rewrite_test(fn, config)
            if not rewrite.try_makedirs(pyc.parent):
                return done
            rewrite._write_pyc(config.stash[rewrite.assertstate_key], code, source_hash, pyc)
        except (AttributeError, TypeError, KeyError, OSError, SyntaxError):
            return done
        done += 1
    return done
