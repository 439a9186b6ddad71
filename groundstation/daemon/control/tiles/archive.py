"""The operator's tile file (``gcs run --map-tiles FILE``), MBTiles or PMTiles, told apart by
its first bytes (never by its name): SQLite's header ``SQLite format 3\\0`` is MBTiles
(``mbtiles.py``), ``PMTiles`` and version byte 3 is PMTiles v3 (``pmtiles_file.py``);
``PM`` followed by the 16-bit version 1 or 2 is an older PMTiles, refused with the way to
convert it; anything else is refused. Either way, tiles are asked for in the XYZ scheme of
the page's Leaflet, and :meth:`TileArchive.response` is the body and headers of
``/tiles/{z}/{x}/{y}`` (sans-IO: the server only sends it).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

from groundstation.daemon.control.tiles.common import StoredTile, TileReader, TilesError
from groundstation.daemon.control.tiles.mbtiles import MBTilesReader
from groundstation.daemon.control.tiles.pmtiles_file import PMTilesReader

__all__ = ["MAX_ZOOM", "TileArchive", "TileBody", "accepts_gzip"]

log = logging.getLogger(__name__)

MAX_ZOOM = 24
"""The deepest zoom asked for (the page's Leaflet stops there)."""
SQLITE_MAGIC = b"SQLite format 3\x00"
PMTILES_MAGIC = b"PMTiles"
MAX_LOGGED_FAULTS = 20


@dataclass(frozen=True)
class TileBody:
    """What ``/tiles/{z}/{x}/{y}`` answers: the bytes, their type and extra headers."""

    data: bytes
    content_type: str
    headers: dict[str, str] = field(default_factory=dict)


class TileArchive:
    """The operator's tile file, MBTiles or PMTiles, open read-only from start to stop."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise TilesError(f"map tiles {self.path}: no such file")
        self._reader = _open_reader(self.path)
        self.info = self._reader.info
        self.content_type = self._reader.content_type
        self._faults = 0

    def cold(self, z: int, x: int, y: int) -> bool:
        """Whether answering ``z/x/y`` would first decode a directory not yet cached (a
        PMTiles leaf: ~10 ms of pure Python); the server then runs :meth:`warm` in a worker
        thread before :meth:`response`, so the event loop keeps turning."""
        return self._on_grid(z, x, y) and self._reader.cold(z, x, y)

    def warm(self, z: int, x: int, y: int) -> None:
        """Decode and cache the directories answering ``z/x/y`` needs (thread-safe)."""
        if self._on_grid(z, x, y):
            self._reader.warm(z, x, y)

    @staticmethod
    def _on_grid(z: int, x: int, y: int) -> bool:
        return 0 <= z <= MAX_ZOOM and 0 <= x < 2**z and 0 <= y < 2**z

    def stored_tile(self, z: int, x: int, y: int) -> StoredTile | None:
        """The tile at XYZ ``z/x/y`` as the file stores it, None when it has none there."""
        return self._reader.stored(z, x, y) if self._on_grid(z, x, y) else None

    def tile(self, z: int, x: int, y: int) -> bytes | None:
        """The image at XYZ ``z/x/y`` (decompressed), None when the file has none there."""
        stored = self.stored_tile(z, x, y)
        return None if stored is None else stored.decoded()

    def response(self, z: int, x: int, y: int, accept_encoding: str) -> TileBody | None:
        """The answer to a request for ``z/x/y`` with that ``Accept-Encoding`` header: a tile
        stored gzip-compressed goes as it is with ``Content-Encoding: gzip`` when the client
        accepts gzip (every browser does), else inflated; None (404) where there is no tile,
        or its bytes cannot be inflated (logged)."""
        stored = self.stored_tile(z, x, y)
        if stored is None:
            return None
        headers = {"Cache-Control": "max-age=3600"}
        if not stored.gzip:
            return TileBody(stored.data, self.content_type, headers)
        headers["Vary"] = "Accept-Encoding"
        if accepts_gzip(accept_encoding):
            return TileBody(stored.data, self.content_type,
                            headers | {"Content-Encoding": "gzip"})
        try:
            return TileBody(stored.decoded(), self.content_type, headers)
        except TilesError as exc:
            self._faults += 1
            if self._faults <= MAX_LOGGED_FAULTS:
                log.warning("map tiles %s: tile %d/%d/%d: %s; served as no tile",
                            self.path, z, x, y, exc)
            return None

    def close(self) -> None:
        self._reader.close()


def _open_reader(path: Path) -> TileReader:
    """The reader for the file's format, by its first bytes."""
    try:
        with path.open("rb") as f:
            head = f.read(16)
    except OSError as exc:
        raise TilesError(f"map tiles {path}: cannot be read ({exc.strerror or exc})"
                         ) from None
    if head.startswith(SQLITE_MAGIC):
        return MBTilesReader(path)
    if head.startswith(PMTILES_MAGIC):
        return PMTilesReader(path)
    if head[:2] == b"PM" and int.from_bytes(head[2:4], "little") in (1, 2):
        version = int.from_bytes(head[2:4], "little")
        raise TilesError(f"map tiles {path}: a PMTiles v{version} file; floe reads v3 "
                         "(convert it: pmtiles convert OLD.pmtiles NEW.pmtiles)")
    if not head:
        raise TilesError(f"map tiles {path}: an empty file, not MBTiles or PMTiles")
    raise TilesError(f"map tiles {path}: not an MBTiles or PMTiles file (it starts with "
                     "neither SQLite's header nor PMTiles')")


def accepts_gzip(accept_encoding: str) -> bool:
    """Whether an ``Accept-Encoding`` header (RFC 9110 12.5.3) accepts gzip: ``gzip`` (or
    ``x-gzip``), else ``*``, with a quality above 0 (1 when none is given)."""
    quality: dict[str, float] = {}
    for part in accept_encoding.split(","):
        name, *params = (p.strip() for p in part.split(";"))
        q = 1.0
        for param in params:
            key, _, value = param.partition("=")
            if key.strip().lower() == "q":
                try:
                    q = float(value)
                except ValueError:
                    q = 0.0
        if name:
            quality[name.lower()] = q
    for name in ("gzip", "x-gzip", "*"):
        if name in quality:
            return quality[name] > 0
    return False
