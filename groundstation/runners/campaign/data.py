"""Reading a campaign folder (what ``gcs campaign CAMPAIGN.yaml --out DIR`` wrote) for its
report.

``DIR/runs.parquet`` (a file, or a dataset folder of part files: whatever
``pyarrow.parquet.read_table`` reads) holds one row per run: ``run_id``, one column per
grid key named as in the campaign file (``scenario``, ``uavs``, ``objective``, ``tau``,
``seed``, dotted scenario overrides verbatim such as ``fleet.speed_m_s``), the metrics
scalars (``mean_uncertainty``, ``bounded_trend``, ``solve_time_median_s``...) and the
mean-uncertainty series (``series_t_s``, ``series_mean_sigma``, one point per mission
second). ``DIR/plans.parquet`` (optional) holds one row per adopted plan (``run_id``,
``plan_index``, ``mu``, ``f1``, ``f2``, ``solve_time_s``...). ``DIR/campaign.yaml``
(optional) is the campaign file: its ``name``, ``grid`` and ``set`` head the report.

A run that was written twice (a worker retried after it had already written) appears twice
with one ``run_id``: :func:`dedupe` keeps the first row of each ``run_id`` (and of each
``(run_id, plan_index)`` in the plans). Every problem is a :class:`CampaignReportError`
with a one-line message naming the file.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from domain.errors import ConfigError, DataError
from domain.yaml_fields import load_yaml_file

__all__ = [
    "KNOWN_GRID_KEYS",
    "SEED_KEY",
    "CampaignData",
    "CampaignReportError",
    "column_codes",
    "dedupe",
    "float_column",
    "grid_keys_of",
    "load_campaign",
    "read_parquet",
    "recorded_grid_keys",
]

SEED_KEY = "seed"
"""The grid key whose values are repetitions (seeds), not conditions."""

KNOWN_GRID_KEYS = ("scenario", "uavs", "objective", "tau", SEED_KEY)
"""Grid keys of a campaign file besides dotted scenario overrides, in their usual order."""

_REQUIRED_RUN_COLUMNS = ("run_id", "mean_uncertainty")


class CampaignReportError(DataError):
    """A campaign folder that cannot be reported on; the message is one line."""


@dataclass
class CampaignData:
    """A campaign folder, read: runs and plans with duplicates dropped."""

    folder: Path
    name: str
    runs: pa.Table
    """One row per ``run_id`` (the first written)."""
    plans: pa.Table | None
    """One row per ``(run_id, plan_index)`` of a run in ``runs``; None without the file."""
    grid_keys: list[str]
    """The grid's keys that are columns of ``runs``, in the campaign file's order."""
    grid: dict[str, Any]
    """The campaign file's ``grid`` as written (or, without the file, each key's values)."""
    fixed: dict[str, Any]
    """The campaign file's ``set`` (fixed scenario overrides)."""
    duplicate_runs: int = 0
    duplicate_plans: int = 0
    warnings: list[str] = field(default_factory=list)


def read_parquet(path: Path, what: str) -> pa.Table:
    """``pyarrow.parquet.read_table(path)`` with every failure as one line."""
    try:
        return pq.read_table(path)
    except (OSError, pa.ArrowException) as exc:
        text = " ".join(str(exc).split()) or type(exc).__name__
        raise CampaignReportError(f"{what}: cannot read {path}: {text}") from None


def column_codes(column: pa.ChunkedArray | pa.Array) -> tuple[np.ndarray, list[Any]]:
    """Each row's index into the column's distinct values, and those values sorted
    (nulls last). Vectorised (``pyarrow.compute``), so a 10 000-row column takes
    milliseconds; a nested column (a list value such as ``[0, 0]``) is compared by its
    JSON text, in Python."""
    if pa.types.is_dictionary(column.type):
        column = column.cast(column.type.value_type)
    if pa.types.is_nested(column.type):
        values = column.to_pylist()
        texts = [json.dumps(v, sort_keys=True) for v in values]
        first = {t: v for t, v in reversed(list(zip(texts, values, strict=True)))}
        codes, distinct_texts = column_codes(pa.array(texts, pa.string()))
        return codes, [first[t] for t in distinct_texts]
    distinct = pc.unique(column)
    distinct = distinct.take(pc.array_sort_indices(distinct, null_placement="at_end"))
    codes = pc.index_in(column, value_set=distinct, skip_nulls=False)
    out = np.asarray(codes.to_numpy(zero_copy_only=False), dtype=np.int64)
    return out, distinct.to_pylist()


def dedupe(table: pa.Table, keys: Sequence[str]) -> tuple[pa.Table, int]:
    """``table`` with only the first row of each combination of ``keys``, in the original
    order, and how many rows were dropped."""
    if table.num_rows == 0:
        return table, 0
    combined = np.zeros(table.num_rows, dtype=np.int64)
    for key in keys:
        codes, distinct = column_codes(table.column(key))
        combined = combined * (len(distinct) + 1) + codes
    _, first = np.unique(combined, return_index=True)
    if len(first) == table.num_rows:
        return table, 0
    return table.take(np.sort(first)), table.num_rows - len(first)


