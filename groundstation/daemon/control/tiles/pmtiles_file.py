"""A raster PMTiles v3 archive (https://github.com/protomaps/PMTiles, spec v3), read with the
``pmtiles`` package's header and directory codecs (``pmtiles.tile``).

Layout: a 127-byte header (magic ``PMTiles``, version 3, the offsets and lengths of the
root directory, metadata, leaf directories and tile data, the tile type and compression,
the zoom range, bounds and centre), then gzip-compressed directories of entries sorted by
tile id. The tile id is the position on the Hilbert curve of each zoom, counted across
zooms: ``id = (4**z - 1) / 3 + hilbert(z, x, y)`` for XYZ ``z/x/y`` (rows from the north,
the page's own scheme, so nothing is flipped). An entry with ``run_length > 0`` gives
``run_length`` consecutive ids one tile's bytes (``tile_data_offset + offset``, ``length``);
an entry with ``run_length == 0`` points to a leaf directory (``leaf_directory_offset +
offset``) holding the ids from its own on.

At start the header is checked against the file's size (a truncated file is refused), the
root directory is read and checked, and a v2 file, vector tiles (MVT, MLT: they need a
style), an unknown tile type and a tile compression floe cannot serve (brotli, zstd) are
refused with one line (:class:`TilesError`). A tile then costs one binary search of the
cached root directory (and of a cached leaf: the last :data:`LEAF_CACHE` leaves read are
kept) plus one ``pread`` of its bytes: 20-30 us (docs/control.md, ``benchmarks/tiles_bench.py``).
The first read in a leaf decodes it (pure Python, ~10 ms for 4096 entries): the server
asks :meth:`PMTilesReader.cold` first and then has :meth:`PMTilesReader.warm` do it in a
worker thread.
A read that fails later (the file changed under floe, a corrupt leaf) is logged once and
answered as no tile; the daemon runs on.
"""

from __future__ import annotations

import logging
import os
import threading
import zlib
from collections import OrderedDict
from enum import Enum
from pathlib import Path

from pmtiles.tile import (
    Compression,
    Entry,
    TileType,
    deserialize_directory,
    deserialize_header,
    find_tile,
    zxy_to_tileid,
)

from groundstation.daemon.control.tiles.common import (
    CONTENT_TYPES,
    GZIP_MAGIC,
    MAX_TILE_BYTES,
    StoredTile,
    TileInfo,
    TilesError,
)

__all__ = ["HEADER_BYTES", "LEAF_CACHE", "MAX_DEPTH", "ROOT_WITHIN_BYTES", "PMTilesReader"]

log = logging.getLogger(__name__)

HEADER_BYTES = 127
ROOT_WITHIN_BYTES = 16_384
"""The spec's bound: header and root directory within the first 16 KiB."""
LEAF_CACHE = 64
"""Leaf directories kept parsed (a leaf holds up to a few thousand entries, ~100 kB)."""
MAX_DEPTH = 4
"""Directories on a tile's path, root included (the spec's writers use at most 2)."""
MAX_LOGGED_FAULTS = 20

_RASTER = {TileType.PNG: "png", TileType.JPEG: "jpg", TileType.WEBP: "webp",
           TileType.AVIF: "avif"}
_VECTOR = {TileType.MVT: "MVT", TileType.MLT: "MLT"}
_SERVED = {Compression.NONE, Compression.GZIP, Compression.UNKNOWN}


