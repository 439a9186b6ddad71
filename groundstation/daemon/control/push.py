"""Live pages over WebSocket: the journal fan-out, the state pushes, and each page's lifetime.

Messages (server -> page), one JSON object each::

    {"type": "hello", "version": 1, "push_hz": 4.0, "tile_url": str | null,
     "instance": str (changes when the daemon restarts)}
    {"type": "state", "state": {...}, "seq": last event sequence number}
    {"type": "events", "events": [{"seq": n, "line": {journal line}}, ...], "dropped": k}

Pages get the operator events (``log_lines.is_operator_event``: not the frequent ``track``,
``truth``, ``detection`` ... state updates, whose effect is in the state); ``dropped``
counts events a page will never see (too many in one batch, or evicted from the buffer
before a reconnect). A page connecting with
``/ws?since=N&instance=I`` first gets the buffered events after N (catch-up after a
reconnect); without ``since``, or when ``I`` names another run of the daemon, the last
``CATCH_UP_EVENTS``.

Bounds: at most ``max_clients`` pages at once (more: HTTP 503 before the upgrade); each page
has a bounded queue (``pages.PageClient``); a page whose queue overflows, or that
takes more than ``WS_SEND_TIMEOUT_S`` to accept one message, is closed with 1013 (try again
later) and, if even the close does not go through within ``WS_CLOSE_TIMEOUT_S``, its
connection is aborted: a page that never reads costs a bounded amount of memory for a
bounded time.

Load (``pacing.py``): a state message is serialised once per push for every page (the
shared :class:`~groundstation.daemon.control.pacing.StateDocument`, also a connecting
page's first state), the catch-up of pages connecting without ``since`` once per journal
sequence number, and each message sent to a page first takes a unit of the server's
:class:`~groundstation.daemon.control.pacing.TurnBudget`, so a push to many pages goes out a
few pages per loop turn.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import time
from collections.abc import Coroutine
from typing import Any

from aiohttp import WSCloseCode, WSMsgType, web

from groundstation.daemon.control.contract import DaemonControl
from groundstation.daemon.control.guard import RejectLog
from groundstation.daemon.control.pacing import StateDocument, TurnBudget
from groundstation.daemon.control.pages import EventBuffer, PageClient
from groundstation.daemon.log_lines import line_level

__all__ = ["CATCH_UP_EVENTS", "WS_CLOSE_TIMEOUT_S", "WS_SEND_TIMEOUT_S", "PageHub"]

log = logging.getLogger(__name__)

CATCH_UP_EVENTS = 200
EVENT_FLUSH_S = 0.1
EVENT_BATCH_MAX = 200
WS_SEND_TIMEOUT_S = 5.0  # a page that takes longer to accept one message is dropped
WS_CLOSE_TIMEOUT_S = 2.0  # then its connection is aborted


class PageHub:
    """The WebSocket pages of one control server and what they are sent."""

    def __init__(self, control: DaemonControl, rejects: RejectLog, *, push_hz: float,
                 tile_url: str | None, instance: str, max_clients: int,
                 budget: TurnBudget | None = None,
                 document: StateDocument | None = None) -> None:
        self.control = control
        self.budget = budget or TurnBudget()
        self.document = document or StateDocument(control)
        self.rejects = rejects
        self.push_hz = push_hz
        self.tile_url = tile_url
        self.instance = instance
        self.max_clients = max_clients
        self.buffer = EventBuffer()
        self.clients: set[PageClient] = set()
        self.open = 0  # WebSocket handlers running (handshaking, live or closing)
        self.stopping = False
        self._pending: list[dict[str, Any]] = []
        self._pending_dropped = 0
        self._catch_up: tuple[int, list[str]] = (-1, [])
        """The catch-up messages of a page connecting without ``since``, at a sequence."""
        self._tasks: list[asyncio.Task[None]] = []
        self._closing: set[asyncio.Task[None]] = set()
        self._group: asyncio.TaskGroup | None = None
        """Where the hub's tasks run while :meth:`run` serves (the group it opens)."""

    # ----------------------------------------------------------------- lifecycle

    def _spawn(self, coro: Coroutine[Any, Any, None], name: str) -> asyncio.Task[None]:
        if self._group is not None:
            return self._group.create_task(coro, name=name)
        return asyncio.create_task(coro, name=name)

    async def run(self) -> None:
        """Push from a task group of this coroutine's own until cancelled (the daemon runs
        it in its root group); :meth:`start` with ``push=False`` only seeds the buffer."""
        async with asyncio.TaskGroup() as group:
            self._group = group
            try:
                self._start_pushing()
                await asyncio.Event().wait()
            finally:
                self._group = None

    def start(self, push: bool = True) -> None:
        """Seed the buffer from the daemon's recent events and (unless ``push`` is False:
        then :meth:`run` pushes) start pushing."""
        try:
            recent = self.control.state().get("events") or []
        except Exception:  # the daemon's state is its business; start anyway
            log.exception("control state() failed while seeding events")
            recent = []
        for line in recent:
            if isinstance(line, dict):
                self.buffer.record(line)
        if push:
            self._start_pushing()

    def _start_pushing(self) -> None:
        self._tasks = [self._spawn(self._pump_events(), "control-events"),
                       self._spawn(self._push_states(), "control-push")]

    async def stop(self) -> None:
        """Stop the pushes and close every page (1001), aborting those that do not answer."""
        self.stopping = True
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        self._tasks = []
        await asyncio.gather(*(self._close_client(c, WSCloseCode.GOING_AWAY, b"daemon stopping")
                               for c in list(self.clients)))

    # ----------------------------------------------------------------- events & pushes

    async def _pump_events(self) -> None:
        """Buffer the daemon's journal events and fan them out in batches every 0.1 s."""
        flusher = self._spawn(self._flush_events(), "control-flush")
        try:
            async for line in self.control.subscribe():
                if not isinstance(line, dict):
                    continue
                level = line_level(line)  # once per line: above DEBUG for operator events
                entry = self.buffer.record(line, level)
                if self.clients and level > logging.DEBUG:
                    self._pending.append(entry)
                    if len(self._pending) > EVENT_BATCH_MAX:
                        self._pending_dropped += len(self._pending) - EVENT_BATCH_MAX
                        del self._pending[:-EVENT_BATCH_MAX]
        except asyncio.CancelledError:
            raise
        except Exception:
            log.exception("daemon event subscription failed; live pages get states only")
        finally:
            await asyncio.sleep(EVENT_FLUSH_S)  # let the last batch go out
            flusher.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await flusher

    async def _flush_events(self) -> None:
        while True:
            await asyncio.sleep(EVENT_FLUSH_S)
            if self._pending:
                msg = json.dumps({"type": "events", "events": self._pending,
                                  "dropped": self._pending_dropped})
                self._pending, self._pending_dropped = [], 0
                self.broadcast(msg)

    async def _push_states(self) -> None:
        period_s = 1.0 / self.push_hz
        failed = False
        while True:
            await asyncio.sleep(period_s)
            self.rejects.flush(time.monotonic())  # a refusal burst's summary line, when due
            if not self.clients:
                continue
            try:
                self.document.invalidate()  # each push carries the state as it is now
                msg = self.state_message()
                failed = False
            except Exception:
                if not failed:
                    log.exception("control state() failed; pages keep their last state")
                failed = True
                continue
            self.broadcast(msg)

    def state_message(self) -> str:
        """The state message: the shared document's text (built at most once per
        ``StateDocument.max_age_s`` for every page and reader)."""
        return f'{{"type": "state", "state": {self.document.text()}, "seq": {self.buffer.seq}}}'

    def _catch_up_messages(self, since: int | None) -> list[str]:
        """The ``events`` messages a connecting page is sent first; serialised once per
        sequence number for pages connecting without ``since`` (a burst of pages)."""
        if since is None and self._catch_up[0] == self.buffer.seq:
            return self._catch_up[1]
        backlog, missed = self.buffer.backlog(since, CATCH_UP_EVENTS)
        messages = [json.dumps({"type": "events", "events": backlog[start:start + EVENT_BATCH_MAX],
                                "dropped": missed if start == 0 else 0})
                    for start in range(0, len(backlog), EVENT_BATCH_MAX)]
        if since is None:
            self._catch_up = (self.buffer.seq, messages)
        return messages

    def broadcast(self, text: str) -> None:
        """Queue ``text`` for every page; pages whose queue overflows are dropped."""
        for client in list(self.clients):
            if not client.offer(text):
                self._evict(client, "its queue is full")

    def _evict(self, client: PageClient, reason: str, *, slow: bool = True) -> None:
        """Stop feeding ``client`` and close it (1013), aborting if the close stalls."""
        if client.evicted:
            return
        client.evicted = True
        self.clients.discard(client)
        if slow:
            self.rejects.note("ws_slow_evicted", f"live page too slow ({reason}); dropped",
                              time.monotonic())
        task = self._spawn(self._close_client(client), "control-ws-close")
        self._closing.add(task)
        task.add_done_callback(self._closing.discard)

    @staticmethod
    async def _close_client(client: PageClient, code: int = WSCloseCode.TRY_AGAIN_LATER,
                            message: bytes = b"too slow, reconnect") -> None:
        """Close politely within ``WS_CLOSE_TIMEOUT_S``, then abort what is left."""
        try:
            async with asyncio.timeout(WS_CLOSE_TIMEOUT_S):
                await client.ws.close(code=code, message=message)
        except Exception:  # timed out or the connection is gone
            pass
        finally:
            client.abort()

    # ----------------------------------------------------------------- one page

    async def handle(self, request: web.Request) -> web.StreamResponse:
        """``GET /ws`` (its origin already checked): 503 beyond ``max_clients``."""
        if self.open >= self.max_clients:
            self.rejects.note("ws_clients_full", f"{self.open} pages connected",
                              time.monotonic())
            refusal = web.json_response(
                {"ok": False, "error": f"too many live pages (limit {self.max_clients}, "
                 "--http-max-ws-clients); close one and retry"},
                status=503, headers={"Retry-After": "5", "Cache-Control": "no-store"})
            # closed by us, within this request's unit of the turn budget: a refused crowd
            # does not wake the loop all at once when it hangs up together
            refusal.force_close()
            return refusal
        self.open += 1
        try:
            return await self._serve(request)
        finally:
            self.open -= 1

    async def _serve(self, request: web.Request) -> web.WebSocketResponse:
        ws = web.WebSocketResponse(heartbeat=20.0, max_msg_size=4096,
                                   timeout=WS_CLOSE_TIMEOUT_S)
        transport = request.transport
        await ws.prepare(request)
        client = PageClient(ws, transport)
        try:
            since_text = request.query.get("since")
            since = int(since_text) if since_text is not None else None
        except ValueError:
            since = None
        if request.query.get("instance", self.instance) != self.instance:
            since = None  # sequence numbers of another daemon run: start afresh
        client.offer(json.dumps({"type": "hello", "version": 1, "push_hz": self.push_hz,
                                 "tile_url": self.tile_url, "instance": self.instance}))
        with contextlib.suppress(Exception):
            client.offer(self.state_message())
        for message in self._catch_up_messages(since):
            client.offer(message)
        if self.stopping:
            await ws.close(code=WSCloseCode.GOING_AWAY)
            return ws
        self.clients.add(client)  # no await since the first offer: nothing interleaves
        sender = asyncio.create_task(self._send_loop(client), name="control-ws-send")
        try:
            async for msg in ws:  # pages send nothing we act on; this detects the close
                if msg.type == WSMsgType.ERROR:
                    break
        finally:
            self.clients.discard(client)
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await sender
            # Closed (the page's close was answered) or dead (heartbeat missed): drop what a
            # page that never reads would otherwise keep in the socket's buffer forever.
            client.abort()
        return ws

    async def _send_loop(self, client: PageClient) -> None:
        """Send the page its queue; one that takes over ``WS_SEND_TIMEOUT_S`` to accept a
        message (it does not read) is dropped."""
        while not client.ws.closed:
            text = await client.next()
            await self.budget.take()  # a few pages per loop turn, however many there are
            if client.ws.closed:
                return
            try:
                async with asyncio.timeout(WS_SEND_TIMEOUT_S):
                    await client.ws.send_str(text)
            except TimeoutError:
                self._evict(client, f"a message took over {WS_SEND_TIMEOUT_S:g} s to send")
                return
            except (ConnectionError, RuntimeError):
                self._evict(client, "connection lost", slow=False)
                return
