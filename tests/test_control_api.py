"""The control API over real sockets on 127.0.0.1 (ephemeral port) against a fake daemon:
reads, auth on every write, malformed bodies, unknown ids, refusals, events, WebSocket."""

from __future__ import annotations

import asyncio
import json
from collections.abc import Awaitable, Callable
from typing import Any

import aiohttp
import pytest
from test_control_fake import FakeControl

from groundstation.daemon.control.server import (
    ControlServer,
    binding_warning,
    is_loopback,
    jsonable,
    new_token,
)

TOKEN = "tok-123"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
Scenario = Callable[[ControlServer, FakeControl, aiohttp.ClientSession], Awaitable[None]]


def serve(scenario: Scenario, fake: FakeControl | None = None) -> FakeControl:
    async def main() -> FakeControl:
        control = fake or FakeControl()
        server = ControlServer(control, "127.0.0.1", 0, TOKEN, push_hz=20.0)
        await server.start()
        try:
            async with aiohttp.ClientSession(base_url=server.url) as http:
                await asyncio.wait_for(scenario(server, control, http), 10.0)
        finally:
            control.close()
            await server.stop()
        return control

    return asyncio.run(main())


async def call(http: aiohttp.ClientSession, method: str, path: str, *,
               body: Any = None, raw: str | None = None,
               headers: dict[str, str] | None = None) -> tuple[int, Any]:
    data = raw if raw is not None else (None if body is None else json.dumps(body))
    async with http.request(method, path, data=data, headers=headers) as resp:
        text = await resp.text()
        try:
            return resp.status, json.loads(text)
        except json.JSONDecodeError:
            return resp.status, text


def test_token_and_loopback_helpers() -> None:
    a, b = new_token(), new_token()
    assert a != b and len(a) >= 20
    for host in ("127.0.0.1", "127.5.0.1", "::1", "[::1]", "localhost"):
        assert is_loopback(host), host
        assert binding_warning(host) is None
    for host in ("0.0.0.0", "::", "192.168.1.10", "gcs.example"):
        assert not is_loopback(host), host
        warning = binding_warning(host)
        assert warning is not None and host in warning
    assert jsonable({"a": float("nan"), "b": (1.0, float("inf"))}) == {"a": None, "b": [1.0, None]}
    with pytest.raises(ValueError, match="token"):
        ControlServer(FakeControl(), token="")


def test_reads_need_no_token() -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        assert server.url.startswith("http://127.0.0.1:") and server.port != 0
        status, state = await call(http, "GET", "/api/state")
        assert status == 200
        assert [v["id"] for v in state["vehicles"]] == ["uav1", "uav2", "uav3"]
        status, body = await call(http, "GET", "/api/targets")
        assert status == 200 and {t["id"] for t in body["targets"]} == {"A", "B", "C"}
        status, body = await call(http, "GET", "/api/targets/B")
        assert status == 200 and body["vy_m_s"] == 1.0
        status, body = await call(http, "GET", "/api/vehicles")
        assert status == 200 and len(body["vehicles"]) == 3
        for ref in ("uav2", "X8-2", "2"):  # id, name or system id
            status, body = await call(http, "GET", f"/api/vehicles/{ref}")
            assert status == 200 and body["id"] == "uav2", ref
        status, body = await call(http, "GET", "/api/vehicles/nope")
        assert status == 404 and "nope" in body["error"]
        status, body = await call(http, "GET", "/api/session")
        assert status == 200 and body["write"] is False
        status, body = await call(http, "GET", "/api/session", headers=AUTH)
        assert body["write"] is True
        status, body = await call(http, "GET", "/api/nothing-here")
        assert status == 404 and body["ok"] is False
        for host in ("localhost:8080", "127.0.0.1", "[::1]:80"):
            status, _ = await call(http, "GET", "/api/state", headers={"Host": host})
            assert status == 200, host
        for host in ("evil.example:8080", "evil.example", "10.0.0.1:80", "[2001:db8::1]:80"):
            status, body = await call(http, "GET", "/api/state", headers={"Host": host})
            assert status == 403 and "Host" in body["error"], host  # DNS rebinding

    fake = serve(scenario)
    assert fake.calls == []


WRITES = [
    ("POST", "/api/targets", {"x_m": 1.0, "y_m": 2.0}),
    ("PUT", "/api/targets/A", {"x_m": 1.0, "y_m": 2.0}),
    ("PATCH", "/api/targets/A", {"x_m": 1.0, "y_m": 2.0}),
    ("DELETE", "/api/targets/A", None),
    ("POST", "/api/vehicles/uav1/launch", None),
    ("POST", "/api/vehicles/uav1/release", None),
    ("POST", "/api/vehicles/uav1/resume", None),
]


