"""The detection feed: JSON lines over UDP (design.md, "Interfaces"), receiver and encoder.

One object per line, one or more lines per datagram (UTF-8, ``\\n``-separated)::

    {"v": 1, "kind": "detection", "time_s": 12.5, "vehicle": 2, "target": "A",
     "lat_deg": 78.93, "lon_deg": 11.95, "sigma_m": 2.236}
    {"v": 1, "kind": "boat", "time_s": 13.0, "vehicle": null, "target": null,
     "lat_deg": 78.92, "lon_deg": 11.90, "sigma_m": 0.0}

    {"v": 1, "kind": "frame", "time_s": 12.5, "vehicle": 2, "target": null,
     "lat_deg": 78.93, "lon_deg": 11.95, "sigma_m": 0.0, "radius_m": 150.0}

``time_s`` is the sender's clock (seconds; the simulator's mission time); ``vehicle`` the
seeing vehicle's MAVLink system id (1-255) or null; ``target`` an id or null (the observer
associates it); ``sigma_m`` the measurement's standard deviation per axis (m, >= 0).
A ``frame`` line says the camera took a frame whose footprint is the disc of ``radius_m``
(finite, > 0, at most ``MAX_FOOTPRINT_RADIUS_M``) around ``lat_deg, lon_deg``; its
detections (none if it saw nothing) follow it in the same datagram with the same ``time_s``
and ``vehicle``. A frame in view of a track without a detection of it is evidence that the
track is not there. A frame's ``target`` is null; ``radius_m`` is ignored on other kinds.
Other keys are ignored (forward compatibility); a missing or wrong required key, ``v`` other
than 1, non-finite numbers, latitude/longitude out of range, a frame without a finite
positive ``radius_m`` or with a target, bad UTF-8 or a line longer than ``MAX_LINE_BYTES``
make the line **malformed**.

A well-formed line is then checked in time, per stream (``kind``, ``vehicle``):

* **out of order**: ``time_s`` earlier than the last accepted line of the same stream
  (equal times are fine: one camera tick sees several targets);
* **late**: ``reference - time_s > max_delay_s``, where ``reference`` is ``clock()`` when
  a clock (the same time base as the sender, e.g. the daemon's mission clock) is given,
  else the newest ``time_s`` accepted from any stream.

Dropped lines are counted in :class:`FeedCounters`, never raised. Lines are checked in the
order above, so each dropped line counts once.
"""

from __future__ import annotations

import asyncio
import dataclasses
import json
import logging
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

from domain.errors import DataError

__all__ = [
    "DEFAULT_ADDRESS",
    "DetectionFeed",
    "FeedCounters",
    "FeedDetection",
    "FeedError",
    "FeedFilter",
    "encode_detection",
    "encode_frame",
    "parse_line",
]

log = logging.getLogger(__name__)

DEFAULT_ADDRESS = ("127.0.0.1", 14600)
MAX_LINE_BYTES = 4096
KINDS = ("detection", "boat", "frame")
MAX_FOOTPRINT_RADIUS_M = 10_000.0
"""A frame's ``radius_m`` above this is garbage (a camera at 120 m sees ~150 m around)."""


class FeedError(DataError):
    """A malformed feed line (the message names the field)."""


@dataclass(frozen=True)
class FeedDetection:
    """One accepted line of the feed (``radius_m``: a frame's footprint, else None)."""

    time_s: float
    kind: str
    vehicle: int | None
    target: str | None
    lat_deg: float
    lon_deg: float
    sigma_m: float
    radius_m: float | None = None


@dataclass
class FeedCounters:
    """What the receiver did with every line it got."""

    datagrams: int = 0
    accepted: int = 0
    late: int = 0
    out_of_order: int = 0
    malformed: int = 0
    callback_errors: int = 0

    def as_dict(self) -> dict[str, int]:
        return asdict(self)


