"""Placeholder for ``gcs campaign report DIR``: the HTML report of a campaign is being
written in another branch, which replaces this module. Only the function's signature is
fixed here, so that ``gcs campaign report`` can dispatch to it."""

from __future__ import annotations

from pathlib import Path

from domain.errors import FloeError

__all__ = ["write_campaign_report"]


def write_campaign_report(dir: Path, out: Path | None) -> Path:
    """Write the HTML report of the campaign folder ``dir`` (to ``out`` or a default) and
    return its path. Not available in this build."""
    raise FloeError(f"the campaign report is not available in this build ({dir}, {out})")