def test_every_write_needs_the_token() -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        for method, path, body in WRITES:
            for headers in (None, {"Authorization": "Bearer wrong"},
                            {"Authorization": TOKEN}, {"Authorization": "Bearer "}):
                status, reply = await call(http, method, path, body=body, headers=headers)
                assert status == 401, (method, path, headers)
                assert "token" in reply["error"]
            status, _ = await call(http, method, path + "?token=wrong", body=body)
            assert status == 401

    fake = serve(scenario)
    assert fake.calls == []  # nothing reached the daemon


def test_writes_with_token_reach_the_daemon() -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        status, reply = await call(http, "POST", "/api/targets", headers=AUTH, body={
            "id": "ice-7", "x_m": 120.5, "y_m": -40.0, "vx_m_s": 0.5, "vy_m_s": -1,
            "sigma0": 3})
        assert status == 201 and reply == {"ok": True, "error": None, "target": "ice-7"}
        status, reply = await call(http, "POST", "/api/targets", headers=AUTH,
                                   body={"lat_deg": 78.94, "lon_deg": 11.93})
        assert status == 201 and reply["target"] == "T1"
        status, reply = await call(http, "POST", f"/api/targets?token={TOKEN}",
                                   body={"x_m": 5, "y_m": 6})
        assert status == 201 and reply["target"] == "T2"
        status, reply = await call(http, "PUT", "/api/targets/ice-7", headers=AUTH,
                                   body={"x_m": 130.0, "y_m": -45.0})
        assert status == 200 and reply["ok"]
        status, reply = await call(http, "PATCH", "/api/targets/A", headers=AUTH,
                                   body={"lat_deg": 78.9, "lon_deg": 11.9})
        assert status == 200
        status, reply = await call(http, "DELETE", "/api/targets/B", headers=AUTH)
        assert status == 200 and reply["target"] == "B"
        status, reply = await call(http, "POST", "/api/vehicles/X8-3/release", headers=AUTH)
        assert status == 200 and reply["vehicle"] == "uav3"
        status, reply = await call(http, "POST", "/api/vehicles/1/launch", headers=AUTH)
        assert status == 200
        status, body = await call(http, "GET", "/api/targets")
        assert {t["id"] for t in body["targets"]} == {"A", "C", "ice-7", "T1", "T2"}

    fake = serve(scenario)
    assert fake.calls == [
        ("add", "ice-7", 120.5, -40.0, None, None, 0.5, -1.0, 3.0),
        ("add", None, None, None, 78.94, 11.93, 0.0, 0.0, None),
        ("add", None, 5.0, 6.0, None, None, 0.0, 0.0, None),
        ("move", "ice-7", 130.0, -45.0, None, None),
        ("move", "A", None, None, 78.9, 11.9),
        ("remove", "B"),
        ("vehicle", "uav3", "release"),
        ("vehicle", "uav1", "launch"),
    ]


BAD_BODIES: list[tuple[str, str, str]] = [
    ("/api/targets", "{not json", "malformed JSON"),
    ("/api/targets", "", "empty"),
    ("/api/targets", "[1, 2]", "JSON object"),
    ("/api/targets", '{"x_m": 1}', "y_m"),
    ("/api/targets", '{"y_m": 1}', "x_m"),
    ("/api/targets", "{}", "position"),
    ("/api/targets", '{"x_m": "1", "y_m": 2}', "x_m"),
    ("/api/targets", '{"x_m": true, "y_m": 2}', "x_m"),
    ("/api/targets", '{"x_m": NaN, "y_m": 2}', "x_m"),
    ("/api/targets", '{"x_m": 1e999, "y_m": 2}', "x_m"),
    ("/api/targets", '{"x_m": 1, "y_m": 2, "lat_deg": 3, "lon_deg": 4}', "not both"),
    ("/api/targets", '{"lat_deg": 95, "lon_deg": 4}', "lat_deg"),
    ("/api/targets", '{"lat_deg": 5, "lon_deg": -181}', "lon_deg"),
    ("/api/targets", '{"x_m": 1, "y_m": 2, "sigma0": -1}', "sigma0"),
    ("/api/targets", '{"x_m": 1, "y_m": 2, "vx_m_s": "fast"}', "vx_m_s"),
    ("/api/targets", '{"x_m": 1, "y_m": 2, "colour": "red"}', "colour"),
    ("/api/targets", '{"id": 7, "x_m": 1, "y_m": 2}', "id"),
    ("/api/targets", '{"id": "", "x_m": 1, "y_m": 2}', "id"),
    ("/api/targets", '{"id": "a/b", "x_m": 1, "y_m": 2}', "id"),
    ("/api/targets", '{"id": "' + "x" * 65 + '", "x_m": 1, "y_m": 2}', "id"),
]


