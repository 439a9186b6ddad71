"""``gcs run``: the ground-station daemon (closes the loop over MAVLink).

    gcs run --vehicles sim:3 --scenario paper-boat --speedup 20 --duration 200
    gcs run --vehicles tcp:127.0.0.1:5760 tcp:127.0.0.1:5770 --launch --targets ice.yaml
    gcs run --config field.yaml --vehicles /dev/ttyUSB0,57600 --scenario svalbard-2015 --advisory

Every flag can be set in ``--config FILE`` (YAML, the flag's name with underscores); flags
win. Bad input (a bad URL or config key, a port in use) is one line on stderr and exit 2; a
run that never heard a vehicle ends with one error line and exit 1.
See docs/daemon.md.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, Any

from groundstation.commands.async_main import run_async

if TYPE_CHECKING:
    from groundstation.daemon.config import DaemonConfig
    from groundstation.daemon.daemon import Daemon

__all__ = ["EXIT_NO_VEHICLE", "build_config", "run", "run_daemon"]

EXIT_NO_VEHICLE = 1
"""``gcs run``'s exit status when the run ended without ever hearing a vehicle."""


class _RunParser(argparse.ArgumentParser):
    def error(self, message: str) -> Any:  # one line, exit 2 (argparse prints usage too)
        self.exit(2, f"gcs run: error: {message}\n")


def _beacon(text: str) -> int | str:
    """``--ship-beacon``: ``off`` or a system id (checked with the configuration)."""
    if text == "off":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected off or a system id, got {text!r}") from None


