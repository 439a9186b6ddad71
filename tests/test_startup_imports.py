"""What start-up imports: heavy libraries load only on the paths that use them.

Each check runs in a fresh interpreter and reads its ``sys.modules`` (a behaviour test,
not a timing test): ``ortools.sat`` and ``pandas`` (~0.3 s of CPU) only when a solve reaches
CP-SAT, scipy (~0.5-1 s) only when a scan's association or a GOSPA metric needs it, filterpy
never (the filter is floe's own numpy), matplotlib only when something is drawn.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

HEAVY = ("ortools", "pandas", "filterpy", "scipy", "matplotlib")

_REPORT = """
import json, sys
print("MODULES " + json.dumps(sorted({m.split(".")[0] for m in sys.modules})), file=sys.stderr)
"""


def _modules_after(code: str, tmp_path: Path) -> tuple[set[str], str]:
    """Run ``code`` in a fresh interpreter; the top-level modules it had loaded, and stdout."""
    script = tmp_path / "probe.py"
    script.write_text(code + "\n" + _REPORT, encoding="utf-8")
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 0, done.stderr
    line = [ln for ln in done.stderr.splitlines() if ln.startswith("MODULES ")][-1]
    return set(json.loads(line.removeprefix("MODULES "))), done.stdout


def _problem_3x10(path: Path) -> Path:
    uavs = [{"id": f"u{k}", "x": 1500.0, "y": 0.0, "heading": h}
            for k, h in enumerate((0.0, 1.5708, 3.1416))]
    targets = [{"id": f"t{k}", "x": 150.0 * k, "y": 1400.0 - 130.0 * k, "sigma": 5.0 + 3.0 * k}
               for k in range(10)]
    path.write_text(json.dumps({"uavs": uavs, "targets": targets, "turn_radius": 105.0}),
                    encoding="utf-8")
    return path


def test_import_planner_loads_no_cp_sat_and_no_pandas(tmp_path: Path) -> None:
    loaded, _ = _modules_after("import planner", tmp_path)
    assert "planner" in loaded and "numpy" in loaded
    assert not loaded & {"ortools", "pandas", "filterpy", "scipy", "matplotlib"}


def test_gcs_plan_3x10_loads_no_cp_sat_and_no_pandas(tmp_path: Path) -> None:
    problem = _problem_3x10(tmp_path / "p.json")
    code = (
        "import sys\nfrom groundstation.cli import main\n"
        f"status = main(['plan', {str(problem)!r}])\nassert status == 0, status\n"
    )
    loaded, out = _modules_after(code, tmp_path)
    result = json.loads(out)
    assert result["status"] == "optimal"
    assert sorted(t for r in result["routes"].values() for t in r) == sorted(
        f"t{k}" for k in range(10)
    )
    assert not loaded & set(HEAVY)


def test_a_solve_that_needs_cp_sat_still_imports_it(tmp_path: Path) -> None:
    problem = _problem_3x10(tmp_path / "p.json")
    code = (
        "import json\nfrom planner import PlanSolver, problem_from_dict\n"
        f"p = problem_from_dict(json.load(open({str(problem)!r})))\n"
        "r = PlanSolver(p, method='position', deterministic=True).solve()\n"
        "print(r.solver)\n"
    )
    loaded, out = _modules_after(code, tmp_path)
    assert out.strip().startswith("cp-sat/position")
    assert "ortools" in loaded


@pytest.mark.parametrize("model", ["linear", "kalman"])
def test_an_observer_predicting_and_correcting_loads_no_filterpy_and_no_scipy(
    tmp_path: Path, model: str
) -> None:
    """The Kalman filter is floe's own numpy (filterpy's import pulled in scipy.stats)."""
    code = (
        "import groundstation.core\nimport numpy as np\n"
        "from observer import Observer, ObserverConfig\n"
        f"obs = Observer(ObserverConfig(model={model!r}))\n"
        "obs.add_target('A', 0.0, 1.0, 2.0)\nobs.predict_to(3.0)\n"
        "out = obs.measure(3.0, 1.5, 2.5, 'A')\nassert out.accepted, out\nobs.predict_to(7.25)\n"
    )
    loaded, _ = _modules_after(code, tmp_path)
    assert not loaded & set(HEAVY)


def test_gcs_simulate_without_plots_loads_no_matplotlib(tmp_path: Path) -> None:
    out = tmp_path / "sim"
    code = (
        "from groundstation.cli import main\n"
        f"status = main(['simulate', '--duration', '20', '--no-plots', '--quiet', '--out', "
        f"{str(out)!r}])\nassert status == 0, status\n"
    )
    loaded, _ = _modules_after(code, tmp_path)
    assert (out / "metrics.json").is_file()
    # paper-boat is a Kalman scenario without discovery: no filterpy, no scipy (GOSPA)
    assert not loaded & set(HEAVY)
    # and local metres throughout: pymap3d (~30 ms) loads at the first fix converted
    assert "pymap3d" not in loaded and "groundstation" in loaded


@pytest.mark.parametrize("argv", [["--help"], ["--vehicles", "sim:1", "--no-such-flag"]])
def test_gcs_run_answers_help_and_a_bad_flag_without_importing_the_daemon(
        tmp_path: Path, argv: list[str]) -> None:
    """The arguments are parsed before the daemon (aiohttp, rich, pymavlink, the planner:
    ~0.5 CPU-s) is imported, so ``--help`` and a typo answer at once."""
    code = (
        "import contextlib, io, sys\nfrom groundstation.cli import main\n"
        "err, out = io.StringIO(), io.StringIO()\n"
        "try:\n"
        "    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):\n"
        f"        status = main(['run', *{argv!r}])\n"
        "except SystemExit as exc:\n"
        "    status = exc.code\n"
        "print(status, out.getvalue().splitlines()[:1], err.getvalue().strip())\n"
    )
    loaded, printed = _modules_after(code, tmp_path)
    if argv == ["--help"]:
        assert printed.startswith("0 ['usage: gcs run")
    else:
        assert printed.startswith("2 [] gcs run: error: unrecognized arguments: --no-such-flag")
    assert not loaded & {"aiohttp", "rich", "pymavlink", "pymap3d", *HEAVY}
    assert "groundstation" in loaded


def test_gcs_run_of_paper_boat_loads_no_solver_library(tmp_path: Path) -> None:
    """paper-boat's problems (3 UAVs x 10 targets) stay in the DP's range, so a whole ``gcs
    run`` of it never imports CP-SAT, pandas or scipy (~1 CPU-s a start until issue 30):
    the solver runner loads them only near the DP's limit."""
    run_dir = tmp_path / "runs"
    code = (
        "from groundstation.cli import main\n"
        "status = main(['run', '--vehicles', 'sim:3', '--scenario', 'paper-boat', '--duration',"
        f" '60', '--speedup', '20', '--run-dir', {str(run_dir)!r}, '--http', 'off',"
        " '--status', 'quiet'])\nassert status == 0, status\n"
    )
    loaded, _ = _modules_after(code, tmp_path)
    journal = [json.loads(line) for line in
               next(run_dir.glob("*/journal.jsonl")).read_text(encoding="utf-8").splitlines()]
    plans = [e for e in journal if e["event"] == "plan"]
    assert plans and not [e for e in journal if e["event"] == "task_error"]
    assert not loaded & set(HEAVY), loaded & set(HEAVY)
