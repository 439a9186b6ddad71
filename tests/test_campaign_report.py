"""The campaign report: a self-contained page whose numbers are the grid cells' statistics.

The campaign folders are synthetic (written here with pyarrow, as ``gcs campaign`` writes
them), so every expected number is computed independently from the values written.
"""

from __future__ import annotations

import base64
import datetime as dt
import math
import shutil
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from domain.errors import FloeError
from groundstation.commands.campaign_report import run as campaign_report_command
from groundstation.runners.campaign.data import load_campaign
from groundstation.runners.campaign.report import (
    CampaignReportError,
    summarise_cells,
    write_campaign_report,
)
from groundstation.runners.campaign.stats import group_cells, series_bands

UAVS = (1, 3)
OBJECTIVES = ("sequence", "latency")
SEEDS = 6
DURATION_S = 30
PLANS_PER_RUN = 4
T_975_DF5 = 2.5705818366147395
"""Student's t 97.5 % quantile for 5 degrees of freedom (SEEDS - 1), from a table."""
Z_975 = 1.959963984540054
CAMPAIGN_YAML = """\
name: synthetic
grid:
  scenario: [paper-boat]
  uavs: [1, 3]
  objective: [sequence, latency]
  tau: [0.5]
  seed: {from: 0, to: 5}
set: {fleet.speed_m_s: 20}
per_plan: true
"""


def _campaign_rows() -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    rng = np.random.default_rng(7)
    runs: list[dict[str, Any]] = []
    plans: list[dict[str, Any]] = []
    for uavs in UAVS:
        for objective in OBJECTIVES:
            for seed in range(SEEDS):
                run_id = f"r-{uavs}-{objective}-{seed}"
                t_s = np.arange(DURATION_S + 1, dtype=float)
                level = 40_000.0 / uavs**1.5 * (1 + 0.4 * rng.random())
                sigma = level * (1 - np.exp(-t_s / 8)) + rng.normal(0, 50, t_s.size)
                verdict = None if seed == 0 else bool(rng.random() < uavs / 4)
                runs.append(
                    {
                        "run_id": run_id,
                        "scenario": "paper-boat",
                        "uavs": uavs,
                        "objective": objective,
                        "tau": 0.5,
                        "seed": seed,
                        "fleet.speed_m_s": 20.0,
                        "campaign": "synthetic",
                        "mean_uncertainty": float(sigma.mean()),
                        "max_uncertainty": float(sigma.max()),
                        "bounded": bool(rng.random() < 0.5),
                        "bounded_trend": verdict,
                        "trend": None if seed == 0 else float(rng.normal(0.4, 0.4)),
                        "plans": PLANS_PER_RUN,
                        "solve_time_median_s": float(rng.uniform(0.001, 0.01) * uavs),
                        "solve_time_max_s": float(rng.uniform(0.01, 0.1) * uavs),
                        "series_t_s": t_s.tolist(),
                        "series_mean_sigma": sigma.tolist(),
                        "floe_version": "0.1.0",
                        "wall_s": 0.5,
                        "cpu_s": 0.4,
                        "worker": f"w{seed % 2}",
                    }
                )
                for k in range(PLANS_PER_RUN):
                    f1 = float(rng.uniform(1e4, 1e5))
                    latency = objective == "latency"
                    plans.append(
                        {
                            "run_id": run_id,
                            "uavs": uavs,
                            "objective": objective,
                            "seed": seed,
                            "plan_index": k,
                            "t_s": 5.0 * k,
                            "mu": 0.0 if latency else float(rng.uniform(5, 50)),
                            "f1": f1,
                            "f2": 0.0 if latency else f1 * float(rng.uniform(0.5, 2.0)),
                            "status": "optimal",
                            "solver": "dp",
                            "solve_time_s": float(rng.uniform(0.001, 0.02) * uavs),
                            "gap": None,
                        }
                    )
    return runs, plans


RUNS, PLANS = _campaign_rows()


