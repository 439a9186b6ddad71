"""The control API against hostile clients, over real sockets on 127.0.0.1 (ephemeral port):
foreign origins, limits (targets, pages, write rate, body), slowloris, garbage tokens and
bodies, and a WebSocket page that never reads."""

from __future__ import annotations

import asyncio
import json
import logging
import socket
import time
from collections.abc import Awaitable, Callable
from typing import Any

import aiohttp
import pytest
from test_control_fake import FakeControl

from groundstation.daemon.control.guard import (
    ControlLimits,
    OriginPolicy,
    RejectLog,
    WriteRateLimiter,
    parse_origin,
)
from groundstation.daemon.control.pages import CLIENT_QUEUE, CLIENT_QUEUE_BYTES
from groundstation.daemon.control.push import WS_CLOSE_TIMEOUT_S, WS_SEND_TIMEOUT_S
from groundstation.daemon.control.server import ControlServer

TOKEN = "tok-456"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
Scenario = Callable[[ControlServer, FakeControl, aiohttp.ClientSession], Awaitable[None]]


def serve(scenario: Scenario, *, limit_s: float = 20.0, **kwargs: Any) -> FakeControl:
    async def main() -> FakeControl:
        control = FakeControl()
        server = ControlServer(control, "127.0.0.1", 0, TOKEN, push_hz=20.0, **kwargs)
        await server.start()
        try:
            async with aiohttp.ClientSession(base_url=server.url) as http:
                await asyncio.wait_for(scenario(server, control, http), limit_s)
        finally:
            control.close()
            await server.stop()
        return control

    return asyncio.run(main())


async def call(http: aiohttp.ClientSession, method: str, path: str, *, body: Any = None,
               raw: str | None = None, headers: dict[str, str] | None = None
               ) -> tuple[int, Any]:
    data = raw if raw is not None else (None if body is None else json.dumps(body))
    async with http.request(method, path, data=data, headers=headers) as resp:
        text = await resp.text()
        try:
            return resp.status, json.loads(text)
        except json.JSONDecodeError:
            return resp.status, text


async def raw_request(port: int, data: bytes) -> tuple[int, dict[str, Any]]:
    """Send raw bytes, return the status and the JSON body of the answer."""
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    try:
        writer.write(data)
        await writer.drain()
        head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), 5.0)
        lines = head.decode("latin-1").split("\r\n")
        length = next(int(line.split(":", 1)[1]) for line in lines
                      if line.lower().startswith("content-length:"))
        body = await asyncio.wait_for(reader.readexactly(length), 5.0)
    finally:
        writer.close()
    return int(lines[0].split()[1]), json.loads(body)


# ------------------------------------------------------------------ pure rules


def test_origin_rule() -> None:
    assert parse_origin("HTTP://LocalHost:8080") == ("http", "localhost", 8080)
    assert parse_origin("https://gcs.example") == ("https", "gcs.example", 443)
    assert parse_origin("http://[::1]:9/") == ("http", "::1", 9)
    for bad in ("gcs.local:8080", "ftp://x", "http://x/path", "http://u@x", "null",
                "http://x:99999", "http://"):
        with pytest.raises(ValueError):
            parse_origin(bad)
    loop = OriginPolicy("127.0.0.1", ["https://gcs.example"])
    assert loop.allowed(None, "127.0.0.1:8080", 8080)  # no Origin: not a browser
    assert loop.allowed("http://127.0.0.1:8080", "127.0.0.1:8080", 8080)
    assert loop.allowed("http://localhost:8080", "127.0.0.1:8080", 8080)  # other loopback form
    assert loop.allowed("http://[::1]:8080", "127.0.0.1:8080", 8080)
    assert loop.allowed("http://localhost:9999", "localhost:9999", 8080)  # an SSH tunnel
    assert loop.allowed("https://gcs.example", "127.0.0.1:8080", 8080)  # allow-listed
    assert loop.allowed("https://GCS.example:443", "127.0.0.1:8080", 8080)
    for foreign in ("http://evil.example", "http://localhost:3000", "https://127.0.0.1:8080",
                    "null", "", "http://gcs.example"):
        assert not loop.allowed(foreign, "127.0.0.1:8080", 8080), foreign
    lan = OriginPolicy("192.168.1.20")
    assert lan.allowed("http://192.168.1.20:8080", "192.168.1.20:8080", 8080)
    assert not lan.allowed("http://localhost:8080", "192.168.1.20:8080", 8080)
    anywhere = OriginPolicy("0.0.0.0")
    assert anywhere.allowed("http://localhost:8080", "10.0.0.5:8080", 8080)
    with pytest.raises(ValueError):
        OriginPolicy("127.0.0.1", ["not an origin"])


