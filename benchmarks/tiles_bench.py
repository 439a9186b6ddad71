"""What one map tile costs the daemon (``gcs run --map-tiles FILE``, docs/control.md).

    nice -n 10 python benchmarks/tiles_bench.py [--max-zoom 13] [--reads 20000]
        [--json benchmarks/tiles_bench.json]

Builds, in a temporary folder, one regional raster archive twice over: every XYZ tile of
10..14 E, 78..80 N (Svalbard) at zooms 0..MAX_ZOOM (29 000 tiles at 13), each 100..1000
random bytes (a tile's bytes do not change the cost of finding it), as a PMTiles v3 archive
written by the ``pmtiles`` package's Writer (its root directory then points to leaf
directories, as a real regional archive's does) and as an MBTiles file. Then times, per
read, with ``time.perf_counter_ns``:

* ``loop_lag_leaf_on_loop`` / ``loop_lag_leaf_in_worker``: the event loop's worst lag
  (ms; a 1 ms ticker) while all the leaves are decoded one after the other, on the loop or
  in a worker thread (``asyncio.to_thread``, as the server does);
* ``pmtiles``: ``TileArchive.cold(z, x, y)`` then ``TileArchive.response(z, x, y, "gzip,
  deflate")``, what the server calls for ``/tiles/z/x/y``, after one pass has read every
  leaf (the daemon's steady state);
* ``pmtiles_cold_check``: ``TileArchive.cold`` on a tile whose leaf is not cached yet (the
  server's question before every tile; true here);
* ``pmtiles_leaf_decode``: ``TileArchive.warm`` then, decoding that leaf (the server runs it
  in a worker thread, so it never holds the event loop);
* ``pmtiles_package_reader``: the ``pmtiles`` package's own ``Reader.get`` (re-reads the
  header and decodes the root and leaf directories on every call: why floe caches them);
* ``mbtiles``: the same calls on the MBTiles file (one SQLite indexed lookup).

The reads are the same random sample of the archive's tiles (seed 1) for every reader.
Figures: median, 99th percentile, mean and maximum in microseconds, with the load average
before (the 2-core development machine is shared: the tails are its other work).
"""

from __future__ import annotations

import argparse
import asyncio
import functools
import json
import math
import os
import random
import sqlite3
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pmtiles.reader import MmapSource, Reader
from pmtiles.tile import (
    Compression,
    TileType,
    deserialize_directory,
    deserialize_header,
    tileid_to_zxy,
    zxy_to_tileid,
)
from pmtiles.writer import Writer

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from groundstation.daemon.control.tiles import TileArchive  # noqa: E402

WEST, SOUTH, EAST, NORTH = 10.0, 78.0, 14.0, 80.0


def _tile_xy(lat_deg: float, lon_deg: float, z: int) -> tuple[int, int]:
    """The XYZ tile holding (lat, lon) at zoom z (Web Mercator)."""
    n = 2**z
    lat = math.radians(lat_deg)
    x = int((lon_deg + 180) / 360 * n)
    y = int((1 - math.log(math.tan(lat) + 1 / math.cos(lat)) / math.pi) / 2 * n)
    return min(x, n - 1), min(y, n - 1)


def region_tiles(max_zoom: int) -> list[tuple[int, int, int]]:
    out = []
    for z in range(max_zoom + 1):
        x0, y0 = _tile_xy(NORTH, WEST, z)
        x1, y1 = _tile_xy(SOUTH, EAST, z)
        out += [(z, x, y) for x in range(x0, x1 + 1) for y in range(y0, y1 + 1)]
    return out


def build(folder: Path, max_zoom: int) -> tuple[Path, Path, list[tuple[int, int, int]]]:
    rng = random.Random(0)
    tiles = region_tiles(max_zoom)
    data = {t: rng.randbytes(rng.randint(100, 1000)) for t in tiles}
    pm = folder / "region.pmtiles"
    with pm.open("wb") as f:
        writer = Writer(f)
        for tile_id, t in sorted((zxy_to_tileid(*t), t) for t in tiles):
            writer.write_tile(tile_id, data[t])
        writer.finalize({"tile_type": TileType.PNG, "tile_compression": Compression.NONE,
                         "min_lon_e7": int(WEST * 1e7), "min_lat_e7": int(SOUTH * 1e7),
                         "max_lon_e7": int(EAST * 1e7), "max_lat_e7": int(NORTH * 1e7)},
                        {"name": "bench"})
    mb = folder / "region.mbtiles"
    db = sqlite3.connect(mb)
    db.execute("CREATE TABLE metadata (name TEXT, value TEXT)")
    db.execute("CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, tile_row INTEGER,"
               " tile_data BLOB)")
    db.execute("CREATE UNIQUE INDEX tile_index ON tiles (zoom_level, tile_column, tile_row)")
    db.execute("INSERT INTO metadata VALUES ('format', 'png')")
    db.executemany("INSERT INTO tiles VALUES (?, ?, ?, ?)",
                   [(z, x, 2**z - 1 - y, data[(z, x, y)]) for z, x, y in tiles])
    db.commit()
    db.close()
    return pm, mb, tiles


