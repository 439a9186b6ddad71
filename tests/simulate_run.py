"""Shared helper of the offline-simulator tests: ``gcs simulate`` of a scenario text."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

from groundstation.cli import main


def simulate_text(root: Path, text: str, *extra: str) -> Path:
    """Write ``text`` to ``root/scenario.yaml``, run ``gcs simulate`` on it in this
    process (quiet, no plots, ``extra`` arguments appended) and return its output folder;
    the run must exit 0."""
    root.mkdir(parents=True, exist_ok=True)
    scenario = root / "scenario.yaml"
    scenario.write_text(text)
    out = root / "run"
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["simulate", "--scenario", str(scenario), "--out", str(out), "--quiet",
                     "--no-plots", *extra]) == 0
    return out
