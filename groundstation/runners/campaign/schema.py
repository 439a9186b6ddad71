"""The columns of ``runs.parquet`` and ``plans.parquet`` (a contract with their readers,
``gcs campaign report`` among them; docs/campaigns.md lists them).

Every part file of a campaign is written with the same schema, built from the campaign
file alone (:func:`runs_schema`, :func:`plans_schema`): pyarrow reads a folder of parts
with the first part's schema, so a column whose type depended on a value (a metric that
is null in one run) would break the folder. The schema's metadata names the grid keys
(``floe.grid_keys``, JSON) and the campaign (``floe.campaign``).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from observer.observer import COUNTER_NAMES

if TYPE_CHECKING:
    import pyarrow as pa

    from groundstation.runners.campaign.grid import CampaignSpec

__all__ = [
    "ARRIVAL_SUMMARIES",
    "COORDINATE_METRICS",
    "WALL_CLOCK_COLUMNS",
    "metrics_columns",
    "plans_schema",
    "rows_to_table",
    "runs_schema",
]

_METRICS: dict[str, str] = {
    "mean_uncertainty": "float64",
    "max_uncertainty": "float64",
    "final_uncertainty": "float64",
    "bounded": "bool",
    "bounded_trend": "bool",
    "boundedness_ratio": "float64",
    "trend": "float64",
    "plans": "int64",
    "solve_time_median_s": "float64",
    "solve_time_max_s": "float64",
    "visits": "int64",
    "lost_targets": "int64",
    "max_estimation_error_m": "float64",
    "uploads": "int64",
    "uploads_per_hour_max": "float64",
    "duration_s": "float64",
    "realtime_factor": "float64",
    "wall_time_s": "float64",
    "mu_ratio_mean": "float64",  # metrics.json mu_ratio {mean, sd, n} (eq. 18)
    "mu_ratio_sd": "float64",
    "mu_ratio_n": "int64",
    "policy": "string",
    "arrival_error_s_median": "float64",
    "arrival_error_s_p90": "float64",
    "arrival_bias_s": "float64",
    **{f"arrival_error_{leg}_s_{inner}": kind
       for leg in ("first", "later")
       for inner, kind in (("median", "float64"), ("p90", "float64"), ("max", "float64"),
                           ("counted", "int64"))},
    "arrival_bias_first_s": "float64",
    "arrival_bias_later_s": "float64",
    "arrivals_counted": "int64",
    "arrivals_superseded": "int64",
    "arrivals_inside_at_command": "int64",
    "arrivals_unfinished": "int64",
    "wind_speed_m_s": "float64",
    "wind_from_deg": "float64",
    "wind_gust_m_s": "float64",
    **{f"observer_counters_{name}": "int64" for name in COUNTER_NAMES},
    # discovery mode's track quality (observer/track_quality.py); null in labelled runs
    "gospa_mean_m": "float64",
    "true_confirmed_fraction": "float64",
    "time_to_confirm_s_median": "float64",
    "time_to_confirm_s_max": "float64",
    "false_tracks_per_hour": "float64",
    "id_switches": "int64",
    # the ship watch (core/watch_metrics.py); null without a watch
    "vehicles_lost": "int64",
    "min_landing_battery_pct": "float64",
    "rtl_end_distance_to_ship_m_median": "float64",
    "rtl_end_distance_to_ship_m_max": "float64",
    "rtl_end_distance_to_ship_m_count": "int64",
    "on_station_shortfall_s": "float64",
    "reliefs": "int64",
    "launches": "int64",
    "first_hour_uncertainty": "float64",
    "last_hour_uncertainty": "float64",
}

ARRIVAL_SUMMARIES: dict[str, tuple[str, ...]] = {
    "arrival_error_s": ("median", "p90"),
    "arrival_error_first_s": ("median", "p90", "max", "counted"),
    "arrival_error_later_s": ("median", "p90", "max", "counted"),
}
"""metrics.json's arrival summaries (None when no arrival was counted) and their keys:
one column ``{key}_{inner}`` each, null for a None summary."""

COORDINATE_METRICS = ("scenario", "uavs", "seed", "objective", "uncertainty_series", "links")
"""metrics.json keys that are not metric columns: the grid columns hold the first four
(``scenario`` as the grid names it), ``series_t_s``/``series_mean_sigma`` the series;
``links`` is per vehicle link, and a campaign's runs (``gcs simulate``) have no link: their
uploads are the ``uploads`` and ``uploads_per_hour_max`` columns."""

WALL_CLOCK_COLUMNS = (
    "wall_s", "cpu_s", "worker", "realtime_factor", "wall_time_s", "solve_time_median_s",
    "solve_time_max_s", "solve_time_s",
)
"""Columns that measure the machine, not the run: the only ones that may differ between
two executions of the same run (plans: ``solve_time_s``)."""

_BASE_COORDINATES = {
    "scenario": "string", "uavs": "int64", "objective": "string", "tau": "float64",
    "seed": "int64",
}
_PLAN_COLUMNS = {
    "plan_index": "int64", "t_s": "float64", "mu": "float64", "f1": "float64",
    "f2": "float64", "objective_value": "float64", "objective": "string",
    "status": "string", "solver": "string", "solve_time_s": "float64", "bound": "float64",
    "gap": "float64", "targets": "int64", "uavs_planned": "int64",
}


def metrics_columns() -> dict[str, str]:
    """The metric columns of a run row and their types."""
    return dict(_METRICS)


def _type(name: str) -> pa.DataType:
    import pyarrow as pa

    types: dict[str, pa.DataType] = {
        "float64": pa.float64(), "int64": pa.int64(), "bool": pa.bool_(),
        "string": pa.string(), "list<float64>": pa.list_(pa.float64()),
    }
    return types[name]


def coordinate_types(spec: CampaignSpec) -> dict[str, str]:
    """One column per coordinate: the five base keys, then every dotted key, typed by its
    values (all integers: int64; numbers: float64; booleans: bool; otherwise string, with
    lists and mappings as JSON text)."""
    out = dict(_BASE_COORDINATES)
    for key in spec.dotted_keys:
        values = spec.grid[key] if key in spec.grid else (spec.overrides[key],)
        out[key] = _METRICS.get(key) or _value_type(values)  # duration_s is also a metric
    return out


def _value_type(values: Sequence[Any]) -> str:
    if all(isinstance(v, bool) for v in values):
        return "bool"
    if all(isinstance(v, int) and not isinstance(v, bool) for v in values):
        return "int64"
    if all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
        return "float64"
    return "string"


def _schema(columns: Mapping[str, str], spec: CampaignSpec) -> pa.Schema:
    import pyarrow as pa

    metadata = {"floe.campaign": spec.name, "floe.grid_keys": json.dumps(list(spec.grid_keys))}
    return pa.schema([pa.field(k, _type(v)) for k, v in columns.items()], metadata=metadata)


def runs_schema(spec: CampaignSpec) -> pa.Schema:
    """``runs.parquet``: run_id, coordinates, campaign, metrics, series, provenance."""
    columns = {"run_id": "string", **coordinate_types(spec), "campaign": "string",
               **_METRICS, "series_t_s": "list<float64>", "series_mean_sigma": "list<float64>",
               "floe_version": "string", "wall_s": "float64", "cpu_s": "float64",
               "worker": "string", "per_plan": "bool"}
    return _schema(columns, spec)


def plans_schema(spec: CampaignSpec) -> pa.Schema:
    """``plans.parquet``: run_id, coordinates, one row per adopted plan."""
    return _schema({"run_id": "string", **coordinate_types(spec), **_PLAN_COLUMNS}, spec)


def rows_to_table(rows: Iterable[Mapping[str, Any]], schema: pa.Schema) -> pa.Table:
    """Rows (dicts) as a table of exactly ``schema``; coordinate values that are not of
    the column's type (a list override in a string column) are stored as JSON text."""
    import pyarrow as pa

    rows = list(rows)
    arrays = []
    for field in schema:
        values = [row.get(field.name) for row in rows]
        if pa.types.is_string(field.type):
            values = [v if v is None or isinstance(v, str) else json.dumps(v) for v in values]
        elif pa.types.is_floating(field.type):
            values = [None if v is None else float(v) for v in values]
        arrays.append(pa.array(values, type=field.type))
    return pa.Table.from_arrays(arrays, schema=schema)