def _write(folder: Path, *, plans: bool = True, dataset: bool = False, dup: int = 0) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "campaign.yaml").write_text(CAMPAIGN_YAML)
    runs = pa.Table.from_pylist(RUNS)
    if dataset:  # a folder of part files; the second repeats `dup` runs of the first
        (folder / "runs.parquet").mkdir()
        half = runs.num_rows // 2
        pq.write_table(runs.slice(0, half), folder / "runs.parquet" / "part-0.parquet")
        again = pa.concat_tables([runs.slice(half), runs.slice(0, dup)])
        pq.write_table(again, folder / "runs.parquet" / "part-1.parquet")
    else:
        pq.write_table(pa.concat_tables([runs, runs.slice(0, dup)]), folder / "runs.parquet")
    if plans:
        table = pa.Table.from_pylist(PLANS)
        pq.write_table(pa.concat_tables([table, table.slice(0, dup)]), folder / "plans.parquet")
    return folder


class _Page(HTMLParser):
    """Images by figure id, each table's rows (text and data-value of each cell), text."""

    def __init__(self) -> None:
        super().__init__()
        self.figure = ""
        self.images: dict[str, dict[str, str | None]] = {}
        self.table = ""
        self.tables: dict[str, list[list[tuple[str, str | None]]]] = {}
        self.cell: tuple[str, str | None] | None = None
        self.text: list[str] = []
        self.sources: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        for key in ("src", "href"):
            if a.get(key):
                self.sources.append(str(a[key]))
        if tag == "figure":
            self.figure = a.get("id") or ""
        elif tag == "img":
            self.images[self.figure] = a
        elif tag == "table":
            self.table = a.get("id") or ""
            self.tables[self.table] = []
        elif tag == "tr":
            self.tables[self.table].append([])
        elif tag == "td":
            self.cell = ("", a.get("data-value"))

    def handle_endtag(self, tag: str) -> None:
        if tag == "td" and self.cell is not None:
            self.tables[self.table][-1].append(self.cell)
            self.cell = None

    def handle_data(self, data: str) -> None:
        self.text.append(data)
        if self.cell is not None:
            self.cell = (self.cell[0] + data, self.cell[1])


def _parse(page: Path) -> _Page:
    parser = _Page()
    parser.feed(page.read_text(encoding="utf-8"))
    parser.close()
    return parser


def _png(img: dict[str, str | None]) -> bytes:
    src = img.get("src") or ""
    assert src.startswith("data:image/png;base64,")
    data = base64.b64decode(src.split(",", 1)[1], validate=True)
    assert data.startswith(b"\x89PNG\r\n\x1a\n") and len(data) > 5000
    return data


def _expected(uavs: int, objective: str) -> dict[str, Any]:
    """A cell's numbers computed independently of floe (numpy, a t table)."""
    runs = [r for r in RUNS if r["uavs"] == uavs and r["objective"] == objective]
    x = np.array([r["mean_uncertainty"] for r in runs])
    assert len(x) == SEEDS
    half = T_975_DF5 * x.std(ddof=1) / math.sqrt(len(x))
    verdicts = [r["bounded_trend"] for r in runs if r["bounded_trend"] is not None]
    ids = {r["run_id"] for r in runs}
    solve = [p["solve_time_s"] for p in PLANS if p["run_id"] in ids]
    return {
        "runs": len(runs),
        "mean": x.mean(),
        "ci": (x.mean() - half, x.mean() + half),
        "bounded": (sum(verdicts), len(verdicts)),
        "solve_plans": float(np.median(solve)),
        "solve_runs": float(np.median([r["solve_time_median_s"] for r in runs])),
    }


def _check_wilson(k: int, n: int, low: float, high: float) -> None:
    """Wilson's bounds are the p0 where |k/n - p0| = z sqrt(p0 (1 - p0) / n)."""
    z = Z_975
    for p0 in (low, high):
        if 0.0 < p0 < 1.0:
            assert (k / n - p0) ** 2 == pytest.approx(z * z * p0 * (1 - p0) / n, rel=1e-9)
    assert low <= k / n <= high


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = _write(tmp_path_factory.mktemp("campaign") / "out")
    when = dt.datetime(2026, 11, 25, 12, 0, tzinfo=dt.UTC)
    page = write_campaign_report(folder, written_at=when)
    assert page == folder / "report.html"
    return page


