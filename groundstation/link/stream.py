"""Byte-stream plumbing shared by TCP and serial links: a protocol and a reconnect loop."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from abc import abstractmethod
from typing import Any

from groundstation.link.base import Backoff, Link, Peer, Received

__all__ = ["ReconnectingLink", "StreamProtocol"]

log = logging.getLogger(__name__)


class StreamProtocol(asyncio.Protocol):
    """Feeds one connection's bytes to its link and reports when it ends."""

    def __init__(self, sink: _StreamSink, peer: Peer | None) -> None:
        self.sink = sink
        self.peer = peer
        self.transport: asyncio.Transport | None = None
        self.closed = asyncio.get_running_loop().create_future()

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        self.sink._stream_made(self)

    def data_received(self, data: bytes) -> None:
        self.sink._arrive(data, self.peer, self)

    def eof_received(self) -> bool | None:
        return False  # close our side too

    def connection_lost(self, exc: Exception | None) -> None:
        if not self.closed.done():
            self.closed.set_result(exc)
        self.sink._stream_lost(self, exc)


class _StreamSink(Link):
    """A link that receives from :class:`StreamProtocol` objects (back-pressure, no drops).

    A new connection gets a fresh decoder; bytes of an earlier connection still waiting in
    the inbox are decoded first (the inbox keeps order), so a reconnect may cost at most
    one frame cut in half, counted as bad."""

    stream = True

    def _stream_made(self, proto: StreamProtocol) -> None:
        self._forget_decoder(proto.peer)

    def _stream_lost(self, proto: StreamProtocol, exc: Exception | None) -> None:
        self._forget_decoder(proto.peer)
        self._paused.discard(proto)

    def _write(self, transport: asyncio.Transport | None, frame: bytes) -> bool:
        if transport is None or transport.is_closing():
            return False
        if transport.get_write_buffer_size() > self.options.max_write_buffer_bytes:
            self._warn("full", "peer is not reading; dropping frames")
            return False
        try:
            transport.write(frame)
        except Exception as exc:
            self.counters.send_errors += 1
            self._warn("write", "write failed: %s", exc)
            return False
        self._count_out(len(frame))
        return True


class ReconnectingLink(_StreamSink):
    """A link with one connection at a time, reopened with back-off whenever it ends.

    Subclasses implement :meth:`_connect` (open a connection with ``StreamProtocol``)
    and :meth:`_describe` (where to, for log lines).
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._proto: StreamProtocol | None = None
        self._task: asyncio.Task[None] | None = None
        self._backoff = Backoff(self.options.reconnect_initial_s, self.options.reconnect_max_s)
        self._ever_connected = False

    @property
    def connected(self) -> bool:
        p = self._proto
        return p is not None and p.transport is not None and not p.transport.is_closing()

    @abstractmethod
    async def _connect(self) -> StreamProtocol: ...

    @abstractmethod
    def _describe(self) -> str: ...

    async def _open(self) -> None:
        self._task = self._spawn(self._run(), f"link {self.link_id}")

    async def _close(self) -> None:
        task, self._task = self._task, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        proto, self._proto = self._proto, None
        if proto is not None and proto.transport is not None:
            proto.transport.close()

    def _on_valid(self, rx: Received) -> Received:
        self._backoff.reset()
        return rx

    async def _run(self) -> None:
        """Connect, wait for the connection to end, wait the back-off, repeat. Never raises
        (except cancellation)."""
        while True:
            try:
                proto = await self._connect()
            except asyncio.CancelledError:
                raise
            except Exception as exc:
                if self.closing:  # the daemon is shutting down: no retry, nothing to say
                    return
                delay = self._backoff.next_delay_s()
                self._warn(
                    "connect",
                    "cannot open %s (%s); retrying every <= %.1f s",
                    self._describe(),
                    exc,
                    delay,
                )
                await asyncio.sleep(delay)
                continue
            self._proto = proto
            self.counters.connects += 1
            if self._ever_connected:
                self.counters.reconnects += 1
                log.info("link %s: reconnected to %s", self.link_id, self._describe())
            else:
                log.info("link %s: connected to %s", self.link_id, self._describe())
            self._ever_connected = True
            exc_lost = await asyncio.shield(proto.closed)
            self._proto = None
            if self.closing:  # the peer closed as the daemon shuts down: no lost link
                return
            delay = self._backoff.next_delay_s()
            log.warning(
                "link %s: lost %s (%s); reconnecting in %.1f s",
                self.link_id,
                self._describe(),
                exc_lost or "closed by peer",
                delay,
            )
            await asyncio.sleep(delay)

    def _send(self, frame: bytes, system_id: int | None) -> bool:
        proto = self._proto
        return self._write(proto.transport if proto is not None else None, frame)
