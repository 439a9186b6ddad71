"""The live map's files: the operator's offline tiles (``gcs run --map-tiles FILE``, served to
the page as ``/tiles/{z}/{x}/{y}``) and Leaflet's own files (``/vendor/leaflet/...``).

* ``archive.py``: :class:`TileArchive`, the operator's file, MBTiles or PMTiles told apart by
  its first bytes, and the answer to a tile request (gzip-compressed tiles sent as they are
  to a browser, inflated for a client that does not accept gzip);
* ``mbtiles.py``: raster MBTiles (SQLite), rows flipped to XYZ;
* ``pmtiles_file.py``: raster PMTiles v3 (the ``pmtiles`` package's codecs), directories
  cached;
* ``common.py``: :class:`TilesError` (one line, naming the file), :class:`TileInfo` (what
  ``/api/session`` tells the page), :class:`StoredTile`;
* ``leaflet_files.py``: Leaflet from the installed ``xstatic-leaflet``.

A file that cannot be served (not MBTiles or PMTiles, truncated or corrupt, PMTiles v1/v2,
vector tiles, an unknown tile type, no tile) is refused at start with one line.
"""

from groundstation.daemon.control.tiles.archive import TileArchive, TileBody, accepts_gzip
from groundstation.daemon.control.tiles.common import StoredTile, TileInfo, TilesError
from groundstation.daemon.control.tiles.leaflet_files import LEAFLET_FILES, leaflet_dir

__all__ = ["LEAFLET_FILES", "StoredTile", "TileArchive", "TileBody", "TileInfo", "TilesError",
           "accepts_gzip", "leaflet_dir"]
