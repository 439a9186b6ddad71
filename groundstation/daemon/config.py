"""Effective configuration of ``gcs run``: nested, frozen, typed.

Defaults < ``--config FILE`` (YAML) < flags. The YAML may use the nested spelling
(``fleet: {lost_after_s: 10, battery: {low_pct: 30}}``) or the flat keys of earlier
releases (``lost_after_s: 10``, ``battery_low_pct: 30``), which are aliases of the nested
fields (:data:`groundstation.daemon.config_parse.ALIASES`). Parsing is
:func:`groundstation.daemon.config_parse.parse_config`, one pure function; defaults that
depend on other keys are resolved by :func:`resolve`, another pure function
(``resolve(resolve(c)) == resolve(c)``). Every closed set of strings is an enum
(:class:`OnExit`, :class:`StatusMode`, :class:`ReplanTrigger`, :class:`OperatingCenter`
here; the core's :class:`~groundstation.core.config.BatteryAction` and the planner's
:class:`~planner.Objective`, re-exported). ``None`` for a core setting
(``loiter_s`` ...) means "the scenario's, else the core's default".

:meth:`DaemonConfig.to_dict` is the nested plain data written to the run folder's
``config.yaml`` and the journal's ``start`` line; parsing it again gives an equal config.
"""

from __future__ import annotations

import dataclasses
import math
import types
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from domain.errors import ConfigError
from domain.geodesy import GeoOrigin
from domain.yaml_fields import load_yaml_file
from groundstation.core.config import BatteryAction, WatchConfig
from groundstation.vehicle.settings import ControllerSettings
from planner import Objective
from world.wind import WindSpec

__all__ = [
    "BatteryAction",
    "BatteryConfig",
    "DaemonConfig",
    "Endpoint",
    "FleetConfig",
    "HttpConfig",
    "LinksConfig",
    "MissionConfig",
    "Objective",
    "OnExit",
    "OperatingCenter",
    "PlannerConfig",
    "RecordsConfig",
    "ReplanTrigger",
    "ShipConfig",
    "SigningConfig",
    "SimConfig",
    "StatusMode",
    "VehicleSettings",
    "WatchSettings",
    "controller_settings",
    "load_config_file",
    "parse_hostport",
    "parse_latlon",
    "resolve",
]

SIM_SPEEDUP = 50.0
"""Default speed-up with ``sim:N`` (real vehicles: 1)."""


class OnExit(StrEnum):
    """What commanded vehicles do when floe stops."""

    LOITER = "loiter"
    RTL = "rtl"


class StatusMode(StrEnum):
    """The console: live table (``auto`` on an interactive terminal), log lines, or quiet
    (warnings and errors only); see ``daemon/console.py``."""

    AUTO = "auto"
    TABLE = "table"
    LOG = "log"
    QUIET = "quiet"


class ReplanTrigger(StrEnum):
    """What makes the core replan: events, a period, or both."""

    EVENT = "event"
    PERIOD = "period"
    BOTH = "both"


class OperatingCenter(StrEnum):
    """Centre of the operating area: the mission origin (home) or the boat."""

    HOME = "home"
    BOAT = "boat"


@dataclass(frozen=True, slots=True)
class Endpoint:
    """A ``HOST:PORT`` to listen on (port 0: ephemeral)."""

    host: str
    port: int

    def __str__(self) -> str:
        return f"{self.host}:{self.port}"


DETECTIONS_UNSET = Endpoint("", -1)
"""``detections`` not given (no parsed address has port -1): :func:`resolve` picks it."""
DETECTIONS_DEFAULT = Endpoint("127.0.0.1", 14600)


@dataclass(frozen=True, slots=True)
class VehicleSettings:
    """Per-vehicle settings (``fleet.settings`` / ``vehicle_settings: {SYSID: {...}}``)."""

    name: str | None = None
    altitude_m: float | None = None
    loiter_radius_m: float | None = None
    speed_m_s: float | None = None
    signing_key_file: str | None = None
    """This vehicle's MAVLink 2 signing key file (32 raw bytes or 64 hex digits)."""
    signing_passphrase_file: str | None = None
    """This vehicle's signing passphrase file (key = SHA-256 of its first line)."""


