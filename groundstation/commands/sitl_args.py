"""``gcs sitl``'s options: one frozen :class:`SitlOptions`, built and checked once from the
parsed arguments by :func:`sitl_options` (one line per mistake, naming the option), and
shared by the built-in vehicles and the ArduPilot launcher (``groundstation.commands.sitl``
and ``sitl_ardupilot``). ``sitl/`` itself never sees arguments."""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

from domain.errors import UsageError
from domain.radio_spec import RadioSpecError, parse_radio_spec
from groundstation.link.url import LinkKind, LinkUrlError, parse_out_url
from world.wind import WindSpec, parse_wind_text

__all__ = [
    "DEFAULT_DETECTIONS",
    "DEFAULT_HOME",
    "SitlOptions",
    "parse_latlon",
    "parse_udp_url",
    "sitl_options",
]

DEFAULT_HOME = (78.93, 11.92)  # near Ny-Alesund, Svalbard
DEFAULT_DETECTIONS = ("127.0.0.1", 14600)


_SCHEMES = frozenset({"udp", "udpout", "udpin", "tcp", "tcpin", "serial"})
_NOT_SENDING = {
    LinkKind.UDP_IN: "listen",
    LinkKind.TCP_CLIENT: "TCP",
    LinkKind.TCP_SERVER: "TCP server",
    LinkKind.SERIAL: "serial port",
}


def parse_udp_url(text: str, option: str) -> tuple[str, int]:
    """``udp:HOST:PORT``, ``udpout:HOST:PORT`` (MAVProxy's spellings of sending) or
    ``HOST:PORT`` -> (host, port): read as ``--out`` is (``link.url.parse_out_url``, a bare
    ``HOST:PORT`` as ``udpout:``), and only a sending UDP link is accepted (these addresses
    are sent to, so ``udpin:`` and the TCP and serial forms are refused)."""
    stripped = text.strip()
    scheme, _, rest = stripped.partition(":")
    url = stripped if scheme.lower() in _SCHEMES else f"udpout:{stripped}"
    try:
        spec = parse_out_url(url)
    except LinkUrlError as exc:
        problem = str(exc)
        for said in (url, f"udpout:{rest}"):  # parse_out_url reads udp: as udpout:
            problem = problem.removeprefix(f"bad link URL {said!r}: ")
        raise UsageError(f"{option}: expected udp:HOST:PORT, got {text!r} ({problem})") from None
    if spec.kind is not LinkKind.UDP_OUT or spec.host is None or spec.port is None:
        what = _NOT_SENDING.get(spec.kind, spec.kind.value)
        raise UsageError(
            f"{option}: sends to udp:HOST:PORT; {scheme.lower()}: ({what}) is not supported"
        )
    return spec.host, spec.port


def parse_latlon(text: str) -> tuple[float, float]:
    """``LAT,LON`` in degrees."""
    try:
        lat, lon = (float(p) for p in text.split(","))
    except ValueError:
        raise UsageError(f"--home: expected LAT,LON in degrees, got {text!r}") from None
    if not (math.isfinite(lat) and -90 <= lat <= 90 and math.isfinite(lon) and -180 <= lon <= 180):
        raise UsageError(f"--home: latitude/longitude out of range in {text!r}")
    return lat, lon


@dataclass(frozen=True, slots=True)
class SitlOptions:
    """Everything ``gcs sitl`` was told, checked; addresses and home parsed.

    ``detections`` None: no detection feed (``--detections none``); ``home`` None: the
    scenario's launch point, else :data:`DEFAULT_HOME`; ``camera_of`` None: not the
    camera-only mode; ``delay_s`` from ``--delay-ms``; ``wind`` None: the scenario's."""

    count: int | None = None
    speedup: float = 1.0
    seed: int = 0
    scenario: str | None = None
    base_port: int = 5760
    host: str = "127.0.0.1"
    out: tuple[str, int] | None = None
    detections: tuple[str, int] | None = DEFAULT_DETECTIONS
    anonymous_detections: bool = False
    wait_for_client: bool = False
    airborne: bool = False
    alt_m: float = 100.0
    home: tuple[float, float] | None = None
    fast_boot: bool = False
    duration_s: float | None = None
    faults: tuple[str, ...] = ()
    loss: float | None = None
    dup: float | None = None
    reorder: float | None = None
    delay_s: float | None = None
    radio: tuple[str, ...] = ()
    ardupilot: str | None = None
    ardupilot_defaults: str | None = None
    camera_of: tuple[tuple[str, int], ...] | None = None
    signing_key_file: str | None = None
    signing_passphrase_file: str | None = None
    wind: WindSpec | None = None


