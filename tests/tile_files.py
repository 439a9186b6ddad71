"""Small raster tile archives made inside the tests (no binary fixture is committed): PNG
tiles drawn with Pillow, and PMTiles v3 archives written with the ``pmtiles`` package's
writer (its ``Writer``; with ``leaf_size``, the writer's own ``build_roots_leaves`` and
``serialize_header``, so a small archive has leaf directories as a large one would)."""

from __future__ import annotations

import gzip
import io
import math
from pathlib import Path
from typing import Any

from pmtiles.tile import Compression, Entry, TileType, serialize_header, zxy_to_tileid
from pmtiles.writer import Writer, build_roots_leaves

__all__ = ["around", "png_tile", "write_pmtiles"]


def png_tile(rgb: tuple[int, int, int], size_px: int = 256) -> bytes:
    """A PNG of one colour."""
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (size_px, size_px), rgb).save(buf, "PNG")
    return buf.getvalue()


def around(lat_deg: float, lon_deg: float, zooms: range, reach: int = 1
           ) -> list[tuple[int, int, int]]:
    """The XYZ tiles within ``reach`` tiles of (lat, lon) at each zoom (Web Mercator)."""
    lat = math.radians(lat_deg)
    out = []
    for z in zooms:
        n = 2**z
        cx = int((lon_deg + 180) / 360 * n)
        cy = int((1 - math.log(math.tan(lat) + 1 / math.cos(lat)) / math.pi) / 2 * n)
        out += [(z, x, y) for x in range(cx - reach, cx + reach + 1)
                for y in range(cy - reach, cy + reach + 1)]
    return out


def write_pmtiles(path: Path, tiles: dict[tuple[int, int, int], bytes], *,
                  tile_type: TileType = TileType.PNG,
                  compression: Compression = Compression.NONE,
                  bounds: tuple[float, float, float, float] = (11.0, 78.5, 13.0, 79.2),
                  center: tuple[float, float, int] | None = None,
                  leaf_size: int | None = None) -> Path:
    """A PMTiles v3 archive of ``tiles`` (XYZ -> image bytes; gzip-compressed here when
    ``compression`` is GZIP). ``leaf_size``: entries per leaf directory (default: the
    writer's choice, a root directory alone for a small archive)."""
    header: dict[str, Any] = {
        "tile_type": tile_type, "tile_compression": compression,
        "min_lon_e7": round(bounds[0] * 1e7), "min_lat_e7": round(bounds[1] * 1e7),
        "max_lon_e7": round(bounds[2] * 1e7), "max_lat_e7": round(bounds[3] * 1e7)}
    if center is not None:
        header.update(center_lon_e7=round(center[0] * 1e7),
                      center_lat_e7=round(center[1] * 1e7), center_zoom=center[2])
    ordered = sorted((zxy_to_tileid(*zxy), data) for zxy, data in tiles.items())
    if compression == Compression.GZIP:
        ordered = [(tid, gzip.compress(data, mtime=0)) for tid, data in ordered]
    if leaf_size is None:
        with path.open("wb") as f:
            writer = Writer(f)
            for tile_id, data in ordered:
                writer.write_tile(tile_id, data)
            writer.finalize(header, {"name": path.stem})
        return path
    entries, blob = [], b""
    for tile_id, data in ordered:
        entries.append(Entry(tile_id, len(blob), len(data), 1))
        blob += data
    root, leaves, _ = build_roots_leaves(entries, leaf_size)
    metadata = gzip.compress(b'{"name": "leaves"}', mtime=0)
    header.update(
        clustered=True, internal_compression=Compression.GZIP,
        min_zoom=min(z for z, _, _ in tiles), max_zoom=max(z for z, _, _ in tiles),
        root_offset=127, root_length=len(root), metadata_offset=127 + len(root),
        metadata_length=len(metadata), leaf_directory_offset=127 + len(root) + len(metadata),
        leaf_directory_length=len(leaves),
        tile_data_offset=127 + len(root) + len(metadata) + len(leaves),
        tile_data_length=len(blob), addressed_tiles_count=len(entries),
        tile_entries_count=len(entries), tile_contents_count=len(entries))
    path.write_bytes(serialize_header(header) + root + metadata + leaves + blob)  # type: ignore[arg-type]
    return path