def test_limits_rate_and_reject_log(caplog: pytest.LogCaptureFixture) -> None:
    with pytest.raises(ValueError, match="max_targets"):
        ControlLimits(max_targets=0)
    with pytest.raises(ValueError, match="header_timeout_s"):
        ControlLimits(header_timeout_s=float("nan"))
    bucket = WriteRateLimiter(2.0)  # burst 4
    assert [bucket.allow(0.0) for _ in range(5)] == [True] * 4 + [False]
    assert bucket.allow(0.5) and not bucket.allow(0.5)  # one token per 0.5 s
    log = RejectLog(logging.getLogger("test.rejects"), every_s=10.0)
    with caplog.at_level(logging.WARNING, logger="test.rejects"):
        for i in range(100):
            log.note("origin_refused", "evil", i * 0.01)
        log.note("origin_refused", "evil", 20.0)
    assert log.counts == {"origin_refused": 101}
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 2 and "+99 more" in lines[1]


# ------------------------------------------------------------------ origins


def test_foreign_origin_refused_on_websocket_and_writes() -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        evil = {"Origin": "http://evil.example", **AUTH}
        status, reply = await call(http, "POST", "/api/targets", headers=evil,
                                   body={"x_m": 1, "y_m": 2})
        assert status == 403 and "Origin" in reply["error"] and "\n" not in reply["error"]
        for method, path in (("DELETE", "/api/targets/A"), ("POST", "/api/vehicles/1/launch"),
                             ("PUT", "/api/targets/A")):
            status, _ = await call(http, method, path, headers=evil, body={"x_m": 1, "y_m": 2})
            assert status == 403, (method, path)
        with pytest.raises(aiohttp.WSServerHandshakeError) as refused:
            await http.ws_connect("/ws", origin="http://evil.example")
        assert refused.value.status == 403
        with pytest.raises(aiohttp.WSServerHandshakeError) as refused:
            await http.ws_connect("/ws", origin=f"http://localhost:{server.port + 1}")
        assert refused.value.status == 403
        # Reads stay open (the browser's CORS rules keep foreign pages from reading them).
        status, _ = await call(http, "GET", "/api/state", headers={"Origin": "http://evil.x"})
        assert status == 200
        status, info = await call(http, "GET", "/api/server")
        assert info["counters"]["origin_refused"] == 6

    fake = serve(scenario)
    assert fake.calls == []


def test_own_and_allow_listed_origins_accepted() -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        own = server.url  # http://127.0.0.1:PORT, and the Host header matches
        for origin in (own, f"http://localhost:{server.port}", "https://ops.example:8443"):
            async with http.ws_connect("/ws", origin=origin) as ws:
                assert (await asyncio.wait_for(ws.receive_json(), 5.0))["type"] == "hello"
        status, reply = await call(http, "POST", "/api/targets", body={"x_m": 1, "y_m": 2},
                                   headers={"Origin": own, **AUTH})
        assert status == 201, reply
        status, reply = await call(http, "POST", "/api/targets", body={"x_m": 3, "y_m": 4},
                                   headers={"Origin": "https://ops.example:8443", **AUTH})
        assert status == 201, reply
        status, reply = await call(http, "POST", "/api/targets", body={"x_m": 5, "y_m": 6},
                                   headers=AUTH)  # no Origin: curl, gcs target
        assert status == 201, reply
        status, reply = await call(http, "POST", "/api/targets", body={"x_m": 5, "y_m": 6},
                                   headers={"Origin": own})  # the origin is no token
        assert status == 401
        status, info = await call(http, "GET", "/api/server")
        assert info["allow_origins"] == ["https://ops.example:8443"]
        assert "origin_refused" not in info["counters"]

    fake = serve(scenario, allow_origins=["https://ops.example:8443"])
    assert [c[0] for c in fake.calls] == ["add", "add", "add"]