def _finite(obj: dict[str, Any], key: str, lo: float | None = None,
            hi: float | None = None) -> float:
    if key not in obj:
        raise FeedError(f"{key}: missing")
    value = obj[key]
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise FeedError(f"{key}: expected a number")
    number = float(value)
    if not math.isfinite(number):
        raise FeedError(f"{key}: not finite")
    if (lo is not None and number < lo) or (hi is not None and number > hi):
        raise FeedError(f"{key}: {number:g} out of range [{lo:g}, {hi:g}]")
    return number


def _vehicle(value: Any) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 255:
        raise FeedError("vehicle: expected a system id 1-255 or null")
    return value


def _target(value: Any) -> str | None:
    if value is None:
        return None
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    if not isinstance(value, str) or not value or len(value) > 64:
        raise FeedError("target: expected an id (string) or null")
    return value


def parse_line(line: bytes | str) -> FeedDetection:
    """One feed line -> :class:`FeedDetection`; raises :class:`FeedError` if malformed."""
    if isinstance(line, bytes):
        if len(line) > MAX_LINE_BYTES:
            raise FeedError(f"line: longer than {MAX_LINE_BYTES} bytes")
        try:
            line = line.decode("utf-8")
        except UnicodeDecodeError:
            raise FeedError("line: not UTF-8") from None
    elif len(line) > MAX_LINE_BYTES:
        raise FeedError(f"line: longer than {MAX_LINE_BYTES} characters")
    try:
        obj = json.loads(line)
    except (json.JSONDecodeError, RecursionError):
        raise FeedError("line: not JSON") from None
    if not isinstance(obj, dict):
        raise FeedError("line: not a JSON object")
    if obj.get("v") != 1 or isinstance(obj.get("v"), bool):
        raise FeedError(f"v: expected 1, got {json.dumps(obj.get('v'))[:20]}")
    kind = obj.get("kind")
    if kind not in KINDS:
        raise FeedError(f"kind: expected one of {', '.join(KINDS)}")
    det = FeedDetection(
        time_s=_finite(obj, "time_s"),
        kind=str(kind),
        vehicle=_vehicle(obj.get("vehicle")),
        target=_target(obj.get("target")),
        lat_deg=_finite(obj, "lat_deg", -90.0, 90.0),
        lon_deg=_finite(obj, "lon_deg", -180.0, 180.0),
        sigma_m=_finite(obj, "sigma_m", 0.0, math.inf),
    )
    if kind != "frame":
        return det
    if det.target is not None:
        raise FeedError("target: must be null for a frame")
    radius_m = _finite(obj, "radius_m", 0.0, MAX_FOOTPRINT_RADIUS_M)
    if radius_m <= 0.0:
        raise FeedError("radius_m: must be > 0 for a frame")
    return dataclasses.replace(det, radius_m=radius_m)


def encode_detection(time_s: float, lat_deg: float, lon_deg: float, *,
                     kind: str = "detection", vehicle: int | None = None,
                     target: str | None = None, sigma_m: float = 0.0,
                     radius_m: float | None = None) -> bytes:
    """One feed line (with its ``\\n``) for senders; raises :class:`FeedError` on values the
    receiver would drop as malformed. ``radius_m`` is written when given (frames need it)."""
    obj: dict[str, Any] = {"v": 1, "kind": kind, "time_s": time_s, "vehicle": vehicle,
                           "target": target, "lat_deg": lat_deg, "lon_deg": lon_deg,
                           "sigma_m": sigma_m}
    if radius_m is not None:
        obj["radius_m"] = radius_m
    line = (json.dumps(obj, allow_nan=True) + "\n").encode("utf-8")
    parse_line(line[:-1])  # same rules as the receiver
    return line


def encode_frame(time_s: float, lat_deg: float, lon_deg: float, radius_m: float, *,
                 vehicle: int | None = None) -> bytes:
    """A ``frame`` line: the camera of ``vehicle`` took a frame of the disc of
    ``radius_m`` around ``lat_deg, lon_deg`` at ``time_s`` (its detections follow)."""
    return encode_detection(time_s, lat_deg, lon_deg, kind="frame", vehicle=vehicle,
                            radius_m=radius_m)


