"""The live page in a real headless browser (Debian's chromium + chromium-driver, Selenium).

Two backends: the fake daemon of test_control_fake.py moved in real time (vehicles circling,
targets drifting), and the real daemon ``gcs run --vehicles sim:3 --sim-airborne --http
127.0.0.1:0`` in a subprocess. On each: the page loads and draws the map, the vehicles move
between two reads of the page's state and two screenshots, a target added by clicking on the
map with the token appears in the daemon's state (and, for the real daemon, in its next
plan), a target can be removed from the page, and a read-only page cannot change anything;
the header shows the wind the daemon plans with (the map draws its arrow). The tracker's
layers: every target and track is drawn in its status' style (``window.floe.layers`` counts
what the last frame drew, checked against the page's state), search cells are shaded by
value (canvas pixels), the counts head the targets table, and a ``track_confirmed`` note
reaches the events pane while a ``track_born`` does not.
Screenshots are saved in pytest's tmp dir and checked (PNG, map drawn: many colours).

Marked ``browser``. Without chromium/chromedriver/selenium the test fails in CI (CI set) with
the install command, and is skipped (with that reason) elsewhere.
"""

from __future__ import annotations

import asyncio
import io
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time
import urllib.parse
import urllib.request
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from environment import need
from test_control_fake import FakeControl, ServerThread

pytestmark = pytest.mark.browser

CHROMIUM = os.environ.get("FLOE_CHROMIUM", "/usr/bin/chromium")
CHROMEDRIVER = os.environ.get("FLOE_CHROMEDRIVER", "/usr/bin/chromedriver")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--disable-dev-shm-usage", "--window-size=1280,800"]
WAIT_S = 10.0


def _missing() -> str | None:
    for path in (CHROMIUM, CHROMEDRIVER):
        if not (os.path.exists(path) or shutil.which(path)):
            return (f"{path} not found: install Debian's browser with "
                    "'apt-get install -y chromium chromium-driver'")
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium not installed: pip install 'selenium>=4.15,<5'"
    return None


@pytest.fixture(scope="module")
def driver(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    reason = _missing()
    need(reason is None, f"live-page browser test: {reason}")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in FLAGS:
        options.add_argument(flag)
    options.add_argument(f"--user-data-dir={tmp_path_factory.mktemp('chromium-profile')}")
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    drv = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    drv.set_page_load_timeout(WAIT_S)
    drv.set_script_timeout(WAIT_S)
    try:
        yield drv
    finally:
        drv.quit()


# ------------------------------------------------------------------ backends


class Backend:
    url: str
    token: str
    real: bool


class FakeBackend(Backend):
    real = False

    def __init__(self, server: ServerThread) -> None:
        self.server = server
        self.url, self.token = server.url, server.token

    def writes(self) -> int:
        return int(self.server.call(lambda: len(self.server.control.calls)))


class DaemonBackend(Backend):
    real = True

    def __init__(self, proc: subprocess.Popen[str], url: str, token: str) -> None:
        self.proc, self.url, self.token = proc, url, token

    def writes(self) -> int:  # what a write would change: the targets
        return len(get(self.url, "/api/targets")["targets"])


def get(url: str, path: str) -> Any:
    with urllib.request.urlopen(url + path, timeout=5) as resp:
        return json.loads(resp.read())


def start_daemon(tmp: Path) -> DaemonBackend:
    cmd = [sys.executable, "-u", "-m", "groundstation.cli", "run", "--vehicles", "sim:3",
           "--sim-airborne", "--http", "127.0.0.1:0", "--detections", "off", "--speedup", "10",
           "--duration", "3000", "--status", "log", "--run-dir", str(tmp / "runs")]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            cwd=tmp)
    assert proc.stdout is not None
    deadline = time.monotonic() + 20.0
    lines: list[str] = []
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line)
        m = re.search(r"control API (http://\S+) token (\S+)", line)
        if m:
            return DaemonBackend(proc, m.group(1), m.group(2))
    proc.kill()
    proc.wait(5)
    raise AssertionError("gcs run did not print its control API:\n" + "".join(lines))


