"""gcs report: the HTML parses, every figure is there, the map shows the tracks."""

from __future__ import annotations

import base64
import contextlib
import io
import json
import math
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from daemon_run import run_gcs

from groundstation.cli import main

SCENARIO = """\
name: report-test
description: three UAVs with loiters, an override and a low battery
duration_s: 100
origin: {lat_deg: 78.93, lon_deg: 11.92}
fleet:
  count: 3
  loiter_s: 15
  loiter_radius_m: 120.0
  launch: {x_m: 0.0, y_m: 0.0}
targets:
  list:
    - {id: A, x_m: 800, y_m: 300, vx_m_s: 0.3, vy_m_s: -0.2}
    - {id: B, x_m: -600, y_m: 900, vx_m_s: -0.2, vy_m_s: 0.1}
    - {id: C, x_m: 1200, y_m: -700, vx_m_s: 0.1, vy_m_s: 0.3}
    - {id: D, x_m: -1000, y_m: -400, vx_m_s: 0.2, vy_m_s: 0.2}
events:
  - {t_s: 40, kind: override, vehicle: "2"}
  - {t_s: 70, kind: battery_low, vehicle: "3"}
observer: {model: kalman, q_per_s: 0.01, iceberg_q_per_s: 0.0005}
policy: {replan: event, commit: true}
"""

TAB_GREEN = np.array([0x2C, 0xA0, 0x2C]) / 255.0  # vehicle 3: its track is drawn last


class _Page(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.imgs: list[dict[str, str | None]] = []
        self.tables: set[str] = set()
        self.text: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "img":
            self.imgs.append(dict(attrs))
        if tag == "table":
            self.tables.add(dict(attrs).get("id") or "")

    def handle_data(self, data: str) -> None:
        self.text.append(data)


def _parse(out: Path) -> _Page:
    page = _Page()
    page.feed((out / "report.html").read_text(encoding="utf-8"))
    page.close()
    return page


def _png(img: dict[str, str | None]) -> bytes:
    src = img.get("src") or ""
    assert src.startswith("data:image/png;base64,")
    data = base64.b64decode(src.split(",", 1)[1], validate=True)
    assert data.startswith(b"\x89PNG\r\n\x1a\n")
    return data


@pytest.fixture(scope="module")
def sim_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("report-sim")
    (root / "s.yaml").write_text(SCENARIO)
    with contextlib.redirect_stdout(io.StringIO()):
        assert (
            main(
                [
                    "simulate",
                    "--scenario",
                    str(root / "s.yaml"),
                    "--out",
                    str(root / "run"),
                    "--quiet",
                    "--no-plots",
                ]
            )
            == 0
        )
    return root / "run"


@pytest.fixture(scope="module")
def sim_report(sim_run: Path) -> Path:
    out = sim_run.parent / "report"
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["report", str(sim_run), "--out", str(out), "--quiet"]) == 0
    return out


def _journal(run: Path) -> list[dict]:
    return [json.loads(line) for line in (run / "journal.jsonl").read_text().splitlines()]


