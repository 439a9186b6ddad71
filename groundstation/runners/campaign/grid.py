"""A campaign file: the grid of runs ``gcs campaign`` computes, validated before any run.

::

    name: paper-fig4
    grid:                      # every combination is one run
      scenario: [paper-boat]   # bundled names or YAML files (relative to this file)
      uavs: [1, 3, 5]
      objective: [sequence]
      tau: [0.5]
      seed: {from: 0, to: 19}  # or a list
      observer.r_m2: [5, 10]   # any scenario field, dotted
    set: {duration_s: 300}     # fixed scenario overrides, dotted keys
    per_plan: true             # also keep one row per adopted plan

Every grid key is optional (``seed`` defaults to ``[0]``, the others to the scenario's
value). Each combination of the scenario and its dotted overrides is parsed by
:func:`world.scenario.parse_scenario` once here, so a bad override is an error naming the
field before anything runs. A run's identity (:attr:`RunTask.run_id`) is a hash of its
coordinates: the five base keys (effective values), the dotted grid keys and the ``set``
overrides, so the same coordinates give the same id on every machine.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
from collections.abc import Container, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from domain.errors import ConfigError
from domain.limits import MAX_FLEET
from domain.yaml_fields import FieldError, Fields, check_number, load_yaml_file
from planner.problem import OBJECTIVES
from world.scenario import Scenario, ScenarioError, load_scenario_data, parse_scenario

__all__ = [
    "BASE_KEYS",
    "MAX_RUNS",
    "CampaignError",
    "CampaignSpec",
    "RunTask",
    "canonical_form",
    "grid_difference",
    "load_campaign",
    "parse_campaign",
    "parse_campaign_shape",
]

BASE_KEYS = ("scenario", "uavs", "objective", "tau", "seed")
"""Grid keys that are not scenario fields; every run row has a column for each."""
MAX_RUNS = 1_000_000
"""The largest grid a campaign accepts."""
MAX_SEED = 2**31 - 1
"""CP-SAT takes a 32-bit random seed."""
RUN_ID_VERSION = "floe-campaign-run/1"
_ALIASES = {"uavs": "fleet.count", "objective": "planner.objective", "tau": "planner.tau"}


class CampaignError(ConfigError):
    """A campaign file or folder cannot be used; the message names the file and field."""


@dataclass(frozen=True)
class RunTask:
    """Everything a worker needs for one run (picklable, no file access: a remote Dask
    worker gets the scenario's mapping, overrides applied, not its path)."""

    run_id: str
    campaign: str
    coords: dict[str, Any]
    scenario_data: Mapping[str, Any]
    scenario_source: str
    uavs: int | None
    seed: int
    per_plan: bool


@dataclass(frozen=True)
class CampaignSpec:
    """A validated campaign file. ``grid`` keeps the file's key order; ``seed`` is always
    there (``[0]`` by default)."""

    name: str
    grid: dict[str, tuple[Any, ...]]
    overrides: dict[str, Any]
    per_plan: bool
    scenario_data: dict[str, tuple[Any, str]]
    base_scenarios: dict[str, Scenario]

    @property
    def grid_keys(self) -> tuple[str, ...]:
        return tuple(self.grid)

    @property
    def dotted_keys(self) -> tuple[str, ...]:
        """Scenario-field columns: dotted grid keys, then ``set`` keys not in the grid."""
        return tuple(k for k in self.grid if k not in BASE_KEYS) + tuple(
            k for k in self.overrides if k not in self.grid
        )

    def run_count(self) -> int:
        return math.prod(len(values) for values in self.grid.values())

    def canonical(self) -> dict[str, Any]:
        """What decides the runs and rows (compared against a folder's copy)."""
        return canonical_form(self.name, self.grid, self.overrides, self.per_plan)

    def _points(self) -> Iterator[dict[str, Any]]:
        keys = self.grid_keys
        for combo in itertools.product(*(self.grid[k] for k in keys)):
            yield dict(zip(keys, combo, strict=True))

    def run_ids(self) -> Iterator[str]:
        """Every run's id, in grid order (cheap: no scenario copies)."""
        for point in self._points():
            yield run_id(self._coords(point))

    def tasks(self, skip: Container[str] = ()) -> Iterator[RunTask]:
        """Every run whose id is not in ``skip``, in grid order (the file's key order,
        last key fastest)."""
        for point in self._points():
            coords = self._coords(point)
            identity = run_id(coords)
            if identity not in skip:
                yield self._task(point, coords, identity)

    def _coords(self, point: Mapping[str, Any]) -> dict[str, Any]:
        dotted = [point[k] for k in self.grid if k not in BASE_KEYS]
        scenario = self.base_scenarios[_combo_key(point["scenario"], dotted)]
        uavs, objective, tau = point.get("uavs"), point.get("objective"), point.get("tau")
        coords: dict[str, Any] = {
            "scenario": point["scenario"],
            "uavs": scenario.fleet.count if uavs is None else uavs,
            "objective": scenario.planner.objective if objective is None else objective,
            "tau": scenario.planner.tau if tau is None else tau,
            "seed": point["seed"],
        }
        for key in self.dotted_keys:
            coords[key] = point[key] if key in point else self.overrides[key]
        return coords

    def _task(self, point: Mapping[str, Any], coords: dict[str, Any], identity: str) -> RunTask:
        raw, source = self.scenario_data[point["scenario"]]
        changes = {k: coords[k] for k in self.dotted_keys}
        if point.get("objective") is not None:
            changes["planner.objective"] = point["objective"]
        if point.get("tau") is not None:
            changes["planner.tau"] = point["tau"]
        return RunTask(
            run_id=identity, campaign=self.name, coords=coords,
            scenario_data=_with_overrides(raw, changes), scenario_source=source,
            uavs=point.get("uavs"), seed=point["seed"], per_plan=self.per_plan,
        )


def run_id(coords: Mapping[str, Any]) -> str:
    """A stable id of a run's coordinates: 16 hex digits of a SHA-256 over canonical JSON
    (sorted keys; every number but ``uavs`` and ``seed`` as a float, so 5 and 5.0 agree)."""
    canonical = {k: (v if k in ("uavs", "seed") else _hashable(v)) for k, v in coords.items()}
    text = json.dumps([RUN_ID_VERSION, canonical], sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def _hashable(value: Any) -> Any:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return value
    return float(value)


def load_campaign(path: Path) -> CampaignSpec:
    """Read and validate a campaign file; raises :class:`CampaignError` naming the field."""
    try:
        data = load_yaml_file(path, str(path))
    except ConfigError as exc:
        raise CampaignError(str(exc)) from None
    try:
        return parse_campaign(data, base_dir=path.parent, default_name=path.stem)
    except FieldError as exc:
        raise CampaignError(f"{path}: {exc}") from None


def parse_campaign(data: Any, *, base_dir: Path, default_name: str = "campaign") -> CampaignSpec:
    """Validate a campaign mapping (module docstring); raises FieldError naming the field.
    Scenario names are bundled names or files, relative to ``base_dir`` first."""
    name, grid, overrides, per_plan = parse_campaign_shape(data, default_name=default_name)
    scenario_data = {
        name_: _load_scenario(name_, base_dir, i) for i, name_ in enumerate(grid["scenario"])
    }
    base_scenarios = _check_scenarios(grid, overrides, scenario_data)
    return CampaignSpec(name, grid, overrides, per_plan, scenario_data, base_scenarios)


def parse_campaign_shape(
    data: Any, *, default_name: str = "campaign"
) -> tuple[str, dict[str, tuple[Any, ...]], dict[str, Any], bool]:
    """The checks that need no scenario: (name, grid, set, per_plan). Comparing a folder's
    copy of a campaign file with a new one needs only this."""
    top = Fields(data)
    name = top.string("name", default_name)
    if not name.strip():
        raise FieldError("name", "must not be empty")
    top.string("description", "")
    per_plan = top.boolean("per_plan", False)
    overrides = _parse_set(top.raw("set"))
    grid_raw = top.raw("grid")
    if not isinstance(grid_raw, Mapping) or not grid_raw:
        raise FieldError("grid", f"must be a mapping of keys to lists of values, got {grid_raw!r}")
    grid = _parse_grid(grid_raw)
    top.done()
    if "scenario" not in grid:
        raise FieldError("grid.scenario", "is required (a list of scenario names or files)")
    for key in overrides:
        if key in grid:
            raise FieldError(f"set.{key}", "is also a grid key")
    for short, dotted in _ALIASES.items():
        for where, keys in (("grid", grid), ("set", overrides)):
            if dotted in keys and short in grid:
                raise FieldError(f"{where}.{dotted}", f"conflicts with grid key {short!r}")
    if "seed" not in grid:
        grid["seed"] = (0,)
    count = math.prod(len(values) for values in grid.values())
    if count > MAX_RUNS:
        raise FieldError("grid", f"{count:,} runs; a campaign takes at most {MAX_RUNS:,}")
    return name, grid, overrides, per_plan


def canonical_form(
    name: str, grid: Mapping[str, Sequence[Any]], overrides: Mapping[str, Any], per_plan: bool
) -> dict[str, Any]:
    """What decides a campaign's runs and rows, for comparing two campaign files."""
    return {"name": name, "grid": {k: list(v) for k, v in grid.items()},
            "set": dict(overrides), "per_plan": per_plan}


def _parse_set(value: Any) -> dict[str, Any]:
    fields = Fields(value, "set")
    out: dict[str, Any] = {}
    for key in list(value or {}):
        if key in BASE_KEYS:
            raise FieldError(f"set.{key}", "is a grid key; put it in grid with one value")
        _check_dotted_key(f"set.{key}", key)
        out[key] = check_plain(f"set.{key}", fields.raw(key))
    fields.done()
    return out


def _parse_grid(raw: Mapping[str, Any]) -> dict[str, tuple[Any, ...]]:
    fields = Fields(raw, "grid")
    grid: dict[str, tuple[Any, ...]] = {}
    for key in list(raw):  # the file's key order is the grid's order
        path = fields.path_of(key)
        value = fields.raw(key)
        if key not in BASE_KEYS:
            _check_dotted_key(path, key)
        if key == "seed" and isinstance(value, Mapping):  # checked by construction
            grid[key] = tuple(_seed_range(Fields(value, path)))
            continue
        if not isinstance(value, list):
            raise FieldError(path, f"must be a list of values (one run each), got {value!r}")
        values: list[Any] = value
        if not values:
            raise FieldError(path, "must not be empty")
        checked = [_check_value(key, f"{path}[{i}]", v) for i, v in enumerate(values)]
        seen: set[str] = set()
        for i, v in enumerate(checked):
            marker = json.dumps(_hashable(v), sort_keys=True)
            if marker in seen:
                raise FieldError(f"{path}[{i}]", f"repeats the value {v!r}")
            seen.add(marker)
        grid[key] = tuple(checked)
    fields.done()
    return grid


def _seed_range(fields: Fields) -> list[int]:
    low = fields.integer("from", minimum=0, maximum=MAX_SEED)
    high = fields.integer("to", minimum=0, maximum=MAX_SEED)
    fields.done()
    if high < low:
        raise FieldError(fields.path_of("to"), f"must be >= from ({low}), got {high}")
    if high - low + 1 > MAX_RUNS:
        raise FieldError(fields.path_of("to"), f"more than {MAX_RUNS:,} seeds")
    return list(range(low, high + 1))


def _check_value(key: str, path: str, value: Any) -> Any:
    if key in ("uavs", "seed"):
        limit = MAX_FLEET if key == "uavs" else MAX_SEED
        low = 1 if key == "uavs" else 0
        if isinstance(value, bool) or not isinstance(value, int):
            raise FieldError(path, f"must be an integer, got {value!r}")
        if not low <= value <= limit:
            raise FieldError(path, f"must be an integer in [{low}, {limit}], got {value}")
        return value
    if key == "tau":
        return check_number(path, value, minimum=0.0, maximum=1.0)
    if key == "objective":
        if value not in OBJECTIVES:
            raise FieldError(path, f"must be one of {', '.join(OBJECTIVES)}, got {value!r}")
        return value
    if key == "scenario":
        if not isinstance(value, str) or not value:
            raise FieldError(path, f"must be a scenario name or file, got {value!r}")
        return value
    return check_plain(path, value)


def check_plain(path: str, value: Any) -> Any:
    """A scenario override's value: what JSON can hold (no dates, no NaN)."""
    try:
        json.dumps(value, allow_nan=False)
    except (TypeError, ValueError):
        raise FieldError(path, "must be a finite number, a string, true/false, or a list or "
                         f"mapping of those, got {value!r}") from None
    return value


def _check_dotted_key(path: str, key: str) -> None:
    parts = key.split(".")
    if not all(part and part.replace("_", "").isalnum() for part in parts):
        raise FieldError(path, "must be a scenario field, dotted (e.g. fleet.speed_m_s)")
    if parts[0] in ("name", "description", "events", "faults"):
        raise FieldError(path, f"scenario field {parts[0]!r} cannot be varied by a campaign")
    if len(parts) == 1 and key != "duration_s":
        raise FieldError(path, f"unknown key: use {', '.join(BASE_KEYS)} or a dotted scenario "
                         "field (e.g. fleet.speed_m_s)")


def _load_scenario(name: str, base_dir: Path, index: int) -> tuple[Any, str]:
    candidate = base_dir / name
    target = str(candidate) if ("/" in name or name.endswith(".yaml")) and (
        candidate.is_file()) else name
    try:
        data, source = load_scenario_data(target)
    except ScenarioError as exc:
        raise FieldError(f"grid.scenario[{index}]", str(exc)) from None
    if data is not None and not isinstance(data, Mapping):
        raise FieldError(f"grid.scenario[{index}]", f"scenario {source}: the file holds a "
                         f"{type(data).__name__}, not a mapping of scenario fields")
    return data, source


def _with_overrides(raw: Any, overrides: Mapping[str, Any]) -> dict[str, Any]:
    """A deep copy of a scenario mapping with dotted ``overrides`` set (missing levels are
    created; the scenario's validation then judges the result)."""
    data: dict[str, Any] = copy.deepcopy(dict(raw or {}))
    for key, value in overrides.items():
        node = data
        parts = key.split(".")
        for depth, part in enumerate(parts[:-1]):
            child = node.get(part)
            if child is None:
                child = node[part] = {}
            if not isinstance(child, dict):
                where = ".".join(parts[: depth + 1])
                raise FieldError(where, f"is {child!r} in the scenario, not a mapping")
            node = child
        node[parts[-1]] = copy.deepcopy(value)
    return data


def _check_scenarios(
    grid: Mapping[str, Sequence[Any]],
    overrides: Mapping[str, Any],
    scenario_data: Mapping[str, tuple[Any, str]],
) -> dict[str, Scenario]:
    """Parse every scenario with every combination of dotted grid values (and ``set``);
    a failure names the grid values that caused it and the scenario's own field path.
    Returns the parsed scenarios by :func:`_combo_key`."""
    dotted = [k for k in grid if k not in BASE_KEYS]
    parsed: dict[str, Scenario] = {}
    for name in grid["scenario"]:
        raw, source = scenario_data[name]
        for combo in itertools.product(*(grid[k] for k in dotted)):
            values = dict(zip(dotted, combo, strict=True))
            where = ", ".join(f"{k}={v!r}" for k, v in values.items())
            label = f"scenario {name}" + (f" with {where}" if where else "")
            try:
                data = _with_overrides(raw, {**overrides, **values})
                scenario = parse_scenario(data, source=source)
            except FieldError as exc:
                key = _blame(exc.path, dotted, overrides)
                raise FieldError(key, f"{label}: {exc}") from None
            parsed[_combo_key(name, combo)] = scenario
    return parsed


def _combo_key(scenario: str, values: Sequence[Any]) -> str:
    """A hashable key of a scenario and its dotted grid values (which may be lists)."""
    return json.dumps([scenario, *values], sort_keys=True)


def _blame(field_path: str, dotted: Sequence[str], overrides: Mapping[str, Any]) -> str:
    """The campaign key a scenario error comes from (the longest matching prefix)."""
    for key in sorted([*dotted, *overrides], key=len, reverse=True):
        if field_path == key or field_path.startswith(key + ".") or field_path.startswith(
            key + "["
        ) or key.startswith(field_path + ".") or not field_path:
            return f"grid.{key}" if key in dotted else f"set.{key}"
    return "grid.scenario"


def grid_difference(stored: Mapping[str, Any], current: Mapping[str, Any]) -> str | None:
    """The first difference between two :meth:`CampaignSpec.canonical` forms, in words,
    or None when they are equal."""
    for key in ("name", "per_plan"):
        if stored.get(key) != current.get(key):
            return f"{key}: {stored.get(key)!r} there, {current.get(key)!r} here"
    for section in ("grid", "set"):
        old, new = stored.get(section, {}), current.get(section, {})
        for key in list(dict.fromkeys([*old, *new])):
            if key not in old:
                return f"{section}.{key}: new key"
            if key not in new:
                return f"{section}.{key}: missing here"
            if old[key] != new[key]:
                return f"{section}.{key}: {_short(old[key])} there, {_short(new[key])} here"
    return None


def _short(value: Any) -> str:
    if isinstance(value, list) and len(value) > 6:
        return f"[{value[0]!r}, {value[1]!r}, ..., {value[-1]!r}] ({len(value)} values)"
    return repr(value)
