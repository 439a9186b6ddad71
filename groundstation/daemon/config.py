"""Effective configuration of ``gcs run``: defaults < ``--config FILE`` (YAML) < flags.

Every flag has a YAML key of the same name with dashes as underscores (``--on-exit`` ->
``on_exit``); per-vehicle settings live under ``vehicle_settings`` keyed by system id. An
unknown key, or a value of the wrong type or range, is a :class:`ConfigError` naming the
key. ``None`` for a core setting (``loiter_s`` ...) means "the scenario's, else the core's
default".
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

from domain import errors
from groundstation.vehicle.settings import ControllerSettings
from world.yaml_fields import load_yaml_file

__all__ = [
    "ConfigError",
    "DaemonConfig",
    "VehicleSettings",
    "controller_settings",
    "load_config_file",
    "parse_hostport",
]


class ConfigError(errors.ConfigError):
    """Bad configuration; the message names the key."""


@dataclass(frozen=True)
class VehicleSettings:
    """Per-vehicle settings (``vehicle_settings: {SYSID: {...}}``)."""

    name: str | None = None
    altitude_m: float | None = None
    loiter_radius_m: float | None = None
    speed_m_s: float | None = None
    signing_key_file: str | None = None
    """This vehicle's MAVLink 2 signing key file (32 raw bytes or 64 hex digits)."""
    signing_passphrase_file: str | None = None
    """This vehicle's signing passphrase file (key = SHA-256 of its first line)."""