def test_every_figure_is_inline_and_nothing_is_fetched(report: Path) -> None:
    page = _parse(report)
    assert set(page.images) == {"fig-fleet", "fig-series", "fig-solve", "fig-mu"}
    for img in page.images.values():
        _png(img)
    assert all(s.startswith("data:image/png;base64,") for s in page.sources)
    # the PNGs beside the page are the embedded ones
    for name in ("fleet", "series", "solve", "mu"):
        on_disk = (report.parent / f"report-{name}.png").read_bytes()
        assert on_disk == _png(page.images[f"fig-{name}"])
    text = " ".join(page.text)
    for words in ("synthetic", "fleet.speed_m_s", "0.1.0", "2026-11-25 12:00:00", "0 to 5"):
        assert words in text
    # mu / (F1/F2): the 48 latency plans (f2 = 0, mu = 0) are left out and said so
    assert "48 plan(s) left out" in text


def test_table_numbers_are_the_cells_mean_ci_bounded_rate_and_median(report: Path) -> None:
    rows = _parse(report).tables["cells"]
    cells = {(int(r[0][0]), r[1][0]): r for r in rows if r}
    assert list(cells) == [(u, o) for u in UAVS for o in OBJECTIVES]  # the grid's order
    for (uavs, objective), row in cells.items():
        want = _expected(uavs, objective)
        values = [v for _, v in row[2:]]
        assert int(values[0] or 0) == want["runs"]
        assert float(values[1] or "nan") == pytest.approx(want["mean"], rel=1e-12)
        low, high = (float(v) for v in (values[2] or "").split(","))
        assert (low, high) == pytest.approx(want["ci"], rel=1e-9)
        k, n = (int(v) for v in (values[4] or "").split(","))
        assert (k, n) == want["bounded"] and n == SEEDS - 1  # seed 0 has no verdict
        _check_wilson(k, n, *(float(v) for v in (values[5] or "").split(",")))
        assert float(values[6] or "nan") == pytest.approx(want["solve_plans"], rel=1e-12)
        assert row[3][0] == f"{want['mean']:,.0f}"


def test_trend_table_and_first_test_count_the_runs_under_each_bound(report: Path) -> None:
    page = _parse(report)
    trend_rows = [r for r in page.tables["trend"] if r]
    cell_rows = [r for r in page.tables["cells"] if r]
    assert len(trend_rows) == len(cell_rows) == len(UAVS) * len(OBJECTIVES)
    for row, cell_row in zip(trend_rows, cell_rows, strict=True):
        uavs, objective = int(row[0][0]), row[1][0]
        runs = [r for r in RUNS if r["uavs"] == uavs and r["objective"] == objective]
        trends = [r["trend"] for r in runs if r["trend"] is not None]
        assert float(row[2][1] or "nan") == pytest.approx(float(np.median(trends)), rel=1e-12)
        assert [c[0] for c in row[3:]] == [
            f"{sum(t <= b for t in trends)}/{len(trends)}" for b in (0.25, 0.4, 0.5, 0.6)
        ]
        first = sum(r["bounded"] for r in runs)
        assert cell_row[-3] == (f"{first}/{len(runs)}", f"{first},{len(runs)}")


def test_paired_table_compares_each_seed_with_the_papers_objective(report: Path) -> None:
    rows = [r for r in _parse(report).tables["paired"] if r]
    assert [(int(r[0][0]), r[1][0]) for r in rows] == [(u, "latency") for u in UAVS]
    for row in rows:
        uavs = int(row[0][0])
        by_seed = {
            (r["objective"], r["seed"]): r["mean_uncertainty"] for r in RUNS if r["uavs"] == uavs
        }
        diffs = np.array(
            [100 * (by_seed["latency", s] / by_seed["sequence", s] - 1) for s in range(SEEDS)]
        )
        half = T_975_DF5 * diffs.std(ddof=1) / math.sqrt(SEEDS)
        mean, low, high = (float(v) for v in (row[3][1] or "").split(","))
        assert (mean, low, high) == pytest.approx(
            (diffs.mean(), diffs.mean() - half, diffs.mean() + half), rel=1e-9, abs=1e-6
        )
        wins = sum(by_seed["latency", s] < by_seed["sequence", s] for s in range(SEEDS))
        assert row[4][1] == f"{wins},{SEEDS - wins}" and int(row[2][0]) == SEEDS


