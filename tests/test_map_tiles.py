"""The operator's offline tiles (groundstation/daemon/control/tiles/, ``--map-tiles``):
MBTiles and PMTiles v3 (archives written here with the ``pmtiles`` writer, tests/tile_files.py),
served over real HTTP; and the vehicle panel's fields of the state document
(groundstation/daemon/vehicle_view.py)."""

from __future__ import annotations

import gzip
import json
import math
import sqlite3
from pathlib import Path
from typing import Any

import pytest
from pmtiles.tile import Compression, TileType, serialize_directory, zxy_to_tileid
from tile_files import png_tile, write_pmtiles

from groundstation.cli import main
from groundstation.daemon.control.tiles import TileArchive, TilesError, accepts_gzip
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
        assert archive.info.to_dict() == {"archive": "mbtiles", "format": "png",
                                          "min_zoom": 3, "max_zoom": 4,
                                          "bounds": [11.0, 78.0, 13.0, 79.0], "center": None}
    finally:
        archive.close()


@pytest.mark.parametrize(("name", "content", "said"), [
    ("missing.mbtiles", None, "no such file"),
    ("junk.mbtiles", b"not sqlite at all, not even close" * 20,
     "not an MBTiles or PMTiles file"),
    ("sqlite.mbtiles", b"SQLite format 3\x00" + bytes(200), "not an MBTiles file"),
    ("vector.mbtiles", "pbf", "is not raster tiles"),
    ("empty.mbtiles", "png", "holds no tiles"),
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


def gcs_run_here(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                 monkeypatch: pytest.MonkeyPatch, *args: str) -> tuple[int, str, str]:
    """``gcs run ARGS`` in this process from ``tmp_path`` (the console script's code path,
    :func:`groundstation.cli.main`, without a new interpreter's ~3 CPU-s of imports): its
    exit status, stdout and stderr. An exception escaping ``main`` fails the test."""
    monkeypatch.chdir(tmp_path)
    capsys.readouterr()
    code = main(["run", *args])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_gcs_run_refuses_bad_tiles_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "bad.mbtiles").write_text("x")
    code, out, err = gcs_run_here(
        tmp_path, capsys, monkeypatch, "--vehicles", "sim:1", "--map-tiles", "bad.mbtiles",
        "--duration", "5", "--status", "log", "--detections", "off",
        "--run-dir", str(tmp_path / "runs"))  # fmt: skip
    assert code != 0
    assert "Traceback" not in err + out
    assert "map tiles bad.mbtiles: not an MBTiles or PMTiles file" in err + out


# ---------------------------------------------------------------- PMTiles v3

RED, BLUE = (200, 40, 40), (30, 60, 200)


def _z3_tiles() -> dict[tuple[int, int, int], bytes]:
    """Distinct bytes per tile at zooms 3 and 4 (what comes back tells where it was read)."""
    tiles = {(3, x, y): f"z3 {x} {y}".encode() for x in range(8) for y in range(8)
             if (x + y) % 3}
    tiles[(4, 9, 4)] = b"z4 9 4"
    return tiles


def test_pmtiles_tiles_are_read_in_the_xyz_scheme(tmp_path: Path) -> None:
    """A PMTiles v3 archive's tiles come back at the XYZ coordinates they were written at
    (rows from the north, as Leaflet asks), with the header's zooms, bounds and centre for
    the page, as the pmtiles package's own reader reads them."""
    from pmtiles.reader import MmapSource
    from pmtiles.reader import Reader as ReferenceReader

    tiles = _z3_tiles()
    path = write_pmtiles(tmp_path / "sea.pmtiles", tiles, center=(11.9, 78.9, 4))
    archive = TileArchive(path)
    try:
        for (z, x, y), data in tiles.items():
            assert archive.tile(z, x, y) == data
        assert archive.tile(3, 0, 0) is None  # not in the archive
        assert archive.tile(4, 0, 0) is None
        assert archive.tile(2, 1, 1) is None and archive.tile(5, 0, 0) is None  # zooms 3..4
        assert archive.tile(3, 8, 0) is None and archive.tile(-1, 0, 0) is None
        assert archive.tile(30, 0, 0) is None
        assert archive.content_type == "image/png"
        assert archive.info.to_dict() == {"archive": "pmtiles", "format": "png",
                                          "min_zoom": 3, "max_zoom": 4,
                                          "bounds": [11.0, 78.5, 13.0, 79.2],
                                          "center": [11.9, 78.9, 4]}
        with path.open("rb") as f:
            reference = ReferenceReader(MmapSource(f))
            for z, x, y in [(3, x, y) for x in range(8) for y in range(8)] + [(4, 9, 4)]:
                assert archive.tile(z, x, y) == reference.get(z, x, y)
    finally:
        archive.close()


def test_pmtiles_leaf_directories_are_read_once(tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """An archive with leaf directories (4 entries each): every tile is found, and each
    directory is decoded once however many tiles are read (root at start, a leaf on first
    use): a tile then costs one search and one read."""
    from groundstation.daemon.control.tiles import pmtiles_file

    tiles = {(5, x, y): f"{x},{y}".encode() for x in range(10, 16) for y in range(3, 9)}
    path = write_pmtiles(tmp_path / "leafy.pmtiles", tiles, leaf_size=4)
    decoded: list[int] = []
    real = pmtiles_file.deserialize_directory

    def counting(buf: bytes) -> list[Any]:
        decoded.append(len(buf))
        return real(buf)

    monkeypatch.setattr(pmtiles_file, "deserialize_directory", counting)
    archive = TileArchive(path)
    try:
        assert len(decoded) == 1  # the root, at start
        for _ in range(3):
            for (z, x, y), data in tiles.items():
                assert archive.tile(z, x, y) == data
        assert len(decoded) == 1 + -(-len(tiles) // 4)  # the root and each leaf, once
        assert archive.tile(5, 0, 0) is None and archive.tile(5, 31, 31) is None
    finally:
        archive.close()


def test_cold_leaves_are_decoded_off_the_event_loop(tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """A leaf's first decode (pure Python, ~10 ms for a real leaf) runs in a worker thread,
    never on the server's event loop: ``cold`` says a tile needs one, ``warm`` decodes it."""
    import threading
    import urllib.request

    from test_control_fake import ServerThread

    from groundstation.daemon.control.tiles import pmtiles_file

    tiles = {(5, x, y): f"{x},{y}".encode() for x in range(10, 14) for y in range(3, 7)}
    archive = TileArchive(write_pmtiles(tmp_path / "leafy.pmtiles", tiles, leaf_size=4))
    threads: list[threading.Thread] = []
    real = pmtiles_file.deserialize_directory

    def recording(buf: bytes) -> list[Any]:
        threads.append(threading.current_thread())
        return real(buf)

    monkeypatch.setattr(pmtiles_file, "deserialize_directory", recording)
    assert archive.cold(5, 10, 3) and not archive.cold(5, 0, 0)  # no entry: nothing to decode
    archive.warm(5, 10, 3)
    assert not archive.cold(5, 10, 3) and len(threads) == 1
    threads.clear()
    try:
        with ServerThread(token="t", tiles=archive) as server:
            for (z, x, y), data in tiles.items():
                with urllib.request.urlopen(f"{server.url}/tiles/{z}/{x}/{y}", timeout=5) as r:
                    assert r.read() == data
            loop_thread = server._thread  # the thread that runs the server's event loop
        assert len(threads) == len(tiles) // 4 - 1  # the 3 other leaves, once each
        assert loop_thread not in threads and threading.current_thread() not in threads
    finally:
        archive.close()
    mb = TileArchive(_mbtiles(tmp_path / "a.mbtiles", rows=[(2, 1, 2, b"mb")]))
    assert not mb.cold(2, 1, 1)
    mb.close()


@pytest.mark.parametrize(("tile_type", "fmt", "content_type"), [
    (TileType.PNG, "png", "image/png"), (TileType.JPEG, "jpg", "image/jpeg"),
    (TileType.WEBP, "webp", "image/webp"), (TileType.AVIF, "avif", "image/avif")])
def test_pmtiles_content_type_is_the_headers(tmp_path: Path, tile_type: TileType, fmt: str,
                                              content_type: str) -> None:
    archive = TileArchive(write_pmtiles(tmp_path / "t.pmtiles", {(2, 1, 1): b"img"},
                                        tile_type=tile_type))
    try:
        assert archive.content_type == content_type and archive.info.format == fmt
    finally:
        archive.close()


def test_format_is_told_by_content_not_name(tmp_path: Path) -> None:
    """A PMTiles archive named .mbtiles and an MBTiles file named .pmtiles are both read."""
    pm = TileArchive(write_pmtiles(tmp_path / "a.mbtiles", {(2, 1, 1): b"pm"}))
    mb = TileArchive(_mbtiles(tmp_path / "b.pmtiles", rows=[(2, 1, 2, b"mb")]))
    try:
        assert pm.info.archive == "pmtiles" and pm.tile(2, 1, 1) == b"pm"
        assert mb.info.archive == "mbtiles" and mb.tile(2, 1, 1) == b"mb"
    finally:
        pm.close()
        mb.close()


def test_gzip_tiles_over_http(tmp_path: Path) -> None:
    """Tiles stored gzip-compressed: a client that accepts gzip gets them as stored with
    ``Content-Encoding: gzip``, one that does not gets the image inflated; the content type
    is the header's; a tile the archive lacks, or a zoom outside its range, is a 404."""
    import urllib.error
    import urllib.request

    from test_control_fake import ServerThread

    red, blue = png_tile(RED, 16), png_tile(BLUE, 16)
    path = write_pmtiles(tmp_path / "gz.pmtiles", {(6, 33, 20): red, (7, 66, 40): blue},
                         compression=Compression.GZIP)
    archive = TileArchive(path)

    def get(url: str, accept: str | None) -> tuple[bytes, Any]:
        request = urllib.request.Request(url)
        if accept is not None:
            request.add_header("Accept-Encoding", accept)
        with urllib.request.urlopen(request, timeout=5) as r:
            return r.read(), r.headers

    try:
        with ServerThread(token="t", tiles=archive) as server:
            body, headers = get(server.url + "/tiles/6/33/20.png", "gzip, deflate, br")
            assert headers["Content-Encoding"] == "gzip"
            assert headers["Content-Type"] == "image/png"
            assert "Accept-Encoding" in headers["Vary"]
            assert gzip.decompress(body) == red and body != red
            for accept in (None, "identity", "gzip;q=0, deflate"):
                body, headers = get(server.url + "/tiles/7/66/40", accept)
                assert body == blue and headers["Content-Encoding"] is None, accept
                assert headers["Content-Type"] == "image/png"
            for missing in ("/tiles/6/0/0", "/tiles/5/16/10", "/tiles/8/132/80",
                            "/tiles/6/x/1", "/tiles/40/1/1"):
                with pytest.raises(urllib.error.HTTPError) as err:
                    get(server.url + missing, "gzip")
                assert err.value.code == 404, missing
            with urllib.request.urlopen(server.url + "/api/session", timeout=5) as r:
                session = json.loads(r.read())
            assert session["tile_url"] == "/tiles/{z}/{x}/{y}"
            assert session["tiles"]["archive"] == "pmtiles"
            assert session["tiles"]["max_zoom"] == 7
    finally:
        archive.close()


def test_unknown_tile_compression_is_told_per_tile(tmp_path: Path) -> None:
    """A header that says its tile compression is unknown: each tile that starts with the
    gzip magic is a gzip member, the others are images as they are."""
    red = png_tile(RED, 16)
    archive = TileArchive(write_pmtiles(
        tmp_path / "u.pmtiles", {(3, 1, 1): gzip.compress(red, mtime=0), (3, 2, 2): red},
        compression=Compression.UNKNOWN))
    try:
        assert archive.tile(3, 1, 1) == red and archive.tile(3, 2, 2) == red
        gz = archive.response(3, 1, 1, "gzip")
        assert gz is not None and gz.headers.get("Content-Encoding") == "gzip"
        plain = archive.response(3, 2, 2, "gzip")
        assert plain is not None and "Content-Encoding" not in plain.headers
    finally:
        archive.close()


def test_accepts_gzip() -> None:
    assert accepts_gzip("gzip, deflate, br") and accepts_gzip("br;q=1.0, gzip;q=0.8")
    assert accepts_gzip("*") and accepts_gzip("x-gzip") and accepts_gzip("GZIP")
    assert not accepts_gzip("") and not accepts_gzip("identity")
    assert not accepts_gzip("gzip;q=0") and not accepts_gzip("gzip;q=0, *")
    assert not accepts_gzip("gzip;q=oops")


def test_corrupt_gzip_tile_is_no_tile_and_logged(tmp_path: Path,
                                                 caplog: pytest.LogCaptureFixture) -> None:
    """A stored tile that does not inflate: 404 to a client that needs it inflated, logged;
    the next tiles are served."""
    path = write_pmtiles(tmp_path / "gz.pmtiles", {(2, 1, 1): b"ok", (2, 2, 2): b"x"},
                         compression=Compression.GZIP)
    data = bytearray(path.read_bytes())
    good = gzip.compress(b"x", mtime=0)
    at = data.rindex(good)
    data[at + 10:at + len(good)] = b"\xff" * (len(good) - 10)  # the deflate stream, broken
    path.write_bytes(bytes(data))
    archive = TileArchive(path)
    try:
        with caplog.at_level("WARNING"):
            assert archive.response(2, 2, 2, "") is None
        assert "tile 2/2/2" in caplog.text and "gz.pmtiles" in caplog.text
        body = archive.response(2, 1, 1, "")
        assert body is not None and body.data == b"ok"
        with pytest.raises(TilesError, match="gzip-compressed tile"):
            archive.tile(2, 2, 2)
    finally:
        archive.close()


def test_an_oversized_tile_is_no_tile(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                      caplog: pytest.LogCaptureFixture) -> None:
    """A tile longer than a tile can be is not read (logged): a corrupt entry cannot make the
    daemon read gigabytes on its event loop."""
    from groundstation.daemon.control.tiles import pmtiles_file

    archive = TileArchive(write_pmtiles(tmp_path / "big.pmtiles",
                                        {(2, 1, 1): b"12345678", (2, 2, 1): b"1234"}))
    monkeypatch.setattr(pmtiles_file, "MAX_TILE_BYTES", 5)
    try:
        with caplog.at_level("WARNING"):
            assert archive.tile(2, 1, 1) is None
        assert "tile 2/1/1: 8 bytes, more than a tile's 5" in caplog.text
        assert archive.tile(2, 2, 1) == b"1234"
    finally:
        archive.close()


def test_a_file_cut_after_start_is_survived(tmp_path: Path,
                                            caplog: pytest.LogCaptureFixture) -> None:
    """The archive cut short while the daemon runs: the tiles beyond the cut are no tiles
    (logged), not a crash; those before it are still served."""
    tiles = {(5, x, y): bytes([x, y]) * 500 for x in range(10, 14) for y in range(3, 7)}
    path = write_pmtiles(tmp_path / "cut.pmtiles", tiles, leaf_size=4)
    archive = TileArchive(path)
    try:
        first = next(iter(sorted(tiles, key=lambda t: zxy_to_tileid(*t))))
        assert archive.tile(*first) == tiles[first]
        with path.open("r+b") as f:
            f.truncate(path.stat().st_size - 3000)
        with caplog.at_level("WARNING"):
            served = {zxy: archive.tile(*zxy) for zxy in tiles}
        assert served[first] == tiles[first]
        lost = [zxy for zxy, data in served.items() if data is None]
        assert lost and all(served[zxy] == tiles[zxy] for zxy in tiles if zxy not in lost)
        assert "served as no tile" in caplog.text
    finally:
        archive.close()


def _pmtiles_bytes(tmp_path: Path, **kw: Any) -> bytes:
    return write_pmtiles(tmp_path / "src.pmtiles", {(2, 1, 1): b"a", (2, 2, 1): b"b"},
                         **kw).read_bytes()


def _with_byte(data: bytes, at: int, value: int) -> bytes:
    return data[:at] + bytes([value]) + data[at + 1:]


REFUSALS: dict[str, tuple[Any, str]] = {
    # name: (the file's bytes, from a good archive's; what the one line says)
    "header cut": (lambda b: b[:60], "a truncated PMTiles file (60 bytes, shorter than its "
                                     "127-byte header)"),
    "tile data cut": (lambda b: b[:-1], "a truncated PMTiles file: its header puts the tile "
                                        "data at bytes"),
    "root cut": (lambda b: b[:130], "a truncated PMTiles file: its header puts the root"),
    "root corrupt": (lambda b: b[:127] + b"\x00" * 8 + b[135:],
                     "a corrupt PMTiles file (root directory"),
    "root past 16 KiB": (lambda b: b[:8] + (20_000).to_bytes(8, "little") + b[16:] +
                         bytes(30_000), "its root directory ends past byte 16384"),
    "version 4": (lambda b: _with_byte(b, 7, 4), "PMTiles version 4 is not read (only v3)"),
    "v2": (lambda b: b"PM\x02\x00" + b"\x00" * 200, "a PMTiles v2 file; floe reads v3 "
                                                   "(convert it: pmtiles convert"),
    "v1": (lambda b: b"PM\x01\x00" + b"\x00" * 200, "a PMTiles v1 file"),
    "mvt": (lambda b: _with_byte(b, 99, TileType.MVT.value),
            "holds vector tiles (MVT), which need a style"),
    "mlt": (lambda b: _with_byte(b, 99, TileType.MLT.value),
            "holds vector tiles (MLT), which need a style"),
    "unknown type": (lambda b: _with_byte(b, 99, TileType.UNKNOWN.value),
                     "its tile type is unknown (0 in the header)"),
    "type byte 9": (lambda b: _with_byte(b, 99, 9),
                    "a corrupt PMTiles header (tile type 9 is not a v3 value)"),
    "brotli tiles": (lambda b: _with_byte(b, 98, Compression.BROTLI.value),
                     "its tiles are compressed with brotli, which floe cannot serve"),
    "zstd directories": (lambda b: _with_byte(b, 97, Compression.ZSTD.value),
                         "its directories are compressed with zstd"),
    "zooms": (lambda b: _with_byte(b, 100, 9), "a corrupt PMTiles header (zooms 9..2)"),
    "empty": (lambda b: b"", "an empty file, not MBTiles or PMTiles"),
}


@pytest.mark.parametrize("case", list(REFUSALS))
def test_unusable_pmtiles_are_one_line(tmp_path: Path, case: str) -> None:
    change, said = REFUSALS[case]
    path = tmp_path / "sea.pmtiles"
    path.write_bytes(change(_pmtiles_bytes(tmp_path)))
    with pytest.raises(TilesError) as err:
        TileArchive(path)
    text = str(err.value)
    assert "\n" not in text and text.startswith(f"map tiles {path}: "), text
    assert said in text, text


def test_no_tiles_pmtiles_is_refused(tmp_path: Path) -> None:
    """An archive whose root directory lists nothing."""
    good = _pmtiles_bytes(tmp_path)
    root_length = int.from_bytes(good[16:24], "little")
    empty_root = serialize_directory([])
    assert len(empty_root) <= root_length
    data = good[:127] + empty_root + b"\x00" * (root_length - len(empty_root)) + \
        good[127 + root_length:]
    path = tmp_path / "none.pmtiles"
    path.write_bytes(data)
    with pytest.raises(TilesError, match="holds no tiles"):
        TileArchive(path)


def test_gcs_run_refuses_vector_pmtiles_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``gcs run --map-tiles`` with vector PMTiles: exit 2, one line, no traceback."""
    write_pmtiles(tmp_path / "roads.pmtiles", {(2, 1, 1): b"mvt"}, tile_type=TileType.MVT)
    code, out, err = gcs_run_here(
        tmp_path, capsys, monkeypatch, "--vehicles", "sim:1", "--map-tiles", "roads.pmtiles",
        "--duration", "5", "--status", "log", "--detections", "off",
        "--run-dir", str(tmp_path / "runs"))  # fmt: skip
    assert code == 2, err
    assert "Traceback" not in err + out
    lines = [line for line in err.splitlines() if "roads.pmtiles" in line]
    assert len(lines) == 1, err
    assert "map tiles roads.pmtiles: holds vector tiles (MVT), which need a style" in lines[0]


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
