"""Smoke test of ``benchmarks/fuzz_daemon.py --quick`` (bounded: about 12 s of wall time):
the script runs the simulator, the fuzzing proxy and ``gcs run`` as subprocesses, sends
its frames and measures. Whether the daemon survives them without false state changes is
the benchmark's verdict (exit status), asserted here only for task errors; the trust
properties themselves are tested in tests/test_daemon_trust.py."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.timeout(90)
def test_fuzz_benchmark_quick_runs_and_measures(tmp_path: Path) -> None:
    out = tmp_path / "fuzz.json"
    proc = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "fuzz_daemon.py"), "--quick", "--json",
         str(out)],
        capture_output=True, text=True, timeout=80, cwd=ROOT,
    )  # fmt: skip
    assert proc.returncode in (0, 1), proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr
    result = json.loads(out.read_text(encoding="utf-8"))
    assert result["frames_on_link"] >= 9_000 and result["frames_other_link"] >= 900
    assert result["task_errors"] == 0
    assert result["daemon_exit"] == 0
    assert result["daemon_rss_kib"]["end"] > 10_000
    gaps = result["worst_telemetry_gap_ms"]
    assert set(gaps) == {"fuzz vehicle 2", "before vehicle 2"}
    assert all(0 < g < 60_000 for g in gaps.values())
    assert proc.returncode == (1 if result["false_state_changes"] else 0)