# ------------------------------------------------------------------ limits


def test_target_limit_and_write_rate() -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        for x in (1, 2):  # the fake starts with A, B, C
            status, _ = await call(http, "POST", "/api/targets", headers=AUTH,
                                   body={"x_m": x, "y_m": 0})
            assert status == 201
        status, reply = await call(http, "POST", "/api/targets", headers=AUTH,
                                   body={"x_m": 3, "y_m": 0})
        assert status == 409 and "limit of 5" in reply["error"]
        status, _ = await call(http, "DELETE", "/api/targets/A", headers=AUTH)
        assert status == 200
        status, _ = await call(http, "POST", "/api/targets", headers=AUTH,
                               body={"x_m": 3, "y_m": 0})
        assert status == 201
        status, info = await call(http, "GET", "/api/server")
        assert info["limits"]["max_targets"] == 5 and info["counters"]["target_limit"] == 1

    fake = serve(scenario, limits=ControlLimits(max_targets=5))
    assert len(fake.targets) == 5

    async def flood(server: ControlServer, fake: FakeControl,
                    http: aiohttp.ClientSession) -> None:
        statuses = []
        for x in range(3):
            status, reply = await call(http, "POST", "/api/targets", headers=AUTH,
                                       body={"x_m": x, "y_m": 0})
            statuses.append(status)
        assert statuses == [201, 429, 429], statuses  # a burst of 1, then 1 per 10 s
        assert "too many writes" in reply["error"]
        status, _ = await call(http, "POST", "/api/targets", body={"x_m": 0, "y_m": 0})
        assert status == 401  # unauthorised writes do not spend the budget...

    fake = serve(flood, limits=ControlLimits(max_writes_per_s=0.1))
    assert len(fake.calls) == 1


def test_websocket_page_limit() -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        first = await http.ws_connect("/ws")
        second = await http.ws_connect("/ws")
        with pytest.raises(aiohttp.WSServerHandshakeError) as refused:
            await http.ws_connect("/ws")
        assert refused.value.status == 503
        status, reply = await call(http, "GET", "/ws")  # the refusal as JSON
        assert status == 503 and "too many live pages" in reply["error"]
        await first.close()
        while server.pages.open > 1:
            await asyncio.sleep(0.01)
        async with http.ws_connect("/ws") as third:
            assert (await asyncio.wait_for(third.receive_json(), 5.0))["type"] == "hello"
        await second.close()
        status, info = await call(http, "GET", "/api/server")
        assert info["counters"]["ws_clients_full"] == 2

    serve(scenario, limits=ControlLimits(max_ws_clients=2))


