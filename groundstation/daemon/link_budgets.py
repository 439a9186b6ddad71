"""Each vehicle link's traffic budget (:class:`~groundstation.mavlink.link_budget.LinkBudget`),
kept by the daemon: built per link at start, fed the link's RADIO_STATUS frames, looked up
by a vehicle's port through the link the vehicle is bound to now (docs/links.md, "Over a
telemetry radio").

A link's configured capacity: ``--link-rate URL=BPS`` (config ``links.link_rate``) for that
link, else a serial link's baud rate (8N1: baud bit/s on the wire), else none: unlimited
until a radio reports on it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import Any

from groundstation.link.base import Link
from groundstation.mavlink.link_budget import LinkBudget

__all__ = ["LinkBudgets"]


class LinkBudgets:
    """The budgets of the daemon's vehicle links, by link id."""

    def __init__(
        self,
        links: Iterable[Link],
        link_of: Callable[[int], Link | None],
        *,
        timeout_floor_s: float,
        rates_bps: Mapping[str, float] | None = None,
    ) -> None:
        rates = rates_bps or {}
        self._link_of = link_of
        self.by_link: dict[str, LinkBudget] = {}
        for link in links:
            spec = link.spec
            configured = rates.get(spec.canonical)
            if configured is None and spec.baud is not None:
                configured = float(spec.baud)
            self.by_link[link.link_id] = LinkBudget(timeout_floor_s, configured)

    def for_system(self, system_id: int) -> LinkBudget | None:
        """The budget of the link ``system_id`` is bound to now (None: not bound)."""
        link = self._link_of(system_id)
        return None if link is None else self.by_link.get(link.link_id)

    def on_radio_status(self, link_id: str, t_s: float, msg: object) -> None:
        """A RADIO_STATUS arrived on ``link_id``: its ground radio's report."""
        budget = self.by_link.get(link_id)
        if budget is not None:
            budget.on_radio_status(t_s, msg)

    def summary(self) -> dict[str, dict[str, Any]]:
        """Per link: capacity (bit/s, None unlimited), SRTT and RTO (s), round-trip samples,
        the radio's last txbuf, exchanges held for it and the mission seconds they waited."""
        out: dict[str, dict[str, Any]] = {}
        for link_id, b in self.by_link.items():
            rto = b.rtt.rto_s
            out[link_id] = {
                "capacity_bps": b.capacity_bps,
                "srtt_s": None if b.rtt.srtt_s is None else round(b.rtt.srtt_s, 3),
                "rto_s": None if rto is None else round(rto, 3),
                "rtt_samples": b.rtt.samples,
                "txbuf_pct": None if b.radio is None else b.radio.txbuf_pct,
                "holds": b.holds,
                "held_s": round(b.held_s, 2),
            }
        return out