def served(archive: TileArchive) -> Callable[[int, int, int], Any]:
    """What the server does for ``/tiles/z/x/y`` from a browser (which accepts gzip): asks
    whether a leaf must be decoded first (in a worker; not here, where all are cached), then
    answers."""

    def serve(z: int, x: int, y: int) -> Any:
        if archive.cold(z, x, y):
            archive.warm(z, x, y)
        return archive.response(z, x, y, "gzip, deflate")

    return serve


def timed(read: Callable[[int, int, int], Any], sample: list[tuple[int, int, int]]
          ) -> list[float]:
    """Microseconds per read; every read must find its tile."""
    out = []
    for z, x, y in sample:
        t0 = time.perf_counter_ns()
        found = read(z, x, y)
        out.append((time.perf_counter_ns() - t0) / 1000)
        assert found is not None, (z, x, y)
    return out


def once_us(call: Callable[[], Any]) -> tuple[float, Any]:
    """Microseconds one call took, and what it returned."""
    t0 = time.perf_counter_ns()
    value = call()
    return (time.perf_counter_ns() - t0) / 1000, value


def figures(us: list[float]) -> dict[str, float]:
    ordered = sorted(us)
    return {"reads": len(us), "median_us": round(statistics.median(us), 2),
            "p99_us": round(ordered[int(0.99 * (len(us) - 1))], 2),
            "mean_us": round(statistics.fmean(us), 2), "max_us": round(ordered[-1], 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], allow_abbrev=False)
    ap.add_argument("--max-zoom", type=int, default=13)
    ap.add_argument("--reads", type=int, default=20000)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        pm, mb, tiles = build(Path(tmp), args.max_zoom)
        sample = random.Random(1).choices(tiles, k=args.reads)
        load = os.getloadavg()[0]
        result: dict[str, Any] = {
            "tiles": len(tiles), "max_zoom": args.max_zoom,
            "pmtiles_bytes": pm.stat().st_size, "mbtiles_bytes": mb.stat().st_size,
            "load_avg_1min_before": round(load, 2), "cpus": os.cpu_count()}
        leaves = leaf_starts(pm)
        result["leaf_directories"] = len(leaves)
        cold, check = [], []
        for zxy in leaves:  # a fresh archive each: its first read in that leaf
            archive = TileArchive(pm)
            us, was_cold = once_us(functools.partial(archive.cold, *zxy))
            assert was_cold, zxy
            check.append(us)
            cold.append(once_us(functools.partial(archive.warm, *zxy))[0])
            archive.close()
        result["pmtiles_cold_check"] = figures(check)
        result["pmtiles_leaf_decode"] = figures(cold)
        result["loop_lag_leaf_on_loop"] = asyncio.run(loop_lag(pm, leaves, threaded=False))
        result["loop_lag_leaf_in_worker"] = asyncio.run(loop_lag(pm, leaves, threaded=True))
        archive = TileArchive(pm)
        timed(served(archive), tiles)  # every leaf read
        result["pmtiles"] = figures(timed(served(archive),
                                          sample))
        archive.close()
        with pm.open("rb") as f:
            package = Reader(MmapSource(f))
            result["pmtiles_package_reader"] = figures(timed(package.get, sample[:2000]))
        mbtiles = TileArchive(mb)
        result["mbtiles"] = figures(timed(served(mbtiles),
                                          sample))
        mbtiles.close()
    text = json.dumps(result, indent=2)
    print(text)
    if args.json:
        args.json.write_text(text + "\n")


async def loop_lag(path: Path, leaves: list[tuple[int, int, int]], *, threaded: bool
                   ) -> dict[str, float]:
    """The event loop's worst lag (ms) while every leaf is decoded, one after the other, on
    the loop itself or (as the server does) in a worker thread: a ticker asks for 1 ms
    sleeps and records how late each wakes."""
    archive = TileArchive(path)
    lags: list[float] = []
    done = asyncio.Event()

    async def ticker() -> None:
        while not done.is_set():
            t0 = time.perf_counter()
            await asyncio.sleep(0.001)
            lags.append((time.perf_counter() - t0 - 0.001) * 1000)

    task = asyncio.create_task(ticker())
    await asyncio.sleep(0.05)
    for zxy in leaves:
        if threaded:
            await asyncio.to_thread(archive.warm, *zxy)
        else:
            archive.warm(*zxy)
        await asyncio.sleep(0)
    done.set()
    await task
    archive.close()
    ordered = sorted(lags)
    return {"ticks": len(lags), "max_ms": round(ordered[-1], 2),
            "p99_ms": round(ordered[int(0.99 * (len(lags) - 1))], 2)}


def leaf_starts(path: Path) -> list[tuple[int, int, int]]:
    """The first tile of each leaf directory the root points to (read with the pmtiles
    package's codecs)."""
    with path.open("rb") as f:
        get = MmapSource(f)
        header = deserialize_header(get(0, 127))
        root = deserialize_directory(get(header["root_offset"], header["root_length"]))
    return [tileid_to_zxy(e.tile_id) for e in root if e.run_length == 0]


if __name__ == "__main__":
    main()