@dataclass(frozen=True, slots=True)
class LinksConfig:
    """The MAVLink side: vehicle links (or ``sim:N``), ``--out`` links, binding, transfers."""

    vehicles: tuple[str, ...] = ()
    out: tuple[str, ...] = ()
    rebind_after_s: float = 10.0
    silent_after_s: float = 10.0
    """A vehicle link that made no vehicle this many wall seconds after its start (or its
    connect) is reported silent, on the console and in the journal (``link_silent``;
    ``daemon/alerts.py``)."""
    gcs_system_id: int = 245
    transfer_timeout_s: float = 1.5
    transfer_retries: int = 5
    link_rate: tuple[str, ...] = ()
    """``URL=BPS``: what the vehicle link URL carries, bit/s (docs/links.md, "Over a
    telemetry radio"); a link not named: its serial baud rate, else unlimited."""
    ship_beacon: int | None = 17
    """The ship's MAVLink system id: its GLOBAL_POSITION_INT goes to every vehicle link at
    1 Hz while the ship's position is known (ArduPilot's ``FOLL_SYSID``; docs/
    ship.md). None (``off``): no beacon."""

    def link_rates(self) -> list[tuple[str, float]]:
        """``link_rate`` as (canonical URL, bit/s); raises ValueError naming a bad entry."""
        return [parse_link_rate(text) for text in self.link_rate]

    @property
    def sim_count(self) -> int | None:
        """N for ``sim:N`` (None: real links)."""
        if len(self.vehicles) == 1 and self.vehicles[0].startswith("sim:"):
            count = self.vehicles[0][4:]
            return int(count) if count.isdigit() else None
        return None


@dataclass(frozen=True, slots=True)
class MissionConfig:
    """What is flown: scenario, targets, duration, origin, area, loiters.

    ``scenario``: None = unset (``sim:N`` resolves it to ``default``), ``"none"`` = no
    scenario asked for explicitly; :attr:`scenario_to_load` is what to load."""

    scenario: str | None = None
    targets: str | None = None
    duration_s: float | None = None
    origin: GeoOrigin | None = None
    seed: int = 0
    loiter_s: float | None = None
    loiter_radius_m: float | None = None
    operating_radius_m: float | None = 10000.0
    operating_center: OperatingCenter = OperatingCenter.HOME
    track_period_s: float = 5.0

    @property
    def scenario_to_load(self) -> str | None:
        """The scenario name or file to load (None: none)."""
        return None if self.scenario in (None, "none") else self.scenario


@dataclass(frozen=True, slots=True)
class BatteryConfig:
    """Low battery: the level (percent) that takes a vehicle out, and what follows."""

    low_pct: float = 25.0
    action: BatteryAction = BatteryAction.RTL


@dataclass(frozen=True, slots=True)
class FleetConfig:
    """How floe treats its vehicles (altitudes, launch, evidence timeouts, per vehicle)."""

    altitude_m: float = 100.0
    altitude_step_m: float = 15.0
    launch: bool | None = None
    lost_after_s: float = 5.0
    lag_threshold_s: float = 2.0
    override_grace_s: float = 2.0
    progress_timeout_s: float = 120.0
    telemetry_rate_hz: float = 2.0
    battery: BatteryConfig = field(default_factory=BatteryConfig)
    settings: Mapping[int, VehicleSettings] = field(
        default_factory=lambda: types.MappingProxyType({})
    )

    def settings_for(self, system_id: int) -> VehicleSettings:
        return self.settings.get(system_id, VehicleSettings())


@dataclass(frozen=True, slots=True)
class PlannerConfig:
    """The planner and the replan policy (None: the scenario's, else the core's)."""

    objective: Objective | None = None
    time_limit_s: float | None = None
    num_workers: int = 1
    replan: ReplanTrigger | None = None
    period_s: float | None = None
    commit: bool | None = None
    wind_replan: bool | None = None
    """False: legs are never replanned for the wind (``CoreConfig.wind_replan_m_s`` None)."""
    wind_replan_m_s: float | None = None
    wind_replan_margin_s: float | None = None
    """The core's wind-replan settings (docs/wind.md, "The first leg"); None: its defaults."""
    upload_min_interval_s: float | None = None
    """At most one new mission per vehicle per this many mission s (``core/uploads.py``,
    docs/planner.md; 0: no minimum); None: the scenario's, else the core's default."""


@dataclass(frozen=True, slots=True)
class HttpConfig:
    """The control API: where it listens (None: off), allowed origins, limits."""

    bind: Endpoint | None = Endpoint("127.0.0.1", 0)
    allow_origins: tuple[str, ...] = ()
    max_targets: int = 100
    max_ws_clients: int = 16
    max_writes_per_s: float = 20.0
    header_timeout_s: float = 5.0
    map_tiles: str | None = None
    """The live map's offline tiles: a raster MBTiles or PMTiles v3 file
    (``control/tiles/``)."""


@dataclass(frozen=True, slots=True)
class RecordsConfig:
    """Where the run folder and the journal go."""

    run_dir: str = "runs"
    journal: str | None = None


@dataclass(frozen=True, slots=True)
class SigningConfig:
    """MAVLink 2 signing: the key file or passphrase file for all vehicles, and setup.
    Only paths: key material never enters the configuration."""

    key_file: str | None = None
    passphrase_file: str | None = None
    setup: bool = False


