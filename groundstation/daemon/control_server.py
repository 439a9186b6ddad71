"""The daemon's control surface: a small HTTP JSON API, a WebSocket push and the live page.

Everything here only calls a :class:`~groundstation.daemon.control_contract.DaemonControl`;
the daemon owns the state. Endpoints (all JSON; docs/control.md has curl examples)::

    GET    /api/state                     the state document (control_contract.py)
    GET    /api/targets | /api/targets/ID  targets (or one)
    POST   /api/targets                   {id?, x_m, y_m | lat_deg, lon_deg,
                                           vx_m_s?, vy_m_s?, sigma0?}     -> 201
    PUT    /api/targets/ID  (or PATCH)    {x_m, y_m | lat_deg, lon_deg}   (a manual fix)
    DELETE /api/targets/ID
    GET    /api/vehicles | /api/vehicles/ID
    POST   /api/vehicles/ID/ACTION        ACTION: launch | resume | release
    GET    /api/events?since=N[&limit=M][&notable=1]
                                          journal events with sequence number > N
                                          (notable=1: without detection/track lines)
    GET    /api/session                   {"write": bool, ...} for the presented token
    GET    /ws                            WebSocket: hello, full state at once, then the
                                          state at ``push_hz`` and event batches
    GET    /                              the live page (web/), no CDN, no build step

Reads need no token. Every write needs ``Authorization: Bearer <token>`` (or ``?token=``)
and is answered 401 without it, 400 with a one-line reason for a malformed body, 404 for an
unknown id and 409 when the daemon refuses it (``{"ok": false, "error": ...}``).

WebSocket messages (server -> page), one JSON object each::

    {"type": "hello", "version": 1, "push_hz": 4.0, "tile_url": str | null,
     "instance": str (changes when the daemon restarts)}
    {"type": "state", "state": {...}, "seq": last event sequence number}
    {"type": "events", "events": [{"seq": n, "line": {journal line}}, ...], "dropped": k}

Pages get every journal event except the frequent ``detection`` and ``track`` lines (their
effect is in the state); ``dropped`` counts events a page will never see (too many in one
batch, or evicted from the buffer before a reconnect).

A page connecting with ``/ws?since=N&instance=I`` first gets the buffered events after N
(catch-up after a reconnect); without ``since``, or when ``I`` names another run of the
daemon, the last ``CATCH_UP_EVENTS``. A client that cannot
keep up (queue full) is disconnected with code 1013 and reconnects to catch up.
"""

from __future__ import annotations

import asyncio
import contextlib
import hmac
import ipaddress
import json
import logging
import math
import secrets
from collections import deque
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

from aiohttp import WSCloseCode, WSMsgType, web

from groundstation.daemon.control_contract import VEHICLE_ACTIONS, DaemonControl
from groundstation.daemon.control_requests import (
    RequestError,
    jsonable,
    parse_move_body,
    parse_target_body,
)

__all__ = [
    "ControlServer",
    "RequestError",
    "binding_warning",
    "is_loopback",
    "jsonable",
    "new_token",
    "parse_move_body",
    "parse_target_body",
]

log = logging.getLogger(__name__)

WEB_DIR = Path(__file__).with_name("web")
STATIC_FILES = {"app.js": "text/javascript", "style.css": "text/css"}
EVENT_BUFFER = 5000
NOTABLE_BUFFER = 2000
QUIET_EVENTS = frozenset({"detection", "track"})  # many per second: not pushed to pages
CATCH_UP_EVENTS = 200
EVENT_FLUSH_S = 0.1
EVENT_BATCH_MAX = 200
CLIENT_QUEUE = 64
MAX_BODY_BYTES = 64 * 1024
CSP = ("default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data: http: "
       "https:; connect-src 'self' ws: wss:; frame-ancestors 'none'")


def new_token() -> str:
    """A fresh random write token (URL-safe, 24 characters, 144 bits)."""
    return secrets.token_urlsafe(18)


def is_loopback(host: str) -> bool:
    """True when ``host`` only accepts connections from this machine (127.0.0.0/8, ::1,
    ``localhost``). Unknown host names and wildcard addresses (0.0.0.0, ::) are not."""
    name = host.strip().strip("[]").lower()
    if name == "localhost" or name.endswith(".localhost"):
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


