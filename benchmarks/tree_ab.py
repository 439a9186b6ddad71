"""Two source trees timed in turn, each in one warm interpreter: the harness of the ``*_ab.py``
benchmarks (``sim_loop_ab.py``, ``sim_vehicle_ab.py``).

Each tree gets one long-lived child (``PYTHONPATH`` set to the tree, started in it) running
the benchmark's own code, which prints ``ready`` once warm, then one figure (CPU seconds)
for every ``run`` line it reads. :func:`interleaved_rounds` asks both for a run each round,
the order alternating every round, so a shared machine's load weighs on both alike.
"""

from __future__ import annotations

import contextlib
import os
import statistics
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
"""This tree."""


@contextlib.contextmanager
def tree_children(
    trees: dict[str, Path], code: str, args: dict[str, list[str]], timeout_s: float = 60.0,
) -> Iterator[dict[str, subprocess.Popen[str]]]:
    """One child per tree running ``code`` with that tree's ``args``, each once warm
    (``ready`` read); closed (stdin shut, waited for ``timeout_s``) on the way out."""
    procs = {
        name: subprocess.Popen(
            [sys.executable, "-c", code, *args[name]],
            env=dict(os.environ, PYTHONPATH=str(root)), cwd=root, text=True,
            stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        for name, root in trees.items()
    }
    try:
        for proc in procs.values():
            assert proc.stdout is not None and proc.stdout.readline().strip() == "ready"
        yield procs
    finally:
        for proc in procs.values():
            if proc.stdin is not None:
                proc.stdin.close()
            proc.wait(timeout=timeout_s)


def interleaved_rounds(procs: dict[str, subprocess.Popen[str]], rounds: int
                       ) -> dict[str, list[float]]:
    """Each child's figure for ``rounds`` runs, asked in turn (module docstring)."""
    out: dict[str, list[float]] = {name: [] for name in procs}
    for k in range(rounds):
        for name in (list(procs) if k % 2 == 0 else list(reversed(procs))):
            proc = procs[name]
            assert proc.stdin is not None and proc.stdout is not None
            proc.stdin.write("run\n")
            proc.stdin.flush()
            out[name].append(float(proc.stdout.readline()))
    return out


def ratio_line(old: list[float], new: list[float]) -> str:
    """``ratio min A, median B``: the other tree's figure over this tree's."""
    return (f"   ratio        min {min(old) / min(new):.2f}, "
            f"median {statistics.median(old) / statistics.median(new):.2f}")