def test_malformed_bodies_are_400_with_the_field() -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        for path, raw, field in BAD_BODIES:
            status, reply = await call(http, "POST", path, raw=raw, headers=AUTH)
            assert status == 400, raw
            assert field in reply["error"], (raw, reply)
            assert "\n" not in reply["error"]
        status, reply = await call(http, "PUT", "/api/targets/A", raw='{"x_m": 1}',
                                   headers=AUTH)
        assert status == 400 and "y_m" in reply["error"]
        status, reply = await call(http, "PUT", "/api/targets/A",
                                   raw='{"x_m": 1, "y_m": 2, "vx_m_s": 1}', headers=AUTH)
        assert status == 400 and "vx_m_s" in reply["error"]
        status, reply = await call(http, "POST", "/api/targets", raw="x" * 70_000,
                                   headers=AUTH)
        assert status == 413
        status, reply = await call(http, "GET", "/api/events?since=abc")
        assert status == 400 and "since" in reply["error"]

    fake = serve(scenario)
    assert fake.calls == []


def test_unknown_ids_are_404_and_refusals_409() -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        status, reply = await call(http, "PUT", "/api/targets/ZZ", body={"x_m": 1, "y_m": 2},
                                   headers=AUTH)
        assert status == 404 and "ZZ" in reply["error"]
        status, reply = await call(http, "DELETE", "/api/targets/ZZ", headers=AUTH)
        assert status == 404
        status, reply = await call(http, "POST", "/api/vehicles/uav9/launch", headers=AUTH)
        assert status == 404 and "uav9" in reply["error"]
        status, reply = await call(http, "POST", "/api/vehicles/uav1/explode", headers=AUTH)
        assert status == 404 and "explode" in reply["error"]
        assert fake.calls == []
        status, reply = await call(http, "POST", "/api/targets", headers=AUTH,
                                   body={"id": "A", "x_m": 1, "y_m": 2})
        assert status == 409 and reply == {"ok": False, "error": "target A exists"}
        fake.refuse = "vehicle uav1 is not on the ground"
        status, reply = await call(http, "POST", "/api/vehicles/uav1/launch", headers=AUTH)
        assert status == 409 and reply["error"] == "vehicle uav1 is not on the ground"
        assert fake.calls[-1] == ("vehicle", "uav1", "launch")

    serve(scenario)


class BrokenControl(FakeControl):
    async def remove_target(self, target_id: str) -> dict[str, Any]:
        raise RuntimeError("boom")


def test_daemon_exception_is_a_one_line_500() -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        status, reply = await call(http, "DELETE", "/api/targets/A", headers=AUTH)
        assert status == 500 and "boom" in reply["error"]
        status, _ = await call(http, "GET", "/api/state")  # still serving
        assert status == 200

    serve(scenario, BrokenControl())


def test_events_since() -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        status, body = await call(http, "GET", "/api/events")
        assert status == 200
        assert [e["line"]["event"] for e in body["events"]] == ["start"]  # seeded from state
        last = body["last"]
        fake.emit("loiter_end", vehicle="uav1")
        fake.emit("plan", routes={})
        for _ in range(100):
            status, body = await call(http, "GET", f"/api/events?since={last}")
            if len(body["events"]) == 2:
                break
            await asyncio.sleep(0.01)
        assert [e["line"]["event"] for e in body["events"]] == ["loiter_end", "plan"]
        assert [e["seq"] for e in body["events"]] == [last + 1, last + 2]
        status, body = await call(http, "GET", f"/api/events?since={last}&limit=1")
        assert [e["line"]["event"] for e in body["events"]] == ["loiter_end"]
        fake.emit("detection", target="A")
        fake.emit("track", target="A", sigma=1.0)
        fake.emit("upload", vehicle="uav1", ok=True)
        for _ in range(100):
            status, body = await call(http, "GET", f"/api/events?since={last + 2}")
            if len(body["events"]) == 3:
                break
            await asyncio.sleep(0.01)
        assert [e["line"]["event"] for e in body["events"]] == ["detection", "track", "upload"]
        status, body = await call(http, "GET", f"/api/events?since={last + 2}&notable=1")
        assert [e["line"]["event"] for e in body["events"]] == ["upload"]
        assert body["missed"] == 0

    serve(scenario)


def test_page_and_static_files_are_served() -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        async with http.get("/") as resp:
            html = await resp.text()
            assert resp.status == 200 and "<canvas" in html
            assert "default-src 'self'" in resp.headers["Content-Security-Policy"]
        for name, kind in (("app.js", "javascript"), ("style.css", "css")):
            async with http.get(f"/static/{name}") as resp:
                assert resp.status == 200 and kind in resp.headers["Content-Type"]
                assert len(await resp.read()) > 100
        async with http.get("/static/..%2Fserver.py") as resp:
            assert resp.status == 404
        async with http.get("/static/index.html.bak") as resp:
            assert resp.status == 404

    serve(scenario)


