"""What the two tile readers (``mbtiles.py``, ``pmtiles_file.py``) share: the one-line
error, the archive's metadata for the page, a tile as it is stored, and the reader's
interface (:class:`TileReader`)."""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from typing import Any, Protocol

from domain.errors import ConfigError

__all__ = ["CONTENT_TYPES", "GZIP_MAGIC", "MAX_TILE_BYTES", "StoredTile", "TileInfo",
           "TileReader", "TilesError"]

CONTENT_TYPES = {"png": "image/png", "jpg": "image/jpeg", "webp": "image/webp",
                 "avif": "image/avif"}
"""The raster formats served, with their content type (a browser draws each of them)."""

MAX_TILE_BYTES = 8 * 1024 * 1024
"""The largest tile served once decompressed: a 256 px raster tile is ~10..100 kB, so a
gzip member that inflates beyond this is a corrupt tile (or a decompression bomb)."""

GZIP_MAGIC = b"\x1f\x8b"


class TilesError(ConfigError):
    """The map tiles file cannot be used (one line, naming the file); also a stored tile that
    cannot be decompressed (the server logs it and answers 404)."""


@dataclass(frozen=True)
class TileInfo:
    """The archive's metadata the page needs: ``format`` (``png``, ``jpg``, ``webp``,
    ``avif``), the zoom range the file holds, and where available the bounds (west, south,
    east, north, degrees) and the centre (longitude, latitude degrees, zoom)."""

    archive: str  # "mbtiles" or "pmtiles"
    format: str
    min_zoom: int
    max_zoom: int
    bounds: tuple[float, float, float, float] | None
    center: tuple[float, float, int] | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"archive": self.archive, "format": self.format, "min_zoom": self.min_zoom,
                "max_zoom": self.max_zoom,
                "bounds": list(self.bounds) if self.bounds else None,
                "center": list(self.center) if self.center else None}


@dataclass(frozen=True)
class StoredTile:
    """A tile's bytes as the archive stores them: ``gzip`` when they are a gzip member (the
    server may send them as they are, with ``Content-Encoding: gzip``)."""

    data: bytes
    gzip: bool = False

    def decoded(self) -> bytes:
        """The image itself: the bytes, inflated when gzip-compressed (at most
        :data:`MAX_TILE_BYTES`; beyond, or a broken member, :class:`TilesError`)."""
        if not self.gzip:
            return self.data
        inflate = zlib.decompressobj(wbits=16 + zlib.MAX_WBITS)  # a gzip member
        try:
            out = inflate.decompress(self.data, MAX_TILE_BYTES)
        except zlib.error as exc:
            raise TilesError(f"a gzip-compressed tile is corrupt ({exc})") from None
        if inflate.unconsumed_tail:
            raise TilesError(f"a gzip-compressed tile inflates beyond {MAX_TILE_BYTES} bytes")
        if not inflate.eof:
            raise TilesError("a gzip-compressed tile is truncated")
        return out


class TileReader(Protocol):
    """One open tile file: what :class:`~.archive.TileArchive` asks of a format."""

    info: TileInfo
    content_type: str

    def stored(self, z: int, x: int, y: int) -> StoredTile | None:
        """The tile at XYZ ``z/x/y`` (already checked to exist on the grid) as stored, None
        when the file has none there."""
        ...

    def cold(self, z: int, x: int, y: int) -> bool:
        """Whether reading ``z/x/y`` would first decode a directory not cached (slow: the
        caller may run :meth:`warm` in a worker thread first)."""
        ...

    def warm(self, z: int, x: int, y: int) -> None:
        """Decode and cache what reading ``z/x/y`` needs (thread-safe)."""
        ...

    def close(self) -> None: ...