@pytest.fixture(params=["fake", "daemon"])
def backend(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Backend]:
    if request.param == "fake":
        with ServerThread(tick_s=0.1, token="page-token", push_hz=5.0) as server:
            yield FakeBackend(server)
        return
    daemon = start_daemon(tmp_path)
    try:
        yield daemon
    finally:
        daemon.proc.terminate()
        try:
            daemon.proc.wait(10)
        except subprocess.TimeoutExpired:
            daemon.proc.kill()
            daemon.proc.wait(5)


# ------------------------------------------------------------------ page helpers


def wait_for(cond: Callable[[], Any], what: str, timeout_s: float = WAIT_S) -> Any:
    deadline = time.monotonic() + timeout_s
    while True:
        value = cond()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def vehicle_positions(drv: Any) -> dict[str, tuple[float, float]]:
    state = drv.execute_script("return window.floe && window.floe.state")
    return {str(v["id"]): (v["x_m"], v["y_m"]) for v in (state or {}).get("vehicles", [])
            if v.get("x_m") is not None}


def screenshot(drv: Any, path: Path) -> bytes:
    png = drv.get_screenshot_as_png()
    path.write_bytes(png)
    return bytes(png)


def check_map_drawn(png: bytes) -> None:
    """A PNG, not blank: the map canvas region has many colours (grid, icons, ellipses)."""
    from PIL import Image

    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 5000
    image = Image.open(io.BytesIO(png)).convert("RGB")
    w, h = image.size
    region = image.crop((0, 40, int(w * 0.6), h))  # the map's side of the page
    colours = region.getcolors(maxcolors=1_000_000) or []
    assert len(colours) > 50, f"map looks empty: {len(colours)} colours"
    dominant = max(count for count, _ in colours) / (region.width * region.height)
    assert dominant < 0.97, f"map is {dominant:.0%} one colour"


def open_page(drv: Any, url: str) -> None:
    drv.get(url)
    wait_for(lambda: drv.execute_script(
        "return window.floe && window.floe.connected && window.floe.states >= 2"),
        "the page to connect and get states")


