"""The operator's offline tiles (groundstation/daemon/control/tiles.py, ``--map-tiles``) and
the vehicle panel's fields of the state document (groundstation/daemon/vehicle_view.py)."""

from __future__ import annotations

import math
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from groundstation.daemon.control.tiles import TileArchive, TilesError
from groundstation.daemon.vehicle_view import gps_state, heading_deg, vehicle_panel
from groundstation.mavlink.telemetry_events import VehicleSnapshot
from groundstation.vehicle.state import FlyRecord


def _mbtiles(path: Path, fmt: str = "png", rows: list[tuple[int, int, int, bytes]] | None = None
             ) -> Path:
    db = sqlite3.connect(path)
    db.execute("CREATE TABLE metadata (name TEXT, value TEXT)")
    db.execute("CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, tile_row INTEGER,"
               " tile_data BLOB)")
    db.executemany("INSERT INTO metadata VALUES (?, ?)", [("format", fmt),
                                                          ("bounds", "11,78,13,79")])
    db.executemany("INSERT INTO tiles VALUES (?, ?, ?, ?)", rows or [])
    db.commit()
    db.close()
    return path


def test_tiles_are_read_in_the_xyz_scheme(tmp_path: Path) -> None:
    """MBTiles rows count from the south: XYZ (z, x, y) is row 2**z - 1 - y."""
    archive = TileArchive(_mbtiles(tmp_path / "a.mbtiles", rows=[
        (3, 5, 2, b"south"), (3, 5, 5, b"north"), (4, 0, 0, b"z4")]))
    try:
        assert archive.tile(3, 5, 5) == b"south"
        assert archive.tile(3, 5, 2) == b"north"
        assert archive.tile(3, 4, 2) is None
        assert archive.tile(3, 8, 0) is None and archive.tile(-1, 0, 0) is None
        assert archive.content_type == "image/png"
        assert archive.info.to_dict() == {"format": "png", "min_zoom": 3, "max_zoom": 4,
                                          "bounds": [11.0, 78.0, 13.0, 79.0]}
    finally:
        archive.close()


@pytest.mark.parametrize(("name", "content", "said"), [
    ("missing.mbtiles", None, "no such file"),
    ("junk.mbtiles", b"not sqlite at all, not even close" * 20, "not an MBTiles file"),
    ("vector.mbtiles", "pbf", "is not raster tiles"),
    ("empty.mbtiles", "png", "holds no tiles"),
    ("sea.pmtiles", b"PMTiles", "PMTiles is not read yet"),
])
def test_unusable_tiles_are_one_line(tmp_path: Path, name: str, content: object,
                                     said: str) -> None:
    path = tmp_path / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif isinstance(content, str):
        _mbtiles(path, fmt=content)
    with pytest.raises(TilesError, match=said) as err:
        TileArchive(path)
    assert "\n" not in str(err.value) and str(path) in str(err.value)


def test_gcs_run_refuses_bad_tiles_in_one_line(tmp_path: Path) -> None:
    (tmp_path / "bad.mbtiles").write_text("x")
    done = subprocess.run(
        [sys.executable, "-m", "groundstation.cli", "run", "--vehicles", "sim:1",
         "--map-tiles", "bad.mbtiles", "--duration", "5", "--status", "log",
         "--detections", "off", "--run-dir", str(tmp_path / "runs")],
        cwd=tmp_path, capture_output=True, text=True, timeout=100, check=False)
    assert done.returncode != 0
    assert "Traceback" not in done.stderr + done.stdout
    assert "map tiles bad.mbtiles: not an MBTiles file" in done.stderr + done.stdout


def test_vehicle_panel_fields() -> None:
    snap = VehicleSnapshot(system_id=1, x_m=450.0, y_m=950.0, alt_m=120.0, heading_rad=math.pi / 2,
                           speed_m_s=21.0, airspeed_m_s=19.5, battery_voltage_v=12.4,
                           battery_remaining_pct=80.0, sensors=(0x20, 0x20, 0x20))
    fly = FlyRecord("T1", 10.0, 20.0, through=((30.0, 40.0), (50.0, 60.0)))
    panel = vehicle_panel(snap, fly, 120.0, "ok", 0.4, None)
    assert panel["airspeed_m_s"] == 19.5 and panel["groundspeed_m_s"] == 21.0
    assert panel["heading_deg"] == pytest.approx(0.0)  # ENU pi/2 = north
    assert panel["gps"] == "ok" and panel["battery_v"] == 12.4
    assert panel["link_quality"] == {"state": "ok", "telemetry_age_s": 0.4, "rssi": None,
                                     "remrssi": None}
    # the commanded loiter: the mission's last point, the configured radius
    assert panel["loiter"] == {"x_m": 50.0, "y_m": 60.0, "radius_m": 120.0}
    assert vehicle_panel(snap, None, 120.0, "lost", None, None)["loiter"] is None


def test_gps_state_and_heading() -> None:
    assert gps_state(None) is None
    assert gps_state((0, 0, 0)) == "absent"
    assert gps_state((0x20, 0x20, 0)) == "unhealthy"
    assert gps_state((0x20, 0, 0x20)) == "unhealthy"
    assert gps_state((0x21, 0x21, 0x20)) == "ok"
    assert heading_deg(0.0) == pytest.approx(90.0)
    assert heading_deg(math.pi) == pytest.approx(270.0)
    assert heading_deg(None) is None
