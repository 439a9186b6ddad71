"""The live map's geography in a real headless browser (Debian's chromium, as
test_live_map_browser.py): Leaflet (from the xstatic-leaflet package, served by the daemon
itself: /vendor/leaflet/) under the page's canvas, tiles from the operator's MBTiles file
(and from a PMTiles file, gzip-compressed tiles sent as they are stored),
latitude/longitude under the cursor, a scale bar, ship-up, the commanded loiter drawn round,
and the vehicle panel.

The fake daemon (test_control_fake.FakeControl) gets one more vehicle, ``G``, whose position
is what a GLOBAL_POSITION_INT said (lat/lon -> local ENU with pymap3d, as the daemon's
``GeoOrigin.to_local``) and whose mission ends in a loiter of 120 m. The MBTiles file is
made here with sqlite3: one colour, zooms 8..10 around the fake's origin (78.93 N, 11.92 E);
Leaflet draws zoom 10 scaled up at the map's zoom (~13).
"""

from __future__ import annotations

import io
import math
import sqlite3
import time
from pathlib import Path
from typing import Any

import pytest
from pmtiles.tile import Compression
from test_control_fake import FakeControl, ServerThread
from test_live_map_browser import driver, open_page, screenshot, wait_for
from tile_files import around, png_tile, write_pmtiles

from domain.geodesy import GeoOrigin
from groundstation.daemon.control.tiles import TileArchive, TileBody

__all__ = ["driver"]  # the browser fixture, shared

pytestmark = pytest.mark.browser

ORIGIN = GeoOrigin(78.93, 11.92)
G_LAT, G_LON = 78.9385, 11.9412  # what vehicle G's GLOBAL_POSITION_INT said
LOITER = (300.0, -400.0, 120.0)  # the commanded loiter: x, y, radius (m)
TILE_RGB = (236, 214, 160)


class GeoFake(FakeControl):
    """The fake daemon with vehicle G at a GLOBAL_POSITION_INT position, loitering."""

    def state(self) -> dict[str, Any]:
        doc = super().state()
        x, y, _ = ORIGIN.to_local(G_LAT, G_LON)
        doc["vehicles"].append({
            "id": "G", "name": "G", "system_id": 9, "x_m": x, "y_m": y, "alt_m": 120.0,
            "heading_rad": 0.3, "speed_m_s": 19.0, "mode": "AUTO", "armed": True,
            "status": "active", "link": "ok", "telemetry_age_s": 0.3, "battery_pct": 81.0,
            "target": "A", "route": ["A"], "aim": [LOITER[0], LOITER[1]], "track": [],
            "airspeed_m_s": 18.5, "groundspeed_m_s": 21.2,
            "heading_deg": 72.8, "gps": "ok", "battery_v": 12.3,
            "link_quality": {"state": "ok", "telemetry_age_s": 0.3, "rssi": 201,
                             "remrssi": 188},
            "loiter": {"x_m": LOITER[0], "y_m": LOITER[1], "radius_m": LOITER[2]},
        })
        return doc


def make_mbtiles(path: Path) -> Path:
    """A raster MBTiles of one colour: zooms 8..10, 3 x 3 tiles around the origin."""
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (256, 256), TILE_RGB).save(buf, "PNG")
    png = buf.getvalue()
    db = sqlite3.connect(path)
    db.execute("CREATE TABLE metadata (name TEXT, value TEXT)")
    db.execute("CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, tile_row INTEGER,"
               " tile_data BLOB)")
    db.executemany("INSERT INTO metadata VALUES (?, ?)",
                   [("name", "test"), ("format", "png"), ("bounds", "11,78.5,13,79.2")])
    lat = math.radians(ORIGIN.lat_deg)
    for z in (8, 9, 10):
        n = 2**z
        cx = int((ORIGIN.lon_deg + 180) / 360 * n)
        cy = int((1 - math.log(math.tan(lat) + 1 / math.cos(lat)) / math.pi) / 2 * n)
        for x in range(cx - 1, cx + 2):
            for y in range(cy - 1, cy + 2):  # MBTiles rows count from the south (TMS)
                db.execute("INSERT INTO tiles VALUES (?, ?, ?, ?)", (z, x, n - 1 - y, png))
    db.commit()
    db.close()
    return path