def click_map(drv: Any, dx: int, dy: int) -> tuple[float, float]:
    """Click at (dx, dy) pixels from the canvas centre; the world point the page computes."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    canvas = drv.find_element(By.ID, "map")
    ActionChains(drv).move_to_element_with_offset(canvas, dx, dy).perform()
    time.sleep(0.05)  # the pointer is over the map: the page stops re-fitting the view
    world = drv.execute_script(
        "const r = document.getElementById('map').getBoundingClientRect();"
        "return window.floe.toWorld(r.width / 2 + arguments[0], r.height / 2 + arguments[1]);",
        dx, dy)
    ActionChains(drv).click().perform()
    return float(world[0]), float(world[1])


def fetch_from_page(drv: Any, method: str, path: str, body: dict[str, Any] | None) -> int:
    status: int = drv.execute_async_script(
        "const done = arguments[arguments.length - 1];"
        "fetch(arguments[1], {method: arguments[0], headers: {'Content-Type': "
        "'application/json'}, body: arguments[2] ? JSON.stringify(arguments[2]) : undefined})"
        ".then(r => done(r.status), e => done(-1));", method, path, body)
    return status


# ------------------------------------------------------------------ the test


def test_live_page(driver: Any, backend: Backend, tmp_path: Path) -> None:
    from selenium.webdriver.common.by import By

    drv = driver
    shots = tmp_path / "screenshots"
    shots.mkdir()
    drv.get("about:blank")
    drv.get_log("browser")  # drop what an earlier page logged

    # --- read-only page: loads, draws, shows vehicles moving, cannot change anything
    open_page(drv, backend.url + "/")
    assert drv.execute_script("return window.floe.write") is False
    assert "can-write" not in (drv.find_element(By.TAG_NAME, "body").get_attribute("class")
                               or "")
    assert drv.find_element(By.ID, "access").text == "read-only"
    assert not drv.find_element(By.ID, "add-target").is_displayed()
    wait_for(lambda: len(vehicle_positions(drv)) == 3, "three vehicles on the page")
    # the wind the core plans with, in the header (the fake: its vehicles' estimate; the
    # daemon without --wind or a windy scenario: still air, said so)
    wind = drv.find_element(By.ID, "wind").text
    assert wind == ("wind 12 m/s from 270° (vehicles uav1,uav2)" if not backend.real
                    else "wind calm (none)"), wind
    rows = drv.find_elements(By.CSS_SELECTOR, "#vehicles tbody tr")
    assert len(rows) == 3
    check_tracker_layers(drv, backend)
    first = vehicle_positions(drv)
    png1 = screenshot(drv, shots / "read-only-1.png")
    check_map_drawn(png1)
    time.sleep(1.0)
    second = wait_for(lambda: (p := vehicle_positions(drv)) and max(
        math.dist(p[k], first[k]) for k in first) > 20.0 and p, "the vehicles to move")
    png2 = screenshot(drv, shots / "read-only-2.png")
    check_map_drawn(png2)
    assert png1 != png2  # the map was redrawn with the vehicles elsewhere
    assert min(math.dist(second[k], first[k]) for k in first) > 1.0  # every vehicle moved

    before = backend.writes()
    targets_before = {t["id"] for t in get(backend.url, "/api/targets")["targets"]}
    click_map(drv, 60, -40)  # a click on a read-only map only selects
    assert fetch_from_page(drv, "POST", "/api/targets", {"x_m": 1.0, "y_m": 2.0}) == 401
    assert fetch_from_page(drv, "DELETE", "/api/targets/" + (sorted(targets_before) or ["A"])[0],
                           None) == 401
    time.sleep(0.3)
    assert backend.writes() == before
    assert {t["id"] for t in get(backend.url, "/api/targets")["targets"]} == targets_before

    # --- with the token: add a target by clicking on the map
    open_page(drv, f"{backend.url}/?token={backend.token}")
    wait_for(lambda: drv.execute_script("return window.floe.write"), "the token to be accepted")
    assert "token=" not in drv.current_url  # removed from the address bar
    assert drv.find_element(By.ID, "access").text == "control"
    drv.find_element(By.ID, "new-id").send_keys("WEB1")
    drv.find_element(By.ID, "add-target").click()
    assert drv.execute_script("return window.floe.mode") == "add"
    x, y = click_map(drv, 90, -60)

    def added() -> dict[str, Any] | None:
        return next((t for t in get(backend.url, "/api/targets")["targets"]
                     if t["id"] == "WEB1"), None)

    target = wait_for(added, "the clicked target in the daemon's state")
    assert math.dist((target["x_m"], target["y_m"]), (x, y)) < 5.0
    wait_for(lambda: "WEB1" in drv.find_element(By.ID, "targets").text,
             "the new target in the page's table")
    wait_for(lambda: "target_added" in drv.find_element(By.ID, "events").text,
             "the target_added event on the page")
    shown = {li.text.split()[1] for li in drv.find_elements(By.CSS_SELECTOR, "#events li")
             if len(li.text.split()) > 1}
    assert "target_added" in shown and not shown & {"truth", "track", "detection", "input"}

    def added_seq() -> int | None:
        events = get(backend.url, "/api/events?since=0&notable=1")["events"]
        return next((e["seq"] for e in events if e["line"].get("event") == "target_added"
                     and e["line"].get("target") == "WEB1"), None)

    seq = wait_for(added_seq, "the target_added event in the daemon's events")

    def next_plan() -> dict[str, Any] | None:
        """The first plan after the target was added (the daemon's order, not our clock)."""
        events = get(backend.url, f"/api/events?since={seq}&notable=1")["events"]
        return next((e["line"] for e in events if e["line"].get("event") == "plan"), None)

    # The real daemon's default commit policy keeps every vehicle on its target until its
    # loiter ends, so its next plan comes at the next loiter end: up to a loiter (60 s) plus
    # a transit of mission time after the add, ~10 s of wall time at 10x on an idle host and
    # more with both cores busy. Wait for that plan event (bounded generously in wall time:
    # 60 s is 600 s of mission time at 10x) and require the new target in it.
    plan = wait_for(next_plan, "the next plan after the target was added", timeout_s=60.0)
    assert "WEB1" in json.dumps(plan.get("routes")), plan
    time.sleep(0.5)
    check_map_drawn(screenshot(drv, shots / "control-added.png"))

    # --- and remove it from the page: select its row, press Remove
    row = drv.find_element(By.CSS_SELECTOR, '#targets tbody tr[data-id="WEB1"]')
    row.click()
    drv.find_element(By.ID, "remove-target").click()
    wait_for(lambda: added() is None, "the target to be removed")
    check_map_drawn(screenshot(drv, shots / "control-removed.png"))
    for name in ("read-only-1", "read-only-2", "control-added", "control-removed"):
        assert (shots / f"{name}.png").stat().st_size > 5000

    if isinstance(backend, FakeBackend):
        check_pan_and_zoom(drv, backend)
        check_reconnect(drv, backend)
    check_fence_and_gps(drv, backend)
    errors = [e for e in drv.get_log("browser") if e.get("level") == "SEVERE"
              and "401" not in e.get("message", "")]  # the read-only writes above
    drv.get("about:blank")  # leave no page reconnecting to a stopped server
    assert errors == [], errors


def expected_layers(state: dict[str, Any]) -> dict[str, int]:
    """What the map must draw for ``state``: each target in its tracker status (confirmed
    when the tracker does not list it), each listed track without a target entry, and every
    search cell."""
    def finite(item: dict[str, Any]) -> bool:
        return all(isinstance(item.get(k), int | float) and math.isfinite(item[k])
                   for k in ("x_m", "y_m"))

    status = {str(t["id"]): t["status"] for t in state.get("tracks") or []}
    out = {"search": len(state.get("search_cells") or []), "confirmed": 0, "tentative": 0,
           "prior": 0}
    ids = set()
    for t in state.get("targets") or []:
        ids.add(str(t["id"]))
        if finite(t):
            out[status.get(str(t["id"]), "confirmed")] += 1
    for t in state.get("tracks") or []:
        if str(t["id"]) not in ids and finite(t):
            out[t["status"]] += 1
    return out


def pixel_blueness(drv: Any, x_m: float, y_m: float) -> int:
    """Blue minus red of the map canvas at world point (x_m, y_m), the median of a 5 x 5
    patch (a grid line or a label through the point does not decide)."""
    return int(drv.execute_script(
        "const c = document.getElementById('map'), d = window.devicePixelRatio || 1;"
        "const p = window.floe.toScreen(arguments[0], arguments[1]);"
        "const img = c.getContext('2d').getImageData(Math.round(p[0] * d) - 2,"
        " Math.round(p[1] * d) - 2, 5, 5).data; const v = [];"
        "for (let i = 0; i < img.length; i += 4) v.push(img[i + 2] - img[i]);"
        "v.sort((a, b) => a - b); return v[12];", x_m, y_m))


def check_tracker_layers(drv: Any, backend: Backend) -> None:
    """The tracker's layers are drawn as the state says (both backends); on the fake, which
    has every kind, also that each kind is there and the search shading follows value."""
    from selenium.webdriver.common.by import By

    def drawn_as_stated() -> dict[str, int] | None:
        state, layers = drv.execute_script(
            "return [window.floe.state, window.floe.layers]")
        want = expected_layers(state)
        return want if layers == want else None

    want = wait_for(drawn_as_stated, "the map to draw the tracker's layers as stated")
    if backend.real:
        return
    assert want == {"search": 9, "confirmed": 1, "tentative": 2, "prior": 1}
    assert drv.find_element(By.ID, "track-counts").text == (
        "1 confirmed · 2 tentative · 1 prior · 9 search cells")
    statuses = {row.get_attribute("data-id"): row.find_elements(By.TAG_NAME, "td")[-1].text
                for row in drv.find_elements(By.CSS_SELECTOR, "#targets tbody tr")}
    assert statuses == {"A": "confirmed", "B": "prior", "C": "tentative"}
    # S6 (centre -1000, 0) holds 7/9 of the top value, S0 (-1000, -1000) 1/9: off-centre
    # points of each, away from the axes and the targets
    strong, weak = pixel_blueness(drv, -1100.0, 100.0), pixel_blueness(drv, -1100.0, -900.0)
    background = 240 - 223  # #dfe9f0
    assert strong > weak + 20 and weak > background + 5, (strong, weak)
    server = backend.server if isinstance(backend, FakeBackend) else None
    assert server is not None
    server.call(lambda: server.control.emit("track_born", target="N8", detail="unassociated"))
    server.call(lambda: server.control.emit("track_confirmed", target="N7", detail="3 of 5"))
    wait_for(lambda: "track_confirmed" in drv.find_element(By.ID, "events").text,
             "the track_confirmed note among the events")
    assert "track_born" not in drv.find_element(By.ID, "events").text


def check_pan_and_zoom(drv: Any, backend: FakeBackend) -> None:
    """Dragging pans the map (and adds nothing); the zoom button zooms."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    writes = backend.writes()
    canvas = drv.find_element(By.ID, "map")
    ActionChains(drv).move_to_element(canvas).perform()  # hovering: no automatic re-fit
    time.sleep(0.05)
    corner = drv.execute_script("return window.floe.toWorld(0, 0)")
    ActionChains(drv).click_and_hold().move_by_offset(120, 80).release().perform()
    moved = drv.execute_script("return window.floe.toWorld(0, 0)")
    scale = drv.execute_script("const a = window.floe.toWorld(0, 0), b = window.floe.toWorld("
                               "100, 0); return b[0] - a[0];")
    assert moved[0] == pytest.approx(corner[0] - 120 * scale / 100, abs=3 * scale / 100)
    assert moved[1] == pytest.approx(corner[1] + 80 * scale / 100, abs=3 * scale / 100)
    drv.find_element(By.ID, "zoom-in").click()
    zoomed = drv.execute_script("const a = window.floe.toWorld(0, 0), b = window.floe.toWorld("
                                "100, 0); return b[0] - a[0];")
    assert zoomed == pytest.approx(scale / 1.5, rel=0.01)
    drv.find_element(By.ID, "fit").click()
    assert backend.writes() == writes


def check_reconnect(drv: Any, backend: FakeBackend) -> None:
    """Cut every page's WebSocket: the page reconnects and catches up what it missed."""
    from selenium.webdriver.common.by import By

    server = backend.server
    connections = drv.execute_script("return window.floe.connections")

    async def cut() -> None:
        for client in list(server.server.pages.clients):
            await client.ws.close()
        # before the page is back; an operator event (pages get no state updates)
        server.control.emit("target_discovered", vehicle="uav1", target="AWAY1")

    asyncio.run_coroutine_threadsafe(cut(), server.loop).result(5.0)
    wait_for(lambda: drv.execute_script(
        "return window.floe.connected && window.floe.connections") == connections + 1,
        "the page to reconnect")
    wait_for(lambda: "AWAY1" in drv.find_element(By.ID, "events").text,
             "the missed event on the page")
    seqs = drv.execute_script("return window.floe.events.map(e => e.seq)")
    assert seqs == sorted(set(seqs))  # nothing shown twice


TILE_RGB = (250, 236, 190)


def test_tile_layer_only_when_configured(driver: Any, tmp_path: Path) -> None:
    """No tile is fetched by default (offline grid); with ?tiles=TEMPLATE the page draws
    Web-Mercator tiles from that server under the map."""
    import http.server
    import threading

    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (256, 256), TILE_RGB).save(buf, "PNG")
    tile_png = buf.getvalue()
    requested: list[str] = []

    class Tiles(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            requested.append(self.path)
            self.send_response(200)
            self.send_header("Content-Type", "image/png")
            self.send_header("Content-Length", str(len(tile_png)))
            self.end_headers()
            self.wfile.write(tile_png)

        def log_message(self, *args: object) -> None:
            pass

    tiles = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Tiles)
    thread = threading.Thread(target=tiles.serve_forever, daemon=True)
    thread.start()
    drv = driver
    try:
        with ServerThread(tick_s=0.1, token="t") as server:
            open_page(drv, server.url + "/")
            time.sleep(0.5)
            assert requested == []
            template = f"http://127.0.0.1:{tiles.server_port}/{{z}}/{{x}}/{{y}}.png"
            open_page(drv, server.url + "/?tiles=" + urllib.parse.quote(template, safe=""))
            wait_for(lambda: len(requested) >= 2, "tile requests")
            z, x, y = (int(p) for p in requested[0].removesuffix(".png").strip("/").split("/"))
            # Around the fake's origin (78.93 N, 11.92 E) at a few km across: z ~ 10-15.
            assert 8 <= z <= 17 and 0 <= x < 2**z and 0 <= y < 2**z
            assert abs(x - (11.92 + 180) / 360 * 2**z) < 4
            time.sleep(0.5)
            png = screenshot(drv, tmp_path / "tiles.png")
            image = Image.open(io.BytesIO(png)).convert("RGB")
            region = image.crop((0, 40, int(image.width * 0.6), image.height))
            counts = {rgb: n for n, rgb in region.getcolors(maxcolors=1_000_000) or []}
            share = counts.get(TILE_RGB, 0) / (region.width * region.height)
            assert share > 0.3, f"tiles cover {share:.0%} of the map"
            drv.get("about:blank")
    finally:
        tiles.shutdown()
        tiles.server_close()


