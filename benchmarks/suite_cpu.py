"""The test suite's CPU, test by test: where a suite on a busy machine spends its time.

    python benchmarks/suite_cpu.py run OUT [pytest arguments...]
    python benchmarks/suite_cpu.py report OUT [--top 25] [--modules 15]
    python benchmarks/suite_cpu.py durations OUT [--min-s 2] > tests/durations.json

With other work beside it (two busy loops on two cores, issue 30) the suite gets a share of
the CPU, not the whole machine, so its wall time is about its total CPU over that share:
the lever is CPU, not waiting. ``run`` runs ``python -m pytest -q`` (the README's command,
its workers and all) with this file loaded as a pytest plugin (``-p suite_cpu``): each
process (the controller and every xdist worker) appends one JSON line per test to
``OUT/cpu-<worker>.jsonl`` with the test's CPU of the process itself (``self``: user + system
of ``getrusage(RUSAGE_SELF)``, before and after the test's setup, call and teardown), of the
subprocesses it waited for (``children``: ``RUSAGE_CHILDREN``; a process never waited for,
or waited for during a later test, is not counted or counted there) and its wall time; and
one line with the process's CPU once its collection is done and one at its end. The whole
run's CPU is measured too (the ``children`` rusage of the pytest command, in
``OUT/run.json``).

``report`` prints the per-test sum, the CPU outside tests (collection, worker start-up,
imports: each worker's total less its tests, and the run's total less every test), the top
tests and the top modules by CPU (self + children).
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import resource
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path
from typing import IO, Any

import pytest

OUT_ENV = "SUITE_CPU_DIR"
"""Where the plugin writes (``run`` sets it)."""

_out: IO[str] | None = None


def _cpu_s() -> tuple[float, float]:
    """(user + system CPU s of this process, of its waited-for children)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime, kids.ru_utime + kids.ru_stime


def _write(record: dict[str, Any]) -> None:
    global _out
    folder = os.environ.get(OUT_ENV)
    if folder is None:
        return
    if _out is None:
        worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
        _out = open(Path(folder) / f"cpu-{worker}.jsonl", "a", encoding="utf-8")  # noqa: SIM115
    _out.write(json.dumps(record) + "\n")
    _out.flush()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Any:
    """One line per test: its CPU (self, children) and wall, setup and teardown included."""
    self0_s, kids0_s = _cpu_s()
    wall0_s = time.perf_counter()
    yield
    self1_s, kids1_s = _cpu_s()
    _write({"id": item.nodeid, "self": self1_s - self0_s, "children": kids1_s - kids0_s,
            "wall": time.perf_counter() - wall0_s})


@pytest.hookimpl(trylast=True)
def pytest_collection_finish(session: pytest.Session) -> None:
    """The process's CPU once it has collected (imports of every test module included)."""
    own_s, kids_s = _cpu_s()
    _write({"mark": "collected", "self": own_s, "children": kids_s})


@pytest.hookimpl(trylast=True)
def pytest_sessionfinish(session: pytest.Session) -> None:
    own_s, kids_s = _cpu_s()
    _write({"mark": "end", "self": own_s, "children": kids_s})


def run(out: Path, pytest_args: list[str]) -> int:
    """The README's test command with this plugin; the whole run's CPU in ``out/run.json``."""
    out.mkdir(parents=True, exist_ok=True)
    for old in out.glob("cpu-*.jsonl"):
        old.unlink()
    env = dict(os.environ, **{OUT_ENV: str(out)})
    here = str(Path(__file__).resolve().parent)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (here, env.get("PYTHONPATH")) if p)
    kids0_s = _cpu_s()[1]
    wall0_s = time.perf_counter()
    status = subprocess.call([sys.executable, "-m", "pytest", "-q", "-p", "suite_cpu",
                              *pytest_args], env=env)
    figures = {"status": status, "wall_s": time.perf_counter() - wall0_s,
               "cpu_s": _cpu_s()[1] - kids0_s}
    (out / "run.json").write_text(json.dumps(figures, indent=2) + "\n", encoding="utf-8")
    print(f"suite_cpu: exit {status}, {figures['wall_s']:.0f} s wall, "
          f"{figures['cpu_s']:.0f} CPU-s; python benchmarks/suite_cpu.py report {out}")
    return status