async def next_message(ws: aiohttp.ClientWebSocketResponse, kind: str) -> dict[str, Any]:
    while True:
        msg = await asyncio.wait_for(ws.receive_json(), 5.0)
        if msg["type"] == kind:
            return msg


def test_websocket_pushes_state_and_events_and_catches_up() -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        async with http.ws_connect("/ws") as ws:
            hello = await ws.receive_json()
            assert hello["type"] == "hello" and hello["push_hz"] == 20.0
            assert hello["instance"] == server.instance
            first = await ws.receive_json()  # the full state at once, not after a period
            assert first["type"] == "state" and len(first["state"]["vehicles"]) == 3
            backlog = await ws.receive_json()
            assert backlog["type"] == "events"
            assert [e["line"]["event"] for e in backlog["events"]] == ["start"]
            fake.advance(2.0)
            state = await next_message(ws, "state")
            assert state["state"]["t"] == 2.0
            fake.emit("detection", vehicle="uav2", target="A")  # not pushed to pages
            fake.emit("loiter_end", vehicle="uav2", nan=float("nan"))
            events = await next_message(ws, "events")
            assert events["events"][0]["line"] == {"t": 2.0, "event": "loiter_end",
                                                   "vehicle": "uav2", "nan": None}
            seen = events["events"][-1]["seq"]
        # Events that happen while the page is away are replayed on reconnect.
        fake.emit("link_lost", vehicle="uav3")
        fake.emit("link_restored", vehicle="uav3")
        await asyncio.sleep(0.05)
        async with http.ws_connect(f"/ws?since={seen}") as ws:
            assert (await ws.receive_json())["type"] == "hello"
            assert (await ws.receive_json())["type"] == "state"
            catch_up = await ws.receive_json()
            assert [e["line"]["event"] for e in catch_up["events"]] == [
                "link_lost", "link_restored"]
            assert catch_up["dropped"] == 0
        async with http.ws_connect(f"/ws?since={seen}&instance={server.instance}") as ws:
            for _ in range(2):
                await ws.receive_json()
            same = await ws.receive_json()
            assert [e["line"]["event"] for e in same["events"]] == ["link_lost", "link_restored"]
        # A page whose numbers belong to an earlier run of the daemon gets the recent history.
        async with http.ws_connect(f"/ws?since={seen + 2}&instance=0ld") as ws:
            for _ in range(2):
                await ws.receive_json()
            fresh = await ws.receive_json()
            assert [e["line"]["event"] for e in fresh["events"]] == [
                "start", "loiter_end", "link_lost", "link_restored"]  # no detection

    serve(scenario)


def test_stop_closes_pages_and_unbinds() -> None:
    async def main() -> None:
        fake = FakeControl()
        server = ControlServer(fake, "127.0.0.1", 0, TOKEN)
        await server.start()
        url = server.url
        async with aiohttp.ClientSession() as http, http.ws_connect(url + "/ws") as ws:
            await ws.receive_json()
            await server.stop()
            closing = (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED)
            while (await asyncio.wait_for(ws.receive(), 5.0)).type not in closing:
                pass
        with pytest.raises(aiohttp.ClientConnectionError):
            async with aiohttp.ClientSession() as http, http.get(url + "/api/state"):
                pass

    asyncio.run(main())


def test_a_page_that_cannot_keep_up_is_dropped_and_can_reconnect() -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        async with http.ws_connect("/ws") as ws:
            for _ in range(3):
                await ws.receive_json()
            for i in range(200):  # faster than any sender: no await in between
                server.pages.broadcast(json.dumps({"type": "noise", "i": i}))
            closing = (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED)
            while (msg := await asyncio.wait_for(ws.receive(), 5.0)).type not in closing:
                pass
            assert ws.close_code == aiohttp.WSCloseCode.TRY_AGAIN_LATER, msg
        async with http.ws_connect("/ws") as ws:
            assert (await ws.receive_json())["type"] == "hello"

    serve(scenario)


class NoJournal(FakeControl):
    def subscribe(self) -> Any:
        async def broken() -> Any:
            raise RuntimeError("journal gone")
            yield {}  # an async generator

        return broken()


def test_states_still_pushed_when_the_event_stream_fails() -> None:
    async def scenario(server: ControlServer, fake: FakeControl,
                       http: aiohttp.ClientSession) -> None:
        async with http.ws_connect("/ws") as ws:
            fake.advance(1.0)
            state = await next_message(ws, "state")
            while state["state"]["t"] != 1.0:
                state = await next_message(ws, "state")

    serve(scenario, NoJournal())
