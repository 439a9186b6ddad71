"""What every link shares: received frames, counters, options, peer routing, the base class.

A link owns one transport (a UDP socket, a TCP connection or server, a serial port). The
transport callback only stamps what arrived with the wall clock and appends the raw bytes
to the link's bounded :class:`~groundstation.link.inbox.Inbox`. The link's drain task then
decodes (one robust decoder per peer byte stream; one per datagram) and hands each valid
frame on as a :class:`Received` to a callback and/or an async iterator, at most
``rx_budget_frames`` frames (one datagram or stream slice may overshoot) per event-loop
turn before it yields. Every link drains in its own task, and asyncio runs ready tasks
first-in first-out, so links are served round-robin: a flooded link delays another by at
most one budget of work per turn, and its own inbox drops its oldest telemetry (counted in
``rx_dropped``). ``LinkOptions(fair=False)`` restores the old path (decode and deliver
inside the transport callback) for benchmarks.

``send(frame, system_id)`` never blocks and never raises: a frame that cannot go out (no
peer yet, disconnected, socket error, full buffer) is counted and dropped.

Frames are bytes both ways: the layer above encodes with ``groundstation.mavlink.codec``.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import time
from abc import ABC, abstractmethod
from collections.abc import AsyncIterator, Callable, Coroutine
from dataclasses import dataclass, field
from typing import Any, TypeAlias

from groundstation.link.binding import (
    BindingRules,
    BindingVerdict,
    Peer,
    PeerTable,
)
from groundstation.link.inbox import Inbox, RawChunk, peek_frames
from groundstation.link.radio import RadioReport, is_radio_message
from groundstation.link.url import LinkSpec
from groundstation.mavlink.codec import MavlinkDecoder
from groundstation.mavlink.evidence import is_autopilot_heartbeat

__all__ = [
    "Backoff",
    "Link",
    "LinkCounters",
    "LinkOptions",
    "PeerTable",
    "ReceiveCallback",
    "Received",
]

log = logging.getLogger(__name__)

_WARN_INTERVAL_S = 5.0

MavMessage: TypeAlias = Any
"""A pymavlink ``MAVLink_message`` (pymavlink ships no type information)."""


@dataclass(frozen=True, slots=True)
class Received:
    """One valid MAVLink frame as it arrived.

    ``raw`` is the exact frame on the wire (what a .tlog stores and what forwarding sends);
    ``t_unix_s`` is the wall-clock time of reception (when the transport read it, not when
    it was decoded); ``peer`` says where on the link it came from (replies to
    ``system_id`` go there). ``foreign``: the system id is bound to another peer of this
    link (see ``groundstation.link.binding``); record and forward it, but it is not that
    vehicle's frame.
    """

    message: MavMessage
    raw: bytes
    link_id: str
    t_unix_s: float
    peer: Peer | None = None
    foreign: bool = False

    @property
    def system_id(self) -> int:
        """MAVLink source system id of the frame."""
        return int(self.message.get_srcSystem())

    @property
    def component_id(self) -> int:
        """MAVLink source component id of the frame."""
        return int(self.message.get_srcComponent())


ReceiveCallback = Callable[[Received], None]


@dataclass
class LinkCounters:
    """Traffic and health counters of one link (monotonic; read them, never reset).

    Receiving: ``frames_in`` valid frames decoded; ``rx_dropped`` / ``rx_dropped_priority``
    frames dropped unread from a full inbox (telemetry / protocol messages, oldest first);
    ``bad_frames``/``bad_bytes`` failed checksums and garbage; ``foreign`` frames of a system
    id bound to another link or peer; ``rx_overflow`` frames a full ``frames()`` iterator
    missed; ``rx_paused`` times a stream was paused for back-pressure; ``radio_frames``
    RADIO_STATUS / RADIO reports of a telemetry radio (``groundstation.link.radio``).
    Sending: ``frames_out``, ``frames_dropped`` (could not send), ``send_errors``.
    """

    bytes_in: int = 0
    bytes_out: int = 0
    frames_in: int = 0
    frames_out: int = 0
    bad_frames: int = 0
    bad_bytes: int = 0
    send_errors: int = 0
    frames_dropped: int = 0
    rx_dropped: int = 0
    rx_dropped_priority: int = 0
    foreign: int = 0
    rx_overflow: int = 0
    rx_paused: int = 0
    radio_frames: int = 0
    reconnects: int = 0
    connects: int = 0

    def as_dict(self) -> dict[str, int]:
        """The counters as a plain dict (for the journal and the status table)."""
        return dict(self.__dict__)

    def receive_summary(self) -> dict[str, int]:
        """The receive health in five numbers: received, dropped, bad, foreign, overflow."""
        return {
            "received": self.frames_in,
            "dropped": self.rx_dropped + self.rx_dropped_priority,
            "bad": self.bad_frames,
            "foreign": self.foreign,
            "overflow": self.rx_overflow,
        }


@dataclass(frozen=True)
class LinkOptions:
    """Tuning shared by all links.

    Back-off: the n-th consecutive failed (re)connect waits
    ``min(reconnect_max_s, reconnect_initial_s * 2**n)``; it resets once a valid frame
    arrives, so a server that accepts and drops at once cannot make the link spin.

    Receiving (see the module docstring): ``rx_budget_frames`` per loop turn;
    ``rx_max_telemetry_frames``/``rx_max_priority_frames`` waiting per inbox class;
    ``rx_stream_max_bytes`` waiting on a stream before reading pauses; ``udp_read_burst``
    datagrams read per socket wake-up, so the kernel's tail drop (blind to message type)
    gives way to the inbox's oldest-telemetry-first drop; ``binding``: peer-address rules
    on listening links. ``fair=False``: the old inline path (benchmarks only).
    """

    reconnect_initial_s: float = 0.5
    reconnect_max_s: float = 10.0
    connect_timeout_s: float = 5.0
    max_write_buffer_bytes: int = 256 * 1024
    rx_queue_size: int = 4096
    fair: bool = True
    rx_budget_frames: int = 64
    rx_max_telemetry_frames: int = 2048
    rx_max_priority_frames: int = 512
    rx_stream_max_bytes: int = 256 * 1024
    rx_stream_slice_bytes: int = 1024
    udp_read_burst: int = 16
    binding: BindingRules = field(default_factory=BindingRules)


class Backoff:
    """Exponential back-off delays: ``initial * 2**n`` capped at ``maximum``."""

    def __init__(self, initial_s: float, maximum_s: float) -> None:
        self.initial_s = initial_s
        self.maximum_s = maximum_s
        self.failures = 0

    def next_delay_s(self) -> float:
        """Delay before the next attempt; counts one more failure."""
        delay = min(self.maximum_s, self.initial_s * (2.0 ** min(self.failures, 30)))
        self.failures += 1
        return delay

    def reset(self) -> None:
        """Forget past failures (after a healthy connection)."""
        self.failures = 0


class Link(ABC):
    """One transport. Subclasses implement ``_open``, ``_close`` and ``_send``; transports
    report what they read with ``_arrive``.

    Receive with ``on_receive`` (a plain function called on the event loop; exceptions
    are logged, never propagated into the transport) and/or ``async for rx in
    link.frames()``. ``now_s`` is the clock peer bindings are timed with (the router sets
    its own; default ``time.monotonic``).
    """

    stream = False
    """True for byte streams (TCP, serial): back-pressure instead of dropping."""

    def __init__(
        self,
        spec: LinkSpec,
        link_id: str | None = None,
        on_receive: ReceiveCallback | None = None,
        options: LinkOptions | None = None,
    ) -> None:
        self.spec = spec
        self.link_id = link_id if link_id is not None else spec.canonical
        self.on_receive = on_receive
        self.options = options or LinkOptions()
        self.counters = LinkCounters()
        self.radio: RadioReport | None = None
        """The latest RADIO_STATUS / RADIO a radio on this link sent (the router sets it)."""
        self.now_s: Callable[[], float] = time.monotonic
        self.on_notice: Callable[[str, dict[str, Any]], None] | None = None
        self._decoders: dict[Peer | None, MavlinkDecoder] = {}
        self._queue: asyncio.Queue[Received | None] | None = None
        self._running = False
        self.closing = False  # set by begin_close(): the owner is shutting down
        self._last_warning: dict[str, float] = {}
        opts = self.options
        self._inbox = (
            Inbox(None, None)
            if self.stream
            else Inbox(opts.rx_max_telemetry_frames, opts.rx_max_priority_frames)
        )
        self._wake = asyncio.Event()
        self._drain_task: asyncio.Task[None] | None = None
        self._group: asyncio.TaskGroup | None = None
        """Where the link's background tasks run (given to :meth:`start` by its owner)."""
        self._paused: set[Any] = set()

    # -- lifecycle -------------------------------------------------------------------
    @property
    def running(self) -> bool:
        """True between ``start()`` and ``stop()``."""
        return self._running

    @property
    def pending(self) -> int:
        """Items waiting in the inbox (received, not yet decoded)."""
        return len(self._inbox)

    def snapshot(self) -> dict[str, object]:
        """Status for the journal and the live table: id, URL, state and counters."""
        return {
            "link": self.link_id,
            "url": self.spec.canonical,
            "running": self._running,
            "connected": self.connected,
            **self.counters.as_dict(),
            "radio": None if self.radio is None else self.radio.as_dict(),
        }

    @property
    @abstractmethod
    def connected(self) -> bool:
        """True while frames can be sent somewhere (a peer or port is there)."""

    def _spawn(self, coro: Coroutine[Any, Any, None], name: str) -> asyncio.Task[None]:
        """A background task of this link: in the task group its owner gave :meth:`start`
        (the daemon's links run in a child task group of its root), else a plain task."""
        if self._group is not None:
            return self._group.create_task(coro, name=name)
        return asyncio.create_task(coro, name=name)

    async def start(self, group: asyncio.TaskGroup | None = None) -> None:
        """Open the transport, its background tasks in ``group`` if given. Listeners raise
        :class:`~domain.errors.LinkError` if they cannot bind; connecting kinds (tcp,
        serial) return at once and keep trying in the background."""
        if self._running:
            return
        self._group = group
        await self._open()
        self._running = True
        if self.options.fair:
            self._drain_task = self._spawn(self._drain_loop(), f"drain {self.link_id}")
        log.info("link %s started (%s)", self.link_id, self.spec.canonical)

    def begin_close(self) -> None:
        """The owner is shutting down: a peer that closes from now on (the embedded
        simulator stopping with the daemon) is expected, not a lost link to warn about."""
        self.closing = True

    async def stop(self) -> None:
        """Close the transport and end ``frames()`` iterators. Idempotent. Frames still
        waiting in the inbox are dropped (not counted)."""
        if not self._running:
            return
        self._running = False
        with contextlib.suppress(Exception):
            await self._close()
        task, self._drain_task = self._drain_task, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        self._inbox.clear()
        self._paused.clear()
        if self._queue is not None:
            if self._queue.full():
                with contextlib.suppress(asyncio.QueueEmpty):
                    self._queue.get_nowait()
            self._queue.put_nowait(None)  # ends frames()
        log.info("link %s stopped", self.link_id)

    async def __aenter__(self) -> Link:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    @abstractmethod
    async def _open(self) -> None: ...

    @abstractmethod
    async def _close(self) -> None: ...

    # -- sending ---------------------------------------------------------------------
    def send(self, frame: bytes, system_id: int | None = None) -> bool:
        """Queue ``frame`` for ``system_id`` (None: every peer). Never blocks or raises.

        Returns True if it was handed to the transport for at least one peer.
        """
        if not self._running:
            self.counters.frames_dropped += 1
            return False
        try:
            ok = self._send(bytes(frame), system_id)
        except Exception as exc:  # a transport bug must not take the caller down
            self.counters.send_errors += 1
            log.warning("link %s: send failed: %s", self.link_id, exc)
            return False
        if not ok:
            self.counters.frames_dropped += 1
        return ok

    @abstractmethod
    def _send(self, frame: bytes, system_id: int | None) -> bool: ...

    def _warn(self, key: str, message: str, *args: object) -> None:
        """Log a warning at most once per ``_WARN_INTERVAL_S`` for each ``key``."""
        now = time.monotonic()
        if now - self._last_warning.get(key, -1e9) >= _WARN_INTERVAL_S:
            self._last_warning[key] = now
            log.warning("link %s: " + message, self.link_id, *args)

    def _count_out(self, nbytes: int) -> None:
        self.counters.bytes_out += nbytes
        self.counters.frames_out += 1

    def _notice(self, event: str, **fields: Any) -> None:
        """Tell the layer above something worth journalling (a binding moved)."""
        log.debug("link %s: %s %s", self.link_id, event, fields)  # the journal line tells it
        if self.on_notice is not None:
            try:
                self.on_notice(event, {"link": self.link_id, **fields})
            except Exception:
                log.exception("link %s: notice callback failed", self.link_id)

    # -- receiving: transport side (cheap, no decoding) ---------------------------------
    def _arrive(self, data: bytes, peer: Peer | None, token: Any = None) -> None:
        """Bytes a transport read: one datagram (datagram links) or a stream chunk.

        Fair mode only queues them; a full datagram inbox drops its oldest item of the
        same class; a stream waiting beyond ``rx_stream_max_bytes`` pauses reading
        (``token`` is the protocol whose transport to pause)."""
        if not self.options.fair:
            if self.stream:
                self._feed(data, peer)
            else:
                self._feed_datagram(data, peer)
            return
        self.counters.bytes_in += len(data)
        t_unix_s = time.time()
        inbox = self._inbox
        if self.stream:
            step = self.options.rx_stream_slice_bytes
            for i in range(0, len(data), step):
                inbox.put(RawChunk(data[i : i + step], peer, t_unix_s, False, 0, token), False)
            if inbox.bytes > self.options.rx_stream_max_bytes:
                self._pause(token)
        else:
            frames, priority = peek_frames(data)
            dropped = inbox.put(RawChunk(data, peer, t_unix_s, True, max(frames, 1)), priority)
            if dropped:
                if priority:
                    self.counters.rx_dropped_priority += dropped
                else:
                    self.counters.rx_dropped += dropped
                self._warn("rx-drop", "receiving faster than it can decode; dropping oldest")
        self._wake.set()

    def _pause(self, token: Any) -> None:
        transport = getattr(token, "transport", None)
        if transport is None or token in self._paused or transport.is_closing():
            return
        with contextlib.suppress(Exception):
            transport.pause_reading()
            self._paused.add(token)
            self.counters.rx_paused += 1

    def _resume_if_drained(self) -> None:
        if self._paused and self._inbox.bytes <= self.options.rx_stream_max_bytes // 2:
            for token in list(self._paused):
                transport = getattr(token, "transport", None)
                if transport is not None and not transport.is_closing():
                    with contextlib.suppress(Exception):
                        transport.resume_reading()
            self._paused.clear()

    # -- receiving: the drain (decoding and delivery, bounded per loop turn) ----------------
    async def _drain_loop(self) -> None:
        """Serve the inbox a budget at a time, yielding to the loop between budgets."""
        while True:
            await self._wake.wait()
            self._wake.clear()
            while len(self._inbox):
                try:
                    self.drain(self.options.rx_budget_frames)
                except Exception:  # a bug must not end receiving on this link
                    log.exception("link %s: receive failed", self.link_id)
                await asyncio.sleep(0)

    def drain(self, budget_frames: int) -> int:
        """Decode and deliver waiting items until ``budget_frames`` frames went out (the
        last item may overshoot it) or the inbox is empty; returns the frames delivered."""
        delivered = 0
        inbox = self._inbox
        while delivered < budget_frames:
            chunk = inbox.pop()
            if chunk is None:
                break
            if chunk.datagram:
                out = self._feed_datagram(chunk.data, chunk.peer, chunk.t_unix_s, count=False)
            else:
                out = self._feed(chunk.data, chunk.peer, chunk.t_unix_s, count=False)
            delivered += len(out)
        self._resume_if_drained()
        return delivered

    def _feed(
        self,
        data: bytes,
        peer: Peer | None = None,
        t_unix_s: float | None = None,
        count: bool = True,
    ) -> list[Received]:
        """Decode stream bytes from ``peer`` (any chunking) and deliver every valid frame."""
        if count:
            self.counters.bytes_in += len(data)
        decoder = self._decoders.get(peer)
        if decoder is None:
            decoder = self._decoders[peer] = MavlinkDecoder()
        bad_frames, bad_bytes = decoder.bad_frames, decoder.bad_bytes
        messages: list[MavMessage] = decoder.feed(data)
        self.counters.bad_frames += decoder.bad_frames - bad_frames
        self.counters.bad_bytes += decoder.bad_bytes - bad_bytes
        return self._emit(messages, peer, t_unix_s)

    def _feed_datagram(
        self, data: bytes, peer: Peer | None, t_unix_s: float | None = None, count: bool = True
    ) -> list[Received]:
        """Decode one datagram: whole frames only, as MAVLink over UDP sends them.

        A fresh decoder per datagram (5 us) means a damaged datagram cannot swallow the
        frames of the next ones; bytes left over at its end count as one bad frame.
        """
        if count:
            self.counters.bytes_in += len(data)
        decoder = MavlinkDecoder()
        messages: list[MavMessage] = decoder.feed(data)
        self.counters.bad_frames += decoder.bad_frames
        self.counters.bad_bytes += decoder.bad_bytes
        out = self._emit(messages, peer, t_unix_s)
        leftover = len(data) - decoder.bad_bytes - sum(len(rx.raw) for rx in out)
        if leftover > 0:
            self.counters.bad_frames += 1
            self.counters.bad_bytes += leftover
        return out

    def _emit(
        self, messages: list[MavMessage], peer: Peer | None, t_unix_s: float | None
    ) -> list[Received]:
        if not messages:
            return []
        if t_unix_s is None:
            t_unix_s = time.time()
        out: list[Received] = []
        for msg in messages:
            rx = Received(msg, bytes(msg.get_msgbuf()), self.link_id, t_unix_s, peer)
            self.counters.frames_in += 1
            rx = self._on_valid(rx)
            self._deliver(rx)
            out.append(rx)
        return out

    def _forget_decoder(self, peer: Peer | None) -> None:
        self._decoders.pop(peer, None)

    def _on_valid(self, rx: Received) -> Received:
        """Hook for subclasses (peer learning, back-off reset); may mark ``rx`` foreign."""
        return rx

    def _bind_peer(self, peers: PeerTable, rx: Received) -> Received:
        """Apply the peer binding rules to ``rx`` (listening links)."""
        if rx.peer is None or is_radio_message(rx.message):
            return rx  # a radio's report binds nothing and keeps no binding alive
        previous = peers.binder.place_of(rx.system_id)
        verdict = peers.heard(
            rx.system_id, rx.peer, is_autopilot_heartbeat(rx.message), self.now_s()
        )
        if verdict is BindingVerdict.FOREIGN:
            self.counters.foreign += 1
            return dataclasses.replace(rx, foreign=True)
        if verdict is BindingVerdict.REBOUND:
            self._notice(
                "peer_rebound", system_id=rx.system_id, peer=str(rx.peer), previous=str(previous)
            )
        return rx

    def _deliver(self, rx: Received) -> None:
        if self.on_receive is not None:
            try:
                self.on_receive(rx)
            except Exception:
                log.exception("link %s: receive callback failed", self.link_id)
        if self._queue is not None:
            try:
                self._queue.put_nowait(rx)
            except asyncio.QueueFull:
                self.counters.rx_overflow += 1

    async def frames(self) -> AsyncIterator[Received]:
        """Iterate received frames until ``stop()``. Frames that arrive while the queue
        (``options.rx_queue_size``) is full are dropped and counted in ``rx_overflow``."""
        if self._queue is None:
            self._queue = asyncio.Queue(maxsize=self.options.rx_queue_size)
        while self._running or not self._queue.empty():
            item = await self._queue.get()
            if item is None:
                return
            yield item