def report(out: Path, top: int, modules: int) -> None:
    """Print the per-test sum, the CPU outside tests, the top tests and modules."""
    tests: list[dict[str, Any]] = []
    marks: dict[str, dict[str, dict[str, float]]] = defaultdict(dict)
    for path in sorted(glob.glob(str(out / "cpu-*.jsonl"))):
        worker = Path(path).stem.removeprefix("cpu-")
        for line in Path(path).read_text(encoding="utf-8").splitlines():
            row = json.loads(line)
            if "mark" in row:
                marks[worker][row["mark"]] = row
            else:
                tests.append({**row, "worker": worker, "cpu": row["self"] + row["children"]})
    total = sum(t["cpu"] for t in tests)
    print(f"tests {len(tests)}: {total:.1f} CPU-s (self {sum(t['self'] for t in tests):.1f}, "
          f"children {sum(t['children'] for t in tests):.1f}), wall summed over workers "
          f"{sum(t['wall'] for t in tests):.1f} s")
    for worker, got in sorted(marks.items()):
        end, collected = got.get("end"), got.get("collected")
        if end is None:
            continue
        mine = [t for t in tests if t["worker"] == worker]
        if not mine:  # xdist's controller: its workers are its children, counted above
            print(f"process {worker}: {end['self']:.1f} CPU-s of its own (runs no test)")
            continue
        outside = end["self"] + end["children"] - sum(t["cpu"] for t in mine)
        line = f"process {worker}: {end['self'] + end['children']:.1f} CPU-s, outside tests " \
               f"{outside:.1f}"
        if collected is not None:
            line += f" (collection and start-up {collected['self']:.1f})"
        print(line)
    run_file = out / "run.json"
    if run_file.exists():
        whole = json.loads(run_file.read_text(encoding="utf-8"))
        print(f"whole run: {whole['cpu_s']:.1f} CPU-s in {whole['wall_s']:.0f} s wall; "
              f"outside tests {whole['cpu_s'] - total:.1f} CPU-s")
    print(f"\ntop {top} tests by CPU-s (cpu, self, children, wall)")
    for t in sorted(tests, key=lambda t: -t["cpu"])[:top]:
        print(f"{t['cpu']:7.2f} {t['self']:6.2f} {t['children']:6.2f} {t['wall']:6.1f}  "
              f"{t['id']}")
    per_module: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0, 0.0, 0.0])
    for t in tests:
        row = per_module[t["id"].split("::", 1)[0]]
        row[0] += t["self"]
        row[1] += t["children"]
        row[2] += t["wall"]
        row[3] += 1
    print(f"\ntop {modules} modules by CPU-s (cpu, self, children, wall, tests)")
    ranked = sorted(per_module.items(), key=lambda kv: -(kv[1][0] + kv[1][1]))
    for name, (own, kids, wall, count) in ranked[:modules]:
        print(f"{own + kids:7.1f} {own:6.1f} {kids:6.1f} {wall:6.1f} {int(count):5d}  {name}")


def _rows(out: Path) -> list[dict[str, Any]]:
    """Every test's row of a run (``cpu-*.jsonl``)."""
    rows: list[dict[str, Any]] = []
    for path in sorted(glob.glob(str(out / "cpu-*.jsonl"))):
        for line in Path(path).read_text(encoding="utf-8").splitlines():
            row = json.loads(line)
            if "mark" not in row:
                rows.append(row)
    return rows


def durations(out: Path, min_s: float) -> str:
    """``tests/durations.json``: each test of at least ``min_s`` wall s in the run, by node
    id, its wall s (one decimal), longest first; what ``tests/conftest.py`` orders the
    workers' shares by."""
    walls = {row["id"]: round(row["wall"], 1) for row in _rows(out) if row["wall"] >= min_s}
    ranked = dict(sorted(walls.items(), key=lambda kv: (-kv[1], kv[0])))
    return json.dumps(ranked, indent=0) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    run_p = sub.add_parser("run", help="run the suite with the plugin")
    run_p.add_argument("out", type=Path)
    run_p.add_argument("pytest_args", nargs=argparse.REMAINDER)
    rep = sub.add_parser("report", help="the figures of a run")
    rep.add_argument("out", type=Path)
    rep.add_argument("--top", type=int, default=25)
    rep.add_argument("--modules", type=int, default=15)
    dur = sub.add_parser("durations", help="the slow tests' wall s, for tests/durations.json")
    dur.add_argument("out", type=Path)
    dur.add_argument("--min-s", type=float, default=2.0)
    args = parser.parse_args(argv)
    if args.command == "run":
        return run(args.out, list(args.pytest_args))
    if args.command == "durations":
        sys.stdout.write(durations(args.out, args.min_s))
        return 0
    report(args.out, args.top, args.modules)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