def test_slowloris_headers_and_slow_body_are_cut_off() -> None:
    timeout_s = 1.0

    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        reader, writer = await asyncio.open_connection("127.0.0.1", server.port)
        start = time.monotonic()
        headers = b"GET /api/state HTTP/1.1\r\nHost: 127.0.0.1\r\n" + b"".join(
            b"X-Slow-%d: a\r\n" % i for i in range(100))
        cut_after_s = None
        for i in range(len(headers)):  # one byte every 0.1 s: never a whole request
            try:
                writer.write(headers[i:i + 1])
                await writer.drain()
                if await asyncio.wait_for(reader.read(1024), 0.1) == b"":
                    cut_after_s = time.monotonic() - start
                    break
            except TimeoutError:
                continue
            except ConnectionError:
                cut_after_s = time.monotonic() - start
                break
        writer.close()
        assert cut_after_s is not None and timeout_s * 0.9 <= cut_after_s < timeout_s + 3.0
        # Headers in time, then a body that never completes: 408 within the timeout too.
        start = time.monotonic()
        status, reply = await raw_request(server.port, (
            f"POST /api/targets HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer {TOKEN}"
            "\r\nContent-Type: application/json\r\nContent-Length: 100\r\n\r\n{\"x_m\": 1"
        ).encode())
        assert status == 408 and "body" in reply["error"]
        assert time.monotonic() - start < timeout_s + 3.0
        status, _ = await call(http, "GET", "/api/state")  # everyone else still served
        assert status == 200

    fake = serve(scenario, limits=ControlLimits(header_timeout_s=timeout_s))
    assert fake.calls == []


# ------------------------------------------------------------------ garbage in


def test_garbage_tokens_and_bodies_are_4xx_without_tracebacks(
        caplog: pytest.LogCaptureFixture) -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        body = b'{"x_m": 1, "y_m": 2}'
        for auth in (b"Bearer \xff\xfe\xfd", b"Bearer tok-45\xc3", b"\xff"):
            status, reply = await raw_request(server.port, (
                b"POST /api/targets HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: " + auth
                + b"\r\nContent-Length: %d\r\nConnection: close\r\n\r\n" % len(body) + body))
            assert status == 401 and "token" in reply["error"], auth
        status, _ = await call(http, "POST", "/api/targets?token=%FF%FE", body={"x_m": 1})
        assert status == 401
        huge_int = "1" + "0" * 400
        for raw, field in (
            ('{"x_m": ' + huge_int + ', "y_m": 2}', "x_m"),
            ('{"x_m": 1, "y_m": -' + huge_int + "}", "y_m"),
            ('{"x_m": 1e300, "y_m": 2}', "x_m"),
            ('{"x_m": 1, "y_m": 2, "vx_m_s": 1e6}', "vx_m_s"),
            ('{"x_m": 1, "y_m": 2, "sigma0": 1e30}', "sigma0"),
            ('{"x_m": Infinity, "y_m": 2}', "x_m"),
            ('{"x_m": -NaN, "y_m": 2}', "body"),
            ('{"x_m": 1' + "0" * 5000 + ', "y_m": 2}', "body"),  # beyond int digit limit
            ("[" * 30_000 + "]" * 30_000, "body"),  # nested deeper than the parser goes
            ('{"x_m": 1, "y_m": 2, "__proto__": {}}', "__proto__"),
        ):
            status, reply = await call(http, "POST", "/api/targets", raw=raw, headers=AUTH)
            assert status == 400 and field in reply["error"], (raw[:40], reply)
            assert "\n" not in reply["error"]
        status, reply = await raw_request(server.port, (
            b"POST /api/targets HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer "
            + TOKEN.encode() + b"\r\nContent-Length: 4\r\nConnection: close\r\n\r\n\xff\xfe{}"))
        assert status == 400 and "body" in reply["error"]
        status, _ = await call(http, "GET", "/api/events?since=" + "9" * 5000)
        assert status == 400
        for garbage in (b"GET /api/vehicles/" + b"x" * 10_000 + b" HTTP/1.1\r\n\r\n",
                        b"POST /api/targets HTTP/1.1\r\nContent-Length: abc\r\n\r\n"):
            reader, writer = await asyncio.open_connection("127.0.0.1", server.port)
            writer.write(garbage)
            answer = await asyncio.wait_for(reader.read(), 5.0)  # aiohttp answers and closes
            writer.close()
            assert answer.split()[1] == b"400"
        status, info = await call(http, "GET", "/api/server")
        assert info["counters"]["bad_http"] == 2 and info["counters"]["unauthorized"] == 4

    with caplog.at_level(logging.DEBUG):
        fake = serve(scenario)
    assert fake.calls == []
    assert not [r for r in caplog.records if r.exc_info or r.levelno >= logging.ERROR]