def _parser() -> argparse.ArgumentParser:
    from groundstation.daemon.config import Objective, OnExit, ReplanTrigger, StatusMode

    p = _RunParser(
        allow_abbrev=False,
        prog="gcs run",
        description="The floe ground-station daemon: keeps a fleet of "
        "fixed-wing UAVs tracking drifting targets over MAVLink.",
        argument_default=argparse.SUPPRESS,
    )
    a = p.add_argument
    a("--config", metavar="FILE", help="YAML file setting any option below (flags win)")
    a(
        "--vehicles",
        nargs="+",
        metavar="URL",
        help="vehicle links (udpin:/udp:/udpout:/tcp:/tcpin:/serial DEVICE,BAUD) or sim:N "
        "for N built-in simulated vehicles in this process",
    )
    a("--out", nargs="+", metavar="URL", help="forward all traffic to these ground stations")
    a("--scenario", metavar="NAME|FILE", help="simulated targets/boat/detections (a scenario)")
    a(
        "--targets",
        metavar="FILE",
        help="YAML list of targets {id, x_m, y_m | lat_deg, lon_deg, vx_m_s, vy_m_s, sigma0}",
    )
    a("--duration", type=float, metavar="S", help="stop after S mission seconds")
    a(
        "--launch",
        dest="launch",
        action="store_true",
        help="arm and launch vehicles on the ground when ready (default: only sim:N)",
    )
    a(
        "--no-launch",
        dest="launch",
        action="store_false",
        help="never arm a vehicle on the ground (wait for `gcs vehicle launch`)",
    )
    a("--advisory", action="store_true", help="plan and journal, never command a vehicle")
    a(
        "--on-exit",
        choices=[m.value for m in OnExit],
        help="what vehicles do when floe stops (default loiter)",
    )
    a("--http", metavar="HOST:PORT|off", help="control API (default 127.0.0.1:0)")
    a(
        "--http-allow-origin",
        dest="http_allow_origins",
        action="append",
        metavar="URL",
        help="also accept live pages/writes from this origin (scheme://host:port; repeatable)",
    )
    a("--map-tiles", metavar="FILE",
      help="the live map's tiles, offline: a raster MBTiles or PMTiles v3 file (told apart "
           "by content; default: a plain background)")
    a("--http-max-targets", type=int, metavar="N", help="targets the API may add up to (100)")
    a("--http-max-ws-clients", type=int, metavar="N", help="live pages at once (default 16)")
    a("--http-max-writes-per-s", type=float, metavar="R", help="API write rate (default 20)")
    a(
        "--http-header-timeout",
        dest="http_header_timeout_s",
        type=float,
        metavar="S",
        help="a request's headers (then its body) must arrive within S seconds (default 5)",
    )
    a("--detections", metavar="HOST:PORT|off",
      help="detection feed UDP (default 127.0.0.1:14600; with sim:N a free port, printed)")
    a("--ship", metavar="URL",
      help="the ship's NMEA 0183 position/heading: udp:HOST:PORT (listen), tcp:HOST:PORT "
      "(connect) or serial:DEVICE[:BAUD] (default 4800); replaces the scenario's boat")
    a("--ship-silent-after", dest="ship_silent_after_s", type=float, metavar="S",
      help="warn when the ship feed gave no valid fix for S mission seconds (default 10)")
    a("--run-dir", metavar="DIR", help="parent of the run folders (default runs)")
    a("--journal", metavar="FILE", help="journal path (default RUN/journal.jsonl)")
    a("--gcs-system-id", type=int, metavar="ID", help="floe's MAVLink system id (default 245)")
    a("--ship-beacon", type=_beacon, metavar="off|SYSID",
      help="the ship's GLOBAL_POSITION_INT to the vehicles from this system id, for "
      "ArduPilot's FOLL_SYSID (default 17; off: none)")
    a(
        "--speedup",
        type=float,
        metavar="K",
        help="mission clock speed-up: the simulator's for "
        "sim:N (default 50 there), else the vehicles' (default 1)",
    )
    a("--seed", type=int, help="random seed (world, solver, faults)")
    a("--num-workers", type=int, help="CP-SAT workers (default 1)")
    a("--origin", metavar="LAT,LON", help="mission origin (default: scenario, else first fix)")
    a("--altitude", dest="altitude_m", type=float, metavar="M", help="default altitude (100)")
    a("--loiter", dest="loiter_s", type=float, metavar="S", help="timed loiter per visit")
    a(
        "--operating-radius",
        dest="operating_radius_m",
        type=float,
        metavar="M",
        help="operating area radius around home or the boat (default 10000)",
    )
    a(
        "--lost-after",
        dest="lost_after_s",
        type=float,
        metavar="S",
        help="declare a silent vehicle lost after S mission seconds (default 5)",
    )
    a(
        "--lag-threshold",
        dest="lag_threshold_s",
        type=float,
        metavar="S",
        help="a vehicle whose newest position is older than S mission seconds (against its "
        "own clock) while its frames keep arriving is lagging: warned, planned from a "
        "prediction (default 2)",
    )
    a(
        "--rebind-after",
        dest="rebind_after_s",
        type=float,
        metavar="S",
        help="a vehicle's link or address may change only after it was silent there for S "
        "mission seconds and its heartbeats came consistently on the new one (default 10)",
    )
    a(
        "--link-silent-after",
        dest="link_silent_after_s",
        type=float,
        metavar="S",
        help="warn when a vehicle link made no vehicle S wall seconds after its start or "
        "its connect (default 10)",
    )
    a(
        "--link-rate",
        dest="link_rate",
        action="append",
        metavar="URL=BPS",
        help="what a vehicle link carries, bit/s (k: x1000): telemetry and uploads are kept "
        "within it (e.g. tcp:10.0.0.5:5760=64k); a serial link: its baud rate; others "
        "unlimited until a radio reports RADIO_STATUS (docs/links.md)",
    )
    a("--replan", choices=[m.value for m in ReplanTrigger], help="replanning trigger")
    a("--objective", choices=[m.value for m in Objective], help="planner objective (scenario's)")
    a("--period", dest="period_s", type=float, metavar="S", help="replan period")
    a("--upload-min-interval", dest="upload_min_interval_s", type=float, metavar="S",
      help="send a vehicle at most one new mission per S mission seconds; safety "
           "commands are never delayed (scenario's, else 15; 0: none; docs/planner.md)")
    a("--commit", dest="commit", action="store_true", help="keep vehicles on their target")
    a("--no-commit", dest="commit", action="store_false", help="let replans redirect")
    a(
        "--wind",
        metavar="SPEED_M_S,FROM_DEG[,GUST]",
        help="the wind floe plans with until the vehicles report theirs (default: the "
        "scenario's, else still air); with sim:N also the wind they fly in. FROM_DEG is "
        "the compass direction it blows from (10,270: 10 m/s from the west)",
    )
    a("--sim-airborne", action="store_true", help="sim:N vehicles start flying in AUTO")
    a("--sim-loss", type=float, metavar="P", help="sim:N packet loss on every link")
    a("--sim-fault", action="append", metavar="SPEC", help="sim:N fault (gcs sitl --fault)")
    a("--sim-radio", action="append", metavar="SPEC",
      help="sim:N links through a simulated SiK telemetry radio: sik[,baud=,air=,loss=,"
      "burst=,ecc=,window=,buffer=,seed=], [VEHICLES:]... for some vehicles, none (repeatable; "
      "after the scenario's radio:)")
    a(
        "--signing-key",
        dest="signing_key_file",
        metavar="FILE",
        help="sign and check MAVLink 2 frames with every vehicle using this key file "
        "(32 raw bytes or 64 hex digits)",
    )
    a(
        "--signing-passphrase-file",
        metavar="FILE",
        help="as --signing-key with key SHA-256(first line of FILE), as MAVProxy's "
        "`signing setup PASSPHRASE` (or set FLOE_SIGNING_PASSPHRASE)",
    )
    a(
        "--signing-setup",
        action="store_true",
        help="send each signed vehicle its key (SETUP_SIGNING) until it signs, as MAVProxy",
    )
    a(
        "--status",
        choices=[m.value for m in StatusMode],
        help="the console: live table (auto: on an interactive terminal), log lines, or "
        "quiet (warnings and errors only, on stderr)",
    )
    return p


