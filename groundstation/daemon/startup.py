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
import secrets
import signal
from collections.abc import Callable
from importlib.metadata import PackageNotFoundError, version
from typing import Any

from domain.errors import ConfigError, UsageError
from domain.geodesy import GeoOrigin
from domain.limits import MAX_COORDINATE_M, MAX_SPEED_M_S, MAX_TARGETS
from domain.yaml_fields import check_number, load_yaml_file
from groundstation.core import events as ev
from groundstation.core.config import CoreConfig, ReplanPolicy, config_to_dict
from groundstation.core.scenario_config import core_config_for
from groundstation.daemon.alerts import OperatorAlerts
from groundstation.daemon.clock import MissionClock
from groundstation.daemon.config import DaemonConfig, resolve
from groundstation.daemon.config_parse import check_config
from groundstation.daemon.console import OperatorConsole
from groundstation.daemon.control.controller import DaemonController
from groundstation.daemon.control.server import ControlLimits, ControlServer, binding_warning
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.embedded import EmbeddedFactory, EmbeddedVehicles
from groundstation.daemon.feed_lines import FeedLines
from groundstation.daemon.gc_guard import frozen_heap
from groundstation.daemon.run_files import open_run_files
from groundstation.daemon.signing_gate import SigningGate, load_signing_keys
from groundstation.daemon.wind_view import fallback_wind
from groundstation.daemon.world import ScenarioWorld
from groundstation.link import LinkError, LinkUrlError, describe_out_link, open_link
from groundstation.link.detection_feed import DetectionFeed
from groundstation.storage import StorageError, atomic_write_text
from groundstation.vehicle.state import LinkState

__all__ = ["StartError", "core_config", "load_targets", "run_daemon"]

log = logging.getLogger(__name__)
MIN_SOLVER_WALL_S = 0.05


class StartError(UsageError):
    """The daemon cannot start (bad input, port in use); one-line message."""


def _versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for name in ("floe", "pymavlink", "ortools", "numpy"):
        try:
            out[name] = version(name)
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
    return dataclasses.replace(
        base,
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
    )


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


