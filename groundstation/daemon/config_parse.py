"""``gcs run``'s configuration from a YAML mapping and flags: one pure function.

:func:`parse_config` ``(data, flags) -> DaemonConfig``. ``data`` is the ``--config`` file's
mapping in the nested spelling (``fleet: {battery: {low_pct: 30}}``) or the flat keys of
earlier releases (:data:`ALIASES`: ``battery_low_pct: 30``), or both; ``flags`` maps a flag
as typed (``--lost-after``) to its value (:data:`FLAGS` says which field each sets).
Flags win over the file; a field given twice in the file (flat and nested) is an error.
A group key given a scalar is its main field's alias (``http: 127.0.0.1:8080`` is
``http: {bind: 127.0.0.1:8080}``).

Rules: an unknown key, a value of the wrong type, a value out of range, or an inconsistent
pair is a :class:`~domain.errors.ConfigError` whose message starts with the
key as the user spelt it (``--lost-after``, ``lost_after_s``, ``fleet.lost_after_s``,
``vehicle_settings.1.colour``). Nothing is resolved here (:func:`config.resolve` does that)
and nothing is read: the function only looks at its arguments.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Callable, Mapping
from enum import StrEnum
from typing import Any

from domain.errors import ConfigError
from domain.fault_spec import FaultError, parse_fault_spec
from domain.geodesy import GeoOrigin
from domain.radio_spec import RadioSpecError, parse_radio_spec
from groundstation.daemon.config import (
    BatteryConfig,
    DaemonConfig,
    Endpoint,
    FleetConfig,
    HttpConfig,
    LinksConfig,
    MissionConfig,
    PlannerConfig,
    RecordsConfig,
    ReplanTrigger,
    ShipConfig,
    SigningConfig,
    SimConfig,
    VehicleSettings,
    WatchSettings,
    parse_hostport,
    parse_latlon,
    parse_link_rate,
)
from groundstation.mavlink.fence_items import MIN_OPERATING_RADIUS_M
from world.wind import WindSpec, parse_wind_text

__all__ = ["ALIASES", "FLAGS", "check_config", "parse_config"]

_GROUPS: tuple[type, ...] = (
    LinksConfig, MissionConfig, FleetConfig, BatteryConfig, PlannerConfig, HttpConfig,
    RecordsConfig, SigningConfig, SimConfig, ShipConfig, WatchSettings,
)  # fmt: skip

ALIASES: dict[str, str] = {
    "vehicles": "links.vehicles",
    "out": "links.out",
    "rebind_after_s": "links.rebind_after_s",
    "gcs_system_id": "links.gcs_system_id",
    "transfer_timeout_s": "links.transfer_timeout_s",
    "transfer_retries": "links.transfer_retries",
    "link_rate": "links.link_rate",
    "scenario": "mission.scenario",
    "targets": "mission.targets",
    "duration": "mission.duration_s",
    "origin": "mission.origin",
    "seed": "mission.seed",
    "loiter_s": "mission.loiter_s",
    "loiter_radius_m": "mission.loiter_radius_m",
    "operating_radius_m": "mission.operating_radius_m",
    "operating_center": "mission.operating_center",
    "track_period_s": "mission.track_period_s",
    "launch": "fleet.launch",
    "altitude_m": "fleet.altitude_m",
    "altitude_step_m": "fleet.altitude_step_m",
    "lost_after_s": "fleet.lost_after_s",
    "lag_threshold_s": "fleet.lag_threshold_s",
    "override_grace_s": "fleet.override_grace_s",
    "progress_timeout_s": "fleet.progress_timeout_s",
    "telemetry_rate_hz": "fleet.telemetry_rate_hz",
    "battery_low_pct": "fleet.battery.low_pct",
    "battery_low_action": "fleet.battery.action",
    "vehicle_settings": "fleet.settings",
    "objective": "planner.objective",
    "solver_time_limit_s": "planner.time_limit_s",
    "num_workers": "planner.num_workers",
    "replan": "planner.replan",
    "period_s": "planner.period_s",
    "commit": "planner.commit",
    "http": "http.bind",
    "http_allow_origins": "http.allow_origins",
    "http_max_targets": "http.max_targets",
    "http_max_ws_clients": "http.max_ws_clients",
    "http_max_writes_per_s": "http.max_writes_per_s",
    "http_header_timeout_s": "http.header_timeout_s",
    "run_dir": "records.run_dir",
    "journal": "records.journal",
    "signing_key_file": "signing.key_file",
    "signing_passphrase_file": "signing.passphrase_file",
    "signing_setup": "signing.setup",
    "sim_airborne": "sim.airborne",
    "sim_fast_boot": "sim.fast_boot",
    "sim_loss": "sim.loss",
    "sim_fault": "sim.faults",
    "sim_radio": "sim.radio",
    "ship": "ship.url",
}
"""The flat keys of earlier releases (still accepted) -> the nested field they set."""

FLAGS: dict[str, str] = {
    "--vehicles": "links.vehicles",
    "--out": "links.out",
    "--rebind-after": "links.rebind_after_s",
    "--link-silent-after": "links.silent_after_s",
    "--link-rate": "links.link_rate",
    "--gcs-system-id": "links.gcs_system_id",
    "--ship-beacon": "links.ship_beacon",
    "--scenario": "mission.scenario",
    "--targets": "mission.targets",
    "--duration": "mission.duration_s",
    "--origin": "mission.origin",
    "--seed": "mission.seed",
    "--loiter": "mission.loiter_s",
    "--operating-radius": "mission.operating_radius_m",
    "--launch": "fleet.launch",
    "--altitude": "fleet.altitude_m",
    "--lost-after": "fleet.lost_after_s",
    "--lag-threshold": "fleet.lag_threshold_s",
    "--objective": "planner.objective",
    "--num-workers": "planner.num_workers",
    "--replan": "planner.replan",
    "--period": "planner.period_s",
    "--upload-min-interval": "planner.upload_min_interval_s",
    "--commit": "planner.commit",
    "--http": "http.bind",
    "--http-allow-origin": "http.allow_origins",
    "--http-max-targets": "http.max_targets",
    "--http-max-ws-clients": "http.max_ws_clients",
    "--http-max-writes-per-s": "http.max_writes_per_s",
    "--http-header-timeout": "http.header_timeout_s",
    "--map-tiles": "http.map_tiles",
    "--detections": "detections",
    "--run-dir": "records.run_dir",
    "--journal": "records.journal",
    "--signing-key": "signing.key_file",
    "--signing-passphrase-file": "signing.passphrase_file",
    "--signing-setup": "signing.setup",
    "--sim-airborne": "sim.airborne",
    "--sim-loss": "sim.loss",
    "--sim-fault": "sim.faults",
    "--sim-radio": "sim.radio",
    "--speedup": "speedup",
    "--advisory": "advisory",
    "--status": "status",
    "--on-exit": "on_exit",
    "--wind": "wind",
    "--ship": "ship.url",
    "--ship-silent-after": "ship.silent_after_s",
}
"""Each flag of ``gcs run`` -> the field it sets (``--no-launch`` is ``--launch`` false)."""

_Given = dict[str, tuple[Any, str]]  # dotted path -> (value, the name the user gave it)


def parse_config(data: Mapping[Any, Any], flags: Mapping[str, Any]) -> DaemonConfig:
    """The configuration of ``data`` (a YAML mapping) overridden by ``flags``; checked.
    Raises :class:`ConfigError` naming the key or flag."""
    given: _Given = {}
    _collect(DaemonConfig, data, "", "", given)
    for flag, value in flags.items():
        if flag not in FLAGS:
            raise ConfigError(f"{flag}: unknown flag")
        given[FLAGS[flag]] = (value, flag)
    config = _build(DaemonConfig, "", given)
    check_config(config, {path: name for path, (_, name) in given.items()})
    return config


# ------------------------------------------------------------------ collecting
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _collect(cls: type, data: Mapping[Any, Any], prefix: str, spelt: str, given: _Given) -> None:
    hints = _hints(cls)
    for key, value in data.items():
        name = f"{spelt}{key}"
        if not isinstance(key, str):
            raise ConfigError(f"{name}: unknown key (see docs/daemon.md for the keys)")
        kind = hints.get(key)
        if kind in _GROUPS and isinstance(value, Mapping):
            _collect(kind, value, f"{prefix}{key}.", f"{name}.", given)
            continue
        if not prefix and key in ALIASES:
            path = ALIASES[key]
        elif key in hints and kind not in _GROUPS:
            path = f"{prefix}{key}"
        elif kind in _GROUPS:
            raise ConfigError(f"{name}: expected a mapping of {key} settings")
        else:
            raise ConfigError(f"{name}: unknown key (see docs/daemon.md for the keys)")
        if path in given:
            raise ConfigError(f"{name}: given twice (also as {given[path][1]})")
        given[path] = (value, name)


def _build(cls: type, prefix: str, given: _Given) -> Any:
    kwargs: dict[str, Any] = {}
    for name, kind in _hints(cls).items():
        path = f"{prefix}{name}"
        if kind in _GROUPS:
            kwargs[name] = _build(kind, f"{path}.", given)
        elif path in given:
            value, spelt = given[path]
            kwargs[name] = _coerce(value, kind, spelt)
    return cls(**kwargs)


# ------------------------------------------------------------------ coercing
def _coerce(value: Any, kind: Any, name: str) -> Any:
    args = typing.get_args(kind)
    optional = typing.get_origin(kind) in (typing.Union, types.UnionType) and type(None) in args
    if optional:
        kind = next(a for a in args if a is not type(None))
    if value is None:
        if optional:
            return None
        raise ConfigError(f"{name}: a value is required")
    if kind is int and optional and value == "off":  # links.ship_beacon: off
        return None
    if kind is Endpoint:
        if value == "off" and optional:
            return None
        if not isinstance(value, str):
            raise ConfigError(f"{name}: expected HOST:PORT or off, got {value!r}")
        return Endpoint(*parse_hostport(value, name))
    if kind is GeoOrigin:
        if not isinstance(value, str):
            raise ConfigError(f"{name}: expected LAT,LON in degrees, got {value!r}")
        return GeoOrigin(*parse_latlon(value, name))
    if isinstance(kind, type) and issubclass(kind, StrEnum):
        names = [m.value for m in kind]
        if value not in names:
            raise ConfigError(f"{name}: expected one of {', '.join(names)}, got {value!r}")
        return kind(value)
    if typing.get_origin(kind) is tuple:
        if isinstance(value, str):
            value = [value]
        if not isinstance(value, list | tuple) or not all(isinstance(v, str) for v in value):
            raise ConfigError(f"{name}: expected a list of strings")
        return tuple(value)
    if typing.get_origin(kind) is Mapping:
        return _vehicle_settings(value, name)
    if kind is WindSpec:
        return _wind(value, name)
    return _scalar(value, kind, name)


def _scalar(value: Any, kind: Any, name: str) -> Any:
    if kind is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{name}: expected true or false, got {value!r}")
        return value
    if kind is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{name}: expected an integer, got {value!r}")
        return value
    if kind is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"{name}: expected a number, got {value!r}")
        return float(value)
    if kind is str:
        if not isinstance(value, str):
            raise ConfigError(f"{name}: expected a string, got {value!r}")
        return value
    raise ConfigError(f"{name}: cannot be set here")  # pragma: no cover - a schema bug


_WIND_KEYS = ("speed_m_s", "from_deg", "gust_m_s", "gust_tau_s")


def _wind(value: Any, name: str) -> WindSpec:
    """``SPEED_M_S,FROM_DEG[,GUST_M_S]`` (the flag) or ``{speed_m_s, from_deg, gust_m_s,
    gust_tau_s}`` (the file; speed and direction required)."""
    if isinstance(value, str):
        return parse_wind_text(value, name)
    if not isinstance(value, Mapping):
        raise ConfigError(f"{name}: expected SPEED_M_S,FROM_DEG[,GUST_M_S] or a mapping "
                          f"{{{', '.join(_WIND_KEYS[:3])}}}, got {value!r}")
    unknown = sorted(str(k) for k in value if k not in _WIND_KEYS)
    if unknown:
        raise ConfigError(f"{name}.{unknown[0]}: unknown key (known: {', '.join(_WIND_KEYS)})")
    for key in ("speed_m_s", "from_deg"):
        if key not in value:
            raise ConfigError(f"{name}.{key}: required")
    numbers = {k: _scalar(v, float, f"{name}.{k}") for k, v in value.items()}
    from_deg = numbers["from_deg"]
    if not (math.isfinite(from_deg) and 0.0 <= from_deg <= 360.0):
        raise ConfigError(f"{name}.from_deg: expected a compass direction in [0, 360], "
                          f"got {from_deg!r}")
    numbers["from_deg"] = from_deg % 360.0
    try:
        return WindSpec(**numbers)
    except ValueError as exc:
        raise ConfigError(f"{name}: {exc}") from None


def _vehicle_settings(value: Any, name: str) -> Mapping[int, VehicleSettings]:
    if not isinstance(value, Mapping):
        raise ConfigError(f"{name}: expected a mapping of system id -> settings")
    out: dict[int, VehicleSettings] = {}
    names = [f.name for f in dataclasses.fields(VehicleSettings)]
    for sysid, settings in value.items():
        where = f"{name}.{sysid}"
        if isinstance(sysid, str) and sysid.isdigit():
            sysid = int(sysid)  # JSON (the journal's start line) has string keys
        if isinstance(sysid, bool) or not isinstance(sysid, int) or not 1 <= sysid <= 255:
            raise ConfigError(f"{where}: the key must be a system id 1..255")
        if not isinstance(settings, Mapping):
            raise ConfigError(f"{where}: expected a mapping")
        kwargs: dict[str, Any] = {}
        for k, v in settings.items():
            if k not in names:
                raise ConfigError(f"{where}.{k}: unknown key (known: {', '.join(sorted(names))})")
            if k in ("name", "signing_key_file", "signing_passphrase_file"):
                if not isinstance(v, str) or not v:
                    raise ConfigError(f"{where}.{k}: expected a non-empty string")
                kwargs[k] = v
            elif isinstance(v, bool) or not isinstance(v, int | float) or not (
                math.isfinite(v) and v > 0
            ):
                raise ConfigError(f"{where}.{k}: expected a number > 0, got {v!r}")
            else:
                kwargs[k] = float(v)
        out[sysid] = VehicleSettings(**kwargs)
    return types.MappingProxyType(out)


# ------------------------------------------------------------------ checking
Check = Callable[[Any], str | None]


def _positive(high: float = math.inf, optional: bool = False) -> Check:
    def check(value: Any) -> str | None:
        if value is None and optional:
            return None
        if isinstance(value, int | float) and math.isfinite(value) and 0 < value <= high:
            return None
        limit = f" and <= {high:g}" if math.isfinite(high) else ""
        return f"expected a number > 0{limit}, got {value!r}"

    return check


def _between(low: float, high: float, text: str) -> Check:
    def check(value: Any) -> str | None:
        ok = isinstance(value, int | float) and math.isfinite(value) and low <= value <= high
        return None if ok else f"expected {text}, got {value!r}"

    return check


def _vehicles(urls: tuple[str, ...]) -> str | None:
    if not urls:
        return "at least one link URL or sim:N is required"
    sims = [v for v in urls if v.startswith("sim:")]
    if sims:
        if len(urls) != 1:
            return "sim:N cannot be mixed with other links"
        count = sims[0][4:]
        if not count.isdigit() or not 1 <= int(count) <= 50:
            return f"expected sim:N with N in 1..50, got {sims[0]!r}"
    return None


def _ship_url(url: str | None) -> str | None:
    if url is None:
        return None
    from groundstation.link.nmea_source import parse_ship_url
    from groundstation.link.url import LinkUrlError

    try:
        parse_ship_url(url)
    except LinkUrlError as exc:
        return str(exc)
    return None


def _gcs_id(value: int) -> str | None:
    if 1 <= value <= 254:
        return None
    return f"expected 1..254 (255 is what other GCSs use), got {value}"


def _loss(value: float) -> str | None:
    ok = math.isfinite(value) and 0 <= value < 1
    return None if ok else f"expected a probability in [0, 1), got {value}"


def _origins(values: tuple[str, ...]) -> str | None:
    from groundstation.daemon.control.guard import parse_origin  # pure, no aiohttp

    for text in values:
        try:
            parse_origin(text)
        except ValueError as exc:
            return str(exc)
    return None


def _link_rates(values: tuple[str, ...]) -> str | None:
    for text in values:
        try:
            parse_link_rate(text)
        except ValueError as exc:
            return str(exc)
    return None


def _check_link_rates_name_vehicles(config: DaemonConfig, name: str) -> None:
    """A ``--link-rate`` must name one of the vehicle links (a rate for a link floe does
    not open would be ignored); ``sim:N``'s links are the simulator's (``--sim-radio``)."""
    from groundstation.link.url import LinkUrlError, parse_link_url

    if not config.links.link_rate:
        return
    if config.sim_count is not None:
        raise ConfigError(f"{name}: sim:N's links are the built-in simulator's: give them "
                          "a radio with --sim-radio")
    vehicles = set()
    for url in config.links.vehicles:
        try:
            vehicles.add(parse_link_url(url).canonical)
        except LinkUrlError:
            return  # the vehicles' own check names the bad URL
    for text in config.links.link_rate:
        try:
            url, _ = parse_link_rate(text)
        except ValueError:
            return  # the field's own check names it
        if url not in vehicles:
            raise ConfigError(f"{name}: {text!r} names no vehicle link (the links are: "
                              f"{', '.join(sorted(vehicles))})")


def _altitudes(settings: Mapping[int, VehicleSettings]) -> str | None:
    alts = [s.altitude_m for s in settings.values() if s.altitude_m is not None]
    return "two vehicles share an altitude_m" if len(alts) != len(set(alts)) else None


_CHECKS: dict[str, Check] = {
    "links.vehicles": _vehicles,
    "speedup": _positive(1000.0, optional=True),
    "mission.duration_s": _positive(optional=True),
    "links.gcs_system_id": _gcs_id,
    "links.ship_beacon": lambda v: None if v is None else _between(1, 254, "1..254 or off")(v),
    "planner.num_workers": _between(1, 64, "1..64"),
    "fleet.altitude_m": _positive(),
    "links.rebind_after_s": _positive(),
    "links.silent_after_s": _positive(),
    "fleet.lost_after_s": _positive(),
    "fleet.lag_threshold_s": _positive(),
    "fleet.telemetry_rate_hz": _positive(),
    "links.transfer_timeout_s": _positive(),
    "mission.track_period_s": _positive(),
    "fleet.override_grace_s": _positive(),
    "fleet.progress_timeout_s": _positive(),
    "planner.time_limit_s": _positive(optional=True),
    "mission.loiter_radius_m": _positive(optional=True),
    "planner.period_s": _positive(optional=True),
    "planner.wind_replan_m_s": _positive(optional=True),
    "planner.wind_replan_margin_s": _positive(optional=True),
    "planner.upload_min_interval_s": lambda v: None if v is None else _between(
        0, 3600, "0..3600 s")(v),
    "mission.operating_radius_m": lambda v: None if v is None else _between(
        MIN_OPERATING_RADIUS_M, 65535, f"{MIN_OPERATING_RADIUS_M:g}..65535 m (the geofence "
        "is the area, in ArduPlane's whole metres; waypoints stay a loiter's room inside it)")(v),
    "mission.loiter_s": lambda v: None if v is None else _between(0, 65535, "0..65535 s")(v),
    "fleet.altitude_step_m": _between(0, math.inf, ">= 0"),
    "fleet.battery.low_pct": _between(0, 100, "0..100"),
    "links.transfer_retries": _between(0, 50, "0..50"),
    "links.link_rate": _link_rates,
    "sim.loss": _loss,
    "http.allow_origins": _origins,
    "http.max_targets": _between(1, 100_000, "1..100000"),
    "http.max_ws_clients": _between(1, 10_000, "1..10000"),
    "http.max_writes_per_s": _positive(10_000.0),
    "http.header_timeout_s": _positive(300.0),
    "fleet.settings": _altitudes,
    "ship.url": _ship_url,
    "ship.silent_after_s": _positive(),
    "ship.max_age_s": _positive(60.0),
}


def _get(config: Any, path: str) -> Any:
    for part in path.split("."):
        config = getattr(config, part)
    return config


def check_config(config: DaemonConfig, names: Mapping[str, str] | None = None) -> None:
    """Raise :class:`ConfigError` for the first bad field, named as in ``names`` (dotted
    path -> the user's spelling; default the dotted path). Also for configurations built
    in code (tests, benchmarks)."""
    names = names or {}
    for path, check in _CHECKS.items():
        message = check(_get(config, path))
        if message is not None:
            raise ConfigError(f"{names.get(path, path)}: {message}")
    planner = config.planner
    if planner.replan in (ReplanTrigger.PERIOD, ReplanTrigger.BOTH) and planner.period_s is None:
        name = names.get("planner.period_s", "planner.period_s")
        raise ConfigError(f"{name}: required when replan is period or both")
    beacon = config.links.ship_beacon
    if beacon is not None and beacon == config.links.gcs_system_id:
        name = names.get("links.ship_beacon", "links.ship_beacon")
        raise ConfigError(f"{name}: the ship's system id must not be floe's own ({beacon})")
    count = config.sim_count
    if count is not None:
        for spec in config.sim.faults:
            try:
                parse_fault_spec(spec, count)
            except FaultError as exc:
                raise ConfigError(f"{names.get('sim.faults', 'sim.faults')}: {exc}") from None
    _check_link_rates_name_vehicles(config, names.get("links.link_rate", "links.link_rate"))
    for spec in config.sim.radio:
        try:
            parse_radio_spec(spec, count if count is not None else 255)
        except RadioSpecError as exc:
            raise ConfigError(f"{names.get('sim.radio', 'sim.radio')}: {exc}") from None
