"""The services of ``gcs run`` that need starting before the daemon runs (the control API's
server, the detection feed's listener), the status display, and where the scenario's camera
sees from. Used by the composition root, :func:`groundstation.daemon.startup.run_daemon`;
what each starts goes on its ``AsyncExitStack``."""

from __future__ import annotations

import contextlib
import dataclasses
import json
import secrets
from collections.abc import Awaitable, Callable, Mapping

from domain.errors import UsageError
from groundstation.daemon.alerts import OperatorAlerts
from groundstation.daemon.config import DaemonConfig
from groundstation.daemon.console import OperatorConsole
from groundstation.daemon.control.controller import DaemonController
from groundstation.daemon.control.server import ControlLimits, ControlServer, binding_warning
from groundstation.daemon.control.tiles import TileArchive, TilesError
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.embedded import EmbeddedVehicles
from groundstation.daemon.feed_lines import FeedHost, FeedLines
from groundstation.daemon.services import FnService, Service
from groundstation.daemon.session import VehicleSession
from groundstation.daemon.ship_beacon import BeaconClock, ShipBeacon
from groundstation.daemon.ship_feed import ShipFeed, ShipFeedHost
from groundstation.link.detection_feed import DetectionFeed
from groundstation.link.nmea_source import describe_ship_source, parse_ship_url
from groundstation.link.url import LinkUrlError
from groundstation.storage import StorageError, atomic_write_text
from groundstation.vehicle.state import LinkState

__all__ = ["StartError", "camera_positions", "feed_counters", "ship_beacon_service",
           "start_control", "start_detection_feed", "start_ship_feed", "status_service"]


class StartError(UsageError):
    """The daemon cannot start (bad input, port in use); one-line message."""


def camera_positions(
    sim: EmbeddedVehicles | None, sessions: Callable[[], Mapping[int, VehicleSession]]
) -> Callable[[], dict[str, tuple[float, float]]]:
    """Where the scenario's camera sees from: the embedded vehicles' true positions, else
    the vehicles' telemetry; a vehicle whose link is down sends no camera data either."""

    def sim_positions() -> dict[str, tuple[float, float]]:
        assert sim is not None
        out: dict[str, tuple[float, float]] = {}
        for sysid, xy in sim.airborne_positions().items():
            session = sessions().get(sysid)
            if session is not None and session.link is not LinkState.LOST:
                out[session.id] = xy
        return out

    def telemetry_positions() -> dict[str, tuple[float, float]]:
        out: dict[str, tuple[float, float]] = {}
        for s in sessions().values():
            x_m, y_m = s.snapshot.x_m, s.snapshot.y_m
            if x_m is None or y_m is None:
                continue
            if s.flying() and s.link is not LinkState.LOST:
                out[s.id] = (x_m, y_m)
        return out

    return sim_positions if sim is not None else telemetry_positions


def status_service(daemon: Daemon, console: OperatorConsole, alerts: OperatorAlerts) -> Service:
    from groundstation.daemon.status import status_loop

    async def status() -> None:
        await status_loop(daemon, console.out, alerts, live=console.live_table)

    return FnService("status", status)


def ship_beacon_service(config: DaemonConfig, daemon: Daemon) -> Service | None:
    """The ship's beacon (``links.ship_beacon``), unless off or advisory (which sends nothing
    but heartbeats)."""
    sysid = config.links.ship_beacon
    if sysid is None or config.advisory:
        return None
    beacon = ShipBeacon(
        sysid,
        daemon.core.ship,
        lambda: daemon.origin_or_none,
        daemon.router.broadcast,
        BeaconClock(daemon.clock.now_s, daemon.clock.wall_s),
        lambda: daemon.sessions.keys(),
        daemon.journal,
    )
    return FnService(beacon.name, beacon.run)


def feed_counters(feed: DetectionFeed | None) -> Callable[[], Mapping[str, int]] | None:
    """The detection feed's counters for the alerts (None without a feed)."""
    if feed is None:
        return None
    return lambda: dataclasses.asdict(feed.counters)


async def stop_quietly(stop: Callable[[], Awaitable[None]]) -> None:
    with contextlib.suppress(Exception):
        await stop()