async def run_daemon(
    config: DaemonConfig,
    *,
    print_fn: Callable[[str], None] = _print,
    on_started: Callable[[Daemon], None] | None = None,
    install_signals: bool = True,
    embedded: EmbeddedFactory | None = None,
) -> Daemon:
    """Run the daemon described by ``config`` until it stops; returns it (for its summary).

    ``embedded`` builds the vehicles of ``--vehicles sim:N`` (the command layer passes the
    built-in simulator; the daemon itself never imports it)."""
    check_config(config)
    config = resolve(config)
    signing_keys = load_signing_keys(config)
    from planner.solve import warm_up

    warm_up()  # the solver's libraries (~0.6 s of CPU) before any clock starts: no mission time
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
        if not signing_keys.setup:  # with setup they start keyless and are sent the key
            for sysid in range(1, (config.sim_count or 0) + 1):
                key = signing_keys.key_for(sysid)
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
    if sim is not None:
        clock = MissionClock(config.speedup_x, source=sim.now_s)
    else:
        clock = MissionClock(config.speedup_x)
    ccfg = core_config(config, scenario, clock.speedup)
    try:
        files = open_run_files(config, clock)
    except StorageError as exc:
        raise StartError(str(exc)) from None
    run_dir, journal, tlog, effective = files.run_dir, files.journal, files.tlog, files.effective
    console = OperatorConsole(config.status)
    cleanups: list[Callable[[], None]] = []
    daemon = Daemon(config, ccfg, clock, run_dir, origin, journal, tlog)
    daemon.wind_fallback_source = wind_source
    server_started = False
    try:
        cleanups.append(console.install())  # detached in the finally, whatever fails
        if signing_keys.enabled:
            daemon.use_signing(SigningGate(signing_keys, config.links.gcs_system_id))
        if sim is not None:
            try:
                await sim.start()
            except OSError as exc:
                raise StartError(f"simulator: cannot open a port: {exc}") from None
            server_started = True
            urls = sim.link_urls()
            daemon.extra_tasks.append(sim.run)
            daemon.on_finish.append(sim.stop)
            vehicles = sim

            def sim_positions() -> dict[str, tuple[float, float]]:
                out: dict[str, tuple[float, float]] = {}
                for sysid, xy in vehicles.airborne_positions().items():
                    session = daemon.sessions.get(sysid)
                    # a vehicle whose link is down sends no camera data either
                    if session is not None and session.link is not LinkState.LOST:
                        out[session.id] = xy
                return out

            positions: Callable[[], dict[str, tuple[float, float]]] = sim_positions
        else:
            urls = list(config.links.vehicles)

            def telemetry_positions() -> dict[str, tuple[float, float]]:
                out: dict[str, tuple[float, float]] = {}
                for s in daemon.sessions.values():
                    snap = s.snapshot
                    if (
                        snap.x_m is not None
                        and snap.y_m is not None
                        and s.flying()
                        and s.link is not LinkState.LOST
                    ):
                        out[s.id] = (snap.x_m, snap.y_m)
                return out

            positions = telemetry_positions
        if scenario is not None:
            daemon.world = ScenarioWorld(scenario, config.mission.seed, positions)
        try:
            links = [open_link(url, link_id=f"vehicles{i}") for i, url in enumerate(urls)]
            outs = [open_link(spec, link_id=f"out{i}") for i, spec in enumerate(out_specs)]
        except LinkUrlError as exc:
            raise StartError(str(exc)) from None
        journal.write(
            "start",
            config=effective,
            versions=_versions(),
            run_dir=str(run_dir),
            speedup=clock.speedup,
            core=config_to_dict(ccfg),
            origin=dataclasses.asdict(origin) if origin else None,
            sim_faults=sim.fault_specs if sim else None,
            scenario=scenario.name if scenario else None,
            wind={**dataclasses.asdict(wind), "source": wind_source},
            signing=(
                {"keys": dict(signing_keys.sources), "setup": signing_keys.setup}
                if signing_keys.enabled
                else None
            ),
        )
        for target in targets:
            if not daemon.inside_area(target.x_m, target.y_m):
                raise StartError(
                    f"--targets: target {target.target!r} at ({target.x_m:.0f}, "
                    f"{target.y_m:.0f}) m is outside the operating area"
                )
            journal.write(
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
        controller = DaemonController(daemon)
        alerts = OperatorAlerts(daemon)

        async def operator_alerts() -> None:
            await alerts.run()

        daemon.extra_tasks.append(operator_alerts)
        await _start_control(config, daemon, controller, print_fn)
        await _start_detection_feed(config, daemon, alerts, print_fn)
        print_fn(
            f"gcs run: run folder {run_dir} (speed-up {clock.speedup:g}x"
            f"{', advisory' if config.advisory else ''})"
        )
        for url in urls:
            print_fn(f"gcs run: vehicles on {url}")
        print_fn(f"gcs run: wind {wind.describe()} ({wind_source}; the "
                 "vehicles' own estimate replaces it once they report one)")
        for spec in out_specs:
            print_fn(f"gcs run: out link {spec.canonical}: {describe_out_link(spec)}")
        if signing_keys.enabled:
            who = ", ".join(f"{k} from {v}" for k, v in signing_keys.sources.items())
            print_fn(f"gcs run: MAVLink 2 signing on ({who})"
                     + (", sending SETUP_SIGNING" if signing_keys.setup else ""))
        if install_signals:
            loop = asyncio.get_running_loop()
            for sig in (signal.SIGINT, signal.SIGTERM):
                with contextlib.suppress(NotImplementedError, RuntimeError):
                    loop.add_signal_handler(sig, daemon.request_stop, sig.name)
        if console.live_table or console.final_table:
            from groundstation.daemon.status import status_loop

            async def status() -> None:
                await status_loop(daemon, console.out, alerts, live=console.live_table)

            daemon.extra_tasks.append(status)
        if on_started is not None:
            on_started(daemon)
        try:
            with frozen_heap():  # collections skip what existed before the run (gc_guard)
                await daemon.run(links, outs)
        except LinkError as exc:
            raise StartError(str(exc)) from None
        try:
            atomic_write_text(
                run_dir / "metrics.json", json.dumps(daemon.metrics_dict(), indent=1) + "\n"
            )
        except StorageError as exc:
            raise StartError(f"metrics.json: {exc}") from None
        return daemon
    finally:
        for stop in daemon.extra_stops:
            with contextlib.suppress(Exception):
                await stop()
        if sim is not None and server_started:
            await sim.close()
        for cleanup in cleanups:
            cleanup()
        files.close()


async def _start_control(
    config: DaemonConfig,
    daemon: Daemon,
    controller: DaemonController,
    print_fn: Callable[[str], None],
) -> None:
    http = config.http
    if http.bind is None:
        return
    host, port = http.bind.host, http.bind.port
    token = secrets.token_urlsafe(16)
    limits = ControlLimits(
        max_targets=http.max_targets,
        max_ws_clients=http.max_ws_clients,
        max_writes_per_s=http.max_writes_per_s,
        header_timeout_s=http.header_timeout_s,
    )
    server = ControlServer(
        controller, host, port, token, allow_origins=list(http.allow_origins), limits=limits
    )
    try:
        await server.start(push=False)  # the pushes run in the daemon's task tree
    except OSError as exc:
        raise StartError(f"http: cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    daemon.extra_tasks.append(server.run)
    daemon.extra_stops.append(server.stop)
    daemon.control_url = str(getattr(server, "url", f"http://{host}:{port}"))
    daemon.control_token = token
    try:  # it holds the write token: 0600 from its creation on
        atomic_write_text(
            daemon.run_dir / "control.json",
            json.dumps({"url": daemon.control_url, "token": token}),
            mode=0o600,
        )
    except StorageError as exc:
        raise StartError(f"control.json: {exc}") from None
    warning = binding_warning(host)
    if warning is not None:
        print_fn(f"gcs run: {warning}")
    print_fn(f"gcs run: live map {daemon.control_url}/ (open it in a browser; the token "
             f"below lets it command, also in {daemon.run_dir}/control.json)")
    print_fn(
        f"gcs run: control API {daemon.control_url} token {token} "
        f"(gcs target/vehicle find it through {daemon.run_dir / 'control.json'})"
    )


async def _start_detection_feed(
    config: DaemonConfig, daemon: Daemon, alerts: OperatorAlerts,
    print_fn: Callable[[str], None]
) -> None:
    if config.detections is None:
        return
    host, port = config.detections.host, config.detections.port

    feed = DetectionFeed(host, port, FeedLines(daemon))
    alerts.feed_counters = lambda: dataclasses.asdict(feed.counters)
    try:
        await feed.start()
    except OSError as exc:
        raise StartError(
            f"detections: cannot listen on UDP {host}:{port}: {exc.strerror or exc}"
        ) from None
    daemon.extra_stops.append(feed.stop)
    bound_host, bound_port = getattr(feed, "address", (host, port))
    chosen = " (a free port; --detections HOST:PORT to choose)" if port == 0 else ""
    print_fn(f"gcs run: detection feed on udp:{bound_host}:{bound_port}{chosen}")