def _wind(text: str | None) -> WindSpec | None:
    if text is None:
        return None
    return parse_wind_text(text, "--wind")  # a ConfigError: a UsageError too


def _camera_of(text: str) -> tuple[tuple[str, int], ...]:
    endpoints = []
    for part in text.split(","):
        host, sep, port = part.strip().removeprefix("tcp:").rpartition(":")
        if not sep or not host or not port.isdigit():
            raise UsageError(f"--camera-of: expected HOST:PORT[,HOST:PORT...], got {part!r}")
        endpoints.append((host, int(port)))
    return tuple(endpoints)


def sitl_options(args: argparse.Namespace) -> SitlOptions:
    """Check ``gcs sitl``'s parsed arguments and freeze them (raises :class:`UsageError`
    naming the option)."""
    if args.count is not None and not 1 <= args.count <= 250:
        raise UsageError(f"--count: expected 1..250, got {args.count}")
    if not (math.isfinite(args.speedup) and 0 < args.speedup <= 1000):
        raise UsageError(f"--speedup: expected a number in (0, 1000], got {args.speedup}")
    if not 0 <= args.base_port <= 65535 - 10 * 250:
        raise UsageError(f"--base-port: expected 0..{65535 - 2500}, got {args.base_port}")
    if not (math.isfinite(args.alt) and 0 < args.alt < 10000):
        raise UsageError(f"--alt: expected metres in (0, 10000), got {args.alt}")
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        raise UsageError(f"--duration: expected a positive number, got {args.duration}")
    for name in ("loss", "dup", "reorder"):
        value = getattr(args, name)
        if value is not None and not 0 <= value <= 1:
            raise UsageError(f"--{name}: expected a probability in [0, 1], got {value}")
    if args.delay_ms is not None and not (math.isfinite(args.delay_ms) and args.delay_ms >= 0):
        raise UsageError(f"--delay-ms: expected >= 0, got {args.delay_ms}")
    for spec in args.sim_radio:
        try:
            parse_radio_spec(spec)
        except RadioSpecError as exc:
            raise UsageError(f"--sim-radio: {exc}") from None
    if args.sim_radio and (args.ardupilot is not None or args.camera_of is not None):
        raise UsageError("--sim-radio: only for the built-in vehicles (not --ardupilot "
                         "or --camera-of)")
    if args.ardupilot is not None and (args.signing_key or args.signing_passphrase_file):
        raise UsageError("--signing-*: real ArduPilot SITL keeps its own key; "
                         "give it one with `gcs run --signing-setup`")
    if args.signing_key and args.signing_passphrase_file:
        raise UsageError("--signing-key and --signing-passphrase-file: give one, not both")
    return SitlOptions(
        count=args.count,
        speedup=float(args.speedup),
        seed=args.seed,
        scenario=args.scenario,
        base_port=args.base_port,
        host=args.host,
        out=parse_udp_url(args.out, "--out") if args.out else None,
        detections=(
            None if args.detections == "none" else parse_udp_url(args.detections, "--detections")
        ),
        anonymous_detections=args.anonymous_detections,
        wait_for_client=args.wait_for_client,
        airborne=args.airborne,
        alt_m=float(args.alt),
        home=parse_latlon(args.home) if args.home else None,
        fast_boot=args.fast_boot,
        duration_s=args.duration,
        faults=tuple(args.fault),
        loss=args.loss,
        dup=args.dup,
        reorder=args.reorder,
        delay_s=None if args.delay_ms is None else args.delay_ms / 1000.0,
        radio=tuple(args.sim_radio),
        ardupilot=args.ardupilot,
        ardupilot_defaults=args.ardupilot_defaults,
        camera_of=_camera_of(args.camera_of) if args.camera_of is not None else None,
        signing_key_file=args.signing_key,
        signing_passphrase_file=args.signing_passphrase_file,
        wind=_wind(args.wind),
    )
