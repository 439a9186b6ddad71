"""Where the ship's NMEA 0183 bytes come from: ``gcs run --ship URL`` (docs/ship.md).

==================================  =======================================================
``udp:HOST:PORT`` / ``udpin:``      listen for UDP datagrams (an NMEA multiplexer's output)
``tcp:HOST:PORT``                   connect to a TCP server (a multiplexer, gpsd's raw
                                    port); reconnect with back-off when it drops
``serial:DEVICE[:BAUD]``            a serial port, 4800 baud unless given (NMEA 0183's
                                    standard; AIS and some compasses use 38400)
==================================  =======================================================

URLs are read by :func:`groundstation.link.url.parse_link_url` (same spellings, same
one-line errors); other kinds (``udpout:``, ``tcpin:``) are refused with a
:class:`~groundstation.link.url.LinkUrlError`. :class:`NmeaSource` only moves bytes: it calls
``on_bytes`` with each read, and the sans-IO :class:`~groundstation.link.nmea.NmeaReader`
makes sense of them.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import re
from collections.abc import Callable
from typing import Any

from groundstation.link.url import LinkKind, LinkSpec, LinkUrlError, parse_link_url

__all__ = ["NMEA_SERIAL_BAUD", "NmeaSource", "describe_ship_source", "parse_ship_url"]

log = logging.getLogger(__name__)

NMEA_SERIAL_BAUD = 4800
"""NMEA 0183's standard baud rate, used when a ``serial:`` URL gives none."""
BACKOFF_START_S = 0.5
BACKOFF_MAX_S = 10.0
"""Reconnection back-off (wall seconds, doubling): a dropped TCP server or unplugged port."""
READ_BYTES = 4096
_SHIP_KINDS = (LinkKind.UDP_IN, LinkKind.TCP_CLIENT, LinkKind.SERIAL)
_BAUD_GIVEN = re.compile(r"[:,][0-9]+$")


def parse_ship_url(url: str) -> LinkSpec:
    """``--ship``'s URL; raises :class:`LinkUrlError` (one line) if it cannot be used."""
    spec = parse_link_url(url)
    if spec.kind not in _SHIP_KINDS:
        raise LinkUrlError(
            f"bad ship URL {url!r}: {spec.kind.value}: is not a ship source; use "
            "udp:HOST:PORT (listen), tcp:HOST:PORT (connect) or serial:DEVICE[:BAUD]")
    if spec.kind is LinkKind.SERIAL and not _BAUD_GIVEN.search(url.strip()):
        spec = dataclasses.replace(spec, baud=NMEA_SERIAL_BAUD)
    return spec


def describe_ship_source(spec: LinkSpec, bound: tuple[str, int] | None = None) -> str:
    """One line naming what the source does, e.g. ``listens on UDP 127.0.0.1:10110``."""
    if spec.kind is LinkKind.SERIAL:
        return f"reads serial {spec.device} at {spec.baud} baud"
    host, port = bound if bound is not None else (spec.host, spec.port)
    if spec.kind is LinkKind.UDP_IN:
        return f"listens on UDP {host}:{port}"
    return f"connects to TCP {host}:{port} (reconnects with back-off)"


class _Datagrams(asyncio.DatagramProtocol):
    def __init__(self, on_bytes: Callable[[bytes], None]) -> None:
        self.on_bytes = on_bytes

    def datagram_received(self, data: bytes, addr: tuple[str | Any, int]) -> None:
        self.on_bytes(data)

    def error_received(self, exc: Exception) -> None:
        log.warning("ship feed socket error: %s", exc)


class NmeaSource:
    """The bytes of one ship URL, handed to ``on_bytes`` on the event loop.

    :meth:`start` binds a UDP listener (raises ``OSError`` if the port is taken; the
    stream kinds connect in :meth:`run`); :meth:`run` reads until cancelled, reconnecting a
    TCP or serial stream with back-off (``on_state`` is told ``connected``/``disconnected``
    with a reason); :meth:`stop` closes what is open."""

    def __init__(self, spec: LinkSpec, on_bytes: Callable[[bytes], None],
                 on_state: Callable[[str, str], None] | None = None) -> None:
        self.spec = spec
        self.on_bytes = on_bytes
        self.on_state = on_state
        self.connects = 0
        """Successful connections of a stream source (a reconnect counts again)."""
        self._transport: asyncio.DatagramTransport | None = None
        self._writer: asyncio.StreamWriter | None = None

    @property
    def name(self) -> str:
        return "ship_feed"

    @property
    def address(self) -> tuple[str, int] | None:
        """The UDP (host, port) bound, None for the other kinds or before :meth:`start`."""
        if self._transport is None:
            return None
        sockname = self._transport.get_extra_info("sockname")
        return str(sockname[0]), int(sockname[1])

    async def start(self) -> None:
        if self.spec.kind is LinkKind.UDP_IN:
            loop = asyncio.get_running_loop()
            local = (self.spec.host or "0.0.0.0", self.spec.port or 0)
            transport, _ = await loop.create_datagram_endpoint(
                lambda: _Datagrams(self.on_bytes), local_addr=local)
            self._transport = transport

    async def stop(self) -> None:
        if self._transport is not None:
            self._transport.close()
            self._transport = None
        self._close_writer()

    async def run(self) -> None:
        """Read until cancelled (a UDP listener only waits: its protocol does the work)."""
        if self.spec.kind is LinkKind.UDP_IN:
            await asyncio.Event().wait()
            return
        backoff_s = BACKOFF_START_S
        while True:
            try:
                reader = await self._open()
            except (OSError, ImportError) as exc:
                self._state("disconnected", f"cannot open: {exc}")
            else:
                self.connects += 1
                self._state("connected", "")
                backoff_s = BACKOFF_START_S
                reason = await self._read(reader)
                self._close_writer()
                self._state("disconnected", reason)
            await asyncio.sleep(backoff_s)
            backoff_s = min(BACKOFF_MAX_S, backoff_s * 2.0)

    async def _open(self) -> asyncio.StreamReader:
        if self.spec.kind is LinkKind.TCP_CLIENT:
            reader, self._writer = await asyncio.open_connection(self.spec.host, self.spec.port)
            return reader
        import serial_asyncio_fast  # only when a serial ship source starts

        reader, self._writer = await serial_asyncio_fast.open_serial_connection(
            url=self.spec.device, baudrate=self.spec.baud)
        return reader

    async def _read(self, reader: asyncio.StreamReader) -> str:
        try:
            while True:
                data = await reader.read(READ_BYTES)
                if not data:
                    return "closed by the other end"
                self.on_bytes(data)
        except OSError as exc:
            return f"read failed: {exc}"

    def _close_writer(self) -> None:
        if self._writer is not None:
            with contextlib.suppress(Exception):
                self._writer.close()
            self._writer = None

    def _state(self, state: str, reason: str) -> None:
        if self.on_state is not None:
            self.on_state(state, reason)