async def start_control(
    config: DaemonConfig,
    daemon: Daemon,
    print_fn: Callable[[str], None],
    stack: contextlib.AsyncExitStack,
) -> Service | None:
    """The control API's server, listening (stopped on the way out), as a service."""
    http = config.http
    if http.bind is None:
        return None
    host, port = http.bind.host, http.bind.port
    token = secrets.token_urlsafe(16)
    limits = ControlLimits(
        max_targets=http.max_targets,
        max_ws_clients=http.max_ws_clients,
        max_writes_per_s=http.max_writes_per_s,
        header_timeout_s=http.header_timeout_s,
    )
    tiles = None
    if http.map_tiles is not None:
        try:
            tiles = TileArchive(http.map_tiles)
        except TilesError as exc:
            raise StartError(str(exc)) from None
        stack.callback(tiles.close)
    server = ControlServer(DaemonController(daemon), host, port, token, tiles=tiles,
                           allow_origins=list(http.allow_origins), limits=limits)
    try:
        await server.start(push=False)  # the pushes run in the daemon's task tree
    except OSError as exc:
        raise StartError(f"http: cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    stack.push_async_callback(stop_quietly, server.stop)
    daemon.control_url = url = str(getattr(server, "url", f"http://{host}:{port}"))
    try:  # it holds the write token: 0600 from its creation on
        atomic_write_text(
            daemon.run_dir / "control.json",
            json.dumps({"url": url, "token": token}),
            mode=0o600,
        )
    except StorageError as exc:
        raise StartError(f"control.json: {exc}") from None
    warning = binding_warning(host)
    if warning is not None:
        print_fn(f"gcs run: {warning}")
    print_fn(f"gcs run: live map {url}/ (open it in a browser; the token "
             f"below lets it command, also in {daemon.run_dir}/control.json)")
    print_fn(
        f"gcs run: control API {url} token {token} "
        f"(gcs target/vehicle find it through {daemon.run_dir / 'control.json'})"
    )
    return FnService("control", server.run)


async def start_detection_feed(
    config: DaemonConfig, host_: FeedHost, print_fn: Callable[[str], None],
    stack: contextlib.AsyncExitStack,
) -> DetectionFeed | None:
    """The detection feed's UDP listener (stopped on the way out); it has no task."""
    if config.detections is None:
        return None
    host, port = config.detections.host, config.detections.port

    feed = DetectionFeed(host, port, FeedLines(host_))
    try:
        await feed.start()
    except OSError as exc:
        raise StartError(
            f"detections: cannot listen on UDP {host}:{port}: {exc.strerror or exc}"
        ) from None
    stack.push_async_callback(stop_quietly, feed.stop)
    bound_host, bound_port = getattr(feed, "address", (host, port))
    chosen = " (a free port; --detections HOST:PORT to choose)" if port == 0 else ""
    print_fn(f"gcs run: detection feed on udp:{bound_host}:{bound_port}{chosen}")
    return feed


async def start_ship_feed(
    config: DaemonConfig, host_: ShipFeedHost, print_fn: Callable[[str], None],
    stack: contextlib.AsyncExitStack,
) -> ShipFeed | None:
    """The ship's NMEA feed (``--ship``): a UDP listener bound now, a TCP or serial stream
    opened by its service; closed, and its counters journalled, on the way out."""
    ship = config.ship
    if ship.url is None:
        return None
    try:
        spec = parse_ship_url(ship.url)
    except LinkUrlError as exc:
        raise StartError(f"ship: {exc}") from None
    feed = ShipFeed(host_, spec, silent_after_s=ship.silent_after_s, max_age_s=ship.max_age_s)
    try:
        await feed.start()
    except OSError as exc:
        raise StartError(f"ship: cannot listen on UDP {spec.host}:{spec.port}: "
                         f"{exc.strerror or exc}") from None
    stack.callback(feed.journal_summary)  # before the run files close (pushed after them)
    stack.push_async_callback(stop_quietly, feed.stop)
    print_fn(f"gcs run: ship feed (NMEA 0183) {spec.canonical}: "
             f"{describe_ship_source(spec, feed.source.address)}")
    return feed
