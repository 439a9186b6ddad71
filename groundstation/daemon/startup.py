"""Building and running a :class:`~groundstation.daemon.daemon.Daemon` from its config.

Order: scenario, embedded simulator (``sim:N``), mission origin and clock, run folder
(``runs/<UTC timestamp>/`` with ``journal.jsonl``, ``flight.tlog``, ``config.yaml``,
``gcs.log``, ``metrics.json`` at the end), core configuration, links, optional control API
and detection feed, then the daemon until it stops. Anything wrong with the input is a
:class:`StartError` (one line, exit 2).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import datetime
import json
import logging
import math
import platform
import secrets
import signal
import sys
from collections.abc import Callable
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import yaml

from groundstation.core import events as ev
from groundstation.core.config import CoreConfig, ReplanPolicy
from groundstation.daemon.clock import MissionClock
from groundstation.daemon.config import DaemonConfig, parse_hostport, parse_latlon
from groundstation.daemon.control import DaemonController
from groundstation.daemon.control_server import ControlServer, binding_warning
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.journal import Journal
from groundstation.daemon.world import ScenarioWorld
from groundstation.detection_feed import DetectionFeed
from groundstation.link import LinkError, LinkUrlError, TlogWriter, open_link
from groundstation.mavlink.geodesy import GeoOrigin

__all__ = ["StartError", "core_config", "load_targets", "run_daemon"]

log = logging.getLogger(__name__)
MIN_SOLVER_WALL_S = 0.05


class StartError(Exception):
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
    config. The solver's wall budget is the time limit divided by the speed-up, so a plan
    takes the same mission time at any speed-up (floor 0.05 s)."""
    if scenario is not None:
        from groundstation.runners.simulate import core_config_for

        base = core_config_for(scenario)
    else:
        base = CoreConfig()
    policy = base.policy
    if config.replan is not None or config.period_s is not None or config.commit is not None:
        replan = config.replan or (
            "event"
            if policy.on_events and policy.period_s is None
            else "period"
            if not policy.on_events
            else "both"
        )
        period = config.period_s if config.period_s is not None else policy.period_s
        commit = config.commit if config.commit is not None else policy.commit
        try:
            policy = ReplanPolicy.from_names(replan, period, commit)
        except ValueError as exc:
            raise StartError(f"replan: {exc}") from None
    limit = config.solver_time_limit_s or base.time_limit_s
    return dataclasses.replace(
        base,
        policy=policy,
        loiter_s=config.loiter_s if config.loiter_s is not None else base.loiter_s,
        loiter_radius_m=(
            config.loiter_radius_m if config.loiter_radius_m is not None else base.loiter_radius_m
        ),
        battery_low_action=config.battery_low_action,
        time_limit_s=max(MIN_SOLVER_WALL_S, limit / speedup),
    )


def load_targets(path: str, origin: GeoOrigin | None) -> list[ev.TargetAdded]:
    """``--targets FILE``: a YAML list of {id, x_m, y_m | lat_deg, lon_deg, vx_m_s, vy_m_s,
    sigma0}; errors name the entry and key."""
    try:
        data = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise StartError(f"--targets: cannot read {path}: {exc.strerror or exc}") from None
    except yaml.YAMLError:
        raise StartError(f"--targets: {path} is not valid YAML") from None
    if not isinstance(data, list):
        raise StartError(f"--targets: {path} must hold a list of targets")
    keys = {"id", "x_m", "y_m", "lat_deg", "lon_deg", "vx_m_s", "vy_m_s", "sigma0"}
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
                if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                    raise StartError(f"{where} ({tid}): {key} must be a finite number")
                values[key] = float(v)
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


def make_run_dir(base: str) -> Path:
    stamp = datetime.datetime.now(datetime.UTC).strftime("%Y%m%dT%H%M%SZ")
    root = Path(base)
    path = root / stamp
    k = 1
    while path.exists():
        k += 1
        path = root / f"{stamp}-{k}"
    try:
        path.mkdir(parents=True)
    except OSError as exc:
        raise StartError(f"run_dir: cannot create {path}: {exc.strerror or exc}") from None
    return path


def _setup_logging(run_dir: Path) -> logging.Handler:
    handler = logging.FileHandler(run_dir / "gcs.log", encoding="utf-8")
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    handler.setLevel(logging.INFO)
    root = logging.getLogger()
    root.addHandler(handler)
    if root.level > logging.INFO or root.level == logging.NOTSET:
        root.setLevel(logging.INFO)
    return handler


def _print(text: str) -> None:
    print(text, flush=True)


