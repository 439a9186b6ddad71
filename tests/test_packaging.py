"""Packaging: floe is published as ``floe-gcs`` (``floe`` on the package index is another
project), its field install holds no plotting, Parquet or Dask, and a command that needs an
extra that is not installed says so in one line (domain/extras.py), never with a traceback.

The "not installed" machine is simulated in a fresh interpreter whose ``sys.modules`` maps
matplotlib, pyarrow and dask to None: an import of them raises ModuleNotFoundError, as on a
``pip install .`` without the extras.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_LEAN = """
import sys
for name in ("matplotlib", "pyarrow", "dask", "distributed"):
    sys.modules[name] = None
from groundstation.cli import main
sys.exit(main(sys.argv[1:]))
"""


def _gcs_lean(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    """``gcs ARGS`` in a fresh interpreter without the optional extras."""
    return subprocess.run([sys.executable, "-c", _LEAN, *args], cwd=cwd, capture_output=True,
                          text=True, timeout=100, check=False)


def _pyproject() -> dict:
    with (ROOT / "pyproject.toml").open("rb") as f:
        return tomllib.load(f)


def test_the_distribution_name_is_not_the_other_projects_floe() -> None:
    project = _pyproject()["project"]
    assert project["name"] == "floe-gcs"


def test_field_install_holds_no_plotting_parquet_or_dask() -> None:
    project = _pyproject()["project"]
    core = {re.split(r"[<>=\[ ;]", d, maxsplit=1)[0].lower() for d in project["dependencies"]}
    assert not core & {"matplotlib", "pyarrow", "dask", "pandas"}, core
    extras = project["optional-dependencies"]
    assert any(d.startswith("matplotlib") for d in extras["plot"])
    assert any(d.startswith("pyarrow") for d in extras["campaign"])
    assert any(d.startswith("dask[distributed]") for d in extras["campaign"])
    # the README's test command installs every extra the tests need
    assert "floe-gcs[plot,campaign]" in extras["test"]


def test_no_hint_names_the_other_projects_package() -> None:
    """Every ``pip install 'floe[...]'`` hint names floe-gcs (or '.[...]' from a checkout)."""
    wrong = re.compile(r"pip install ['\"]?floe[\[\s'\"]")
    offenders = []
    for path in [*ROOT.glob("groundstation/**/*.py"), *ROOT.glob("docs/*.md"),
                 ROOT / "README.md", *ROOT.glob("campaigns/*.py")]:
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if wrong.search(line):
                offenders.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    assert not offenders, offenders


def test_simulate_without_matplotlib_refuses_plots_in_one_line(tmp_path: Path) -> None:
    done = _gcs_lean(["simulate", "--duration", "20", "--uavs", "1", "--quiet",
                      "--out", str(tmp_path / "sim")], tmp_path)
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert "floe-gcs[plot]" in lines[0] and "--no-plots" in lines[0]


def test_simulate_and_report_on_the_lean_install(tmp_path: Path) -> None:
    """--no-plots runs without matplotlib; ``gcs report`` (all figures) says what to install."""
    out = tmp_path / "sim"
    done = _gcs_lean(["simulate", "--duration", "20", "--uavs", "1", "--quiet", "--no-plots",
                      "--out", str(out)], tmp_path)
    assert done.returncode == 0, done.stderr
    assert (out / "metrics.json").is_file()
    report = _gcs_lean(["report", "--out", str(tmp_path / "rep"), str(out)], tmp_path)
    assert report.returncode == 2, report.stderr
    assert "Traceback" not in report.stderr
    lines = report.stderr.strip().splitlines()
    assert len(lines) == 1 and "floe-gcs[plot]" in lines[0], lines