# ------------------------------------------------------------------ the geofence and GPS fix

FENCE = (150.0, -100.0, 900.0)  # the fence of FenceFake: centre x, y and radius (m)
FENCE_RGB = (0xD9, 0x48, 0x0F)  # app.js FENCE_COLOUR


class FenceFake(FakeControl):
    """The fake daemon with an operating area, its geofence (held verified by two of the
    three vehicles) and a GPS fix per vehicle: uav1 RTK fixed, uav2 without a fix, uav3 no
    GPS_RAW_INT yet (SYS_STATUS' health)."""

    def state(self) -> dict[str, Any]:
        doc = super().state()
        doc["operating_center_m"] = [FENCE[0], FENCE[1]]
        doc["operating_radius_m"] = FENCE[2] - 300.0
        doc["fence"] = {"x_m": FENCE[0], "y_m": FENCE[1], "radius_m": FENCE[2]}
        fixes = [({"fix_type": 6, "fix": "RTK fixed", "satellites": 10, "hdop": 1.21,
                   "ok": True}, "RTK fixed, 10 sats, HDOP 1.2"),
                 ({"fix_type": 1, "fix": "no fix", "satellites": 3, "hdop": 1.21,
                   "ok": False}, "no fix, 3 sats, HDOP 1.2"),
                 (None, "ok")]
        for v, (fix, text) in zip(doc["vehicles"], fixes, strict=True):
            v.update(gps="ok", gps_fix=fix, gps_text=text,
                     fence_verified=v["id"] != "uav2")
        return doc


