"""TCP links: ``tcp:`` (connect, reconnect with back-off) and ``tcpin:`` (accept clients).

The client link sets TCP keep-alive and (on Linux) ``TCP_USER_TIMEOUT`` so that a peer that
vanishes without closing (a radio bridge switched off) is noticed within about half a
minute, then reconnected. The server link treats every accepted connection as a peer and
replies to a system id on the connection it is bound to (``groundstation.link.binding``:
the connection its autopilot heartbeat first came from; a connection that closes releases
its system ids).
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
from typing import Any

from domain.errors import LinkError
from groundstation.link.base import PeerTable, Received
from groundstation.link.stream import ReconnectingLink, StreamProtocol, _StreamSink

__all__ = ["TcpClientLink", "TcpServerLink"]

_KEEPALIVE_IDLE_S = 10
_KEEPALIVE_INTERVAL_S = 5
_KEEPALIVE_COUNT = 3
_USER_TIMEOUT_MS = 30_000
RECEIVE_BUFFER_BYTES = 256 * 1024
"""The kernel's receive buffer of a vehicle's TCP connection. Left to itself Linux grows it
up to ``tcp_rmem`` (32 MiB here) while floe's back-pressure pauses reading: a flood then
parks a minute of stale frames in floe's own socket. Capped, the sender's buffers fill
instead (ArduPilot then skips telemetry itself) and a backlog drains sooner."""


def _tune_socket(sock: socket.socket | None) -> None:
    """Keep-alive, unacknowledged-data timeout (where the platform has them), and a
    bounded receive buffer (:data:`RECEIVE_BUFFER_BYTES`)."""
    if sock is None:
        return
    with contextlib.suppress(OSError):
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER_BYTES)
    with contextlib.suppress(OSError):
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
        for name, value in (
            ("TCP_KEEPIDLE", _KEEPALIVE_IDLE_S),
            ("TCP_KEEPINTVL", _KEEPALIVE_INTERVAL_S),
            ("TCP_KEEPCNT", _KEEPALIVE_COUNT),
            ("TCP_USER_TIMEOUT", _USER_TIMEOUT_MS),
        ):
            opt = getattr(socket, name, None)
            if opt is not None:
                sock.setsockopt(socket.IPPROTO_TCP, opt, value)


class TcpClientLink(ReconnectingLink):
    """``tcp:HOST:PORT``: one connection to a server (ArduPilot SITL serves 5760)."""

    def _describe(self) -> str:
        return f"TCP {self.spec.host}:{self.spec.port}"

    async def _connect(self) -> StreamProtocol:
        loop = asyncio.get_running_loop()
        _, proto = await asyncio.wait_for(
            loop.create_connection(
                lambda: StreamProtocol(self, None), self.spec.host or "", self.spec.port or 0
            ),
            timeout=self.options.connect_timeout_s,
        )
        if proto.transport is not None:
            _tune_socket(proto.transport.get_extra_info("socket"))
        return proto


class TcpServerLink(_StreamSink):
    """``tcpin:HOST:PORT``: accept any number of clients; each is a peer."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.peers = PeerTable(self.options.binding)
        self._server: asyncio.Server | None = None
        self._clients: dict[Any, StreamProtocol] = {}

    @property
    def connected(self) -> bool:
        return bool(self._clients)

    @property
    def client_count(self) -> int:
        """Number of clients connected now."""
        return len(self._clients)

    @property
    def local_address(self) -> tuple[str, int]:
        """The bound (host, port): useful after binding port 0."""
        if self._server is None or not self._server.sockets:
            raise LinkError(f"link {self.link_id} is not started")
        sockname = self._server.sockets[0].getsockname()
        return (str(sockname[0]), int(sockname[1]))

    async def _open(self) -> None:
        loop = asyncio.get_running_loop()
        host, port = self.spec.host or "0.0.0.0", self.spec.port or 0
        try:
            self._server = await loop.create_server(
                lambda: StreamProtocol(self, None), host, port, reuse_address=True
            )
        except OSError as exc:
            raise LinkError(f"cannot listen on TCP {host}:{port}: {exc.strerror or exc}") from None

    async def _close(self) -> None:
        server, self._server = self._server, None
        if server is not None:
            server.close()
        for proto in list(self._clients.values()):
            if proto.transport is not None:
                proto.transport.close()
        self._clients.clear()
        if server is not None:
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(server.wait_closed(), timeout=1.0)

    def _stream_made(self, proto: StreamProtocol) -> None:
        assert proto.transport is not None
        proto.peer = proto.transport.get_extra_info("peername")
        _tune_socket(proto.transport.get_extra_info("socket"))
        super()._stream_made(proto)
        self._clients[proto.peer] = proto
        self.peers.add(proto.peer)
        self.counters.connects += 1

    def _stream_lost(self, proto: StreamProtocol, exc: Exception | None) -> None:
        super()._stream_lost(proto, exc)
        if self._clients.get(proto.peer) is proto:
            del self._clients[proto.peer]
            self.peers.forget(proto.peer)

    def _on_valid(self, rx: Received) -> Received:
        if rx.peer not in self._clients:  # drained after its client left: bind nothing to it
            return rx
        return self._bind_peer(self.peers, rx)

    def _send(self, frame: bytes, system_id: int | None) -> bool:
        sent = False
        for peer in self.peers.peers_for(system_id):
            proto = self._clients.get(peer)
            sent = self._write(proto.transport if proto else None, frame) or sent
        return sent
