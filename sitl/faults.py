"""Seeded fault injection for one vehicle's link and autopilot (sans-IO, virtual time).

Link impairments apply per MAVLink message, independently in each direction ("up":
ground station -> vehicle, "down": vehicle -> ground station):

* ``loss`` p: the message is dropped with probability p;
* ``dup`` p: delivered twice;
* ``reorder`` p: held back an extra U(0.05, 0.5) s so that later messages overtake it;
* ``delay_s`` d and ``jitter_s`` j: delivered after d + U(0, j) seconds.

Scheduled events (simulated seconds since the start): ``drop`` (the link is down in both
directions for ``for_s``), ``kill`` (the autopilot process dies for ``for_s``: it stops
sending, its connections drop, then it comes back rebooted on the ground where it came
down, disarmed, ``time_boot_ms`` from 0, INITIALISING then MANUAL, the mission reloaded
from storage), ``reboot``, ``mode`` (the operator switches mode, e.g. to FBWA
or RTL, as with the RC transmitter), ``battery`` (the pack suddenly reads ``pct``
percent) and ``airspeed`` (the pitot reads wrong from ``at``, for ``for_s`` or for good:
ArduPlane's health check disables the sensor 4.4 s later, its WIND estimate degrades, and
it re-enables the sensor about 30 s after the fault ends; :mod:`sitl.sim_airspeed`).
Events come from ``--fault`` specs or a scenario's scripted events.

Spec grammar (command line)::

    VEHICLES:KIND[:key=value,...]      VEHICLES = sysid | a,b,c | all
    1:loss:p=0.2,dir=up       all:delay:s=0.3,jitter=0.1       2:dup:p=0.05
    3:reorder:p=0.1           1:drop:at=60,for=20              2:reboot:at=120
    2:kill:at=60,for=30
    1:mode:at=90,mode=FBWA    3:battery:at=200,pct=10
    1:airspeed:at=120         1:airspeed:at=120,for=60

One builder: every fault spec floe makes is spelt by :func:`fault_spec`, the whole list
(the user's ``--fault``/``sim_fault`` specs, then the all-links impairments of
``--loss/--dup/--reorder/--delay-ms``/``sim_loss``, then the scenario's scripted events) is
assembled by :func:`fault_specs`, and turned into each vehicle's :class:`VehicleFaults`
(seeded ``seed * 1000 + sysid``) by :func:`build_faults`. ``gcs sitl``, ``gcs run
--vehicles sim:N`` and the scenario setup (:mod:`sitl.sitl_setup`) all use them.
"""

from __future__ import annotations

import heapq
import random
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from itertools import count
from typing import Any

from domain.fault_spec import FaultError, fault_mode, parse_fault_spec

__all__ = [
    "FaultError",
    "FaultEvent",
    "LinkImpairment",
    "VehicleFaults",
    "apply_fault",
    "build_faults",
    "fault_spec",
    "fault_specs",
    "parse_fault_spec",
]

@dataclass(frozen=True)
class FaultEvent:
    """A scheduled fault: ``kind`` kill | reboot | mode | battery | drop | airspeed |
    airspeed_ok (the end of an airspeed fault)."""

    t_s: float
    kind: str
    mode: int = 0
    fraction: float = 0.0
    duration_s: float = 0.0


@dataclass
class LinkImpairment:
    """Loss, duplication, reordering and delay of one direction of a link."""

    loss: float = 0.0
    dup: float = 0.0
    reorder: float = 0.0
    delay_s: float = 0.0
    jitter_s: float = 0.0
    _queue: list[tuple[float, int, Any]] = field(default_factory=list, repr=False)
    _order: Any = field(default_factory=count, repr=False)

    @property
    def transparent(self) -> bool:
        """True when the impairment does nothing (the fast path)."""
        return not (self.loss or self.dup or self.reorder or self.delay_s or self.jitter_s)

    @property
    def holding(self) -> bool:
        """True while items wait for their delivery time."""
        return bool(self._queue)

    def push(self, item: Any, t_s: float, rng: random.Random) -> None:
        """Offer an item sent at ``t_s``."""
        if self.loss and rng.random() < self.loss:
            return
        copies = 2 if self.dup and rng.random() < self.dup else 1
        for _ in range(copies):
            due = t_s + self.delay_s + (rng.uniform(0.0, self.jitter_s) if self.jitter_s else 0.0)
            if self.reorder and rng.random() < self.reorder:
                due += rng.uniform(0.05, 0.5)
            heapq.heappush(self._queue, (due, next(self._order), item))

    def pop_due(self, t_s: float) -> list[Any]:
        """Items whose delivery time has come, in delivery order."""
        out = []
        while self._queue and self._queue[0][0] <= t_s + 1e-12:
            out.append(heapq.heappop(self._queue)[2])
        return out


