"""A raster MBTiles file (SQLite; https://github.com/mapbox/mbtiles-spec 1.3) read in the
XYZ scheme the page's Leaflet asks in: MBTiles rows count from the south, so XYZ ``z/x/y``
is ``tile_row = 2**z - 1 - y``.

The file is opened read-only once, at start; one that SQLite cannot read as MBTiles, holds
vector tiles (``format: pbf``, which need a style to draw) or no tile is refused with one
line (:class:`TilesError`). A read is one indexed lookup of a small blob (well under a
millisecond), done on the event loop.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path
from typing import Any

from groundstation.daemon.control.tiles.common import (
    CONTENT_TYPES,
    StoredTile,
    TileInfo,
    TilesError,
)

__all__ = ["MBTilesReader"]

_FORMATS = {"png": "png", "jpg": "jpg", "jpeg": "jpg", "webp": "webp"}


class MBTilesReader:
    """One MBTiles file, open read-only."""

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            self._db = sqlite3.connect(f"file:{path.resolve()}?mode=ro", uri=True,
                                       check_same_thread=False)
        except sqlite3.Error as exc:
            raise TilesError(f"map tiles {path}: not an MBTiles file ({exc})") from None
        try:
            meta = dict(self._db.execute("SELECT name, value FROM metadata").fetchall())
            zooms = self._db.execute("SELECT MIN(zoom_level), MAX(zoom_level) "
                                     "FROM tiles").fetchone()
        except sqlite3.Error as exc:
            self._db.close()
            raise TilesError(f"map tiles {path}: not an MBTiles file ({exc})") from None
        fmt = str(meta.get("format", "png")).lower()
        if fmt not in _FORMATS:
            self._db.close()
            raise TilesError(f"map tiles {path}: format {fmt!r} is not raster tiles "
                             "(png, jpg or webp; vector tiles need a style)")
        if zooms is None or zooms[0] is None:
            self._db.close()
            raise TilesError(f"map tiles {path}: holds no tiles")
        self.content_type = CONTENT_TYPES[_FORMATS[fmt]]
        self.info = TileInfo("mbtiles", _FORMATS[fmt], int(zooms[0]), int(zooms[1]),
                             _bounds(meta.get("bounds")), _center(meta.get("center")))

    def stored(self, z: int, x: int, y: int) -> StoredTile | None:
        row = self._db.execute(
            "SELECT tile_data FROM tiles WHERE zoom_level=? AND tile_column=? AND tile_row=?",
            (z, x, 2**z - 1 - y)).fetchone()
        return None if row is None else StoredTile(bytes(row[0]))

    def cold(self, z: int, x: int, y: int) -> bool:
        """Never: an indexed lookup has nothing to decode first."""
        return False

    def warm(self, z: int, x: int, y: int) -> None:
        """Nothing to decode ahead."""

    def close(self) -> None:
        self._db.close()


def _numbers(text: Any, count: int) -> list[float] | None:
    try:
        values = [float(v) for v in str(text).split(",")]
    except (TypeError, ValueError):
        return None
    return values if len(values) == count else None


def _bounds(text: Any) -> tuple[float, float, float, float] | None:
    """The metadata's ``bounds``: ``west,south,east,north`` in degrees."""
    values = _numbers(text, 4)
    return None if values is None else (values[0], values[1], values[2], values[3])


def _center(text: Any) -> tuple[float, float, int] | None:
    """The metadata's ``center``: ``longitude,latitude,zoom``."""
    values = _numbers(text, 3)
    return None if values is None else (values[0], values[1], int(values[2]))