@dataclass
class DaemonConfig:
    """Everything ``gcs run`` can be told (see docs/daemon.md for each key)."""

    vehicles: list[str] = field(default_factory=list)
    out: list[str] = field(default_factory=list)
    scenario: str | None = None
    targets: str | None = None
    duration: float | None = None
    launch: bool | None = None
    advisory: bool = False
    on_exit: str = "loiter"
    http: str = "127.0.0.1:0"
    http_allow_origins: list[str] = field(default_factory=list)
    http_max_targets: int = 100
    http_max_ws_clients: int = 16
    http_max_writes_per_s: float = 20.0
    http_header_timeout_s: float = 5.0
    detections: str = "127.0.0.1:14600"
    run_dir: str = "runs"
    journal: str | None = None
    gcs_system_id: int = 245
    speedup: float = 50.0
    seed: int = 0
    num_workers: int = 1
    solver_time_limit_s: float | None = None
    origin: str | None = None
    altitude_m: float = 100.0
    altitude_step_m: float = 15.0
    loiter_s: float | None = None
    loiter_radius_m: float | None = None
    replan: str | None = None
    period_s: float | None = None
    commit: bool | None = None
    operating_radius_m: float | None = 10000.0
    operating_center: str = "home"
    lost_after_s: float = 5.0
    rebind_after_s: float = 10.0
    override_grace_s: float = 2.0
    progress_timeout_s: float = 120.0
    battery_low_pct: float = 25.0
    battery_low_action: str = "rtl"
    telemetry_rate_hz: float = 2.0
    transfer_timeout_s: float = 1.5
    transfer_retries: int = 5
    track_period_s: float = 5.0
    sim_airborne: bool = False
    sim_fast_boot: bool = True
    sim_loss: float = 0.0
    sim_fault: list[str] = field(default_factory=list)
    status: str = "auto"
    signing_key_file: str | None = None
    signing_passphrase_file: str | None = None
    signing_setup: bool = False
    vehicle_settings: dict[int, VehicleSettings] = field(default_factory=dict)

    # ------------------------------------------------------------------ derived
    @property
    def sim_count(self) -> int | None:
        """N for ``--vehicles sim:N`` (None: real links)."""
        if len(self.vehicles) == 1 and self.vehicles[0].startswith("sim:"):
            return int(self.vehicles[0][4:])
        return None

    def resolve_defaults(self) -> None:
        """Defaults that depend on other keys: ``sim:N`` without a scenario flies the bundled
        ``default`` scenario (``none``: no scenario), and launches its vehicles unless they
        start airborne."""
        if self.scenario == "none":
            self.scenario = None
        elif self.sim_count is not None and self.scenario is None:
            self.scenario = "default"
        if self.launch is None:
            self.launch = self.sim_count is not None and not self.sim_airborne

    def settings_for(self, system_id: int) -> VehicleSettings:
        return self.vehicle_settings.get(system_id, VehicleSettings())

    def to_dict(self) -> dict[str, Any]:
        """Plain data (the run folder's config.yaml and the journal's start event)."""
        out = dataclasses.asdict(self)
        out["vehicle_settings"] = {
            int(k): {n: v for n, v in dataclasses.asdict(s).items() if v is not None}
            for k, s in self.vehicle_settings.items()
        }
        return out

    def validate(self) -> None:
        """Raise :class:`ConfigError` naming the first bad key."""
        if not self.vehicles:
            raise ConfigError("vehicles: at least one link URL or sim:N is required")
        sims = [v for v in self.vehicles if v.startswith("sim:")]
        if sims:
            if len(self.vehicles) != 1:
                raise ConfigError("vehicles: sim:N cannot be mixed with other links")
            count = sims[0][4:]
            if not count.isdigit() or not 1 <= int(count) <= 50:
                raise ConfigError(f"vehicles: expected sim:N with N in 1..50, got {sims[0]!r}")
        _positive("speedup", self.speedup, high=1000.0)
        if self.duration is not None:
            _positive("duration", self.duration)
        if self.on_exit not in ("loiter", "rtl"):
            raise ConfigError(f"on_exit: expected loiter or rtl, got {self.on_exit!r}")
        if not 1 <= self.gcs_system_id <= 255 or self.gcs_system_id == 255:
            raise ConfigError(
                f"gcs_system_id: expected 1..254 (255 is what other GCSs use), "
                f"got {self.gcs_system_id}"
            )
        if not 1 <= self.num_workers <= 64:
            raise ConfigError(f"num_workers: expected 1..64, got {self.num_workers}")
        for name in (
            "altitude_m",
            "lost_after_s",
            "rebind_after_s",
            "telemetry_rate_hz",
            "transfer_timeout_s",
            "track_period_s",
            "override_grace_s",
            "progress_timeout_s",
        ):
            _positive(name, getattr(self, name))
        for name in ("solver_time_limit_s", "loiter_radius_m", "period_s"):
            value = getattr(self, name)
            if value is not None:
                _positive(name, value)
        if self.loiter_s is not None and not (
            math.isfinite(self.loiter_s) and 0 <= self.loiter_s <= 65535
        ):
            raise ConfigError(f"loiter_s: expected 0..65535 s, got {self.loiter_s}")
        if not (math.isfinite(self.altitude_step_m) and self.altitude_step_m >= 0):
            raise ConfigError(f"altitude_step_m: expected >= 0, got {self.altitude_step_m}")
        if self.operating_radius_m is not None:
            _positive("operating_radius_m", self.operating_radius_m)
        if self.operating_center not in ("home", "boat"):
            raise ConfigError(
                f"operating_center: expected home or boat, got {self.operating_center!r}"
            )
        if self.replan is not None and self.replan not in ("event", "period", "both"):
            raise ConfigError(f"replan: expected event, period or both, got {self.replan!r}")
        if self.replan in ("period", "both") and self.period_s is None:
            raise ConfigError("period_s: required when replan is period or both")
        if not 0 <= self.battery_low_pct <= 100:
            raise ConfigError(f"battery_low_pct: expected 0..100, got {self.battery_low_pct}")
        if self.battery_low_action not in ("rtl", "release"):
            raise ConfigError(
                f"battery_low_action: expected rtl or release, got {self.battery_low_action!r}"
            )
        if not 0 <= self.transfer_retries <= 50:
            raise ConfigError(f"transfer_retries: expected 0..50, got {self.transfer_retries}")
        if not 0 <= self.sim_loss < 1:
            raise ConfigError(f"sim_loss: expected a probability in [0, 1), got {self.sim_loss}")
        if self.status not in ("auto", "table", "log", "quiet"):
            raise ConfigError(f"status: expected auto, table, log or quiet, got {self.status!r}")
        for key in ("http", "detections"):
            value = getattr(self, key)
            if value != "off":
                parse_hostport(value, key)
        if self.origin is not None:
            parse_latlon(self.origin, "origin")
        self._validate_http()
        alts = [s.altitude_m for s in self.vehicle_settings.values() if s.altitude_m is not None]
        if len(alts) != len(set(alts)):
            raise ConfigError("vehicle_settings: two vehicles share an altitude_m")


    def _validate_http(self) -> None:
        from groundstation.daemon.control_guard import parse_origin  # pure, no aiohttp

        for text in self.http_allow_origins:
            try:
                parse_origin(text)
            except ValueError as exc:
                raise ConfigError(f"http_allow_origins: {exc}") from None
        if not 1 <= self.http_max_targets <= 100_000:
            raise ConfigError(f"http_max_targets: expected 1..100000, got {self.http_max_targets}")
        if not 1 <= self.http_max_ws_clients <= 10_000:
            raise ConfigError(
                f"http_max_ws_clients: expected 1..10000, got {self.http_max_ws_clients}"
            )
        _positive("http_max_writes_per_s", self.http_max_writes_per_s, high=10_000.0)
        _positive("http_header_timeout_s", self.http_header_timeout_s, high=300.0)


def _positive(name: str, value: float, high: float = math.inf) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and 0 < value <= high):
        limit = f" and <= {high:g}" if math.isfinite(high) else ""
        raise ConfigError(f"{name}: expected a number > 0{limit}, got {value!r}")