def move_to(drv: Any, px: float, py: float) -> None:
    """The pointer to canvas pixel (px, py) (from its top-left corner)."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    canvas = drv.find_element(By.ID, "map")
    w, h = drv.execute_script("const c = document.getElementById('map');"
                              "return [c.clientWidth, c.clientHeight];")
    ActionChains(drv).move_to_element_with_offset(
        canvas, round(px - w / 2), round(py - h / 2)).perform()


def metres_per_px(drv: Any) -> float:
    a, b = drv.execute_script("return [window.floe.toWorld(0, 0), window.floe.toWorld(100, 0)]")
    return math.hypot(b[0] - a[0], b[1] - a[1]) / 100


def test_geographic_map(driver: Any, tmp_path: Path) -> None:
    from PIL import Image
    from selenium.webdriver.common.by import By

    drv = driver
    tiles = TileArchive(make_mbtiles(tmp_path / "sea.mbtiles"))
    with ServerThread(tick_s=0.1, token="t", control=GeoFake(), tiles=tiles) as server:
        open_page(drv, server.url + "/")
        wait_for(lambda: drv.execute_script("return window.floe.basemap.geo"),
                 "Leaflet under the map, in the origin's frame")
        # ---- tiles from the operator's file, through the daemon
        wait_for(lambda: (drv.execute_script("return window.floe.basemap.tileEvents") or
                          {}).get("load", 0) >= 1, "tiles loaded from the MBTiles file")
        time.sleep(0.5)
        png = screenshot(drv, tmp_path / "geo.png")
        image = Image.open(io.BytesIO(png)).convert("RGB")
        region = image.crop((0, 40, int(image.width * 0.6), image.height))
        counts = {rgb: n for n, rgb in region.getcolors(maxcolors=1_000_000) or []}
        share = counts.get(TILE_RGB, 0) / (region.width * region.height)
        assert share > 0.3, f"tiles cover {share:.0%} of the map"
        # ---- a scale bar (Leaflet's, metric)
        scale = drv.find_element(By.CSS_SELECTOR, "#scale-box .leaflet-control-scale-line")
        assert scale.text.endswith((" m", " km")), scale.text

        # ---- latitude/longitude under the cursor = vehicle G's GLOBAL_POSITION_INT
        canvas = drv.find_element(By.ID, "map")
        from selenium.webdriver.common.action_chains import ActionChains

        ActionChains(drv).move_to_element(canvas).perform()  # hovering: no re-fit
        time.sleep(0.1)
        x, y, _ = ORIGIN.to_local(G_LAT, G_LON)
        px, py = drv.execute_script("return window.floe.toScreen(arguments[0], arguments[1])",
                                    x, y)
        lat, lon = drv.execute_script("return window.floe.toLatLon(arguments[0], arguments[1])",
                                      px, py)
        assert lat == pytest.approx(G_LAT, abs=1e-7) and lon == pytest.approx(G_LON, abs=1e-7)
        move_to(drv, px, py)
        cursor = wait_for(lambda: drv.execute_script("return window.floe.cursor"),
                          "the cursor's position")
        m_px = metres_per_px(drv)
        north_m = (cursor["lat"] - G_LAT) * math.radians(1) * 6_360_000
        east_m = (cursor["lon"] - G_LON) * math.radians(1) * 6_360_000 * math.cos(
            math.radians(G_LAT))
        assert math.hypot(north_m, east_m) < 1.5 * m_px, (cursor, m_px)
        text = drv.find_element(By.ID, "cursor").text
        assert "°N" in text and "°E" in text, text

        # ---- the commanded loiter is drawn as a circle
        loiter = wait_for(lambda: [c for c in drv.execute_script("return window.floe.loiters")
                                   if c["vehicle"] == "G"], "G's loiter drawn")[0]
        assert loiter["segments"] >= 64
        cx, cy = drv.execute_script("return window.floe.toScreen(arguments[0], arguments[1])",
                                    LOITER[0], LOITER[1])
        radii = []
        for k in range(16):
            a = 2 * math.pi * k / 16
            ex, ey = drv.execute_script(
                "return window.floe.toScreen(arguments[0], arguments[1])",
                LOITER[0] + LOITER[2] * math.cos(a), LOITER[1] + LOITER[2] * math.sin(a))
            radii.append(math.hypot(ex - cx, ey - cy))
        assert max(radii) / min(radii) < 1.01, radii  # round on the screen
        r_px = sum(radii) / len(radii)
        assert r_px > 10
        # its outline on the canvas: the vehicle's colour within 2 px of the radius, all round
        hits = drv.execute_script("""
            const c = document.getElementById('map'), d = window.devicePixelRatio || 1;
            const ctx = c.getContext('2d');
            const [cx, cy, r, colour] = arguments;
            const want = [1, 3, 5].map(i => parseInt(colour.slice(i, i + 2), 16));
            let hits = 0;
            for (let k = 0; k < 24; k++) {
              const a = 2 * Math.PI * k / 24;
              let found = false;
              for (let dr = -2; dr <= 2 && !found; dr++) {
                const x = Math.round((cx + (r + dr) * Math.cos(a)) * d);
                const y = Math.round((cy - (r + dr) * Math.sin(a)) * d);
                const p = ctx.getImageData(x, y, 1, 1).data;
                found = Math.abs(p[0] - want[0]) + Math.abs(p[1] - want[1]) +
                        Math.abs(p[2] - want[2]) < 60;
              }
              if (found) hits += 1;
            }
            return hits;""", cx, cy, r_px, loiter["colour"])
        assert hits >= 22, f"loiter outline found at {hits} of 24 angles"

        # ---- the vehicle panel
        row = drv.find_element(By.CSS_SELECTOR, "#vehicle-panel tbody tr[data-id='G']")
        cells = [td.text for td in row.find_elements(By.TAG_NAME, "td")]
        assert cells == ["G", "18.5", "21.2", "73°", "120", "ok", "12.3", "81",
                         "ok · 0.3 s · 201/188"], cells

        # ---- ship-up: the map turns by the ship's course (the fake's boat moves east)
        assert drv.execute_script("return window.floe.orient") == "north"
        drv.find_element(By.ID, "orient").click()
        rotation = wait_for(lambda: drv.execute_script("return window.floe.rotation"),
                            "the map to turn ship-up")
        assert rotation == pytest.approx(math.pi / 2, abs=0.05)  # course 090: east is up
        transform = drv.execute_script(
            "return getComputedStyle(document.getElementById('stack')).transform")
        assert transform.startswith("matrix("), transform
        drv.find_element(By.ID, "orient").click()
        wait_for(lambda: drv.execute_script("return window.floe.rotation === 0"),
                 "north-up again")
        drv.get("about:blank")
    tiles.close()


PM_RGB = (150, 205, 230)


class RecordingArchive(TileArchive):
    """The operator's file, recording the Content-Encoding of each tile it answers."""

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self.sent: list[str | None] = []

    def response(self, z: int, x: int, y: int, accept_encoding: str) -> TileBody | None:
        body = super().response(z, x, y, accept_encoding)
        if body is not None:
            self.sent.append(body.headers.get("Content-Encoding"))
        return body


