"""The daemon's control surface: a small HTTP JSON API, a WebSocket push and the live page.

Everything here only calls a :class:`~groundstation.daemon.control.contract.DaemonControl`;
the daemon owns the state. Endpoints (all JSON; docs/control.md has curl examples)::

    GET    /api/state                     the state document (contract.py)
    GET    /api/targets | /api/targets/ID  targets (or one)
    POST   /api/targets                   {id?, x_m, y_m | lat_deg, lon_deg,
                                           vx_m_s?, vy_m_s?, sigma0?}     -> 201
    PUT    /api/targets/ID  (or PATCH)    {x_m, y_m | lat_deg, lon_deg, sigma0?}
                                          (an operator's fix: the track is re-seated)
    DELETE /api/targets/ID
    GET    /api/vehicles | /api/vehicles/ID
    POST   /api/vehicles/ID/ACTION        ACTION: launch | resume | release | rtl
    POST   /api/fleet/ACTION              ACTION: release | rtl | resume (every vehicle;
                                          the answer says per vehicle what happened)
    GET    /api/events?since=N[&limit=M][&notable=1]
                                          journal events with sequence number > N
                                          (notable=1: operator events only)
    GET    /api/session                   {"write": bool, ...} for the presented token
    GET    /api/server                    limits, allowed origins, refusal counters
    GET    /ws                            WebSocket: hello, full state at once, then the
                                          state at ``push_hz`` and event batches
    GET    /                              the live page (web/), no CDN, no build step

Reads need no token. Every write needs ``Authorization: Bearer <token>`` (or ``?token=``)
and is answered 401 without it, 400 with a one-line reason for a malformed body, 404 for an
unknown id and 409 when the daemon refuses it (``{"ok": false, "error": ...}``). Writes and
the WebSocket upgrade are refused 403 from a foreign ``Origin`` (``guard.py``);
limits (``ControlLimits``) answer 409 (targets), 413 (body), 408 (slow body), 429 (write
rate) and 503 (WebSocket pages); headers must arrive within ``header_timeout_s``.

The WebSocket pages (messages, catch-up, bounds) are ``push.PageHub``'s. The loop is kept
free (``pacing.py``): every request first takes a unit of the server's :class:`TurnBudget`
(at most 8 per loop turn), and reads answer from the one shared :class:`StateDocument`
(built at most every 0.1 s, made stale by every write).
"""

from __future__ import annotations

import asyncio
import hmac
import json
import logging
import math
import secrets
import time
from collections.abc import Awaitable, Callable, Iterable
from pathlib import Path
from typing import Any

from aiohttp import web
from aiohttp.http_exceptions import HttpProcessingError

from groundstation.daemon.control.bodies import (
    RequestError,
    jsonable,
    parse_move_body,
    parse_target_body,
)
from groundstation.daemon.control.contract import FLEET_ACTIONS, VEHICLE_ACTIONS, DaemonControl
from groundstation.daemon.control.guard import (
    ControlLimits,
    OriginPolicy,
    RejectLog,
    WriteRateLimiter,
    is_loopback,
)
from groundstation.daemon.control.pacing import StateDocument, TurnBudget
from groundstation.daemon.control.push import PageHub
from groundstation.daemon.control.tiles import LEAFLET_FILES, TileArchive, leaflet_dir

