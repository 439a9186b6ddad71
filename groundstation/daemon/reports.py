"""The daemon's run in figures: the summary printed at the end (also in ``metrics.json``
and the ``stop`` journal line), and the periodic ``link_drops`` lines."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any, Protocol

from groundstation.link.base import Link

__all__ = ["LinkReporter", "RunState", "run_summary"]


class RunState(Protocol):
    """What the summary reads of the daemon (the daemon has it all)."""

    @property
    def sessions(self) -> Mapping[int, Any]: ...
    @property
    def metrics(self) -> Any: ...
    @property
    def clock(self) -> Any: ...
    @property
    def core(self) -> Any: ...
    @property
    def signing(self) -> Any: ...
    @property
    def router(self) -> Any: ...
    @property
    def newcomers(self) -> Any: ...
    @property
    def unknown_frames(self) -> int: ...
    @property
    def budgets(self) -> Any: ...


def run_summary(daemon: RunState, wall: float, cpu: float) -> dict[str, Any]:
    """Mission and wall time, uncertainty, plans, uploads, visits, links, signing and the
    frames of systems that never became vehicles."""
    metrics = daemon.metrics.to_dict(wall)
    delays = [d for s in daemon.sessions.values() for d in s.upload_delays_s]
    return {
        "mission_s": round(daemon.clock.now_s(), 2),
        "wall_s": round(wall, 2),
        "cpu_s": round(cpu, 2),
        "mean_uncertainty": metrics.get("mean_uncertainty"),
        "max_uncertainty": metrics.get("max_uncertainty"),
        "final_uncertainty": metrics.get("final_uncertainty"),
        "plans": daemon.core.view().plans_adopted,
        "uploads_ok": sum(s.uploads_ok for s in daemon.sessions.values()),
        "uploads_failed": sum(s.uploads_failed for s in daemon.sessions.values()),
        "loiter_to_upload_s": sorted(round(d, 3) for d in delays),
        "visits": len(metrics.get("visits", [])),
        **({"signing": daemon.signing.summary()} if daemon.signing is not None else {}),
        "links": daemon.router.link_stats(),
        "link_budgets": daemon.budgets.summary(),
        "unknown_systems": {
            "frames": daemon.unknown_frames,
            "heartbeats": daemon.newcomers.heartbeats,
            "duplicates": daemon.newcomers.duplicates,
            "pending": daemon.newcomers.pending,
            "rate_limited": daemon.newcomers.rate_limited,
        },
    }


class LinkReporter:
    """What changed in each link's receive trouble (frames dropped unread, bad, foreign,
    iterator overflow) since the last report: the increase and the totals."""

    def __init__(self) -> None:
        self._reported: dict[str, dict[str, int]] = {}

    def changes(self, links: Iterable[Link]) -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        for link in links:
            now = link.counters.receive_summary()
            now["dropped_priority"] = link.counters.rx_dropped_priority
            before = self._reported.get(link.link_id, {})
            delta = {k: v - before.get(k, 0) for k, v in now.items() if k != "received"}
            if any(delta.values()):
                self._reported[link.link_id] = now
                out.append({"link": link.link_id, **delta, "totals": now})
        return out
