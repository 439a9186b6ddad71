"""How many pytest-xdist workers run the suite (pyproject's ``addopts`` asks ``-n auto``).

The suite waits more than it computes: most of its wall time is end-to-end runs of
``gcs run`` against the built-in simulator in (sped-up) real time. It runs on
``SUITE_WORKERS`` workers: two per core and one more (at most 8), chosen by measurement on
the shared 2-core machine (docs/contributing.md). Beside other work the workers' share of
the CPU is what bounds the suite: with two busy loops on two cores, 4 workers get about
4/6 of the machine where 2 got 2/4 (6 min 51 s to 7 min 49 s instead of 10 min 19 s), and
5 get 5/7: in two interleaved pairs 5 min 43 s and 5 min 25 s against 6 min 23 s and
6 min 11 s on 4 (pytest's count); on an idle machine they keep both cores busy through the
end-to-end runs' waits. A run
of one test file (or of node ids in one file) runs in this process, without workers: no
start-up of workers that would each collect it again, and ``-s``/``--pdb`` work as usual.
``-n N`` on the command line, or ``PYTEST_XDIST_AUTO_NUM_WORKERS=N``, overrides both.

A suite started in the background of a non-interactive shell (``nohup bash -c ... &``)
inherits SIGINT ignored, and so would every ``gcs`` process a test starts: its Ctrl-C
tests would wait for nothing. :func:`pytest_configure` gives the suite (and so its
children) the default Ctrl-C back.

Every xdist worker collects every test module, and pytest's assertion rewriting of the
158 test modules (36 000 lines) is about half of a worker's collection (8 of 16 CPU-s
beside two busy loops). In a fresh checkout the workers would all rewrite the same modules
at once; :func:`pytest_sessionstart` rewrites them once in the controller, before the
workers start, into pytest's own cache (the same files pytest would write), so each worker
only reads them. With ``PYTHONDONTWRITEBYTECODE`` set (the team's shared machines set it,
to keep ``__pycache__`` out of checkouts) nothing is written beside the sources: the
controller's rewrites go to a temporary folder, removed when the session ends, that the
workers read them from (:func:`_read_rewrites_from_the_controller`).

xdist's ``worksteal`` gives each worker a contiguous share of the collection and lets an
idle worker take the back half of a busy one's queue. A share that ended on a 47 s flood
test left one worker running alone for the last half minute, so
:func:`pytest_collection_modifyitems` deals the modules by their measured wall time
(``tests/durations.json``, written by ``benchmarks/suite_cpu.py durations``): the long
modules (15 s or more) go, longest first, to the share with the least so far, at the front
of it, and the rest follow in their usual order; a module's tests stay together (their
module fixtures are made once). A test missing from the file counts as short; without the
file nothing is reordered.
"""

from __future__ import annotations

import fnmatch
import json
import os
import shutil
import signal
import sys
import tempfile
from pathlib import Path
from typing import Any

import pytest

SUITE_WORKERS = min(8, 2 * (os.cpu_count() or 1) + 1)

REWRITES_ENV = "FLOE_TEST_REWRITES"
"""The controller's temporary folder of rewritten test modules, for its workers (set only
with ``PYTHONDONTWRITEBYTECODE``)."""
TESTS = Path(__file__).resolve().parent
DURATIONS = TESTS / "durations.json"
LONG_MODULE_S = 15.0
"""A module whose tests took this much wall time or more is dealt first (module docstring)."""


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
    the test modules once, into pytest's cache or, when bytecode is not to be written, a
    temporary folder the workers are told of (module docstring)."""
    config = session.config
    if (not config.pluginmanager.has_plugin("dsession")
            or config.getoption("assertmode") != "rewrite"):
        return
    if not sys.dont_write_bytecode:
        _rewrite_test_modules_once(config, TESTS, None)
        return
    folder = Path(tempfile.mkdtemp(prefix="floe-test-rewrites-"))
    config.add_cleanup(lambda: shutil.rmtree(folder, ignore_errors=True))
    if _rewrite_test_modules_once(config, TESTS, folder):
        os.environ[REWRITES_ENV] = str(folder)


def _read_rewrites_from_the_controller() -> None:
    """In a worker whose controller rewrote the test modules into a temporary folder
    (``PYTHONDONTWRITEBYTECODE``): pytest's import hook looks for them there. It only reads
    (bytecode is not written) and checks each against its source's hash, as always."""
    folder = os.environ.get(REWRITES_ENV)
    if not folder or "PYTEST_XDIST_WORKER" not in os.environ:
        return
    try:
        from _pytest.assertion import rewrite
        own_cache_dir = rewrite.get_cache_dir
    except (ImportError, AttributeError):
        return
    if getattr(own_cache_dir, "floe_rewrites", False):
        return  # this module imported a second time (tests/test_suite_order.py)

    def cache_dir(file_path: Path) -> Path:
        return Path(folder) if file_path.resolve().parent == TESTS else own_cache_dir(file_path)

    cache_dir.floe_rewrites = True  # type: ignore[attr-defined]
    rewrite.get_cache_dir = cache_dir