# ------------------------------------------------------------------ a page that never reads


def test_websocket_page_that_never_reads_is_bounded_and_dropped() -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        sock.setblocking(False)
        loop = asyncio.get_running_loop()
        await loop.sock_connect(sock, ("127.0.0.1", server.port))
        await loop.sock_sendall(sock, (
            f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{server.port}\r\nUpgrade: websocket\r\n"
            "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
            "Sec-WebSocket-Version: 13\r\n\r\n").encode())
        try:
            while not server.pages.clients:
                await asyncio.sleep(0.01)
            (client,) = server.pages.clients
            message = json.dumps({"type": "noise", "pad": "x" * 256_000})
            most, most_bytes, sent = 0, 0, 0
            deadline = time.monotonic() + WS_SEND_TIMEOUT_S + 10.0
            while server.pages.clients and time.monotonic() < deadline:
                server.pages.broadcast(message)  # 2.5 MB/s, never read
                sent += 1
                most, most_bytes = max(most, len(client)), max(most_bytes, client.queued_bytes)
                await asyncio.sleep(0.1)
            assert not server.pages.clients, "a page that never reads was never dropped"
            assert most <= CLIENT_QUEUE and most_bytes <= CLIENT_QUEUE_BYTES
            assert sent * len(message) > CLIENT_QUEUE_BYTES  # more than its queue may hold
            assert client.queued_bytes == 0  # freed when dropped
            # The connection is aborted, not left waiting for a close it will never read.
            deadline = time.monotonic() + WS_CLOSE_TIMEOUT_S + 5.0
            while server.pages.open and time.monotonic() < deadline:
                await asyncio.sleep(0.05)
            assert server.pages.open == 0
            _, info = await call(http, "GET", "/api/server")
            assert info["counters"]["ws_slow_evicted"] == 1
            async with http.ws_connect("/ws") as ws:  # others still served
                assert (await asyncio.wait_for(ws.receive_json(), 5.0))["type"] == "hello"
        finally:
            sock.close()

    serve(scenario, limit_s=40.0)


# ------------------------------------------------------------------ gcs run settings


def test_gcs_run_flags_and_config_keys(tmp_path: Any) -> None:
    from domain.errors import ConfigError
    from groundstation.commands.run import build_config

    path = tmp_path / "run.yaml"
    path.write_text("vehicles: [sim:1]\nhttp_allow_origins: [https://ops.example]\n"
                    "http_max_targets: 50\nhttp_header_timeout_s: 2.5\n", encoding="utf-8")
    config = build_config(["--config", str(path), "--http-max-ws-clients", "4",
                           "--http-max-writes-per-s", "5"])
    assert config.http.allow_origins == ("https://ops.example",)
    assert (config.http.max_targets, config.http.max_ws_clients) == (50, 4)
    assert (config.http.max_writes_per_s, config.http.header_timeout_s) == (5.0, 2.5)
    config = build_config(["--vehicles", "sim:1", "--http-allow-origin", "http://a.example:81",
                           "--http-allow-origin", "http://b.example"])
    assert config.http.allow_origins == ("http://a.example:81", "http://b.example")
    defaults = build_config(["--vehicles", "sim:1"])
    assert ControlLimits().max_targets == defaults.http.max_targets == 100
    assert ControlLimits().max_ws_clients == defaults.http.max_ws_clients == 16
    for bad, key in ((["--http-allow-origin", "ops.example"], "--http-allow-origin"),
                     (["--http-max-targets", "0"], "--http-max-targets"),
                     (["--http-max-ws-clients", "-1"], "--http-max-ws-clients"),
                     (["--http-header-timeout", "inf"], "--http-header-timeout")):
        with pytest.raises(ConfigError, match=key):
            build_config(["--vehicles", "sim:1", *bad])