def fence_as_drawn(drv: Any) -> dict[str, Any]:
    """The fence the page drew in its last frame, with the latitude/longitude of its centre
    and of each of its points under the map's transform of that same frame (one script:
    no frame can come between)."""
    drawn: dict[str, Any] | None = drv.execute_script("""
        const f = window.floe.fence;
        if (!f) return null;
        f.centre = window.floe.toLatLon(f.cx, f.cy);
        f.latlon = f.points.map(p => window.floe.toLatLon(p[0], p[1]));
        return f;""")
    assert drawn is not None, "no fence drawn"
    return drawn


def check_fence_drawn(drv: Any, origin: Any, fence: tuple[float, float, float]) -> None:
    """The page's fence is a circle round on the screen, centred on the fence's lat/lon,
    whose every point lies ``radius`` metres from that centre, drawn in the fence's colour
    all round (the canvas' pixels)."""
    x_m, y_m, radius_m = fence
    f = fence_as_drawn(drv)
    assert f["segments"] >= 96 and len(f["points"]) == f["segments"]
    lat0, lon0, _ = origin.to_geodetic(x_m, y_m, 0.0)
    assert f["centre"][0] == pytest.approx(lat0, abs=1e-7), (f["centre"], lat0)
    assert f["centre"][1] == pytest.approx(lon0, abs=1e-7), (f["centre"], lon0)
    for lat, lon in f["latlon"]:
        ex, ny, _ = origin.to_local(lat, lon)
        assert math.hypot(ex - x_m, ny - y_m) == pytest.approx(radius_m, abs=1.0)
        # and on the sphere (haversine), within its flattening at 79 N
        p1, p2 = math.radians(lat0), math.radians(lat)
        a = (math.sin((p2 - p1) / 2) ** 2 + math.cos(p1) * math.cos(p2)
             * math.sin(math.radians(lon - lon0) / 2) ** 2)
        assert 2 * 6_371_000 * math.asin(math.sqrt(a)) == pytest.approx(radius_m, rel=0.01)
    radii = [math.hypot(px - f["cx"], py - f["cy"]) for px, py in f["points"]]
    assert max(radii) / min(radii) < 1.01, (min(radii), max(radii))  # round on the screen
    assert min(radii) > 50
    hits, inside = drv.execute_script("""
        const c = document.getElementById('map'), d = window.devicePixelRatio || 1;
        const ctx = c.getContext('2d');
        const [points, want] = arguments;
        let hits = 0, inside = 0;
        for (let k = 0; k < points.length; k += 5) {
          const [x, y] = points[k];
          if (x < 3 || y < 3 || x > c.clientWidth - 3 || y > c.clientHeight - 3) continue;
          inside += 1;
          let found = false;
          for (let dx = -1; dx <= 1 && !found; dx++) {
            for (let dy = -1; dy <= 1 && !found; dy++) {
              const p = ctx.getImageData(Math.round((x + dx) * d), Math.round((y + dy) * d),
                                         1, 1).data;
              found = Math.abs(p[0] - want[0]) + Math.abs(p[1] - want[1]) +
                      Math.abs(p[2] - want[2]) < 60;
            }
          }
          if (found) hits += 1;
        }
        return [hits, inside];""", f["points"], list(FENCE_RGB))
    assert inside >= 12 and hits >= 0.85 * inside, f"fence outline at {hits} of {inside}"