@dataclass(frozen=True, slots=True)
class SimConfig:
    """The built-in vehicles of ``sim:N`` (the count is ``links.vehicles``)."""

    airborne: bool = False
    fast_boot: bool = True
    loss: float = 0.0
    faults: tuple[str, ...] = ()
    radio: tuple[str, ...] = ()
    """Telemetry-radio specs (``sik,loss=0.05``; docs/sitl.md), after the scenario's."""


@dataclass(frozen=True, slots=True)
class ShipConfig:
    """The ship's NMEA 0183 feed (``--ship URL``; docs/ship.md): ``url`` None = none (the
    scenario's boat or the detection feed's ``boat`` lines, if any, place the ship)."""

    url: str | None = None
    silent_after_s: float = 10.0
    """Warn when the feed gave no valid fix for this many mission seconds."""
    max_age_s: float = 3.0
    """Course, speed and heading older than this (mission s) are not fused into a fix."""


@dataclass(frozen=True, slots=True)
class WatchSettings:
    """The ship watch (``watch:``; docs/ship.md) for a ``gcs run`` whose scenario has none
    (real vehicles, a real ship): any key given turns the watch on, with the core's
    defaults for the rest; with a scenario's ``watch:``, the keys given override its."""

    on_station: int | None = None
    endurance_s: float | None = None
    reserve_pct: float | None = None
    home_update_m: float | None = None
    recovery_radius_m: float | None = None
    launch_s: float | None = None

    @property
    def given(self) -> dict[str, Any]:
        """The keys given, by name."""
        return {name: getattr(self, name) for name in self.__slots__
                if getattr(self, name) is not None}


@dataclass(frozen=True, slots=True)
class DaemonConfig:
    """Everything ``gcs run`` can be told (docs/daemon.md has each key)."""

    links: LinksConfig = field(default_factory=LinksConfig)
    mission: MissionConfig = field(default_factory=MissionConfig)
    fleet: FleetConfig = field(default_factory=FleetConfig)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    http: HttpConfig = field(default_factory=HttpConfig)
    records: RecordsConfig = field(default_factory=RecordsConfig)
    signing: SigningConfig = field(default_factory=SigningConfig)
    sim: SimConfig = field(default_factory=SimConfig)
    ship: ShipConfig = field(default_factory=ShipConfig)
    watch: WatchSettings = field(default_factory=WatchSettings)
    detections: Endpoint | None = DETECTIONS_UNSET
    """The detection feed's UDP address; None: off (unset: see :func:`resolve`)."""
    speedup: float | None = None
    advisory: bool = False
    status: StatusMode = StatusMode.AUTO
    on_exit: OnExit = OnExit.LOITER
    wind: WindSpec | None = None
    """``--wind`` / ``wind: {speed_m_s, from_deg, gust_m_s}``: the core's fallback wind
    (else the scenario's) and, with ``sim:N``, the wind the built-in vehicles fly in."""

    @property
    def sim_count(self) -> int | None:
        """N for ``--vehicles sim:N`` (None: real links)."""
        return self.links.sim_count

    @property
    def speedup_x(self) -> float:
        """The resolved speed-up (``speedup`` unless unresolved: then its default)."""
        if self.speedup is not None:
            return self.speedup
        return SIM_SPEEDUP if self.sim_count is not None else 1.0

    def settings_for(self, system_id: int) -> VehicleSettings:
        return self.fleet.settings_for(system_id)

    def to_dict(self) -> dict[str, Any]:
        """Nested plain data (config.yaml, the journal's start line): enums as their
        values, the origin as ``LAT,LON``, endpoints as ``HOST:PORT`` or ``off``, per-vehicle
        settings without their unset keys. ``parse_config(c.to_dict(), {}) == c``."""
        out = {f.name: _plain(getattr(self, f.name)) for f in dataclasses.fields(self)}
        out["detections"] = _off(self.detections)
        if self.links.ship_beacon is None:
            out["links"]["ship_beacon"] = "off"
        if self.detections == DETECTIONS_UNSET:  # unresolved: left to resolve() again
            del out["detections"]
        return out