def test_dataset_folder_with_duplicate_runs_gives_the_same_cells(tmp_path: Path) -> None:
    grid = ["scenario", "uavs", "objective", "tau", "seed"]  # as in CAMPAIGN_YAML
    plain = summarise_cells(pa.Table.from_pylist(RUNS), pa.Table.from_pylist(PLANS), grid)
    folder = _write(tmp_path / "ds", dataset=True, dup=5)
    data = load_campaign(folder)
    assert (data.duplicate_runs, data.duplicate_plans) == (5, 5)
    assert data.runs.num_rows == len(RUNS)
    assert summarise_cells(data.runs, data.plans, data.grid_keys) == plain
    # summarise_cells drops duplicate run_ids itself (the engine passes raw tables)
    raw = pq.read_table(folder / "runs.parquet")
    assert raw.num_rows == len(RUNS) + 5
    assert summarise_cells(raw, data.plans, grid) == plain
    assert [s.values for s in plain] == [
        {"scenario": "paper-boat", "uavs": u, "objective": o, "tau": 0.5}
        for u in UAVS
        for o in sorted(OBJECTIVES)
    ]
    # without the campaign file's keys: the known keys and every dotted column
    assert list(summarise_cells(raw)[0].values) == [*grid[:4], "fleet.speed_m_s"]


def test_series_band_is_the_mean_and_t_interval_over_seeds_at_each_second() -> None:
    runs = pa.Table.from_pylist(RUNS)
    cells = group_cells(runs, ["uavs", "objective", "seed"])
    bands = series_bands(runs, cells)
    assert bands is not None and bands.step_s == 1
    assert bands.t_s.tolist() == list(range(DURATION_S + 1))
    for c, values in enumerate(cells.values):
        series = np.array(
            [
                r["series_mean_sigma"]
                for r in RUNS
                if r["uavs"] == values["uavs"] and r["objective"] == values["objective"]
            ]
        )
        mean = series.mean(axis=0)
        half = T_975_DF5 * series.std(axis=0, ddof=1) / math.sqrt(SEEDS)
        assert bands.count[c].tolist() == [SEEDS] * (DURATION_S + 1)
        np.testing.assert_allclose(bands.mean[c], mean, rtol=1e-12)
        np.testing.assert_allclose(bands.low[c], mean - half, rtol=1e-9, atol=1e-6)
        np.testing.assert_allclose(bands.high[c], mean + half, rtol=1e-9, atol=1e-6)


def test_a_campaign_without_plans_uses_the_runs_solve_times(tmp_path: Path) -> None:
    folder = _write(tmp_path / "noplans", plans=False)
    page_path = write_campaign_report(folder, tmp_path / "elsewhere" / "page.html")
    page = _parse(page_path)
    assert set(page.images) == {"fig-fleet", "fig-series", "fig-solve"}
    assert (tmp_path / "elsewhere" / "page-solve.png").exists()
    assert not (folder / "report.html").exists()
    text = " ".join(page.text)
    assert "not shown: this campaign kept no plans" in text
    for row in (r for r in page.tables["cells"] if r):
        want = _expected(int(row[0][0]), row[1][0])
        assert float(row[8][1] or "nan") == pytest.approx(want["solve_runs"], rel=1e-12)


