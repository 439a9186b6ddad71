"""``gcs sitl``'s argument checks, shared by the built-in vehicles and the ArduPilot
launcher (``groundstation.commands.sitl`` and ``sitl_ardupilot``): one line per mistake."""

from __future__ import annotations

import argparse
import math

from domain import errors

__all__ = [
    "DEFAULT_DETECTIONS",
    "DEFAULT_HOME",
    "UsageError",
    "parse_latlon",
    "parse_udp_url",
]

DEFAULT_HOME = (78.93, 11.92)  # near Ny-Alesund, Svalbard
DEFAULT_DETECTIONS = ("127.0.0.1", 14600)


class UsageError(errors.UsageError):
    """Bad command-line value (the message names the option)."""


def parse_udp_url(text: str, option: str) -> tuple[str, int]:
    """``udp:HOST:PORT`` (or ``HOST:PORT``) -> (host, port)."""
    body = text[4:] if text.startswith("udp:") else text
    host, sep, port = body.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise UsageError(f"{option}: expected udp:HOST:PORT, got {text!r}")
    return host, int(port)


def parse_latlon(text: str) -> tuple[float, float]:
    """``LAT,LON`` in degrees."""
    try:
        lat, lon = (float(p) for p in text.split(","))
    except ValueError:
        raise UsageError(f"--home: expected LAT,LON in degrees, got {text!r}") from None
    if not (math.isfinite(lat) and -90 <= lat <= 90 and math.isfinite(lon) and -180 <= lon <= 180):
        raise UsageError(f"--home: latitude/longitude out of range in {text!r}")
    return lat, lon


def _check(args: argparse.Namespace) -> None:
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