__all__ = [
    "ControlLimits",
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
STATIC_FILES = {"app.js": "text/javascript", "layers.js": "text/javascript",
                "geo.js": "text/javascript",
                "style.css": "text/css"}
WRITE_METHODS = frozenset({"POST", "PUT", "PATCH", "DELETE"})
CSP = ("default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data: http: "
       "https:; connect-src 'self' ws: wss:; frame-ancestors 'none'")


def new_token() -> str:
    """A fresh random write token (URL-safe, 24 characters, 144 bits)."""
    return secrets.token_urlsafe(18)


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


class Refused(Exception):
    """A request refused at the edge: HTTP ``status`` with the one-line ``message``."""

    def __init__(self, status: int, message: str, **headers: str) -> None:
        super().__init__(message)
        self.status = status
        self.headers = headers


class _ProtocolLog(logging.LoggerAdapter[logging.Logger]):
    """aiohttp's own log of requests it could not parse (a line too long, a bad header):
    a client's mistake is counted and logged as one rate-limited line, without traceback;
    anything else keeps its traceback."""

    def __init__(self, rejects: RejectLog) -> None:
        super().__init__(logging.getLogger("aiohttp.server"), {})
        self.rejects = rejects

    def _client_fault(self, exc_info: Any) -> bool:
        if not isinstance(exc_info, HttpProcessingError):
            return False
        lines = str(exc_info.message or "").strip().splitlines() or [""]
        self.rejects.note("bad_http", f"{type(exc_info).__name__}: {lines[0][:100]}",
                          time.monotonic())
        return True

    def exception(self, msg: object, *args: Any, exc_info: Any = True, **kw: Any) -> None:
        if not self._client_fault(exc_info):
            self.logger.exception(msg, *args, exc_info=exc_info, **kw)

    def debug(self, msg: object, *args: Any, **kw: Any) -> None:
        if not self._client_fault(kw.get("exc_info")):
            self.logger.debug(msg, *args, **kw)


class ControlServer:
    """HTTP + WebSocket + static page server over a :class:`DaemonControl`.

    ``port`` 0 binds an ephemeral port; :attr:`url` is the bound address after ``start()``.
    ``push_hz`` is the rate of full-state pushes to pages; ``tile_url`` an optional map tile
    URL template (``https://.../{z}/{x}/{y}.png``) handed to pages (no default: offline);
    ``tiles`` the operator's MBTiles or PMTiles file (``tiles/``), served as
    ``/tiles/{z}/{x}/{y}`` (it sets ``tile_url``). Leaflet's files are served from
    ``xstatic-leaflet``.
    ``allow_origins``: origins (``scheme://host[:port]``) allowed besides the page's own;
    ``limits``: see :class:`ControlLimits`; ``budget``: the work allowed per loop turn and
    ``document``: the shared state document (``pacing.py``; by default 8 units per turn and
    a document at most 0.1 s old)."""

    def __init__(self, control: DaemonControl, host: str = "127.0.0.1", port: int = 8080,
                 token: str | None = None, *, push_hz: float = 4.0,
                 tile_url: str | None = None, tiles: TileArchive | None = None,
                 allow_origins: Iterable[str] = (),
                 limits: ControlLimits | None = None, budget: TurnBudget | None = None,
                 document: StateDocument | None = None) -> None:
        if token is not None and not token:
            raise ValueError("token must not be empty")
        if not (math.isfinite(push_hz) and 0.1 <= push_hz <= 50.0):
            raise ValueError(f"push_hz must be in [0.1, 50], got {push_hz}")
        self.control = control
        self.host = host
        self.port = port
        self.token = token if token is not None else new_token()
        self.push_hz = push_hz
        self.tiles = tiles
        if tiles is not None:  # the operator's file, served here (offline)
            tile_url = "/tiles/{z}/{x}/{y}"
        self.tile_url = tile_url
        self.leaflet = leaflet_dir()
        self.origins = OriginPolicy(host, allow_origins)  # ValueError on a bad origin
        self.limits = limits or ControlLimits()
        self.rejects = RejectLog(log)
        self._writes = WriteRateLimiter(self.limits.max_writes_per_s)
        self._runner: web.AppRunner | None = None
        self._url: str | None = None
        self.instance = secrets.token_hex(4)  # tells a page its daemon was restarted
        self.budget = budget or TurnBudget()
        self.document = document or StateDocument(control)
        self.pages = PageHub(control, self.rejects, push_hz=push_hz, tile_url=tile_url,
                             instance=self.instance, max_clients=self.limits.max_ws_clients,
                             budget=self.budget, document=self.document)

    # ----------------------------------------------------------------- lifecycle

    @property
    def url(self) -> str:
        """``http://HOST:PORT`` actually bound (after ``start()``)."""
        if self._url is None:
            raise RuntimeError("ControlServer not started")
        return self._url

    async def start(self, push: bool = True) -> None:
        """Bind and serve; raises OSError if the address is taken. With ``push=False`` the
        live pages are fed only while :meth:`run` runs (the daemon's task tree)."""
        warning = binding_warning(self.host)
        if warning:
            log.warning(warning)
        app = web.Application(client_max_size=self.limits.max_body_bytes,
                              middlewares=[self._middleware])
        r = app.router
        r.add_get("/", self._index)
        r.add_get("/index.html", self._index)
        r.add_get("/static/{name}", self._static)
        r.add_get("/vendor/leaflet/{name:.+}", self._leaflet)
        r.add_get("/tiles/{z}/{x}/{y}", self._tile)
        r.add_get("/api/state", self._get_state)
        r.add_get("/api/session", self._get_session)
        r.add_get("/api/server", self._get_server)
        r.add_get("/api/targets", self._get_targets)
        r.add_get("/api/targets/{id}", self._get_target)
        r.add_post("/api/targets", self._post_target)
        r.add_put("/api/targets/{id}", self._move_target)
        r.add_patch("/api/targets/{id}", self._move_target)
        r.add_delete("/api/targets/{id}", self._delete_target)
        r.add_get("/api/vehicles", self._get_vehicles)
        r.add_get("/api/vehicles/{id}", self._get_vehicle)
        r.add_post("/api/vehicles/{id}/{action}", self._vehicle_action)
        r.add_post("/api/fleet/{action}", self._fleet_action)
        r.add_get("/api/events", self._get_events)
        r.add_get("/ws", self.pages.handle)
        # aiohttp's keep-alive timer also runs from the connection's start until a whole
        # request has arrived: headers sent byte by byte are cut off after this (slowloris);
        # the rest of a body not read (408, 413) is awaited as long, then the socket closed.
        timeout_s = self.limits.header_timeout_s
        self._runner = web.AppRunner(app, access_log=None, handle_signals=False,
                                     keepalive_timeout=timeout_s, lingering_time=timeout_s,
                                     logger=_ProtocolLog(self.rejects))
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
        self.pages.start(push)

    async def run(self) -> None:
        """Feed the live pages from a child task group until cancelled."""
        await self.pages.run()

    async def stop(self) -> None:
        """Close every page's WebSocket, stop the pushes and unbind."""
        await self.pages.stop()
        if self._runner is not None:
            await self._runner.cleanup()
            self._runner = None

    async def __aenter__(self) -> ControlServer:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

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

    def _origin_refusal(self, request: web.Request) -> web.Response | None:
        """403 for a WebSocket upgrade or a write from an origin the rule does not allow."""
        if request.method not in WRITE_METHODS and request.path != "/ws":
            return None
        origin = request.headers.get("Origin")
        if self.origins.allowed(origin, request.headers.get("Host"), self.port):
            return None
        shown = (origin or "")[:80]
        self.rejects.note("origin_refused", f"{request.method} {request.path} from Origin "
                          f"{shown!r}", time.monotonic())
        return _error(403, f"Origin {shown} is not allowed here (the page's own origin is; "
                      "add others with --http-allow-origin)")

    @web.middleware
    async def _middleware(self, request: web.Request, handler: Handler) -> web.StreamResponse:
        await self.budget.take()  # at most budget.per_turn requests per loop turn
        if not self._host_allowed(request):
            self.rejects.note("host_refused", "Host header is not a loopback address",
                              time.monotonic())
            host_refusal = _error(403, "Host header is not a loopback address (DNS rebinding?)")
            host_refusal.force_close()  # a refused crowd is closed a few per turn, by us
            return host_refusal
        if (refused := self._origin_refusal(request)) is not None:
            refused.force_close()
            return refused
        if request.method in WRITE_METHODS:
            self.document.invalidate()  # a write checks ids against the state as it is now
        try:
            response = await handler(request)
        except web.HTTPException as exc:
            if not request.path.startswith("/api/"):
                raise
            if isinstance(exc, web.HTTPRequestEntityTooLarge):
                self.rejects.note("body_too_large", request.path, time.monotonic())
                return _error(413, f"body: larger than {self.limits.max_body_bytes} bytes")
            return _error(exc.status, exc.reason or "error")
        except RequestError as exc:
            self.rejects.note("bad_request", f"{request.method} {request.path}: {exc}",
                              time.monotonic())
            return _error(400, str(exc))
        except Refused as exc:
            return _error(exc.status, str(exc), **exc.headers)
        except Exception as exc:
            log.exception("control request %s %s failed", request.method, request.path)
            return _error(500, f"daemon error: {type(exc).__name__}: {exc}"[:200])
        response.headers.setdefault("X-Content-Type-Options", "nosniff")
        return response

    def authorized(self, request: web.Request) -> bool:
        """The request carries the write token (Bearer header or ``?token=``). A token that
        is not valid UTF-8 (or any other garbage) is simply not the token."""
        try:
            header = request.headers.get("Authorization", "")
            presented = None
            if header[:7].lower() == "bearer ":
                presented = header[7:].strip()
            elif "token" in request.query:
                presented = request.query["token"]
            if not presented:
                return False
            return hmac.compare_digest(presented.encode("utf-8"), self.token.encode("utf-8"))
        except (UnicodeError, ValueError):
            return False

    def _require_token(self, request: web.Request) -> web.Response | None:
        """401 without the token; 429 beyond the write rate (tokens of the bucket are spent
        by authorised writes only)."""
        if not self.authorized(request):
            self.rejects.note("unauthorized", f"{request.method} {request.path}",
                              time.monotonic())
            return _error(401, "missing or wrong token (send Authorization: Bearer <token>)",
                          **{"WWW-Authenticate": 'Bearer realm="floe"'})
        if not self._writes.allow(time.monotonic()):
            self.rejects.note("rate_limited", f"{request.method} {request.path}",
                              time.monotonic())
            return _error(429, f"too many writes (limit {self.limits.max_writes_per_s:g} per "
                          "second); slow down", **{"Retry-After": "1"})
        return None

    async def _body(self, request: web.Request) -> Any:
        """The JSON body, read within ``header_timeout_s`` (408 otherwise); a body that is
        not JSON (bad UTF-8, nested too deep, an integer of thousands of digits) is 400."""
        try:
            async with asyncio.timeout(self.limits.header_timeout_s):
                raw = await request.read()
        except TimeoutError:
            self.rejects.note("body_timeout", request.path, time.monotonic())
            raise Refused(408, f"body: not received within {self.limits.header_timeout_s:g} s",
                          Connection="close") from None
        if not raw.strip():
            raise RequestError("body: empty (expected a JSON object)")
        try:
            return json.loads(raw)
        except (ValueError, RecursionError) as exc:  # JSON, UTF-8 and int-size errors
            reason = str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__
            raise RequestError(f"body: malformed JSON ({reason})") from None

    def _state(self) -> dict[str, Any]:
        """The shared state document (``pacing.StateDocument``): do not change it."""
        return self.document.doc()

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

    async def _leaflet(self, request: web.Request) -> web.StreamResponse:
        name = request.match_info["name"]
        if self.leaflet is None or name not in LEAFLET_FILES:
            raise web.HTTPNotFound()
        return web.FileResponse(self.leaflet / name, headers={
            "Content-Type": LEAFLET_FILES[name], "Cache-Control": "max-age=3600"})

    async def _tile(self, request: web.Request) -> web.Response:
        if self.tiles is None:
            raise web.HTTPNotFound()
        try:
            z, x, y = (int(request.match_info[k].split(".")[0]) for k in ("z", "x", "y"))
        except ValueError:
            raise web.HTTPNotFound() from None
        if self.tiles.cold(z, x, y):  # a PMTiles leaf to decode first: off the loop
            await asyncio.to_thread(self.tiles.warm, z, x, y)
        tile = self.tiles.response(z, x, y, request.headers.get("Accept-Encoding", ""))
        if tile is None:
            raise web.HTTPNotFound()
        return web.Response(body=tile.data, content_type=tile.content_type,
                            headers=tile.headers)

    # ----------------------------------------------------------------- reads

    async def _get_state(self, request: web.Request) -> web.Response:
        return web.Response(text=self.document.text(), content_type="application/json",
                            headers={"Cache-Control": "no-store"})

    async def _get_session(self, request: web.Request) -> web.Response:
        return _json({"write": self.authorized(request), "push_hz": self.push_hz,
                      "tile_url": self.tile_url, "version": 1,
                      "tiles": self.tiles.info.to_dict() if self.tiles else None})

    async def _get_server(self, request: web.Request) -> web.Response:
        allow = sorted(f"{s}://{h if ':' not in h else f'[{h}]'}:{p}"
                       for s, h, p in self.origins.allow)
        return _json({"limits": self.limits.to_dict(), "allow_origins": allow,
                      "ws_clients": self.pages.open, "counters": dict(self.rejects.counts)})

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
            limit = int(request.query.get("limit", "5000"))
        except ValueError:
            raise RequestError("since/limit: expected integers") from None
        if limit < 1:
            raise RequestError("limit: must be >= 1")
        notable = request.query.get("notable", "0") not in ("0", "false", "")
        return _json(self.pages.buffer.since(since, limit, notable))

    # ----------------------------------------------------------------- writes

    async def _post_target(self, request: web.Request) -> web.Response:
        if (denied := self._require_token(request)) is not None:
            return denied
        target_id, kwargs = parse_target_body(await self._body(request))
        count = len(self._state().get("targets") or [])
        if count >= self.limits.max_targets:
            self.rejects.note("target_limit", f"{count} targets", time.monotonic())
            return _error(409, f"targets: limit of {self.limits.max_targets} reached "
                          "(--http-max-targets); remove one first")
        reply = await self.control.add_target(target_id, **kwargs)
        self.document.invalidate()
        return self._reply(reply, 201)

    async def _move_target(self, request: web.Request) -> web.Response:
        if (denied := self._require_token(request)) is not None:
            return denied
        target_id = request.match_info["id"]
        kwargs = parse_move_body(await self._body(request))
        if self._find("targets", target_id) is None:
            return _error(404, f"unknown target {target_id!r}")
        reply = await self.control.move_target(target_id, **kwargs)
        self.document.invalidate()
        return self._reply(reply)

    async def _delete_target(self, request: web.Request) -> web.Response:
        if (denied := self._require_token(request)) is not None:
            return denied
        target_id = request.match_info["id"]
        if self._find("targets", target_id) is None:
            return _error(404, f"unknown target {target_id!r}")
        reply = await self.control.remove_target(target_id)
        self.document.invalidate()
        return self._reply(reply)

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
        reply = await self.control.vehicle_action(str(vehicle["id"]), action)
        self.document.invalidate()
        return self._reply(reply)

    async def _fleet_action(self, request: web.Request) -> web.Response:
        if (denied := self._require_token(request)) is not None:
            return denied
        action = request.match_info["action"]
        if action not in FLEET_ACTIONS:
            return _error(404, f"unknown fleet action {action!r} (one of "
                          f"{', '.join(FLEET_ACTIONS)})")
        reply = await self.control.fleet_action(action)
        self.document.invalidate()
        return self._reply(reply)