def check_fence_and_gps(drv: Any, backend: Backend) -> None:
    """The real daemon (sim:3 on loopback, real MAVLink): every vehicle holds the area's
    fence, verified, and the page draws that fence (zoomed out until it fits), while the
    panel shows each vehicle's GPS_RAW_INT fix as the simulator sends it (ArduPlane SITL's:
    RTK fixed, 10 satellites, HDOP 1.21). The fake daemon has no fence: none is drawn."""
    from selenium.webdriver.common.by import By

    from domain.geodesy import GeoOrigin

    if not backend.real:
        assert drv.execute_script("return window.floe.fence") is None
        assert not drv.find_element(By.ID, "legend-fence").is_displayed()
        return
    state = wait_for(lambda: (s := drv.execute_script("return window.floe.state")) and all(
        v.get("fence_verified") for v in s["vehicles"]) and s,
        "every vehicle to hold the fence, verified", timeout_s=30.0)
    fence = state["fence"]
    assert fence is not None and fence["radius_m"] > 0, fence
    origin = GeoOrigin(state["origin"]["lat_deg"], state["origin"]["lon_deg"])
    for _ in range(20):  # zoom out until the fence is on the map
        w, h, f = drv.execute_script("const c = document.getElementById('map');"
                                     "return [c.clientWidth, c.clientHeight, window.floe.fence]")
        r_px = max(math.hypot(x - f["cx"], y - f["cy"]) for x, y in f["points"])
        if r_px < 0.4 * min(w, h):
            break
        drv.find_element(By.ID, "zoom-out").click()
        time.sleep(0.1)
    check_fence_drawn(drv, origin, (fence["x_m"], fence["y_m"], fence["radius_m"]))
    legend = drv.find_element(By.ID, "legend").text
    assert "verified on 3 of 3" in legend, legend
    rows = drv.find_elements(By.CSS_SELECTOR, "#vehicle-panel tbody tr")
    cells = [row.find_elements(By.TAG_NAME, "td")[5].text for row in rows]
    assert cells == ["RTK fixed, 10 sats, HDOP 1.2"] * 3, cells
    drv.find_element(By.ID, "fit").click()


