"""Every benchmark in benchmarks/ starts at the current commit (issue 30).

A benchmark is run by hand, rarely, so nothing else notices when a change elsewhere
breaks one (``daemon_latency.py`` read a session attribute that no longer existed).
Each script is found by listing the folder, so a new one is checked without being named
here: a script (``if __name__ == "__main__"``) must print its usage for ``--help`` (its
imports and its argument parser work), a helper module must import. The daemon latency
benchmark also runs end to end on a short run, since its measure is the one that broke.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"

_PROBE = """
import contextlib, io, json, runpy, sys
results = {}
for path in sys.argv[1:]:
    script = "__main__" in open(path, encoding="utf-8").read()
    out = io.StringIO()
    saved = sys.argv, list(sys.path)
    sys.argv = [path, "--help"] if script else [path]
    sys.path.insert(0, path.rsplit("/", 1)[0])
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
            runpy.run_path(path, run_name="__main__" if script else "probe")
        status = "imported" if not script else "no usage printed"
    except SystemExit as exc:
        status = "usage" if exc.code in (0, None) and "usage" in out.getvalue() else (
            f"exit {exc.code!r}")
    except BaseException as exc:
        status = f"{type(exc).__name__}: {exc}"
    finally:
        sys.argv, sys.path[:] = saved
    results[path.rsplit("/", 1)[1]] = [script, status]
print("RESULTS " + json.dumps(results))
"""


def test_every_benchmark_script_prints_its_usage_and_every_helper_imports() -> None:
    scripts = sorted(str(p) for p in BENCHMARKS.glob("*.py"))
    assert len(scripts) >= 20 and any(s.endswith("planner_bench.py") for s in scripts)
    done = subprocess.run([sys.executable, "-c", _PROBE, *scripts], capture_output=True,
                          text=True, timeout=240, check=False, cwd=BENCHMARKS.parent)
    assert done.returncode == 0, done.stderr[-2000:]
    line = [ln for ln in done.stdout.splitlines() if ln.startswith("RESULTS ")][-1]
    results = json.loads(line.removeprefix("RESULTS "))
    assert sorted(results) == sorted(Path(s).name for s in scripts)
    bad = {name: status for name, (script, status) in results.items()
           if status != ("usage" if script else "imported")}
    assert not bad


def test_daemon_latency_runs_and_counts_every_loiter_end(tmp_path: Path) -> None:
    """Two built-in vehicles, 90 mission s at 10x: the first loiters end (targets on a
    400 m ring, 20 s loiters) and every loiter end is in the figures, answered or not
    (counts only; the delays themselves depend on the machine's load)."""
    out = tmp_path / "latency.json"
    done = subprocess.run(
        [sys.executable, str(BENCHMARKS / "daemon_latency.py"), "--sizes", "2",
         "--duration", "90", "--speedup", "10", "--ring", "400", "--out", str(out)],
        capture_output=True, text=True, timeout=240, check=False, cwd=BENCHMARKS.parent)
    assert done.returncode == 0, done.stderr[-2000:]
    (row,) = json.loads(out.read_text(encoding="utf-8"))["results"]
    assert row["vehicles"] == 2 and row["joined"] == 2
    assert row["loiter_ends"] >= 1
    assert row["plans"] >= 2 and row["uploads_ok"] >= 2
    assert row["loiter_ends_unanswered"] <= row["loiter_ends"]
    assert row[f"loiter_ends_over_{0.5}_s"] <= row["loiter_ends"]