def grid_keys_of(columns: Sequence[str], declared: Sequence[str] | None = None) -> list[str]:
    """The grid keys of a runs table: the campaign file's (``declared``) that are columns,
    else every known key (``scenario``, ``uavs``, ``objective``, ``tau``, ``seed``) and
    every dotted column (a scenario override), in that order."""
    present = set(columns)
    if declared:
        return [k for k in declared if k in present]
    known = [k for k in KNOWN_GRID_KEYS if k in present]
    return known + [c for c in columns if "." in c and c not in known]


def _campaign_file(folder: Path, warnings: list[str]) -> dict[str, Any]:
    path = folder / "campaign.yaml"
    if not path.exists():
        warnings.append("no campaign.yaml: the grid is read from runs.parquet")
        return {}
    try:
        data = load_yaml_file(path, str(path))
    except ConfigError as exc:
        warnings.append(f"campaign.yaml ignored: {exc}")
        return {}
    if not isinstance(data, Mapping):
        warnings.append("campaign.yaml ignored: not a mapping")
        return {}
    return dict(data)


def _values_of(table: pa.Table, key: str) -> list[Any]:
    return [v for v in column_codes(table.column(key))[1] if v is not None]


def recorded_grid_keys(runs: pa.Table) -> list[str] | None:
    """The grid keys ``gcs campaign`` records in the Parquet schema (``floe.grid_keys``,
    a JSON list), if any."""
    raw = (runs.schema.metadata or {}).get(b"floe.grid_keys")
    try:
        keys = json.loads(raw) if raw else None
    except ValueError:
        return None
    if isinstance(keys, list) and all(isinstance(k, str) for k in keys):
        return keys
    return None


def load_campaign(folder: Path) -> CampaignData:
    """Read ``folder`` (see the module docstring). Raises :class:`CampaignReportError`
    when it is not a folder, has no readable ``runs.parquet``, the runs have no row or
    lack ``run_id`` / ``mean_uncertainty``, or ``plans.parquet`` exists but cannot be
    read."""
    folder = Path(folder)
    if not folder.is_dir():
        what = "does not exist" if not folder.exists() else "is not a folder"
        raise CampaignReportError(f"{folder} {what} (expected a gcs campaign --out folder)")
    runs_path = folder / "runs.parquet"
    if not runs_path.exists():
        raise CampaignReportError(
            f"{folder}: no runs.parquet (not a gcs campaign folder, or no run finished yet)"
        )
    runs = read_parquet(runs_path, "runs")
    missing = [c for c in _REQUIRED_RUN_COLUMNS if c not in runs.column_names]
    if runs.num_rows and missing:
        raise CampaignReportError(f"{runs_path}: no column {', '.join(missing)}")
    if runs.num_rows == 0:
        raise CampaignReportError(f"{runs_path}: no run in it (the campaign wrote nothing yet)")
    warnings: list[str] = []
    spec = _campaign_file(folder, warnings)
    recorded = recorded_grid_keys(runs)
    runs, duplicate_runs = dedupe(runs, ["run_id"])
    grid_spec = spec.get("grid") if isinstance(spec.get("grid"), Mapping) else None
    declared = [str(k) for k in grid_spec] if grid_spec else recorded
    keys = grid_keys_of(runs.column_names, declared)
    if declared:
        absent = [k for k in declared if k not in keys]
        if absent:
            warnings.append(f"grid key(s) {', '.join(absent)} are not columns of runs.parquet")
    grid = dict(grid_spec) if grid_spec else {k: _values_of(runs, k) for k in keys}
    fixed = spec.get("set") if isinstance(spec.get("set"), Mapping) else {}
    name = str(spec.get("name") or "")
    if not name and "campaign" in runs.column_names:
        name = ", ".join(str(v) for v in _values_of(runs, "campaign"))
    plans: pa.Table | None = None
    duplicate_plans = 0
    plans_path = folder / "plans.parquet"
    if plans_path.exists():
        plans = read_parquet(plans_path, "plans")
        if plans.num_rows and "run_id" not in plans.column_names:
            raise CampaignReportError(f"{plans_path}: no column run_id")
        if plans.num_rows:
            plans, duplicate_plans = dedupe(
                plans, ["run_id", "plan_index"] if "plan_index" in plans.column_names else []
            )
            known = pc.is_in(
                plans.column("run_id"), value_set=runs.column("run_id").combine_chunks()
            )
            orphans = plans.num_rows - int(pc.sum(known).as_py() or 0)
            if orphans:
                warnings.append(f"{orphans} plan row(s) of runs not in runs.parquet ignored")
                plans = plans.filter(known)
    return CampaignData(
        folder=folder,
        name=name or folder.name,
        runs=runs,
        plans=plans,
        grid_keys=keys,
        grid=grid,
        fixed=dict(fixed or {}),
        duplicate_runs=duplicate_runs,
        duplicate_plans=duplicate_plans,
        warnings=warnings,
    )


def float_column(table: pa.Table, name: str) -> np.ndarray:
    """Column ``name`` as float64 with NaN for nulls (all NaN when there is no such
    column)."""
    if name not in table.column_names:
        return np.full(table.num_rows, math.nan)
    try:
        values = pc.cast(table.column(name), pa.float64())
    except pa.ArrowException:
        return np.full(table.num_rows, math.nan)
    return np.asarray(values.to_numpy(zero_copy_only=False), dtype=np.float64)
