"""Building and running a :class:`~groundstation.daemon.daemon.Daemon` from its config.

Order: scenario, embedded simulator (``sim:N``), mission origin and clock, run folder
(``runs/<UTC timestamp>/`` with ``journal.jsonl``, ``flight.tlog``, ``config.yaml``,
``gcs.log``, ``metrics.json`` at the end), core configuration, links, optional control API
and detection feed, then the daemon until it stops. Anything wrong with the input is a
:class:`StartError` (one line, exit 2).

The run's files are probed and opened by :mod:`groundstation.daemon.run_files` (a full disk
or ``--journal /dev/full`` is refused at start; during the run a full disk is one line,
never a stop). ``control.json`` (mode 0600 from creation) and ``metrics.json`` are written
atomically; a failure there is one line, exit 2.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import json
import logging
import platform
import signal
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import TYPE_CHECKING, Any

from domain.errors import ConfigError
from domain.extras import DISTRIBUTION
from domain.geodesy import GeoOrigin
from domain.limits import MAX_COORDINATE_M, MAX_SPEED_M_S, MAX_TARGETS
from domain.yaml_fields import check_number, load_yaml_file
from groundstation.core import events as ev
from groundstation.core.config import CoreConfig, ReplanPolicy, WatchConfig, config_to_dict
from groundstation.core.scenario_config import core_config_for
from groundstation.daemon.alerts import OperatorAlerts
from groundstation.daemon.clock import MissionClock
from groundstation.daemon.composition import (
    StartError,
    camera_positions,
    feed_counters,
    ship_beacon_service,
    start_control,
    start_detection_feed,
    start_ship_feed,
    status_service,
)
from groundstation.daemon.config import DaemonConfig, resolve
from groundstation.daemon.config_parse import check_config
from groundstation.daemon.console import OperatorConsole
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.embedded import EmbeddedFactory, EmbeddedService, EmbeddedVehicles
from groundstation.daemon.gc_guard import frozen_heap
from groundstation.daemon.run_files import RunFiles, open_run_files
from groundstation.daemon.services import FnService, Service
from groundstation.daemon.session import VehicleSession
from groundstation.daemon.signing_gate import SigningGate, SigningKeys, load_signing_keys
from groundstation.daemon.wind_view import fallback_wind
from groundstation.daemon.world import ScenarioWorld
from groundstation.link import LinkError, LinkSpec, LinkUrlError, describe_out_link, open_link
from groundstation.storage import StorageError, atomic_write_text

if TYPE_CHECKING:
    from world.scenario import Scenario
    from world.wind import WindSpec

__all__ = ["MetricsNotWritten", "StartError", "core_config", "load_targets", "run_daemon"]

log = logging.getLogger(__name__)
MIN_SOLVER_WALL_S = 0.05


def _versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for name, dist in (("floe", DISTRIBUTION), ("pymavlink", "pymavlink"),
                       ("ortools", "ortools"), ("numpy", "numpy")):
        try:
            out[name] = version(dist)
        except PackageNotFoundError:
            out[name] = "unknown"
    return out


def core_config(config: DaemonConfig, scenario: Any, speedup: float) -> CoreConfig:
    """The core's settings: the scenario's (or the core's defaults), overridden by the
    config (``planner.wind_replan: false`` turns the wind replan off). The solver's wall
    budget is the time limit divided by the speed-up, so a plan takes the same mission time
    at any speed-up (floor 0.05 s). The fallback wind is the
    config's, else the scenario's (``wind_view.fallback_wind``)."""
    base = core_config_for(scenario) if scenario is not None else CoreConfig()
    policy = base.policy
    planner, mission = config.planner, config.mission
    if planner.replan is not None or planner.period_s is not None or planner.commit is not None:
        replan = planner.replan or (
            "event"
            if policy.on_events and policy.period_s is None
            else "period"
            if not policy.on_events
            else "both"
        )
        period = planner.period_s if planner.period_s is not None else policy.period_s
        commit = planner.commit if planner.commit is not None else policy.commit
        try:
            policy = ReplanPolicy.from_names(replan, period, commit)
        except ValueError as exc:
            raise StartError(f"replan: {exc}") from None
    limit = planner.time_limit_s or base.time_limit_s
    wind_replan_m_s = (
        None if planner.wind_replan is False else planner.wind_replan_m_s or base.wind_replan_m_s
    )
    interval = planner.upload_min_interval_s  # core/uploads.py; None: the scenario's
    return dataclasses.replace(
        base,
        upload_min_interval_s=(base.upload_min_interval_s if interval is None
                               else interval),
        wind_replan_m_s=wind_replan_m_s,
        wind_replan_margin_s=planner.wind_replan_margin_s or base.wind_replan_margin_s,
        policy=policy,
        loiter_s=mission.loiter_s if mission.loiter_s is not None else base.loiter_s,
        loiter_radius_m=(
            mission.loiter_radius_m
            if mission.loiter_radius_m is not None
            else base.loiter_radius_m
        ),
        objective=planner.objective or base.objective,
        battery_low_action=config.fleet.battery.action,
        time_limit_s=max(MIN_SOLVER_WALL_S, limit / speedup),
        wind_xy_m_s=fallback_wind(config, scenario)[0].mean_xy_m_s,
        watch=_watch(config, base.watch),
    )


def _watch(config: DaemonConfig, scenario_watch: WatchConfig | None) -> WatchConfig | None:
    """The scenario's watch with the config's ``watch:`` keys over it; the config's alone
    when the scenario has none (docs/ship.md)."""
    given = config.watch.given
    if not given:
        return scenario_watch
    try:
        return dataclasses.replace(scenario_watch or WatchConfig(), **given)
    except (TypeError, ValueError) as exc:
        raise StartError(f"watch: {exc}") from None


_LIMITS = {
    "x_m": MAX_COORDINATE_M, "y_m": MAX_COORDINATE_M, "lat_deg": 90.0, "lon_deg": 180.0,
    "vx_m_s": MAX_SPEED_M_S, "vy_m_s": MAX_SPEED_M_S, "sigma0": 1e12,
}  # fmt: skip


def load_targets(path: str, origin: GeoOrigin | None) -> list[ev.TargetAdded]:
    """``--targets FILE``: a YAML list of {id, x_m, y_m | lat_deg, lon_deg, vx_m_s, vy_m_s,
    sigma0}; errors name the entry and key."""
    try:
        data = load_yaml_file(path, f"--targets {path}")
    except ConfigError as exc:
        raise StartError(str(exc)) from None
    if not isinstance(data, list):
        raise StartError(f"--targets: {path} must hold a list of targets")
    keys = {"id", "x_m", "y_m", "lat_deg", "lon_deg", "vx_m_s", "vy_m_s", "sigma0"}
    if len(data) > MAX_TARGETS:
        raise StartError(f"--targets: {len(data)} targets; floe's limit is {MAX_TARGETS}")
    out: list[ev.TargetAdded] = []
    for i, item in enumerate(data):
        where = f"--targets: entry {i}"
        if not isinstance(item, dict):
            raise StartError(f"{where}: expected a mapping")
        unknown = set(item) - keys
        if unknown:
            raise StartError(f"{where}: unknown key {sorted(unknown)[0]!r}")
        tid = item.get("id")
        if not isinstance(tid, str | int) or isinstance(tid, bool) or str(tid) == "":
            raise StartError(f"{where}: id must be a string")
        values: dict[str, float] = {}
        for key in keys - {"id"}:
            if key in item:
                v = item[key]
                try:
                    values[key] = check_number(key, v, minimum=-_LIMITS[key], maximum=_LIMITS[key])
                except ConfigError as exc:
                    raise StartError(f"{where} ({tid}): {exc}") from None
        if "x_m" in values and "y_m" in values:
            x, y = values["x_m"], values["y_m"]
        elif "lat_deg" in values and "lon_deg" in values:
            if origin is None:
                raise StartError(f"{where} ({tid}): lat/lon needs a mission origin (--origin)")
            x, y, _ = origin.to_local(values["lat_deg"], values["lon_deg"])
        else:
            raise StartError(f"{where} ({tid}): give x_m and y_m, or lat_deg and lon_deg")
        if values.get("sigma0", 0.0) < 0:
            raise StartError(f"{where} ({tid}): sigma0 must be >= 0")
        out.append(
            ev.TargetAdded(
                0.0,
                str(tid),
                x,
                y,
                values.get("vx_m_s", 0.0),
                values.get("vy_m_s", 0.0),
                values.get("sigma0"),
            )
        )
    if len({t.target for t in out}) != len(out):
        raise StartError("--targets: two targets share an id")
    return out


def _print(text: str) -> None:
    print(text, flush=True)


@dataclass
class _Setup:
    """What the run is built from, known before any file or port is opened."""

    config: DaemonConfig
    keys: SigningKeys
    scenario: Scenario | None
    wind: WindSpec
    wind_source: str
    sim: EmbeddedVehicles | None
    origin: GeoOrigin | None
    targets: list[ev.TargetAdded]
    out_specs: list[LinkSpec]
    clock: MissionClock
    core: CoreConfig


async def run_daemon(
    config: DaemonConfig,
    *,
    print_fn: Callable[[str], None] = _print,
    on_started: Callable[[Daemon], None] | None = None,
    install_signals: bool = True,
    embedded: EmbeddedFactory | None = None,
) -> Daemon:
    """Run the daemon described by ``config`` until it stops; returns it (for its summary).

    The composition root: what must be released (run files, console, embedded vehicles,
    control server, detection feed) goes on one ``AsyncExitStack``; the daemon is built
    with its collaborators, the services with theirs, and :meth:`Daemon.run` starts them
    all in its one root task group. ``embedded`` builds the vehicles of ``--vehicles
    sim:N`` (the command layer passes the built-in simulator; the daemon never imports it)."""
    setup = _prepare(config, embedded)
    config, sim = setup.config, setup.sim
    async with contextlib.AsyncExitStack() as stack:
        files = _open_files(setup, stack)
        console = OperatorConsole(config.status)
        stack.callback(console.install())  # detached on the way out, whatever fails
        urls = await _start_embedded(sim, stack) if sim else list(config.links.vehicles)
        daemon = _build_daemon(setup, files, urls)
        _journal_start(setup, files, daemon)
        services: list[Service] = [EmbeddedService(sim)] if sim is not None else []
        control = await start_control(config, daemon, print_fn, stack)
        feed = await start_detection_feed(config, daemon, print_fn, stack)
        ship = await start_ship_feed(config, daemon, print_fn, stack)
        services += [ship] if ship is not None else []
        alerts = OperatorAlerts(daemon, feed_counters(feed),
                                silent_after_s=config.links.silent_after_s)
        services += [FnService("alerts", alerts.run), *([control] if control else [])]
        beacon = ship_beacon_service(config, daemon)
        services += [beacon] if beacon is not None else []
        _print_start(setup, files.run_dir, urls, print_fn)
        if install_signals:
            _install_signals(daemon)
        if console.live_table or console.final_table:
            services.append(status_service(daemon, console, alerts))
        if on_started is not None:
            on_started(daemon)
        try:
            with frozen_heap():  # collections skip what existed before the run (gc_guard)
                await daemon.run(services)
        except LinkError as exc:
            raise StartError(str(exc)) from None
        _write_metrics(daemon)
        return daemon


def _prepare(config: DaemonConfig, embedded: EmbeddedFactory | None) -> _Setup:
    """Check and resolve the config, load keys, scenario and targets, build (not start) the
    embedded vehicles, choose the origin and clock: everything before a file or port."""
    check_config(config)
    config = resolve(config)
    keys = load_signing_keys(config)
    scenario = None
    if config.mission.scenario_to_load is not None:
        from world.scenario import load_scenario

        try:
            scenario = load_scenario(config.mission.scenario_to_load)
        except (ValueError, OSError) as exc:
            raise StartError(f"scenario: {exc}") from None
    wind, wind_source = fallback_wind(config, scenario)
    sim: EmbeddedVehicles | None = None
    if config.sim_count is not None:
        if embedded is None:
            raise StartError("vehicles: sim:N needs the built-in simulator (run it with gcs run)")
        sim_keys: dict[int, bytes] = {}
        if not keys.setup:  # with setup they start keyless and are sent the key
            for sysid in range(1, (config.sim_count or 0) + 1):
                key = keys.key_for(sysid)
                if key is not None:
                    sim_keys[sysid] = key
        sim = embedded(config, scenario, sim_keys, wind)
    origin: GeoOrigin | None = None
    if scenario is not None:
        origin = scenario.origin
    elif sim is not None:
        origin = sim.origin
    elif config.mission.origin is not None:
        origin = config.mission.origin
    targets = load_targets(config.mission.targets, origin) if config.mission.targets else []
    from groundstation.link import parse_link_url, parse_out_url

    try:
        for url in [] if sim is not None else config.links.vehicles:
            parse_link_url(url)
        out_specs = [parse_out_url(url) for url in config.links.out]  # MAVProxy's --out
    except LinkUrlError as exc:
        raise StartError(str(exc)) from None
    clock = MissionClock(config.speedup_x, source=sim.now_s if sim is not None else None)
    core = core_config(config, scenario, clock.speedup)
    _warm_up_planner(config.sim_count, scenario, len(targets), core.time_limit_s)
    return _Setup(config, keys, scenario, wind, wind_source, sim, origin, targets, out_specs,
                  clock, core)


def _warm_up_planner(
    sim_count: int | None, scenario: Scenario | None, given_targets: int, time_limit_s: float
) -> None:
    """Load CP-SAT and the LP (~1 CPU-s of imports) before any clock starts, so that no
    mission time passes during them, when the first problem is already known to be beyond
    the DP: the built-in fleet (``sim:N``) against the scenario's and ``--targets``'
    targets. Otherwise the solver runner loads them after the first problem beyond the DP
    (``planner.solve.needs_libraries``), and a run that stays in its range never does."""
    if sim_count is None:  # real vehicles: the fleet is known when they are heard
        return
    known = given_targets
    if scenario is not None and scenario.targets_known:
        known += scenario.target_count
    from planner.solve import needs_libraries, warm_up

    if needs_libraries(sim_count, known, time_limit_s):
        warm_up()


def _open_files(setup: _Setup, stack: contextlib.AsyncExitStack) -> RunFiles:
    try:
        files = open_run_files(setup.config, setup.clock)
    except StorageError as exc:
        raise StartError(str(exc)) from None
    stack.callback(files.close)
    return files


async def _start_embedded(sim: EmbeddedVehicles, stack: contextlib.AsyncExitStack) -> list[str]:
    """Open the embedded vehicles' ports (closed on the way out); their link URLs."""
    try:
        await sim.start()
    except OSError as exc:
        raise StartError(f"simulator: cannot open a port: {exc}") from None
    stack.push_async_callback(sim.close)
    return sim.link_urls()


def _build_daemon(setup: _Setup, files: RunFiles, urls: list[str]) -> Daemon:
    """The daemon with its collaborators: links, signing gate, scenario world."""
    config = setup.config
    try:
        links = [open_link(url, link_id=f"vehicles{i}") for i, url in enumerate(urls)]
        outs = [open_link(spec, link_id=f"out{i}") for i, spec in enumerate(setup.out_specs)]
    except LinkUrlError as exc:
        raise StartError(str(exc)) from None
    signing = (SigningGate(setup.keys, config.links.gcs_system_id)
               if setup.keys.enabled else None)
    daemon: Daemon | None = None

    def sessions() -> Mapping[int, VehicleSession]:
        return daemon.sessions if daemon is not None else {}

    world = (None if setup.scenario is None else ScenarioWorld(
        setup.scenario, config.mission.seed, camera_positions(setup.sim, sessions)))
    daemon = Daemon(config, setup.core, setup.clock, files.run_dir, setup.origin,
                    files.journal, files.tlog, links=links, out_links=outs, signing=signing,
                    world=world, wind_fallback_source=setup.wind_source,
                    link_model=None if setup.sim is None else setup.sim.radio_stats)
    return daemon


def _journal_start(setup: _Setup, files: RunFiles, daemon: Daemon) -> None:
    """The ``start`` line, then the ``--targets`` (refused outside the operating area)."""
    clock, keys, wind = setup.clock, setup.keys, setup.wind
    files.journal.write(
        "start",
        config=files.effective,
        versions=_versions(),
        run_dir=str(files.run_dir),
        speedup=clock.speedup,
        core=config_to_dict(setup.core),
        origin=dataclasses.asdict(setup.origin) if setup.origin else None,
        sim_faults=setup.sim.fault_specs if setup.sim else None,
        scenario=setup.scenario.name if setup.scenario else None,
        wind={**dataclasses.asdict(wind), "source": setup.wind_source},
        signing=(
            {"keys": dict(keys.sources), "setup": keys.setup}
            if keys.enabled
            else None
        ),
    )
    for target in setup.targets:
        if not daemon.inside_area(target.x_m, target.y_m):
            raise StartError(
                f"--targets: target {target.target!r} at ({target.x_m:.0f}, "
                f"{target.y_m:.0f}) m is outside the operating area"
            )
        files.journal.write(
            "target_added",
            target=target.target,
            x_m=target.x_m,
            y_m=target.y_m,
            vx_m_s=target.vx_m_s,
            vy_m_s=target.vy_m_s,
            sigma0=target.sigma0,
            source="file",
        )
        daemon.core_event(target)


def _print_start(setup: _Setup, run_dir: Path, urls: list[str],
                 print_fn: Callable[[str], None]) -> None:
    config, keys = setup.config, setup.keys
    print_fn(
        f"gcs run: run folder {run_dir} (speed-up {setup.clock.speedup:g}x"
        f"{', advisory' if config.advisory else ''})"
    )
    for url in urls:
        print_fn(f"gcs run: vehicles on {url}")
    print_fn(f"gcs run: wind {setup.wind.describe()} ({setup.wind_source}; the "
             "vehicles' own estimate replaces it once they report one)")
    for spec in setup.out_specs:
        print_fn(f"gcs run: out link {spec.canonical}: {describe_out_link(spec)}")
    if keys.enabled:
        who = ", ".join(f"{k} from {v}" for k, v in keys.sources.items())
        print_fn(f"gcs run: MAVLink 2 signing on ({who})"
                 + (", sending SETUP_SIGNING" if keys.setup else ""))


def _install_signals(daemon: Daemon) -> None:
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, daemon.request_stop, sig.name)


class MetricsNotWritten(StartError):
    """``metrics.json`` could not be written (a full disk at the very end): one line, exit
    2; the run itself happened, and :attr:`daemon` has its summary for the console."""

    def __init__(self, message: str, daemon: Daemon) -> None:
        super().__init__(message)
        self.daemon = daemon


def _write_metrics(daemon: Daemon) -> None:
    try:
        atomic_write_text(
            daemon.run_dir / "metrics.json", json.dumps(daemon.metrics_dict(), indent=1) + "\n"
        )
    except StorageError as exc:
        raise MetricsNotWritten(f"metrics.json: {exc}", daemon) from None
