"""The operator's offline map tiles (``gcs run --map-tiles FILE``): a raster MBTiles file
(SQLite; https://github.com/mapbox/mbtiles-spec 1.3), served to the live page as
``/tiles/{z}/{x}/{y}`` (the page's Leaflet asks in the XYZ scheme; MBTiles rows count from
the south: ``tile_row = 2**z - 1 - y``).

The file is opened read-only once, at start; a file that is not MBTiles, or holds vector
tiles (``format: pbf``, which need a style to draw), is refused with one line
(:class:`TilesError`). Reads are one indexed lookup of a small blob (well under a
millisecond), done on the event loop.

Also the Leaflet files the page loads (``/vendor/leaflet/...``): they come from the
``xstatic-leaflet`` package (a floe dependency), never from a CDN, never committed here.
"""

from __future__ import annotations

import sqlite3
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from domain.errors import ConfigError

__all__ = ["LEAFLET_FILES", "TileArchive", "TilesError", "leaflet_dir"]

_TYPES = {"png": "image/png", "jpg": "image/jpeg", "jpeg": "image/jpeg",
          "webp": "image/webp"}
MAX_ZOOM = 24

LEAFLET_FILES = {
    "leaflet.js": "text/javascript",
    "leaflet.css": "text/css",
    "images/layers.png": "image/png",
    "images/layers-2x.png": "image/png",
    "images/marker-icon.png": "image/png",
    "images/marker-icon-2x.png": "image/png",
    "images/marker-shadow.png": "image/png",
}
"""What ``/vendor/leaflet/NAME`` serves, with its content type (nothing else)."""


class TilesError(ConfigError):
    """The map tiles file cannot be used (one line, naming the file)."""


def leaflet_dir() -> Path | None:
    """The folder of Leaflet's files in the installed ``xstatic-leaflet``, None when it is
    not installed (the page then draws its own map without tiles)."""
    try:
        from xstatic.pkg import leaflet  # type: ignore[import-untyped]
    except ImportError:
        return None
    path = Path(leaflet.BASE_DIR)
    return path if (path / "leaflet.js").is_file() else None


@dataclass(frozen=True)
class TileInfo:
    """The archive's metadata the page needs."""

    format: str
    min_zoom: int
    max_zoom: int
    bounds: tuple[float, float, float, float] | None  # west, south, east, north (degrees)

    def to_dict(self) -> dict[str, Any]:
        return {"format": self.format, "min_zoom": self.min_zoom, "max_zoom": self.max_zoom,
                "bounds": list(self.bounds) if self.bounds else None}


class TileArchive:
    """One MBTiles file, open read-only."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise TilesError(f"map tiles {self.path}: no such file")
        if self.path.suffix.lower() == ".pmtiles":
            raise TilesError(f"map tiles {self.path}: PMTiles is not read yet; give an "
                             "MBTiles file (raster: png, jpg or webp)")
        try:
            self._db = sqlite3.connect(f"file:{self.path.resolve()}?mode=ro", uri=True,
                                       check_same_thread=False)
            meta = dict(self._db.execute("SELECT name, value FROM metadata").fetchall())
            zooms = self._db.execute("SELECT MIN(zoom_level), MAX(zoom_level) "
                                     "FROM tiles").fetchone()
        except sqlite3.Error as exc:
            raise TilesError(f"map tiles {self.path}: not an MBTiles file ({exc})") from None
        fmt = str(meta.get("format", "png")).lower()
        if fmt not in _TYPES:
            self._db.close()
            raise TilesError(f"map tiles {self.path}: format {fmt!r} is not raster tiles "
                             "(png, jpg or webp; vector tiles need a style)")
        if zooms is None or zooms[0] is None:
            self._db.close()
            raise TilesError(f"map tiles {self.path}: holds no tiles")
        self.content_type = _TYPES[fmt]
        self.info = TileInfo(fmt, int(zooms[0]), int(zooms[1]), _bounds(meta.get("bounds")))

    def tile(self, z: int, x: int, y: int) -> bytes | None:
        """The tile at XYZ ``z/x/y``, None when the archive has none there."""
        if not (0 <= z <= MAX_ZOOM and 0 <= x < 2**z and 0 <= y < 2**z):
            return None
        row = self._db.execute(
            "SELECT tile_data FROM tiles WHERE zoom_level=? AND tile_column=? AND tile_row=?",
            (z, x, 2**z - 1 - y)).fetchone()
        return None if row is None else bytes(row[0])

    def close(self) -> None:
        self._db.close()


def _bounds(text: Any) -> tuple[float, float, float, float] | None:
    try:
        west, south, east, north = (float(v) for v in str(text).split(","))
    except (TypeError, ValueError):
        return None
    return west, south, east, north