def test_simulate_report_has_every_figure_and_the_tracks(sim_run: Path, sim_report: Path) -> None:
    tmp_path = sim_report
    page = _parse(tmp_path)
    by_alt = {img.get("alt"): img for img in page.imgs}
    assert set(by_alt) == {
        "Map of the flight",
        "Uncertainty against time",
        "Plan timeline per vehicle",
        "Solve times and upload retries",
    }
    pngs = {alt: _png(img) for alt, img in by_alt.items()}
    assert {"summary", "events"} <= page.tables
    text = " ".join(page.text)
    for word in ("override", "release", "send_home", "plans", "uncertainty"):
        assert word in text

    # the plotted extent covers every vehicle's track (from the journalled telemetry)
    records = _journal(sim_run)
    track = {
        v: [
            (r["x_m"], r["y_m"])
            for r in records
            if r["event"] == "input" and r["kind"] == "Telemetry" and r["vehicle"] == v
        ]
        for v in ("1", "2", "3")
    }
    xs = [p[0] for pts in track.values() for p in pts]
    ys = [p[1] for pts in track.values() for p in pts]
    img = by_alt["Map of the flight"]
    x0, x1 = map(float, (img["data-xlim"] or "").split(","))
    y0, y1 = map(float, (img["data-ylim"] or "").split(","))
    assert x0 <= min(xs) and max(xs) <= x1 and y0 <= min(ys) and max(ys) <= y1
    bbox = [float(v) for v in (img["data-track-bbox"] or "").split(",")]
    assert bbox == pytest.approx([min(xs), max(xs), min(ys), max(ys)], abs=1e-3)

    # and the pixels: vehicle 3 is drawn in tab:green across its track's horizontal extent
    info = json.loads((tmp_path / "figures.json").read_text())["map"]
    ax0, _ay0, ax1, _ay1 = info["axes_px"]
    from matplotlib.image import imread  # (not at collection: every worker would pay it)

    pixels = imread(io.BytesIO(pngs["Map of the flight"]), format="png")[:, :, :3]
    green = np.argwhere(np.all(np.abs(pixels - TAB_GREEN) < 0.02, axis=2))
    assert len(green) > 100
    cols = green[:, 1]

    def px(x: float) -> float:
        return ax0 + (x - x0) / (x1 - x0) * (ax1 - ax0)

    v3 = [p[0] for p in track["3"]]
    assert cols.min() <= px(min(v3)) + 3 and cols.max() >= px(max(v3)) - 3
    assert ax0 - 6 <= cols.min() and cols.max() <= ax1 + 6


def test_loiters_and_events_reach_the_report(sim_run: Path, sim_report: Path) -> None:
    info = json.loads((sim_report / "figures.json").read_text())
    flies = [r for r in _journal(sim_run) if r["event"] == "fly"]
    assert info["map"]["loiters"] == len(flies) > 0
    assert info["timeline"]["fly"] == len(flies)
    assert info["solves"]["plans"] == sum(1 for r in _journal(sim_run) if r["event"] == "plan")