def test_fence_and_gps_fix_on_the_map(driver: Any) -> None:
    """The geofence of the state document drawn as a circle on the geographic map, with its
    own style and a legend, north-up and ship-up; the vehicle panel's GPS fix, a vehicle
    without a fix shown as a warning."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    from domain.geodesy import GeoOrigin

    drv = driver
    origin = GeoOrigin(78.93, 11.92)  # the fake's origin
    with ServerThread(tick_s=0.1, token="t", push_hz=5.0, control=FenceFake()) as server:
        open_page(drv, server.url + "/")
        wait_for(lambda: drv.execute_script("return window.floe.basemap.geo"),
                 "Leaflet under the map, in the origin's frame")
        ActionChains(drv).move_to_element(drv.find_element(By.ID, "map")).perform()
        time.sleep(0.3)  # hovering: the view no longer re-fits
        wait_for(lambda: drv.execute_script("return window.floe.fence"), "the fence drawn")
        check_fence_drawn(drv, origin, FENCE)
        legend = drv.find_element(By.ID, "legend").text
        assert "operating area" in legend, legend
        assert "geofence 900 m · verified on 2 of 3" in legend, legend

        # ---- ship-up: the map (and the fence with it) turns by the ship's course
        drv.find_element(By.ID, "orient").click()
        rotation = wait_for(lambda: drv.execute_script("return window.floe.rotation"),
                            "the map to turn ship-up")
        assert rotation == pytest.approx(math.pi / 2, abs=0.05)
        ActionChains(drv).move_to_element(drv.find_element(By.ID, "map")).perform()
        time.sleep(0.3)
        check_fence_drawn(drv, origin, FENCE)
        # the canvas draws north-up inside the turned box: the fence's north point straight
        # above its centre on the canvas, the box turned a quarter (east up on the screen)
        f = fence_as_drawn(drv)
        north = f["points"][len(f["points"]) // 4]  # angle pi/2 in ENU: north
        assert north[1] < f["cy"] and abs(north[0] - f["cx"]) < 2.0, (north, f["cx"], f["cy"])
        transform = drv.execute_script(
            "return getComputedStyle(document.getElementById('stack')).transform")
        a, b = (float(v) for v in transform[len("matrix("):].split(",")[:2])
        assert math.atan2(b, a) == pytest.approx(-math.pi / 2, abs=0.05), transform
        drv.find_element(By.ID, "orient").click()
        wait_for(lambda: drv.execute_script("return window.floe.rotation === 0"),
                 "north-up again")

        # ---- the GPS fix per vehicle in the panel; no fix is a warning
        def gps_cells() -> dict[str, tuple[str, str]]:
            out = {}
            for row in drv.find_elements(By.CSS_SELECTOR, "#vehicle-panel tbody tr"):
                cell = row.find_elements(By.TAG_NAME, "td")[5]
                out[row.get_attribute("data-id")] = (cell.text, cell.get_attribute("class"))
            return out

        cells = wait_for(lambda: (c := gps_cells()) and len(c) == 3 and c, "the panel")
        assert cells["uav1"] == ("RTK fixed, 10 sats, HDOP 1.2", ""), cells
        assert cells["uav2"][0] == "no fix, 3 sats, HDOP 1.2", cells
        assert "gps-warn" in cells["uav2"][1], cells
        assert cells["uav3"] == ("ok", ""), cells  # no GPS_RAW_INT yet: SYS_STATUS' health
        errors = [e for e in drv.get_log("browser") if e.get("level") == "SEVERE"]
        drv.get("about:blank")
    assert errors == [], errors
