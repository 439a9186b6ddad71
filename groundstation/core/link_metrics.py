"""Each vehicle link's figures for ``metrics.json`` (``links``; docs/links.md, "What a link
carried"): air time used, uploads, their success and latency, and the telemetry's age.

One entry per vehicle, for the link it was bound to at the end:

* ``airtime_pct``: the share of the link's capacity it used, in %. Where a link model
  measured its own air time (the built-in simulator's SiK radios, ``--sim-radio``) that
  figure (``airtime_source`` ``"radio model"``: every packet of both radios, empty and
  statistics packets included); else, on a link whose capacity is known (``--link-rate``,
  a serial link's baud rate), the busier direction of its serial line,
  ``100 * 10 * max(bytes_in, bytes_out) / (rate_bps * mission_s)`` (``"serial line"``:
  8N1 takes 10 bits a byte); else None (a socket with no known capacity).
* ``uploads`` and ``uploads_per_hour``: mission uploads sent on the link (every purpose:
  targets, parks, homes), ``uploads * 3600 / mission_s``; ``upload_ok_pct``: the share
  verified (None without an upload).
* ``upload_latency_s``: ``{p50, p95}`` of the mission seconds from an upload's first
  MISSION_COUNT to the verdict of its verifying download (the journal's ``upload`` line's
  ``took_s``; the set-current and mode change that follow are not in it).
* ``telemetry_age_s``: ``{p50, p95}`` of the age of the vehicle's newest position, sampled
  once a mission second while it had one and its link was not lost (against its own clock:
  :mod:`groundstation.vehicle.freshness`).

A link shared by several vehicles gives each of them the link's ``airtime_pct``.
``gcs simulate`` has no link (:func:`offline_link_entries`): ``link`` and ``airtime_pct``
are None, its uploads are the core's FlyToTargets, applied at once and never lost (latency
0, all verified), and its telemetry is exact (age 0): the same keys, with what the offline
model is.

Percentiles are nearest-rank (the smallest sample with at least that share of the samples
at or below it): no interpolation between two measured values.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

__all__ = ["LinkUse", "link_entries", "offline_link_entries", "percentiles"]


def percentiles(values: Sequence[float], digits: int = 3) -> dict[str, float | None]:
    """``{p50, p95}`` by nearest rank (None without a value)."""
    if not values:
        return {"p50": None, "p95": None}
    ordered = sorted(values)

    def rank(q: float) -> float:
        return round(ordered[max(0, math.ceil(q * len(ordered)) - 1)], digits)

    return {"p50": rank(0.50), "p95": rank(0.95)}


@dataclass(frozen=True)
class LinkUse:
    """What one vehicle's link carried and how its uploads and telemetry fared."""

    vehicle: str
    link: str | None
    """The link it was bound to at the end (its URL), None if never bound."""
    uploads_ok: int
    uploads_failed: int
    upload_latencies_s: Sequence[float]
    telemetry_ages_s: Sequence[float]
    bytes_in: int = 0
    bytes_out: int = 0
    rate_bps: float | None = None
    """The link's known capacity (bit/s on its serial line), None: unknown."""
    model_airtime_pct: float | None = None
    """Air time a link model measured (the simulator's radio), None: no model."""


def link_entries(uses: Iterable[LinkUse], mission_s: float) -> list[dict[str, object]]:
    """The ``links`` list of ``metrics.json`` (see the module docstring)."""
    out: list[dict[str, object]] = []
    for use in uses:
        uploads = use.uploads_ok + use.uploads_failed
        airtime: float | None = None
        source: str | None = None
        if use.model_airtime_pct is not None:
            airtime, source = use.model_airtime_pct, "radio model"
        elif use.rate_bps and mission_s > 0:
            busier = max(use.bytes_in, use.bytes_out)
            airtime, source = 100.0 * 10.0 * busier / (use.rate_bps * mission_s), "serial line"
        out.append({
            "vehicle": use.vehicle,
            "link": use.link,
            "airtime_pct": None if airtime is None else round(airtime, 2),
            "airtime_source": source,
            "uploads": uploads,
            "uploads_per_hour": round(uploads * 3600.0 / mission_s, 2) if mission_s > 0 else None,
            "upload_ok_pct": round(100.0 * use.uploads_ok / uploads, 2) if uploads else None,
            "upload_latency_s": percentiles(use.upload_latencies_s),
            "telemetry_age_s": percentiles(use.telemetry_ages_s),
        })  # fmt: skip
    return out


def offline_link_entries(
    vehicles: Iterable[str], uploads: Mapping[str, int], mission_s: float
) -> list[dict[str, object]]:
    """``gcs simulate``'s ``links``: no link, every upload applied at once, exact
    telemetry (module docstring)."""
    return link_entries(
        (LinkUse(v, None, uploads.get(v, 0), 0, [0.0] * min(1, uploads.get(v, 0)), [0.0])
         for v in vehicles),
        mission_s,
    )