_read_rewrites_from_the_controller()


def _rewrite_test_modules_once(config: pytest.Config, folder: Path, into: Path | None) -> int:
    """Rewrite every test module of ``folder`` whose rewrite in ``into`` (None: pytest's
    own cache) is missing or stale, as pytest's import hook would; the number rewritten
    or found fresh. A forked child takes every other module, so two processes share the
    work where the workers wait for it (beside two busy loops on two cores they get a whole
    core, one process two thirds of one); a child that fails leaves its modules to the
    workers' own import hook. pytest's rewrite helpers are internal: if they change,
    nothing is rewritten here and the workers do it as before."""
    try:
        from _pytest.assertion import rewrite
    except ImportError:
        return 0
    patterns = [*config.getini("python_files"), "conftest.py"]
    modules = [fn for fn in sorted(folder.glob("*.py"))
               if any(fnmatch.fnmatch(fn.name, pattern) for pattern in patterns)]
    child = os.fork() if hasattr(os, "fork") and len(modules) > 8 else -1
    if child == 0:  # the child: every other module, then out without pytest's exit hooks
        done = _rewrite_modules(rewrite, config, modules[1::2], into)
        os._exit(0 if done == len(modules[1::2]) else 1)
    done = _rewrite_modules(rewrite, config, modules[::2] if child > 0 else modules, into)
    if child > 0:
        _, status = os.waitpid(child, 0)
        done += len(modules[1::2]) if os.waitstatus_to_exitcode(status) == 0 else 0
    return done


def _rewrite_modules(rewrite: Any, config: pytest.Config, modules: list[Path],
                     into: Path | None) -> int:
    """:func:`_rewrite_test_modules_once` for ``modules``: how many it did before a
    failure (pytest's internals changed, a folder that cannot be written)."""
    done = 0
    for fn in modules:
        try:
            pyc = (into or rewrite.get_cache_dir(fn)) / (fn.name[:-3] + rewrite.PYC_TAIL)
            if rewrite._read_pyc(fn, pyc) is None:
                source_hash, code = rewrite._rewrite_test(fn, config)
                if not rewrite.try_makedirs(pyc.parent):
                    return done
                rewrite._write_pyc(config.stash[rewrite.assertstate_key], code, source_hash,
                                   pyc)
        except (AttributeError, TypeError, KeyError, OSError, SyntaxError):
            return done
        done += 1
    return done


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """In an xdist worker: the order of the module docstring (every worker computes the
    same one, as xdist requires; under ``--dist load`` it only changes which worker runs
    what)."""
    workerinput = getattr(config, "workerinput", None)
    if workerinput is None:
        return
    try:
        known = {str(k): float(v) for k, v in json.loads(DURATIONS.read_text()).items()}
    except (OSError, ValueError, AttributeError):
        return
    items[:] = deal(items, int(workerinput["workercount"]), known)


def deal(items: list[pytest.Item], workers: int, wall_s: dict[str, float]) -> list[pytest.Item]:
    """``items`` reordered so that xdist's first shares (``n // workers`` items, then the
    rest split alike) each start with long modules of about equal total wall time."""
    modules: dict[str, list[pytest.Item]] = {}
    for item in items:
        modules.setdefault(item.nodeid.split("::", 1)[0], []).append(item)
    cost = {m: sum(wall_s.get(i.nodeid, 0.0) for i in its) for m, its in modules.items()}
    long = sorted((m for m in modules if cost[m] >= LONG_MODULE_S), key=lambda m: -cost[m])
    dealt = set(long)
    sizes, left = [], len(items)
    for k in range(workers):
        sizes.append(left // (workers - k))
        left -= sizes[-1]
    shares: list[list[pytest.Item]] = [[] for _ in range(workers)]
    loads = [0.0] * workers
    for m in long:
        k = min(range(workers), key=lambda j: (loads[j], j))
        shares[k] += modules[m]
        loads[k] += cost[m]
    rest = [i for m, its in modules.items() if m not in dealt for i in its]
    out: list[pytest.Item] = []
    end = 0  # where xdist's share k ends
    for share, size in zip(shares, sizes, strict=True):
        end += size
        out += share
        need = max(0, end - len(out))
        out += rest[:need]
        del rest[:need]
    return out + rest