def test_tiles_from_a_pmtiles_file(driver: Any, tmp_path: Path) -> None:
    """The same map from a PMTiles v3 archive (made here with the pmtiles writer): PNG tiles
    stored gzip-compressed, zooms 8..10 around the origin, sent to the browser as stored
    (``Content-Encoding: gzip``) and drawn; the archive's max zoom reaches the page (Leaflet
    scales zoom 10 up instead of asking for tiles the file lacks)."""
    from PIL import Image

    drv = driver
    png = png_tile(PM_RGB)
    path = write_pmtiles(tmp_path / "sea.pmtiles",
                         dict.fromkeys(around(ORIGIN.lat_deg, ORIGIN.lon_deg, range(8, 11)),
                                       png),
                         compression=Compression.GZIP)
    tiles = RecordingArchive(path)
    with ServerThread(tick_s=0.1, token="t", control=GeoFake(), tiles=tiles) as server:
        open_page(drv, server.url + "/")
        wait_for(lambda: drv.execute_script("return window.floe.basemap.geo"),
                 "Leaflet under the map, in the origin's frame")
        wait_for(lambda: (drv.execute_script("return window.floe.basemap.tileEvents") or
                          {}).get("load", 0) >= 1, "tiles loaded from the PMTiles file")
        time.sleep(0.5)
        image = Image.open(io.BytesIO(screenshot(drv, tmp_path / "pmtiles.png"))).convert("RGB")
        region = image.crop((0, 40, int(image.width * 0.6), image.height))
        counts = {rgb: n for n, rgb in region.getcolors(maxcolors=1_000_000) or []}
        share = counts.get(PM_RGB, 0) / (region.width * region.height)
        assert share > 0.3, f"tiles cover {share:.0%} of the map"
        assert tiles.sent and set(tiles.sent) == {"gzip"}, tiles.sent
        drv.get("about:blank")
    tiles.close()


def test_leaflet_is_served_by_the_daemon_not_committed(tmp_path: Path) -> None:
    """Leaflet comes from the installed xstatic-leaflet (a registry package), not a file of
    this repository; the daemon serves it, and nothing else under /vendor/."""
    import urllib.error
    import urllib.request

    web = Path(__file__).resolve().parents[1] / "groundstation/daemon/control/web"
    assert not list(web.glob("leaflet*"))
    with ServerThread(token="t") as server:
        with urllib.request.urlopen(server.url + "/vendor/leaflet/leaflet.js", timeout=5) as r:
            body = r.read()
            assert r.headers["Content-Type"].startswith("text/javascript")
        assert b"Leaflet" in body[:2000] and len(body) > 100_000
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(server.url + "/vendor/leaflet/../server.py", timeout=5)
        assert err.value.code == 404