def binding_warning(host: str) -> str | None:
    """The start-up warning to print when the control API is reachable from elsewhere."""
    if is_loopback(host):
        return None
    return (f"WARNING: control API and live page bound to {host}, reachable from other "
            "machines on that network; reads need no token, writes need the token")


def _json(data: Any, status: int = 200, **headers: str) -> web.Response:
    return web.Response(text=json.dumps(jsonable(data)), status=status,
                        content_type="application/json",
                        headers={"Cache-Control": "no-store", **headers})


def _error(status: int, message: str, **headers: str) -> web.Response:
    return _json({"ok": False, "error": message}, status, **headers)


Handler = Callable[[web.Request], Awaitable[web.StreamResponse]]


class _Client:
    """One WebSocket page: a bounded queue of serialised messages and its sender task."""

    def __init__(self, ws: web.WebSocketResponse) -> None:
        self.ws = ws
        self.queue: asyncio.Queue[str] = asyncio.Queue(CLIENT_QUEUE)
        self.overflowed = False

    def offer(self, text: str) -> None:
        try:
            self.queue.put_nowait(text)
        except asyncio.QueueFull:
            self.overflowed = True


class ControlServer:
    """HTTP + WebSocket + static page server over a :class:`DaemonControl`.

    ``port`` 0 binds an ephemeral port; :attr:`url` is the bound address after ``start()``.
    ``push_hz`` is the rate of full-state pushes to pages; ``tile_url`` an optional map tile
    URL template (``https://.../{z}/{x}/{y}.png``) handed to pages (no default: offline)."""

    def __init__(self, control: DaemonControl, host: str = "127.0.0.1", port: int = 8080,
                 token: str | None = None, *, push_hz: float = 4.0,
                 tile_url: str | None = None) -> None:
        if token is not None and not token:
            raise ValueError("token must not be empty")
        if not (math.isfinite(push_hz) and 0.1 <= push_hz <= 50.0):
            raise ValueError(f"push_hz must be in [0.1, 50], got {push_hz}")
        self.control = control
        self.host = host
        self.port = port
        self.token = token if token is not None else new_token()
        self.push_hz = push_hz
        self.tile_url = tile_url
        self._runner: web.AppRunner | None = None
        self._url: str | None = None
        self._clients: set[_Client] = set()
        self._events: deque[dict[str, Any]] = deque(maxlen=EVENT_BUFFER)
        self._notable: deque[dict[str, Any]] = deque(maxlen=NOTABLE_BUFFER)
        self._notable_evicted = 0  # seq of the newest notable event no longer buffered
        self._seq = 0
        self._pending: list[dict[str, Any]] = []
        self._pending_dropped = 0
        self._tasks: list[asyncio.Task[None]] = []
        self._stopping = False
        self._closing: set[asyncio.Task[bool]] = set()
        self.instance = secrets.token_hex(4)  # tells a page its daemon was restarted

    # ----------------------------------------------------------------- lifecycle

    @property
    def url(self) -> str:
        """``http://HOST:PORT`` actually bound (after ``start()``)."""
        if self._url is None:
            raise RuntimeError("ControlServer not started")
        return self._url

    async def start(self) -> None:
        """Bind and serve; raises OSError if the address is taken."""
        warning = binding_warning(self.host)
        if warning:
            log.warning(warning)
        self._seed_events()
        app = web.Application(client_max_size=MAX_BODY_BYTES, middlewares=[self._middleware])
        r = app.router
        r.add_get("/", self._index)
        r.add_get("/index.html", self._index)
        r.add_get("/static/{name}", self._static)
        r.add_get("/api/state", self._get_state)
        r.add_get("/api/session", self._get_session)
        r.add_get("/api/targets", self._get_targets)
        r.add_get("/api/targets/{id}", self._get_target)
        r.add_post("/api/targets", self._post_target)
        r.add_put("/api/targets/{id}", self._move_target)
        r.add_patch("/api/targets/{id}", self._move_target)
        r.add_delete("/api/targets/{id}", self._delete_target)
        r.add_get("/api/vehicles", self._get_vehicles)
        r.add_get("/api/vehicles/{id}", self._get_vehicle)
        r.add_post("/api/vehicles/{id}/{action}", self._vehicle_action)
        r.add_get("/api/events", self._get_events)
        r.add_get("/ws", self._websocket)
        self._runner = web.AppRunner(app, access_log=None, handle_signals=False)
        await self._runner.setup()
        site = web.TCPSite(self._runner, self.host, self.port)
        try:
            await site.start()
        except BaseException:
            await self._runner.cleanup()
            self._runner = None
            raise
        addresses = self._runner.addresses  # the sockets' (host, port, ...) as bound
        self.port = int(addresses[0][1]) if addresses else self.port
        shown = f"[{self.host}]" if ":" in self.host else self.host
        self._url = f"http://{shown}:{self.port}"
        self._tasks = [asyncio.create_task(self._pump_events(), name="control-events"),
                       asyncio.create_task(self._push_states(), name="control-push")]

    async def stop(self) -> None:
        """Close every page's WebSocket, stop the pushes and unbind."""
        self._stopping = True
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        self._tasks = []
        for client in list(self._clients):
            with contextlib.suppress(Exception):
                await client.ws.close(code=WSCloseCode.GOING_AWAY, message=b"daemon stopping")
        if self._runner is not None:
            await self._runner.cleanup()
            self._runner = None

    async def __aenter__(self) -> ControlServer:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    # ----------------------------------------------------------------- events & pushes

    def _seed_events(self) -> None:
        try:
            recent = self.control.state().get("events") or []
        except Exception:  # the daemon's state is its business; start anyway
            log.exception("control state() failed while seeding events")
            recent = []
        for line in recent:
            if isinstance(line, dict):
                self._record(line)

    def _record(self, line: dict[str, Any]) -> dict[str, Any]:
        self._seq += 1
        entry = {"seq": self._seq, "line": jsonable(line)}
        self._events.append(entry)
        if line.get("event") not in QUIET_EVENTS:
            if len(self._notable) == NOTABLE_BUFFER:
                self._notable_evicted = self._notable[0]["seq"]
            self._notable.append(entry)
        return entry

    async def _pump_events(self) -> None:
        """Buffer the daemon's journal events and fan them out in batches every 0.1 s."""
        flusher = asyncio.create_task(self._flush_events(), name="control-flush")
        try:
            async for line in self.control.subscribe():
                if not isinstance(line, dict):
                    continue
                entry = self._record(line)
                if self._clients and line.get("event") not in QUIET_EVENTS:
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
                self._broadcast(msg)

    async def _push_states(self) -> None:
        period_s = 1.0 / self.push_hz
        failed = False
        while True:
            await asyncio.sleep(period_s)
            if not self._clients:
                continue
            try:
                msg = self._state_message()
                failed = False
            except Exception:
                if not failed:
                    log.exception("control state() failed; pages keep their last state")
                failed = True
                continue
            self._broadcast(msg)

    def _state_message(self) -> str:
        return json.dumps({"type": "state", "state": jsonable(self.control.state()),
                           "seq": self._seq})

    def _broadcast(self, text: str) -> None:
        for client in list(self._clients):
            client.offer(text)
            if client.overflowed:
                self._clients.discard(client)
                task = asyncio.create_task(client.ws.close(
                    code=WSCloseCode.TRY_AGAIN_LATER, message=b"too slow, reconnect"))
                self._closing.add(task)
                task.add_done_callback(self._closing.discard)

    # ----------------------------------------------------------------- plumbing

    def _host_allowed(self, request: web.Request) -> bool:
        """Bound to loopback, only requests addressed to a loopback name are served: a web
        page elsewhere cannot read the API through DNS rebinding."""
        if not is_loopback(self.host):
            return True
        host = request.headers.get("Host", "")
        name = host.rsplit(":", 1)[0] if not host.endswith("]") else host
        if host.startswith("["):
            name = host[1:].split("]", 1)[0]
        return is_loopback(name)

    @web.middleware
    async def _middleware(self, request: web.Request, handler: Handler) -> web.StreamResponse:
        if not self._host_allowed(request):
            return _error(403, "Host header is not a loopback address (DNS rebinding?)")
        try:
            response = await handler(request)
        except web.HTTPException as exc:
            if not request.path.startswith("/api/"):
                raise
            if isinstance(exc, web.HTTPRequestEntityTooLarge):
                return _error(413, f"body: larger than {MAX_BODY_BYTES} bytes")
            return _error(exc.status, exc.reason or "error")
        except RequestError as exc:
            return _error(400, str(exc))
        except Exception as exc:
            log.exception("control request %s %s failed", request.method, request.path)
            return _error(500, f"daemon error: {type(exc).__name__}: {exc}"[:200])
        response.headers.setdefault("X-Content-Type-Options", "nosniff")
        return response

    def authorized(self, request: web.Request) -> bool:
        """The request carries the write token (Bearer header or ``?token=``)."""
        header = request.headers.get("Authorization", "")
        presented = None
        if header[:7].lower() == "bearer ":
            presented = header[7:].strip()
        elif "token" in request.query:
            presented = request.query["token"]
        if not presented:
            return False
        return hmac.compare_digest(presented.encode(), self.token.encode())

    def _require_token(self, request: web.Request) -> web.Response | None:
        if self.authorized(request):
            return None
        return _error(401, "missing or wrong token (send Authorization: Bearer <token>)",
                      **{"WWW-Authenticate": 'Bearer realm="floe"'})

    async def _body(self, request: web.Request) -> Any:
        raw = await request.read()
        if not raw.strip():
            raise RequestError("body: empty (expected a JSON object)")
        try:
            return json.loads(raw)
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise RequestError(f"body: malformed JSON ({exc})") from None

    def _state(self) -> dict[str, Any]:
        state = self.control.state()
        return state if isinstance(state, dict) else {}

    def _find(self, kind: str, wanted: str) -> dict[str, Any] | None:
        """A vehicle/target by id; vehicles also by name or system id."""
        items = [i for i in self._state().get(kind) or [] if isinstance(i, dict)]
        for item in items:
            if str(item.get("id")) == wanted:
                return item
        if kind == "vehicles":
            for key in ("name", "system_id"):
                for item in items:
                    if item.get(key) is not None and str(item.get(key)) == wanted:
                        return item
        return None

    @staticmethod
    def _reply(reply: Any, ok_status: int = 200) -> web.Response:
        if not isinstance(reply, dict):
            return _error(500, "daemon gave no reply")
        if reply.get("ok"):
            return _json(reply, ok_status)
        return _json({**reply, "error": str(reply.get("error") or "refused")}, 409)

    # ----------------------------------------------------------------- pages

    async def _index(self, request: web.Request) -> web.StreamResponse:
        return web.FileResponse(WEB_DIR / "index.html", headers={
            "Content-Type": "text/html; charset=utf-8", "Cache-Control": "no-cache",
            "Content-Security-Policy": CSP, "Referrer-Policy": "no-referrer"})

    async def _static(self, request: web.Request) -> web.StreamResponse:
        name = request.match_info["name"]
        if name not in STATIC_FILES:
            raise web.HTTPNotFound()
        return web.FileResponse(WEB_DIR / name, headers={
            "Content-Type": f"{STATIC_FILES[name]}; charset=utf-8",
            "Cache-Control": "no-cache"})

    # ----------------------------------------------------------------- reads

    async def _get_state(self, request: web.Request) -> web.Response:
        return _json(self._state())

    async def _get_session(self, request: web.Request) -> web.Response:
        return _json({"write": self.authorized(request), "push_hz": self.push_hz,
                      "tile_url": self.tile_url, "version": 1})

    async def _get_targets(self, request: web.Request) -> web.Response:
        state = self._state()
        return _json({"t": state.get("t"), "targets": state.get("targets") or []})

    async def _get_target(self, request: web.Request) -> web.Response:
        target_id = request.match_info["id"]
        item = self._find("targets", target_id)
        if item is None:
            return _error(404, f"unknown target {target_id!r}")
        return _json(item)

    async def _get_vehicles(self, request: web.Request) -> web.Response:
        state = self._state()
        return _json({"t": state.get("t"), "vehicles": state.get("vehicles") or []})

    async def _get_vehicle(self, request: web.Request) -> web.Response:
        vehicle_id = request.match_info["id"]
        item = self._find("vehicles", vehicle_id)
        if item is None:
            return _error(404, f"unknown vehicle {vehicle_id!r}")
        return _json(item)

    async def _get_events(self, request: web.Request) -> web.Response:
        try:
            since = int(request.query.get("since", "0"))
            limit = int(request.query.get("limit", str(EVENT_BUFFER)))
        except ValueError:
            raise RequestError("since/limit: expected integers") from None
        if limit < 1:
            raise RequestError("limit: must be >= 1")
        notable = request.query.get("notable", "0") not in ("0", "false", "")
        buffer = self._notable if notable else self._events
        events = [e for e in buffer if e["seq"] > since][:limit]
        if notable:
            missed = max(0, self._notable_evicted - since)
        else:
            oldest = self._events[0]["seq"] if self._events else self._seq + 1
            missed = max(0, oldest - since - 1)
        return _json({"events": events, "last": self._seq, "missed": missed})

    # ----------------------------------------------------------------- writes

    async def _post_target(self, request: web.Request) -> web.Response:
        if (denied := self._require_token(request)) is not None:
            return denied
        target_id, kwargs = parse_target_body(await self._body(request))
        reply = await self.control.add_target(target_id, **kwargs)
        return self._reply(reply, 201)

    async def _move_target(self, request: web.Request) -> web.Response:
        if (denied := self._require_token(request)) is not None:
            return denied
        target_id = request.match_info["id"]
        kwargs = parse_move_body(await self._body(request))
        if self._find("targets", target_id) is None:
            return _error(404, f"unknown target {target_id!r}")
        return self._reply(await self.control.move_target(target_id, **kwargs))

    async def _delete_target(self, request: web.Request) -> web.Response:
        if (denied := self._require_token(request)) is not None:
            return denied
        target_id = request.match_info["id"]
        if self._find("targets", target_id) is None:
            return _error(404, f"unknown target {target_id!r}")
        return self._reply(await self.control.remove_target(target_id))

    async def _vehicle_action(self, request: web.Request) -> web.Response:
        if (denied := self._require_token(request)) is not None:
            return denied
        action = request.match_info["action"]
        if action not in VEHICLE_ACTIONS:
            return _error(404, f"unknown action {action!r} (one of {', '.join(VEHICLE_ACTIONS)})")
        wanted = request.match_info["id"]
        vehicle = self._find("vehicles", wanted)
        if vehicle is None:
            return _error(404, f"unknown vehicle {wanted!r}")
        return self._reply(await self.control.vehicle_action(str(vehicle["id"]), action))

    # ----------------------------------------------------------------- websocket

    async def _websocket(self, request: web.Request) -> web.StreamResponse:
        ws = web.WebSocketResponse(heartbeat=20.0, max_msg_size=4096)
        await ws.prepare(request)
        client = _Client(ws)
        try:
            since_text = request.query.get("since")
            since = int(since_text) if since_text is not None else None
        except ValueError:
            since = None
        if request.query.get("instance", self.instance) != self.instance:
            since = None  # sequence numbers of another daemon run: start afresh
        await ws.send_str(json.dumps({"type": "hello", "version": 1, "push_hz": self.push_hz,
                                      "tile_url": self.tile_url, "instance": self.instance}))
        with contextlib.suppress(Exception):
            await ws.send_str(self._state_message())
        backlog = list(self._notable)
        backlog = ([e for e in backlog if e["seq"] > since] if since is not None
                   else backlog[-CATCH_UP_EVENTS:])
        missed = max(0, self._notable_evicted - since) if since is not None else 0
        for start in range(0, len(backlog), EVENT_BATCH_MAX):
            await ws.send_str(json.dumps({"type": "events",
                                          "events": backlog[start:start + EVENT_BATCH_MAX],
                                          "dropped": missed if start == 0 else 0}))
        if self._stopping:
            await ws.close(code=WSCloseCode.GOING_AWAY)
            return ws
        self._clients.add(client)
        sender = asyncio.create_task(self._send_loop(client), name="control-ws-send")
        try:
            async for msg in ws:  # pages send nothing we act on; this detects the close
                if msg.type == WSMsgType.ERROR:
                    break
        finally:
            self._clients.discard(client)
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await sender
        return ws

    async def _send_loop(self, client: _Client) -> None:
        while not client.ws.closed:
            text = await client.queue.get()
            try:
                await asyncio.wait_for(client.ws.send_str(text), 5.0)
            except (ConnectionError, TimeoutError, RuntimeError):
                await client.ws.close(code=WSCloseCode.TRY_AGAIN_LATER)
                return
