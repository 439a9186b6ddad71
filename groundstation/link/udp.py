"""UDP links: ``udpin:``/``udp:`` (listen) and ``udpout:`` (send).

A listening link binds a vehicle's system id to the address its autopilot HEARTBEAT first
came from (moved only on the evidence rules of ``groundstation.link.binding``; frames of it
from other addresses are counted ``foreign`` and marked so), and sends a frame for that
system id there (a broadcast goes to every address currently holding a system id).
A sending link sends everything to its destination and reads replies
on the same socket, whoever sends them (a broadcast destination gets replies from the
vehicles' own addresses).

UDP send errors (``error_received``) are logged, rate-limited, and counted in
``send_errors``; they never stop the link.

Reading: asyncio reads one datagram per socket wake-up; in fair mode the link then reads up
to ``udp_read_burst - 1`` more that are already waiting, straight into its inbox, so under
a flood the inbox (which drops oldest telemetry first, counted) rather than the kernel
(which drops the newest, of any type, silently) decides what is lost.
"""

from __future__ import annotations

import asyncio
import contextlib
import ipaddress
import socket
from typing import Any

from domain.errors import LinkError
from groundstation.link.base import Link, PeerTable, Received

_MAX_DATAGRAM = 65535

__all__ = ["UdpInLink", "UdpOutLink"]


class _DatagramProtocol(asyncio.DatagramProtocol):
    def __init__(self, link: _UdpLink) -> None:
        self.link = link

    def datagram_received(self, data: bytes, addr: tuple[Any, ...]) -> None:
        self.link._datagram(data, addr)

    def error_received(self, exc: Exception) -> None:
        self.link._socket_error(exc)


class _UdpLink(Link):
    """Shared datagram plumbing."""

    _transport: asyncio.DatagramTransport | None = None
    _sock: socket.socket | None = None

    @property
    def local_address(self) -> tuple[str, int]:
        """The bound (host, port): useful after binding port 0."""
        if self._transport is None:
            raise LinkError(f"link {self.link_id} is not started")
        sockname = self._transport.get_extra_info("sockname")
        return (str(sockname[0]), int(sockname[1]))

    async def _close(self) -> None:
        if self._transport is not None:
            self._transport.close()
            self._transport = None
        self._sock = None

    async def _endpoint(self, sock: socket.socket) -> None:
        """Hand our own socket to asyncio (we keep it to read bursts)."""
        loop = asyncio.get_running_loop()
        transport, _ = await loop.create_datagram_endpoint(
            lambda: _DatagramProtocol(self), sock=sock
        )
        self._transport = transport
        self._sock = sock

    def _datagram(self, data: bytes, addr: tuple[Any, ...]) -> None:
        self._arrive(data, addr)
        sock = self._sock
        if not self.options.fair or sock is None:
            return
        for _ in range(self.options.udp_read_burst - 1):
            try:
                data, addr = sock.recvfrom(_MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                self._socket_error(exc)
                return
            self._arrive(data, addr)

    def _socket_error(self, exc: Exception) -> None:
        self.counters.send_errors += 1
        self._warn("udp-error", "UDP socket error: %s", exc)

    def _sendto(self, frame: bytes, addr: tuple[Any, ...]) -> bool:
        transport = self._transport
        if transport is None or transport.is_closing():
            return False
        buffered = getattr(transport, "get_write_buffer_size", lambda: 0)()
        if buffered > self.options.max_write_buffer_bytes:
            self._warn("udp-full", "send buffer full, dropping frames")
            return False
        errors = self.counters.send_errors
        transport.sendto(frame, addr)
        if self.counters.send_errors != errors:  # error_received ran synchronously
            return False
        self._count_out(len(frame))
        return True


class UdpInLink(_UdpLink):
    """``udpin:HOST:PORT`` / ``udp:HOST:PORT``: listen; reply per system id."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.peers = PeerTable(self.options.binding)

    @property
    def connected(self) -> bool:
        return self._transport is not None and bool(self.peers.by_system)

    async def _open(self) -> None:
        loop = asyncio.get_running_loop()
        host, port = self.spec.host or "0.0.0.0", self.spec.port or 0
        sock: socket.socket | None = None
        try:
            infos = await loop.getaddrinfo(
                host, port, type=socket.SOCK_DGRAM, flags=socket.AI_PASSIVE
            )
            family, _, _, _, sockaddr = infos[0]
            sock = socket.socket(family, socket.SOCK_DGRAM)
            sock.setblocking(False)
            sock.bind(sockaddr)
            await self._endpoint(sock)
        except OSError as exc:
            if sock is not None:
                with contextlib.suppress(OSError):
                    sock.close()
            raise LinkError(f"cannot listen on UDP {host}:{port}: {exc.strerror or exc}") from None

    def _on_valid(self, rx: Received) -> Received:
        return self._bind_peer(self.peers, rx)

    def _send(self, frame: bytes, system_id: int | None) -> bool:
        sent = False
        for peer in self.peers.peers_for(system_id):
            assert isinstance(peer, tuple)
            sent = self._sendto(frame, peer) or sent
        return sent


def _local_bind_for(address: str) -> str:
    """Bind a sending socket to loopback when it only talks to loopback."""
    try:
        ip = ipaddress.ip_address(address)
    except ValueError:
        return "0.0.0.0"
    if ip.version == 6:
        return "::1" if ip.is_loopback else "::"
    return "127.0.0.1" if ip.is_loopback else "0.0.0.0"


class UdpOutLink(_UdpLink):
    """``udpout:HOST:PORT``: send to one destination, read replies on the same socket."""

    _destination: tuple[Any, ...] | None = None

    @property
    def connected(self) -> bool:
        return self._transport is not None

    async def _open(self) -> None:
        loop = asyncio.get_running_loop()
        host, port = self.spec.host or "", self.spec.port or 0
        try:
            infos = await loop.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
        except OSError as exc:
            raise LinkError(f"cannot resolve UDP destination {host!r}: {exc}") from None
        family, _, _, _, sockaddr = infos[0]
        sock: socket.socket | None = None
        try:
            sock = socket.socket(family, socket.SOCK_DGRAM)
            sock.setblocking(False)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
            sock.bind((_local_bind_for(str(sockaddr[0])), 0))
            await self._endpoint(sock)
        except OSError as exc:
            if sock is not None:
                with contextlib.suppress(OSError):
                    sock.close()
            raise LinkError(f"cannot open a UDP socket: {exc.strerror or exc}") from None
        self._destination = tuple(sockaddr)

    def _send(self, frame: bytes, system_id: int | None) -> bool:
        if self._destination is None:
            return False
        return self._sendto(frame, self._destination)