def test_missing_empty_or_corrupt_folder_is_a_one_line_floe_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def message(folder: Path) -> str:
        with pytest.raises(CampaignReportError) as info:
            write_campaign_report(folder)
        assert isinstance(info.value, FloeError)
        text = str(info.value)
        assert "\n" not in text and str(folder) in text
        return text

    assert "does not exist" in message(tmp_path / "nowhere")
    (tmp_path / "empty").mkdir()
    assert "no runs.parquet" in message(tmp_path / "empty")
    (tmp_path / "empty" / "runs.parquet").mkdir()  # a dataset folder with no part yet
    assert "no run in it" in message(tmp_path / "empty")
    bad = _write(tmp_path / "bad", plans=False)
    (bad / "runs.parquet").write_bytes(b"PAR1 this is not parquet")
    assert "cannot read" in message(bad)
    shutil.rmtree(bad)
    bad.mkdir()
    pq.write_table(pa.table({"run_id": ["a"], "uavs": [1]}), bad / "runs.parquet")
    assert "no column mean_uncertainty" in message(bad)
    # the command: one line on stderr, exit status 2
    assert campaign_report_command([str(tmp_path / "empty"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("gcs campaign report: error: ")


def test_without_campaign_yaml_the_grid_keys_come_from_the_parquet_metadata(
    tmp_path: Path,
) -> None:
    folder = _write(tmp_path / "meta", plans=False)
    (folder / "campaign.yaml").unlink()
    runs = pq.read_table(folder / "runs.parquet")
    keys = b'["scenario", "uavs", "objective", "seed"]'  # as gcs campaign records them
    pq.write_table(runs.replace_schema_metadata({b"floe.grid_keys": keys}), folder / "runs.parquet")
    data = load_campaign(folder)
    assert data.grid_keys == ["scenario", "uavs", "objective", "seed"]
    assert data.name == "synthetic"  # the campaign column
    assert any("no campaign.yaml" in w for w in data.warnings)
    assert data.grid["objective"] == ["latency", "sequence"]


def test_a_list_valued_override_is_a_grid_key() -> None:
    rows = [
        {
            "run_id": f"r{k}",
            "seed": k % 2,
            "targets.random.vx_m_s": [0, 0] if k < 2 else [-3, 3],
            "mean_uncertainty": float(k),
        }
        for k in range(4)
    ]
    cells = summarise_cells(pa.Table.from_pylist(rows))
    assert [c.values for c in cells] == [
        {"targets.random.vx_m_s": [-3, 3]},
        {"targets.random.vx_m_s": [0, 0]},
    ]
    assert [c.mean_uncertainty_m2 for c in cells] == [2.5, 0.5]
    assert [c.runs for c in cells] == [2, 2]


def test_table_gives_each_cells_growth_over_the_second_half_with_a_bootstrap_interval(
    report: Path,
) -> None:
    """Issue 31: the Figure 4 verdict is the ensemble's growth (mean curve, last third over
    middle third) with an interval over the seeds, not a count of runs called bounded."""
    page = _parse(report)
    text = " ".join(page.text)
    assert "growth 2nd half (last/middle third) [95 % CI]" in text
    assert "bounded (" not in text  # no column calls the trend threshold bounded
    for row in (r for r in page.tables["cells"] if r):
        uavs, objective = int(row[0][0]), row[1][0]
        runs = [r for r in RUNS if r["uavs"] == uavs and r["objective"] == objective]
        t = np.asarray(runs[0]["series_t_s"])
        middle = (t > DURATION_S / 3) & (t <= 2 * DURATION_S / 3)
        last = t > 2 * DURATION_S / 3
        curves = np.array([r["series_mean_sigma"] for r in runs])
        want = curves.mean(axis=0)[last].mean() / curves.mean(axis=0)[middle].mean()
        value, low, high = (float(v) for v in (row[5][1] or "").split(","))
        assert value == pytest.approx(want, rel=1e-12)
        assert low < value < high
        assert row[5][0] == f"{value:.2f} [{low:.2f}, {high:.2f}]"


def test_table_gives_mu_over_the_realised_f1_f2_per_cell(report: Path) -> None:
    """Issue 31: eq. 18's mu against the realised F1/F2 of the plans (f2 / f1, floe's f2
    holding mu), mean and sd over the plans; latency plans (mu 0) have none."""
    for row in (r for r in _parse(report).tables["cells"] if r):
        uavs, objective = int(row[0][0]), row[1][0]
        ids = {r["run_id"] for r in RUNS if r["uavs"] == uavs and r["objective"] == objective}
        ratios = [p["f2"] / p["f1"] for p in PLANS if p["run_id"] in ids and p["mu"] != 0]
        if objective == "latency":
            assert not ratios and row[-2][0] == "-"
            continue
        mean, sd, n = (float(v) for v in (row[-2][1] or "").split(","))
        assert (mean, sd, n) == pytest.approx(
            (np.mean(ratios), np.std(ratios, ddof=1), len(ratios)), rel=1e-9
        )
        per_run = [
            np.mean([p["f2"] / p["f1"] for p in PLANS if p["run_id"] == i]) for i in sorted(ids)
        ]
        half = T_975_DF5 * np.std(per_run, ddof=1) / math.sqrt(len(per_run))
        low, high = (float(v) for v in (row[-1][1] or "").split(","))
        assert (low, high) == pytest.approx(
            (np.mean(per_run) - half, np.mean(per_run) + half), rel=1e-9
        )
