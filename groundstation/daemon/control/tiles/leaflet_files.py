"""The Leaflet files the live page loads (``/vendor/leaflet/...``): they come from the
``xstatic-leaflet`` package (a floe dependency), never from a CDN, never committed here."""

from __future__ import annotations

from pathlib import Path

__all__ = ["LEAFLET_FILES", "leaflet_dir"]

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


def leaflet_dir() -> Path | None:
    """The folder of Leaflet's files in the installed ``xstatic-leaflet``, None when it is
    not installed (the page then draws its own map without tiles)."""
    try:
        from xstatic.pkg import leaflet  # type: ignore[import-untyped]
    except ImportError:
        return None
    path = Path(leaflet.BASE_DIR)
    return path if (path / "leaflet.js").is_file() else None