def _plain(value: Any) -> Any:
    if isinstance(value, GeoOrigin):
        return f"{value.lat_deg!r},{value.lon_deg!r}"
    if isinstance(value, Endpoint):
        return str(value)
    if isinstance(value, VehicleSettings):
        return {f.name: getattr(value, f.name) for f in dataclasses.fields(value)
                if getattr(value, f.name) is not None}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        out = {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
        if isinstance(value, HttpConfig):
            out["bind"] = _off(value.bind)
        return out
    if isinstance(value, StrEnum):
        return value.value
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    return value


def _off(value: Endpoint | None) -> Any:
    return "off" if value is None else str(value)


def resolve(config: DaemonConfig) -> DaemonConfig:
    """Defaults that depend on other keys, resolved (pure and idempotent):

    * ``speedup``: 50 with ``sim:N``, else 1;
    * ``mission.scenario``: ``default`` with ``sim:N`` when unset (``none``: none);
    * ``fleet.launch``: on for ``sim:N`` unless its vehicles start airborne, else off;
    * ``detections``: 127.0.0.1:14600, but with ``sim:N`` a free port (127.0.0.1:0, printed
      at start): the built-in vehicles play the camera, nothing outside needs the address,
      and two ``sim:N`` runs can run side by side."""
    sim = config.sim_count is not None
    mission, fleet, detections = config.mission, config.fleet, config.detections
    if detections == DETECTIONS_UNSET:
        detections = Endpoint("127.0.0.1", 0) if sim else DETECTIONS_DEFAULT
    if sim and mission.scenario is None:
        mission = dataclasses.replace(mission, scenario="default")
    if fleet.launch is None:
        fleet = dataclasses.replace(fleet, launch=sim and not config.sim.airborne)
    return dataclasses.replace(
        config, speedup=config.speedup_x, mission=mission, fleet=fleet, detections=detections
    )


MAX_LINK_RATE_BPS = 1e9


def parse_link_rate(text: str) -> tuple[str, float]:
    """``URL=BPS`` (``--link-rate``): a vehicle link URL and what it carries, bit/s, a
    positive number with an optional ``k`` (x 1000): ``tcp:127.0.0.1:5760=64k``. Returns
    (the URL's canonical spelling, bit/s); ValueError with one line on anything else."""
    from groundstation.link.url import LinkUrlError, parse_link_url

    url, sep, rate = text.rpartition("=")
    if not sep or not url:
        raise ValueError(f"link rate {text!r}: expected URL=BPS, e.g. tcp:10.0.0.5:5760=64k")
    scale = 1000.0 if rate.lower().endswith("k") else 1.0
    number = rate[:-1] if scale > 1.0 else rate
    try:
        bps = float(number) * scale
    except ValueError:
        bps = math.nan
    if not (math.isfinite(bps) and 0 < bps <= MAX_LINK_RATE_BPS):
        raise ValueError(f"link rate {text!r}: {rate!r} is not a rate in bit/s "
                         f"(0 < BPS <= {MAX_LINK_RATE_BPS:g})")
    try:
        spec = parse_link_url(url)
    except LinkUrlError as exc:
        raise ValueError(f"link rate {text!r}: {exc}") from None
    return spec.canonical, bps


def parse_hostport(text: str, key: str) -> tuple[str, int]:
    """``HOST:PORT`` (``udp:``/``tcp:``/``http:`` prefix allowed) -> (host, port); port 0 =
    ephemeral."""
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


def load_config_file(path: str) -> dict[str, Any]:
    """Read a YAML mapping; errors name the file."""
    data = load_yaml_file(path, f"--config {path}")
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"--config: {path} must hold a mapping of keys")
    return data


LAG_WALL_FLOOR_S = 0.3
"""The least lag threshold in wall seconds: at a speed-up of K a vehicle is lagging only
beyond ``max(lag_threshold_s, 0.3 K)`` mission s (a host that pauses the daemon for 40 ms
at 50x is not a backlog on the link)."""


def controller_settings(
    config: DaemonConfig, vehicle: VehicleSettings, index: int,
    planned_speed_m_s: float | None = None, watch: WatchConfig | None = None,
) -> ControllerSettings:
    """The mapping from the daemon's configuration (the only place that knows both).
    ``planned_speed_m_s``: the core's airspeed (the scenario's), the configured speed of a
    vehicle without its own ``speed_m_s`` whose cruise airspeed cannot be read. ``watch``:
    the core's ship watch (its ``ready_pct``; with ``on_station``, launches on order)."""
    fleet = config.fleet
    return ControllerSettings(
        altitude_m=vehicle.altitude_m or fleet.altitude_m + fleet.altitude_step_m * index,
        loiter_radius_m=vehicle.loiter_radius_m,
        speed_m_s=vehicle.speed_m_s or planned_speed_m_s,
        launch=bool(fleet.launch),
        advisory=config.advisory,
        lost_after_s=fleet.lost_after_s,
        lag_threshold_s=max(fleet.lag_threshold_s, LAG_WALL_FLOOR_S * config.speedup_x),
        override_grace_s=fleet.override_grace_s,
        battery_low_pct=fleet.battery.low_pct,
        telemetry_rate_hz=fleet.telemetry_rate_hz,
        progress_timeout_s=fleet.progress_timeout_s,
        ready_pct=None if watch is None else watch.ready_pct,
        launch_on_order=watch is not None and watch.on_station is not None,
        params_snapshot=True,
    )