class PMTilesReader:
    """One PMTiles v3 archive, open read-only; its root directory and recent leaves cached."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._leaves: OrderedDict[int, list[Entry]] = OrderedDict()
        self._lock = threading.Lock()  # the leaf cache, shared with warm() in a worker
        self._faults = 0
        self._fd = -1
        try:
            self._fd = os.open(path, os.O_RDONLY)
            self._size_bytes = os.fstat(self._fd).st_size
            self._open()
        except (TilesError, OSError) as exc:
            if self._fd >= 0:
                os.close(self._fd)
            if isinstance(exc, TilesError):
                raise
            raise TilesError(f"map tiles {path}: cannot be read ({exc.strerror or exc})"
                             ) from None

    # ------------------------------------------------------------------ opening

    def _refuse(self, why: str) -> TilesError:
        return TilesError(f"map tiles {self.path}: {why}")

    def _open(self) -> None:
        head = os.pread(self._fd, HEADER_BYTES, 0)
        if len(head) < HEADER_BYTES:
            raise self._refuse(f"a truncated PMTiles file ({len(head)} bytes, shorter than "
                               f"its {HEADER_BYTES}-byte header)")
        if head[7] != 3:
            raise self._refuse(f"PMTiles version {head[7]} is not read (only v3)")
        for what, pos, kind in (("internal compression", 97, Compression),
                                ("tile compression", 98, Compression),
                                ("tile type", 99, TileType)):
            if head[pos] not in {m.value for m in kind}:
                raise self._refuse(f"a corrupt PMTiles header ({what} {head[pos]} is not a "
                                   "v3 value)")
        header = deserialize_header(head)
        tile_type = header["tile_type"]
        if tile_type in _VECTOR:
            raise self._refuse(f"holds vector tiles ({_VECTOR[tile_type]}), which need a "
                               "style to draw; give raster tiles (png, jpg, webp or avif)")
        if tile_type not in _RASTER:
            raise self._refuse("its tile type is unknown (0 in the header); floe serves "
                               "raster tiles (png, jpg, webp or avif)")
        if header["internal_compression"] != Compression.GZIP:
            raise self._refuse(f"its directories are compressed with "
                               f"{header['internal_compression'].name.lower()}; floe reads "
                               "gzip (the pmtiles tool's default)")
        compression = header["tile_compression"]
        if compression not in _SERVED:
            raise self._refuse(f"its tiles are compressed with {compression.name.lower()}, "
                               "which floe cannot serve; store them uncompressed or gzip")
        for name in ("root", "metadata", "leaf_directory", "tile_data"):
            offset = header[f"{name}_offset"]  # type: ignore[literal-required]
            length = header[f"{name}_length"]  # type: ignore[literal-required]
            if offset + length > self._size_bytes:
                raise self._refuse(
                    f"a truncated PMTiles file: its header puts the {name.replace('_', ' ')} "
                    f"at bytes {offset}..{offset + length}, the file has {self._size_bytes}")
        if header["root_offset"] + header["root_length"] > ROOT_WITHIN_BYTES:
            raise self._refuse(f"a corrupt PMTiles header (its root directory ends past byte "
                               f"{ROOT_WITHIN_BYTES}, where v3 keeps it)")
        if not 0 <= header["min_zoom"] <= header["max_zoom"] <= 31:
            raise self._refuse(f"a corrupt PMTiles header (zooms {header['min_zoom']}.."
                               f"{header['max_zoom']})")
        self._header = header
        self._gzip = compression == Compression.GZIP
        self._sniff_gzip = compression == Compression.UNKNOWN
        self._tile_base = header["tile_data_offset"]
        self._leaf_base = header["leaf_directory_offset"]
        try:
            self._root = self._directory(header["root_offset"], header["root_length"])
        except _Corrupt as exc:
            raise self._refuse(f"a corrupt PMTiles file (root directory: {exc})") from None
        if not self._root:
            raise self._refuse("holds no tiles")
        self._has_leaves = any(e.run_length == 0 for e in self._root)
        fmt = _RASTER[tile_type]
        self.content_type = CONTENT_TYPES[fmt]
        self.info = TileInfo("pmtiles", fmt, header["min_zoom"], header["max_zoom"],
                             _bounds(header["min_lon_e7"], header["min_lat_e7"],
                                     header["max_lon_e7"], header["max_lat_e7"]),
                             _center(header["center_lon_e7"], header["center_lat_e7"],
                                     header["center_zoom"]))

    def _directory(self, offset: int, length: int) -> list[Entry]:
        """The directory at ``offset`` (``length`` bytes), its entries checked to point inside
        the tile data or the leaf directories."""
        data = os.pread(self._fd, length, offset)
        if len(data) != length:
            raise _Corrupt(f"{len(data)} of {length} bytes at {offset}")
        try:
            entries = deserialize_directory(data)
        except (EOFError, OSError, ValueError, zlib.error) as exc:  # BadGzipFile: OSError
            raise _Corrupt(str(exc) or type(exc).__name__) from None
        tiles_bytes = self._header["tile_data_length"]
        leaves_bytes = self._header["leaf_directory_length"]
        for entry in entries:
            end = entry.offset + entry.length
            if entry.offset < 0 or (end > leaves_bytes if entry.run_length == 0
                                    else end > tiles_bytes):
                raise _Corrupt(f"entry of tile id {entry.tile_id} points past its section")
        return entries

    # ------------------------------------------------------------------ reading

    def stored(self, z: int, x: int, y: int) -> StoredTile | None:
        """The tile at XYZ ``z/x/y``: None outside the header's zooms or where no entry
        covers its id (a leaf not yet cached is decoded here)."""
        entry = self._entry(z, x, y, load=True)
        return None if not isinstance(entry, Entry) else self._read_tile(entry, z, x, y)

    def cold(self, z: int, x: int, y: int) -> bool:
        """Whether finding ``z/x/y`` would first decode a leaf directory not cached (~10 ms
        of pure Python for a leaf of 4096 entries): the server then calls :meth:`warm` in a
        worker thread, so the event loop keeps turning. An archive whose root directory
        holds every entry (a small one) is never cold: no search is made."""
        return self._has_leaves and self._entry(z, x, y, load=False) is _COLD

    def warm(self, z: int, x: int, y: int) -> None:
        """Decode and cache the directories on the path to ``z/x/y`` (thread-safe)."""
        self._entry(z, x, y, load=True)

    def _entry(self, z: int, x: int, y: int, *, load: bool) -> Entry | _Cold | None:
        """The entry that holds ``z/x/y``'s bytes, None when none does; without ``load``,
        :data:`_COLD` where a leaf on the path is not cached."""
        if not self._header["min_zoom"] <= z <= self._header["max_zoom"]:
            return None
        tile_id = zxy_to_tileid(z, x, y)
        entries = self._root
        for _ in range(MAX_DEPTH):
            entry = find_tile(entries, tile_id)
            if entry is None or entry.run_length > 0:
                return entry
            leaf = self._cached_leaf(entry.offset)
            if leaf is None:
                if not load:
                    return _COLD
                leaf = self._load_leaf(entry)
            entries = leaf
        self._fault(f"tile {z}/{x}/{y}: deeper than {MAX_DEPTH} directories")
        return None

    def _cached_leaf(self, offset: int) -> list[Entry] | None:
        with self._lock:
            leaf = self._leaves.get(offset)
            if leaf is not None:
                self._leaves.move_to_end(offset)
            return leaf

    def _load_leaf(self, entry: Entry) -> list[Entry]:
        """Decode the leaf ``entry`` points to and keep it (the last :data:`LEAF_CACHE`); a
        corrupt leaf is logged and kept as empty, so it is read (and logged) once."""
        try:
            leaf = self._directory(self._leaf_base + entry.offset, entry.length)
        except (_Corrupt, OSError) as exc:
            self._fault(f"leaf directory at {entry.offset}: {exc}")
            leaf = []
        with self._lock:
            self._leaves[entry.offset] = leaf
            self._leaves.move_to_end(entry.offset)
            if len(self._leaves) > LEAF_CACHE:
                self._leaves.popitem(last=False)
        return leaf

    def _read_tile(self, entry: Entry, z: int, x: int, y: int) -> StoredTile | None:
        if entry.length > MAX_TILE_BYTES:
            self._fault(f"tile {z}/{x}/{y}: {entry.length} bytes, more than a tile's "
                        f"{MAX_TILE_BYTES}")
            return None
        try:
            data = os.pread(self._fd, entry.length, self._tile_base + entry.offset)
        except OSError as exc:
            self._fault(f"tile {z}/{x}/{y}: {exc.strerror or exc}")
            return None
        if len(data) != entry.length:
            self._fault(f"tile {z}/{x}/{y}: {len(data)} of {entry.length} bytes (the file "
                        "changed?)")
            return None
        gzip = self._gzip or (self._sniff_gzip and data.startswith(GZIP_MAGIC))
        return StoredTile(data, gzip)

    def _fault(self, what: str) -> None:
        """Log a failed read (the first :data:`MAX_LOGGED_FAULTS`; the daemon runs on)."""
        with self._lock:
            self._faults += 1
            faults = self._faults
        if faults <= MAX_LOGGED_FAULTS:
            log.warning("map tiles %s: %s; served as no tile", self.path, what)

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1
        with self._lock:
            self._leaves.clear()


class _Corrupt(Exception):
    """A directory that cannot be decoded."""


class _Cold(Enum):
    """A tile's path goes through a leaf not cached yet."""

    COLD = "cold"


_COLD = _Cold.COLD


def _bounds(west_e7: int, south_e7: int, east_e7: int, north_e7: int
            ) -> tuple[float, float, float, float] | None:
    """The header's bounds in degrees (west, south, east, north); None when out of range."""
    west, south, east, north = (v / 1e7 for v in (west_e7, south_e7, east_e7, north_e7))
    if -180 <= west < east <= 180 and -90 <= south < north <= 90:
        return west, south, east, north
    return None


def _center(lon_e7: int, lat_e7: int, zoom: int) -> tuple[float, float, int] | None:
    """The header's centre: longitude, latitude (degrees), zoom; None when out of range."""
    lon, lat = lon_e7 / 1e7, lat_e7 / 1e7
    return (lon, lat, zoom) if -180 <= lon <= 180 and -90 <= lat <= 90 else None
