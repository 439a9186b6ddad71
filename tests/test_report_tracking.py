"""gcs report on the multi-target tracker's journal lines: ``track`` lines with ``status``,
``search`` lines and the ``track_*`` notes give the tracking figure and the lifecycle
table; a journal without them gives today's report (no figure, no table). Synthetic
journals, no simulation: fast."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path
from typing import Any

from groundstation.cli import main
from groundstation.runners.report.page import build_report
from groundstation.runners.report.track_data import tracking_of


def _write(path: Path, records: list[dict[str, Any]]) -> Path:
    path.write_text("".join(json.dumps(r) + "\n" for r in records), encoding="utf-8")
    return path


def _base() -> list[dict[str, Any]]:
    return [
        {"event": "start", "t": 0.0, "frontend": "simulate", "scenario": "synthetic", "seed": 1},
        {"event": "input", "t": 0.0, "kind": "VehicleJoined", "vehicle": "1", "x_m": 0.0,
         "y_m": 0.0},
        {"event": "input", "t": 5.0, "kind": "Telemetry", "vehicle": "1", "x_m": 100.0,
         "y_m": 50.0},
        {"event": "truth", "t": 5.0, "target": "ice1", "x_m": 510.0, "y_m": 490.0},
    ]


def _tracker_lines() -> list[dict[str, Any]]:
    """Four tracks: N1 born, confirmed; N2 born from clutter and deleted; N3 still
    tentative; P1 a prior entry; two search snapshots (the second is drawn)."""
    return [
        {"event": "track_born", "t": 1.0, "target": "N1", "detail": "unassociated detection"},
        {"event": "track", "t": 1.0, "target": "N1", "status": "tentative", "x_m": 500.0,
         "y_m": 500.0, "sigma": 900.0},
        {"event": "track", "t": 1.0, "target": "P1", "status": "prior", "x_m": -400.0,
         "y_m": 300.0, "sigma": 1800.0},
        {"event": "search", "t": 1.0, "cells": [["c0", 150.0, 150.0, 300.0, 10.0]]},
        {"event": "note", "t": 2.0, "kind": "track_born", "target": "N2", "detail": "clutter?"},
        {"event": "track", "t": 2.0, "target": "N2", "status": "tentative", "x_m": 900.0,
         "y_m": -100.0, "sigma": 900.0},
        {"event": "track_confirmed", "t": 3.0, "target": "N1", "detail": "3 of 5"},
        {"event": "track", "t": 3.0, "target": "N1", "status": "confirmed", "x_m": 505.0,
         "y_m": 495.0, "sigma": 20.0},
        {"event": "track_deleted", "t": 4.0, "target": "N2", "detail": "not confirmed"},
        {"event": "track_born", "t": 4.5, "target": "N3", "detail": "unassociated detection"},
        {"event": "track", "t": 4.5, "target": "N3", "status": "tentative", "x_m": 0.0,
         "y_m": 800.0, "sigma": 900.0},
        {"event": "search", "t": 5.0, "cells": [
            ["c0", 150.0, 150.0, 300.0, 120.0], ["c1", 450.0, 150.0, 300.0, 480.5],
            ["c2", 150.0, 450.0, 300.0, 0.0], ["bad", 1.0, "x", 300.0, 1.0],
        ]},
    ]


def test_tracking_data_reads_every_kind_of_line_and_skips_garbage() -> None:
    data = tracking_of(_base() + _tracker_lines())
    assert data.present()
    assert data.final_status() == {"N1": "confirmed", "N2": "tentative", "N3": "tentative",
                                   "P1": "prior"}
    assert [(e.kind, e.track) for e in data.lifecycle] == [
        ("born", "N1"), ("born", "N2"), ("confirmed", "N1"), ("deleted", "N2"), ("born", "N3")]
    assert [c.id for c in data.last_search()] == ["c0", "c1", "c2"]
    assert data.skipped == 1  # the cell with a string coordinate
    counts = data.counts()
    assert counts["born"] == 2 + 1 and counts["confirmed"] == 1 and counts["deleted"] == 1
    assert (counts["final_confirmed"], counts["final_tentative"], counts["final_prior"]) == (
        1, 1, 1)  # N2 was deleted: not counted at the end


def test_report_draws_the_tracking_figure_and_the_lifecycle_table(tmp_path: Path) -> None:
    journal = _write(tmp_path / "journal.jsonl", _base() + _tracker_lines())
    result = build_report(journal, tmp_path / "out")
    figures = {f.name: f for f in result.figures}
    assert "tracking" in figures
    info = figures["tracking"].info
    assert info["tracks"] == {"confirmed": ["N1"], "tentative": ["N3"], "prior": ["P1"]}
    assert info["deleted"] == ["N2"]
    assert info["search_cells"] == 3 and info["search_value_max_m2"] == 480.5
    assert info["counts"]["confirmed"] == 1 and info["skipped"] == 1
    page = result.html_path.read_text(encoding="utf-8")
    assert 'id="fig-tracking"' in page and 'id="tracks"' in page
    table = page.split('id="tracks"', 1)[1].split("</table>", 1)[0]
    assert table.count("<tr>") == 1 + 5  # header + 5 lifecycle notes
    assert "not confirmed" in table and "3 of 5" in table
    assert "<th>tracker</th>" in page and "3 born, 1 confirmed, 1 deleted" in page
    assert "malformed tracker entries" in page  # the skipped cell is a warning
    saved = json.loads((tmp_path / "out" / "figures.json").read_text())
    assert saved["tracking"]["tracks"]["prior"] == ["P1"]
    # tentative tracks stay out of the per-target estimates (map, uncertainty)
    assert result.data is not None and set(result.data.target_estimates) == {"N1", "P1"}


def test_journal_without_tracker_lines_gives_todays_report(tmp_path: Path) -> None:
    old = [
        *_base(),
        {"event": "track", "t": 5.0, "target": "A", "x_m": 500.0, "y_m": 500.0, "sigma": 30.0},
        {"event": "track", "t": 6.0, "target": "A", "x_m": 501.0, "y_m": 500.0, "sigma": 31.0},
    ]
    journal = _write(tmp_path / "journal.jsonl", old)
    out = tmp_path / "out"
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["report", str(journal), "--out", str(out), "--quiet"]) == 0
    page = (out / "report.html").read_text(encoding="utf-8")
    names = set(json.loads((out / "figures.json").read_text()))
    assert "tracking" not in names and {"map", "uncertainty"} <= names
    assert 'id="tracks"' not in page and "<th>tracker</th>" not in page
    # known targets, every one confirmed from the start: still today's report
    confirmed = [{**r, "status": "confirmed"} if r["event"] == "track" else r for r in old]
    result = build_report(_write(tmp_path / "j2.jsonl", confirmed), tmp_path / "out2")
    assert "tracking" not in {f.name for f in result.figures}
    assert result.data is not None and set(result.data.target_estimates) == {"A"}