def parse_hostport(text: str, key: str) -> tuple[str, int]:
    """``HOST:PORT`` (``udp:`` prefix allowed) -> (host, port); port 0 = ephemeral."""
    body = text.split(":", 1)[1] if text.startswith(("udp:", "tcp:", "http:")) else text
    host, sep, port = body.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) < 65536:
        raise ConfigError(f"{key}: expected HOST:PORT or off, got {text!r}")
    return host, int(port)


def parse_latlon(text: str, key: str) -> tuple[float, float]:
    """``LAT,LON`` in degrees."""
    try:
        lat, lon = (float(p) for p in text.split(","))
    except ValueError:
        raise ConfigError(f"{key}: expected LAT,LON in degrees, got {text!r}") from None
    if not (math.isfinite(lat) and -90 <= lat <= 90 and math.isfinite(lon) and -180 <= lon <= 180):
        raise ConfigError(f"{key}: latitude/longitude out of range in {text!r}")
    return lat, lon


def _field_types() -> dict[str, str]:
    return {f.name: str(f.type) for f in dataclasses.fields(DaemonConfig)}


def _coerce(key: str, value: Any, type_text: str) -> Any:
    optional = "None" in type_text
    if value is None:
        if optional:
            return None
        raise ConfigError(f"{key}: a value is required")
    if type_text.startswith("list"):
        if isinstance(value, str):
            value = [value]
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise ConfigError(f"{key}: expected a list of strings")
        return list(value)
    if type_text.startswith("bool"):
        if not isinstance(value, bool):
            raise ConfigError(f"{key}: expected true or false, got {value!r}")
        return value
    if type_text.startswith("int"):
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{key}: expected an integer, got {value!r}")
        return value
    if type_text.startswith("float"):
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"{key}: expected a number, got {value!r}")
        return float(value)
    if type_text.startswith("str"):
        if not isinstance(value, str):
            raise ConfigError(f"{key}: expected a string, got {value!r}")
        return value
    raise ConfigError(f"{key}: cannot be set here")


def _vehicle_settings(value: Any) -> dict[int, VehicleSettings]:
    if not isinstance(value, dict):
        raise ConfigError("vehicle_settings: expected a mapping of system id -> settings")
    out: dict[int, VehicleSettings] = {}
    names = {f.name for f in dataclasses.fields(VehicleSettings)}
    for sysid, settings in value.items():
        where = f"vehicle_settings.{sysid}"
        if isinstance(sysid, bool) or not isinstance(sysid, int) or not 1 <= sysid <= 255:
            raise ConfigError(f"{where}: the key must be a system id 1..255")
        if not isinstance(settings, dict):
            raise ConfigError(f"{where}: expected a mapping")
        kwargs: dict[str, Any] = {}
        for k, v in settings.items():
            if k not in names:
                raise ConfigError(f"{where}.{k}: unknown key (known: {', '.join(sorted(names))})")
            if k in ("name", "signing_key_file", "signing_passphrase_file"):
                if not isinstance(v, str) or not v:
                    raise ConfigError(f"{where}.{k}: expected a non-empty string")
                kwargs[k] = v
            else:
                if (
                    isinstance(v, bool)
                    or not isinstance(v, int | float)
                    or not (math.isfinite(v) and v > 0)
                ):
                    raise ConfigError(f"{where}.{k}: expected a number > 0, got {v!r}")
                kwargs[k] = float(v)
        out[sysid] = VehicleSettings(**kwargs)
    return out


def apply_mapping(config: DaemonConfig, data: dict[str, Any], where: str = "") -> None:
    """Set ``config`` fields from a YAML mapping (unknown keys are errors naming the key)."""
    types = _field_types()
    for key, value in data.items():
        name = f"{where}{key}"
        if not isinstance(key, str) or key not in types:
            raise ConfigError(f"{name}: unknown key (see docs/daemon.md for the keys)")
        if key == "vehicle_settings":
            config.vehicle_settings = _vehicle_settings(value)
            continue
        setattr(config, key, _coerce(name, value, types[key]))


def load_config_file(path: str) -> dict[str, Any]:
    """Read a YAML mapping; errors name the file."""
    try:
        data = load_yaml_file(path, f"--config {path}")
    except errors.ConfigError as exc:
        raise ConfigError(str(exc)) from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"--config: {path} must hold a mapping of keys")
    return data


def controller_settings(
    config: DaemonConfig, vehicle: VehicleSettings, index: int
) -> ControllerSettings:
    """The mapping from the daemon's configuration (the only place that knows both)."""
    return ControllerSettings(
        altitude_m=vehicle.altitude_m or config.altitude_m + config.altitude_step_m * index,
        loiter_radius_m=vehicle.loiter_radius_m,
        speed_m_s=vehicle.speed_m_s,
        launch=bool(config.launch),
        advisory=config.advisory,
        lost_after_s=config.lost_after_s,
        override_grace_s=config.override_grace_s,
        battery_low_pct=config.battery_low_pct,
        telemetry_rate_hz=config.telemetry_rate_hz,
        progress_timeout_s=config.progress_timeout_s,
    )