def build_config(argv: list[str]) -> DaemonConfig:
    """Parse ``argv`` (and its ``--config`` file) into the effective, resolved
    :class:`DaemonConfig` (raises ConfigError naming the flag or key)."""
    parser = _parser()
    spelling = {a.dest: a.option_strings[0] for a in reversed(parser._actions) if a.option_strings}
    args = vars(parser.parse_args(argv))
    from groundstation.daemon.config import load_config_file, resolve
    from groundstation.daemon.config_parse import parse_config  # pymavlink, for the fence

    path = args.pop("config", None)
    data = load_config_file(path) if path else {}
    flags = {spelling[dest]: value for dest, value in args.items()}
    return resolve(parse_config(data, flags))


async def run_daemon(config: DaemonConfig, **options: Any) -> Daemon:
    """The daemon with the built-in simulator wired in for ``--vehicles sim:N`` (the
    composition the daemon itself may not do); ``options`` go to
    :func:`groundstation.daemon.startup.run_daemon`."""
    from groundstation.commands.embedded_sim import build_embedded_sim
    from groundstation.daemon.startup import run_daemon as run_bare

    return await run_bare(config, embedded=build_embedded_sim, **options)


def _print_summary(daemon: Daemon) -> None:
    """The run's summary on the console, whatever became of the run's files (a full disk:
    the journal's stop line may be lost, this line never is)."""
    from groundstation.daemon.status import link_lines

    summary = daemon.summary()
    mean = summary.get("mean_uncertainty")
    mean_text = f"{mean:.0f} m^2" if isinstance(mean, (int, float)) else "n/a"
    print(
        f"gcs run: stopped ({daemon.stop_reason or 'done'}) after {summary['mission_s']:.1f} "
        f"mission s; plans {summary['plans']}, uploads {summary['uploads_ok']} ok / "
        f"{summary['uploads_failed']} failed, mean uncertainty "
        f"{mean_text}; run folder {daemon.run_dir}"
    )
    links = summary.get("links")
    for line in link_lines(links if isinstance(links, dict) else {}, only_trouble=True):
        print(f"gcs run: {line}")


def run(argv: list[str]) -> int:
    """Entry point of ``gcs run``; returns the exit status. The arguments are checked before
    the daemon is imported, so ``--help`` and a mistyped flag answer at once."""
    from domain.errors import ConfigError

    try:
        config = build_config(argv)
    except ConfigError as exc:
        print(f"gcs run: error: {exc}", file=sys.stderr)
        return 2
    from groundstation.daemon.alerts import never_heard
    from groundstation.daemon.startup import MetricsNotWritten, StartError

    try:
        daemon = run_async(lambda: run_daemon(config))
    except MetricsNotWritten as exc:  # the run happened: its summary, then the error
        _print_summary(exc.daemon)
        print(f"gcs run: error: {exc}", file=sys.stderr)
        return 2
    except (StartError, ConfigError) as exc:
        print(f"gcs run: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    if daemon.internal_error is not None:
        print(
            f"gcs run: error: {daemon.internal_error} (a bug: please report it with "
            f"{daemon.run_dir}/gcs.log and journal.jsonl; the vehicles keep their last mission)",
            file=sys.stderr,
        )
        return 70
    _print_summary(daemon)
    silent = never_heard(daemon)
    if silent is not None:
        print(f"gcs run: error: {silent}; nothing was flown (see the warnings above and "
              f"{daemon.run_dir}/gcs.log)", file=sys.stderr)
        return EXIT_NO_VEHICLE
    return 0