async def run_daemon(
    config: DaemonConfig,
    *,
    print_fn: Callable[[str], None] = _print,
    on_started: Callable[[Daemon], None] | None = None,
    install_signals: bool = True,
) -> Daemon:
    """Run the daemon described by ``config`` until it stops; returns it (for its summary)."""
    config.validate()
    config.resolve_defaults()
    scenario = None
    if config.scenario is not None:
        from sitl.scenario import load_scenario

        try:
            scenario = load_scenario(config.scenario)
        except (ValueError, OSError) as exc:
            raise StartError(f"scenario: {exc}") from None
    sim = None
    if config.sim_count is not None:
        from groundstation.daemon.embedded_sim import build_embedded_sim

        sim = build_embedded_sim(config, scenario)
    origin: GeoOrigin | None = None
    if scenario is not None:
        origin = scenario.origin
    elif sim is not None:
        origin = sim.origin
    elif config.origin is not None:
        origin = GeoOrigin(*parse_latlon(config.origin, "origin"))
    targets = load_targets(config.targets, origin) if config.targets else []
    from groundstation.link import parse_link_url

    for url in [*([] if sim is not None else config.vehicles), *config.out]:
        try:
            parse_link_url(url)
        except LinkUrlError as exc:
            raise StartError(str(exc)) from None
    if sim is not None:
        server = sim.server
        clock = MissionClock(config.speedup, source=lambda: server.t_s)
    else:
        clock = MissionClock(config.speedup)
    ccfg = core_config(config, scenario, clock.speedup)
    run_dir = make_run_dir(config.run_dir)
    handler = _setup_logging(run_dir)
    journal = Journal(
        Path(config.journal) if config.journal else run_dir / "journal.jsonl",
        clock.now_s,
        clock.unix_s,
    )
    tlog = TlogWriter(run_dir / "flight.tlog")
    effective = config.to_dict()
    (run_dir / "config.yaml").write_text(
        yaml.safe_dump(effective, sort_keys=False), encoding="utf-8"
    )
    daemon = Daemon(config, ccfg, clock, run_dir, origin, journal, tlog)
    server_started = False
    cleanups: list[Callable[[], None]] = []
    try:
        if sim is not None:
            try:
                await sim.server.start()
            except OSError as exc:
                raise StartError(f"simulator: cannot open a port: {exc}") from None
            server_started = True
            urls = [f"tcp:127.0.0.1:{port}" for port in sim.server.tcp_ports]

            async def simulator() -> None:
                await sim.server.run()

            daemon.extra_tasks.append(simulator)
            daemon.on_finish.append(sim.server.stop)

            def sim_positions() -> dict[str, tuple[float, float]]:
                out: dict[str, tuple[float, float]] = {}
                for v in sim.server.vehicles():
                    session = daemon.sessions.get(v.system_id)
                    # a vehicle whose link is down sends no camera data either
                    if session is not None and not v.airframe.on_ground and session.link != "lost":
                        out[session.id] = (v.airframe.x_m, v.airframe.y_m)
                return out

            positions: Callable[[], dict[str, tuple[float, float]]] = sim_positions
        else:
            urls = list(config.vehicles)

            def telemetry_positions() -> dict[str, tuple[float, float]]:
                out: dict[str, tuple[float, float]] = {}
                for s in daemon.sessions.values():
                    snap = s.snapshot
                    if (
                        snap.x_m is not None
                        and snap.y_m is not None
                        and s.flying()
                        and s.link != "lost"
                    ):
                        out[s.id] = (snap.x_m, snap.y_m)
                return out

            positions = telemetry_positions
        if scenario is not None:
            daemon.world = ScenarioWorld(scenario, config.seed, positions)
        try:
            links = [open_link(url, link_id=f"vehicles{i}") for i, url in enumerate(urls)]
            outs = [open_link(url, link_id=f"out{i}") for i, url in enumerate(config.out)]
        except LinkUrlError as exc:
            raise StartError(str(exc)) from None
        journal.write(
            "start",
            config=effective,
            versions=_versions(),
            run_dir=str(run_dir),
            speedup=clock.speedup,
            core=_core_dict(ccfg),
            origin=dataclasses.asdict(origin) if origin else None,
            sim_faults=sim.fault_specs if sim else None,
            scenario=scenario.name if scenario else None,
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
        await _start_control(config, daemon, controller, print_fn)
        await _start_detection_feed(config, daemon, print_fn)
        print_fn(
            f"gcs run: run folder {run_dir} (speed-up {clock.speedup:g}x"
            f"{', advisory' if config.advisory else ''})"
        )
        for url in urls:
            print_fn(f"gcs run: vehicles on {url}")
        if install_signals:
            loop = asyncio.get_running_loop()
            for sig in (signal.SIGINT, signal.SIGTERM):
                with contextlib.suppress(NotImplementedError, RuntimeError):
                    loop.add_signal_handler(sig, daemon.request_stop, sig.name)
        if not _use_table(config) and config.status != "quiet":
            console = logging.StreamHandler(sys.stdout)
            console.setFormatter(logging.Formatter("gcs run: %(message)s"))
            console.setLevel(logging.INFO)
            daemon_log = logging.getLogger("groundstation.daemon.daemon")
            daemon_log.addHandler(console)
            cleanups.append(lambda: daemon_log.removeHandler(console))
        if _use_table(config):
            from groundstation.daemon.status import status_loop

            async def status() -> None:
                await status_loop(daemon)

            daemon.extra_tasks.append(status)
        if on_started is not None:
            on_started(daemon)
        try:
            await daemon.run(links, outs)
        except LinkError as exc:
            raise StartError(str(exc)) from None
        (run_dir / "metrics.json").write_text(
            json.dumps(daemon.metrics_dict(), indent=1), encoding="utf-8"
        )
        return daemon
    finally:
        for stop in daemon.extra_stops:
            with contextlib.suppress(Exception):
                await stop()
        if sim is not None and server_started:
            await sim.server.close()
        for cleanup in cleanups:
            cleanup()
        journal.close()
        tlog.close()
        logging.getLogger().removeHandler(handler)
        handler.close()


def _core_dict(ccfg: CoreConfig) -> dict[str, Any]:
    out = dataclasses.asdict(ccfg)
    return out


def _use_table(config: DaemonConfig) -> bool:
    if config.status == "table":
        return True
    if config.status == "log":
        return False
    return sys.stdout.isatty()


async def _start_control(
    config: DaemonConfig,
    daemon: Daemon,
    controller: DaemonController,
    print_fn: Callable[[str], None],
) -> None:
    if config.http == "off":
        return
    host, port = parse_hostport(config.http, "http")
    token = secrets.token_urlsafe(16)
    server = ControlServer(controller, host, port, token)
    try:
        await server.start()
    except OSError as exc:
        raise StartError(f"http: cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    daemon.extra_stops.append(server.stop)
    daemon.control_url = str(getattr(server, "url", f"http://{host}:{port}"))
    daemon.control_token = token
    (daemon.run_dir / "control.json").write_text(
        json.dumps({"url": daemon.control_url, "token": token}), encoding="utf-8"
    )
    warning = binding_warning(host)
    if warning is not None:
        print_fn(f"gcs run: {warning}")
    print_fn(
        f"gcs run: control API {daemon.control_url} token {token} "
        f"(for gcs target/vehicle: export FLOE_API={daemon.control_url} "
        f"FLOE_TOKEN={token})"
    )


async def _start_detection_feed(
    config: DaemonConfig, daemon: Daemon, print_fn: Callable[[str], None]
) -> None:
    if config.detections == "off":
        return
    host, port = parse_hostport(config.detections, "detections")

    def on_detection(item: Any) -> None:
        _feed_detection(daemon, item)

    feed = DetectionFeed(host, port, on_detection)
    try:
        await feed.start()
    except OSError as exc:
        raise StartError(
            f"detections: cannot listen on UDP {host}:{port}: {exc.strerror or exc}"
        ) from None
    daemon.extra_stops.append(feed.stop)
    bound_host, bound_port = getattr(feed, "address", (host, port))
    daemon.detection_address = (bound_host, bound_port)
    print_fn(f"gcs run: detection feed on udp:{bound_host}:{bound_port}")


def _field(item: Any, name: str) -> Any:
    return item.get(name) if isinstance(item, dict) else getattr(item, name, None)


def _feed_detection(daemon: Daemon, item: Any) -> None:
    """One line of the detection feed (design.md) -> the core (boat or detection)."""
    lat, lon = _field(item, "lat_deg"), _field(item, "lon_deg")
    if daemon.origin_or_none is None or lat is None or lon is None:
        daemon.detections_dropped += 1
        return
    x, y, _ = daemon.origin.to_local(float(lat), float(lon))
    t = daemon.clock.now_s()
    if _field(item, "kind") == "boat":
        daemon.boat_xy_m = (x, y)
        daemon.core.set_boat(x, y)
        return
    sysid = _field(item, "vehicle")
    session = daemon.sessions.get(int(sysid)) if isinstance(sysid, int) else None
    sigma = _field(item, "sigma_m")
    r = float(sigma) ** 2 if isinstance(sigma, int | float) and sigma > 0 else None
    target = _field(item, "target")
    daemon.add_detection(
        ev.Detection(
            t, session.id if session else None, str(target) if target is not None else None, x, y, r
        )
    )