class VehicleFaults:
    """All faults of one vehicle, driven by one seeded generator."""

    def __init__(self, seed: int) -> None:
        self.rng = random.Random(seed)
        self.up = LinkImpairment()
        self.down = LinkImpairment()
        self.events: list[FaultEvent] = []
        self._drops: list[tuple[float, float]] = []
        self._next_event = 0

    def add_event(self, event: FaultEvent) -> None:
        """Schedule an event (kept sorted by time)."""
        if event.kind == "drop":
            self._drops.append((event.t_s, event.t_s + event.duration_s))
        self.events.append(event)
        self.events.sort(key=lambda e: e.t_s)

    def link_down(self, t_s: float) -> bool:
        """True while a link drop is in force."""
        return any(a <= t_s < b for a, b in self._drops)

    def send_up(self, item: Any, t_s: float) -> None:
        """A message from the ground station enters the link."""
        if not self.link_down(t_s):
            self.up.push(item, t_s, self.rng)

    def send_down(self, item: Any, t_s: float) -> None:
        """A message from the vehicle enters the link."""
        if not self.link_down(t_s):
            self.down.push(item, t_s, self.rng)

    def pass_down(self, items: list[Any], t_s: float) -> list[Any]:
        """Every item enters the down link at ``t_s`` (:meth:`send_down`); returns what the
        link delivers by ``t_s``, in delivery order (``down.pop_due``). A link with no
        impairment, nothing held back and no drop in force delivers exactly the items, in
        order, without the queue (its generator is not drawn from either way)."""
        down = self.down
        if not down.holding and down.transparent and not self.link_down(t_s):
            return items
        for item in items:
            self.send_down(item, t_s)
        return down.pop_due(t_s)

    def due_events(self, t_s: float) -> list[FaultEvent]:
        """Autopilot events (kill, reboot, mode, battery, airspeed) whose time has come,
        each once."""
        out = []
        while self._next_event < len(self.events) and self.events[self._next_event].t_s <= t_s:
            event = self.events[self._next_event]
            self._next_event += 1
            if event.kind != "drop":
                out.append(event)
        return out


def apply_fault(faults: VehicleFaults, kind: str, options: dict[str, str]) -> None:
    """Add one parsed fault to a vehicle's faults."""
    directions = {"up": [faults.up], "down": [faults.down], "both": [faults.up, faults.down]}[
        options.get("dir", "both")
    ]
    for link in directions:
        if kind == "loss":
            link.loss = float(options["p"])
        elif kind == "dup":
            link.dup = float(options["p"])
        elif kind == "reorder":
            link.reorder = float(options["p"])
        elif kind == "delay":
            link.delay_s = float(options["s"])
            link.jitter_s = float(options.get("jitter", 0.0))
    if kind in ("loss", "dup", "reorder", "delay"):
        return
    at = float(options["at"])
    if kind == "drop":
        faults.add_event(FaultEvent(at, "drop", duration_s=float(options["for"])))
    elif kind == "kill":
        faults.add_event(FaultEvent(at, "kill", duration_s=float(options["for"])))
    elif kind == "reboot":
        faults.add_event(FaultEvent(at, "reboot"))
    elif kind == "mode":
        faults.add_event(FaultEvent(at, "mode", mode=fault_mode(options["mode"])))
    elif kind == "battery":
        faults.add_event(FaultEvent(at, "battery", fraction=float(options["pct"]) / 100.0))
    elif kind == "airspeed":
        faults.add_event(FaultEvent(at, "airspeed"))
        if "for" in options:
            faults.add_event(FaultEvent(at + float(options["for"]), "airspeed_ok"))


def fault_spec(vehicles: int | str, kind: str, options: Mapping[str, float | str] = {}) -> str:
    """One spec in the grammar: ``fault_spec(2, "drop", {"at": 60.0, "for": 30.0})`` ->
    ``2:drop:at=60.0,for=30.0`` (numbers as ``repr``, so they parse back exactly)."""
    body = ",".join(f"{k}={v!r}" if isinstance(v, float) else f"{k}={v}"
                    for k, v in options.items())
    return f"{vehicles}:{kind}:{body}" if body else f"{vehicles}:{kind}"


def fault_specs(
    specs: Iterable[str] = (),
    *,
    loss: float | None = None,
    dup: float | None = None,
    reorder: float | None = None,
    delay_s: float | None = None,
    scripted: Iterable[str] = (),
) -> list[str]:
    """All of a run's specs, in the order they are applied (a later spec of the same kind
    for the same vehicle wins): ``specs`` (the user's), then the impairments of every link
    (``None``: none), then ``scripted`` (the scenario's)."""
    out = list(specs)
    for kind, value in (("loss", loss), ("dup", dup), ("reorder", reorder)):
        if value is not None:
            out.append(fault_spec("all", kind, {"p": float(value)}))
    if delay_s is not None:
        out.append(fault_spec("all", "delay", {"s": float(delay_s)}))
    out += scripted
    return out


def build_faults(specs: Sequence[str], system_ids: Sequence[int], seed: int) -> dict[
    int, VehicleFaults
]:
    """Each vehicle's faults with ``specs`` applied in order; raises :class:`FaultError`
    naming the bad spec (the vehicles are system ids 1..max(system_ids))."""
    faults = {sysid: VehicleFaults(seed * 1000 + sysid) for sysid in system_ids}
    count = max(system_ids, default=0)
    for spec in specs:
        for sysid, kind, options in parse_fault_spec(spec, count):
            if sysid in faults:
                apply_fault(faults[sysid], kind, options)
    return faults