def test_bad_input_is_a_one_line_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["report", str(tmp_path / "missing"), "--out", str(tmp_path / "o")]) == 2
    assert "no such file" in capsys.readouterr().err
    assert main(["report", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "neither journal.jsonl nor flight.tlog" in err and "Traceback" not in err


def test_daemon_run_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A short ``gcs run --vehicles sim:3`` at 50x: reported (tracks from its tlog) and
    replayed when its journal holds the core's inputs (else a clear error). The run is the
    daemon in this process (no new interpreter's imports); it stops once it has flown 30
    mission s and made a verified upload (the report's uploads), 120 s the bound: with
    other work on the machine, 30 s at a fixed duration sometimes ended before the first."""
    runs = tmp_path / "runs"
    runs.mkdir()
    daemon, _ = run_gcs(
        runs, "--vehicles", "sim:3", "--scenario", "paper-boat", "--duration", "120",
        "--speedup", "50", "--sim-airborne", timeout_s=100.0,
        until=lambda journal: bool(journal) and journal[-1]["t"] >= 30.0 and any(
            e["event"] == "upload" and e.get("ok") for e in journal))  # fmt: skip
    assert daemon.internal_error is None
    [run] = list(runs.iterdir())
    out = tmp_path / "report"
    assert main(["report", str(run), "--out", str(out), "--quiet"]) == 0
    capsys.readouterr()
    page = _parse(out)
    alts = {img.get("alt") for img in page.imgs}
    assert {"Map of the flight", "Uncertainty against time", "Plan timeline per vehicle"} <= alts
    info = json.loads((out / "figures.json").read_text())["map"]
    x0, x1 = info["xlim"]
    bx0, bx1, by0, _by1 = info["track_bbox"]
    assert x0 <= bx0 < bx1 <= x1 and math.isfinite(by0)
    text = " ".join(page.text)
    assert "uploads" in text and "link losses" in text and "flight.tlog" in text
    has_inputs = '"event":"input"' in (run / "journal.jsonl").read_text()
    status = main(["replay", str(run), "--no-resolve"])
    captured = capsys.readouterr()
    if has_inputs:
        assert status == 0, captured.out[-2000:]
    else:
        assert status == 2 and "no core inputs" in captured.err


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"", "the journal is empty"),
        (b"\n\n  \n", "the journal is empty"),
        (bytes(range(256)) * 20, "no readable journal record"),
        (b'{"event": "start", "t": 0.0, "con', "no readable journal record"),
        (b'[1, 2]\n"text"\n', "no readable journal record"),
        (b'{"event": "track", "t": 1.0, "target": "A", "x_m": 1, "y_m": 2, "sigma": 3}\n',
         "no 'start' record"),
    ],
)  # fmt: skip
def test_empty_or_garbage_journal_is_a_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: bytes, message: str
) -> None:
    for target in (tmp_path / "journal.jsonl", tmp_path):  # the file, and its run folder
        (tmp_path / "journal.jsonl").write_bytes(content)
        assert main(["report", str(target), "--out", str(tmp_path / "o"), "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and "\n" not in err and "Traceback" not in err
        assert not (tmp_path / "o").exists()  # nothing written for nothing


def test_damaged_lines_are_counted_with_their_numbers(
    sim_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lines = (sim_run / "journal.jsonl").read_bytes().split(b"\n")
    for k in range(10, 40, 3):  # ten damaged lines
        lines[k] = b"\x00\xff" + lines[k][:10]
    (tmp_path / "journal.jsonl").write_bytes(b"\n".join(lines))
    assert main(["report", str(tmp_path / "journal.jsonl"), "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    assert "skipped 10 of" in err and "journal lines: 11, 14, 17, 20, 23 and 5 more" in err
    assert err.count("(skipped)") == 5  # the first few, not one line per damaged line


def test_unwritable_output_is_a_one_line_error_and_leaves_no_half_page(
    sim_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:  # fmt: skip
    import errno
    import os

    from groundstation import storage

    out = tmp_path / "o"
    out.mkdir()
    (out / "report.html").write_text("old page\n")
    real_fdopen = os.fdopen

    class FullFile(io.BufferedWriter):
        def write(self, data: object) -> int:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    def fdopen(fd: int, mode: str = "r", *args: object, **kwargs: object) -> object:
        if "w" in mode:
            return FullFile(io.FileIO(fd, "w"))
        return real_fdopen(fd, mode, *args, **kwargs)  # type: ignore[call-overload]

    monkeypatch.setattr(storage.os, "fdopen", fdopen)
    assert main(["report", str(sim_run), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("gcs report: error: cannot write ") and "No space left" in err
    assert "\n" not in err and "Traceback" not in err
    assert (out / "report.html").read_text() == "old page\n"
    assert sorted(p.name for p in out.iterdir()) == ["report.html"]  # no temporaries


def test_report_title_names_the_frontend_and_the_run_once() -> None:
    """The title read "run run, ..." for a gcs run folder."""
    from groundstation.runners.report.data import RunData, _title

    run = RunData("run", Path("runs/20261121T071106Z"), start={"scenario": "paper-boat"})
    run.vehicle_tracks = {"1": [], "2": []}
    assert _title(run) == "gcs run 20261121T071106Z, scenario paper-boat, 2 vehicle(s)"
    sim = RunData("simulate", Path("out/paper"), start={"scenario": "paper-boat", "seed": 3})
    assert _title(sim) == "gcs simulate paper, scenario paper-boat, seed 3, 0 vehicle(s)"
    assert _title(RunData("tlog", Path("x/flight.tlog"))) == "tlog flight.tlog, 0 vehicle(s)"
    assert "run run" not in _title(run)