class FeedFilter:
    """Sans-IO: the malformed / out-of-order / late decision and the counters."""

    def __init__(self, max_delay_s: float = 5.0, clock: Callable[[], float] | None = None
                 ) -> None:
        if not (math.isfinite(max_delay_s) and max_delay_s >= 0.0):
            raise ValueError(f"max_delay_s must be finite and >= 0, got {max_delay_s}")
        self.max_delay_s = max_delay_s
        self.clock = clock
        self.counters = FeedCounters()
        self.last_reason: str | None = None
        self._last: dict[tuple[str, int | None], float] = {}
        self._newest: float | None = None

    def feed(self, datagram: bytes) -> list[FeedDetection]:
        """Every accepted detection of one datagram, in order."""
        self.counters.datagrams += 1
        out: list[FeedDetection] = []
        for raw in datagram.split(b"\n"):
            if not raw.strip():
                continue
            det = self.check(raw)
            if det is not None:
                out.append(det)
        return out

    def check(self, line: bytes | str) -> FeedDetection | None:
        """The line's detection if accepted, else None (and the drop is counted)."""
        try:
            det = parse_line(line)
        except FeedError as exc:
            self.counters.malformed += 1
            self.last_reason = f"malformed: {exc}"
            return None
        stream = (det.kind, det.vehicle)
        last = self._last.get(stream)
        if last is not None and det.time_s < last:
            self.counters.out_of_order += 1
            self.last_reason = (f"out of order: {det.kind} vehicle {det.vehicle} at "
                                f"{det.time_s:g} s after {last:g} s")
            return None
        reference = self.clock() if self.clock is not None else self._newest
        if reference is not None and reference - det.time_s > self.max_delay_s:
            self.counters.late += 1
            self.last_reason = f"late: {det.time_s:g} s, now {reference:g} s"
            return None
        self._last[stream] = det.time_s
        self._newest = det.time_s if self._newest is None else max(self._newest, det.time_s)
        self.counters.accepted += 1
        return det


class _Protocol(asyncio.DatagramProtocol):
    def __init__(self, feed: DetectionFeed) -> None:
        self.feed = feed

    def datagram_received(self, data: bytes, addr: tuple[str | Any, int]) -> None:
        self.feed._datagram(data)

    def error_received(self, exc: Exception) -> None:
        log.warning("detection feed socket error: %s", exc)


class DetectionFeed:
    """Receive the feed on UDP ``host:port`` (port 0: ephemeral, see :attr:`address`) and
    call ``on_detection`` for every accepted line, on the event loop."""

    def __init__(self, host: str = DEFAULT_ADDRESS[0], port: int = DEFAULT_ADDRESS[1],
                 on_detection: Callable[[FeedDetection], None] | None = None, *,
                 max_delay_s: float = 5.0, clock: Callable[[], float] | None = None) -> None:
        self.host = host
        self.port = port
        self.on_detection = on_detection
        self.filter = FeedFilter(max_delay_s, clock)
        self._transport: asyncio.DatagramTransport | None = None

    @property
    def counters(self) -> FeedCounters:
        return self.filter.counters

    @property
    def address(self) -> tuple[str, int]:
        """(host, port) actually bound."""
        if self._transport is None:
            raise RuntimeError("DetectionFeed not started")
        sockname = self._transport.get_extra_info("sockname")
        return str(sockname[0]), int(sockname[1])

    async def start(self) -> None:
        """Bind the UDP socket (raises OSError if the port is taken)."""
        loop = asyncio.get_running_loop()
        transport, _ = await loop.create_datagram_endpoint(
            lambda: _Protocol(self), local_addr=(self.host, self.port))
        self._transport = transport

    async def stop(self) -> None:
        if self._transport is not None:
            self._transport.close()
            self._transport = None

    async def __aenter__(self) -> DetectionFeed:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    def _datagram(self, data: bytes) -> None:
        for det in self.filter.feed(data):
            if self.on_detection is None:
                continue
            try:
                self.on_detection(det)
            except Exception:
                self.filter.counters.callback_errors += 1
                log.exception("detection feed consumer failed on %s", det)
