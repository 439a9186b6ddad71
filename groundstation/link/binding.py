"""Which place (a link, or a peer address on one link) a vehicle's system id is bound to.

Pure bookkeeping, no I/O and no clock: every call is given the time. The router binds
system ids to vehicle links; listening links (``udpin:``, ``tcpin:``) bind them to peer
addresses. Both apply the same rules, so one forged frame can redirect nothing:

* A system id is **bound** to the place where its autopilot was first heard: a HEARTBEAT
  whose ``type`` is not GCS and whose ``autopilot`` is not ``MAV_AUTOPILOT_INVALID`` (the
  autopilot component; gimbals, cameras and companions send ``autopilot = INVALID``).
  Other frames never bind. System id 0 (broadcast) is never bound.
* Frames of a bound system id from the bound place are **own**; from any other place they
  are **foreign** (the caller counts them and does not hand them on as the vehicle's).
* **Re-binding** to place P needs evidence from the vehicle itself: the bound place has
  been silent for that system id for at least ``rebind_after_s``, and P delivered at least
  ``evidence_heartbeats`` autopilot HEARTBEATs of it spanning at least ``evidence_span_s``,
  with no gap longer than ``evidence_max_gap_s``, all since the bound place last heard it
  (any frame of the system id from the bound place clears the evidence).
"""

from __future__ import annotations

import enum
from collections.abc import Hashable
from dataclasses import dataclass, field
from typing import Generic, TypeVar

__all__ = ["Binder", "BindingRules", "BindingVerdict", "Peer", "PeerTable"]

P = TypeVar("P", bound=Hashable)

Peer = Hashable
"""A transport address: a UDP ``(host, port)``, a TCP client number; None on 1:1 links."""

@dataclass(frozen=True)
class BindingRules:
    """Evidence needed before a bound system id may move (see the module docstring)."""

    rebind_after_s: float = 10.0
    evidence_heartbeats: int = 3
    evidence_span_s: float = 2.0
    evidence_max_gap_s: float = 5.0


class BindingVerdict(enum.Enum):
    """What a frame means for its system id's binding."""

    UNBOUND = "unbound"  # not bound, and this frame does not bind it: pass it on
    BOUND = "bound"  # this autopilot heartbeat bound it here now
    OWN = "own"  # from the bound place
    FOREIGN = "foreign"  # bound elsewhere: count it, do not hand it on as the vehicle's
    REBOUND = "rebound"  # this heartbeat completed the evidence: bound here from now on

    @property
    def delivered(self) -> bool:
        """True if the frame may be handed on as the system's own."""
        return self is not BindingVerdict.FOREIGN


@dataclass
class _Evidence:
    first_s: float
    last_s: float
    count: int = 1


@dataclass
class _Binding(Generic[P]):
    place: P
    last_heard_s: float
    evidence: dict[P, _Evidence] = field(default_factory=dict)


class Binder(Generic[P]):
    """System id -> place bindings under :class:`BindingRules`."""

    def __init__(self, rules: BindingRules | None = None) -> None:
        self.rules = rules or BindingRules()
        self._bindings: dict[int, _Binding[P]] = {}

    def place_of(self, system_id: int) -> P | None:
        """Where ``system_id`` is bound, None if it is not."""
        binding = self._bindings.get(system_id)
        return binding.place if binding is not None else None

    def bound(self) -> dict[int, P]:
        """Every binding, system id -> place."""
        return {sysid: b.place for sysid, b in self._bindings.items()}

    def forget(self, place: P) -> list[int]:
        """Unbind every system id bound to ``place`` (a TCP client that went away)."""
        gone = [sysid for sysid, b in self._bindings.items() if b.place == place]
        for sysid in gone:
            del self._bindings[sysid]
        for b in self._bindings.values():
            b.evidence.pop(place, None)
        return gone

    def observe(
        self, system_id: int, place: P, autopilot_heartbeat: bool, now_s: float
    ) -> BindingVerdict:
        """Account for one frame of ``system_id`` from ``place`` at ``now_s``."""
        binding = self._bindings.get(system_id)
        if binding is None:
            if autopilot_heartbeat and system_id != 0:
                self._bindings[system_id] = _Binding(place, now_s)
                return BindingVerdict.BOUND
            return BindingVerdict.UNBOUND
        if binding.place == place:
            binding.last_heard_s = now_s
            binding.evidence.clear()
            return BindingVerdict.OWN
        if not autopilot_heartbeat:
            return BindingVerdict.FOREIGN
        rules = self.rules
        ev = binding.evidence.get(place)
        if ev is None or now_s - ev.last_s > rules.evidence_max_gap_s:
            ev = binding.evidence[place] = _Evidence(now_s, now_s)
        else:
            ev.count += 1
            ev.last_s = now_s
        if (
            now_s - binding.last_heard_s >= rules.rebind_after_s
            and ev.count >= rules.evidence_heartbeats
            and ev.last_s - ev.first_s >= rules.evidence_span_s
        ):
            self._bindings[system_id] = _Binding(place, now_s)
            return BindingVerdict.REBOUND
        return BindingVerdict.FOREIGN


class PeerTable:
    """Which peer each system id speaks from, on one multi-peer link.

    A vehicle's system id is bound to the peer its autopilot HEARTBEAT first came from and
    moves only on the evidence rules of :mod:`groundstation.link.binding`; frames of it from
    other peers are foreign. A system id that never sent an autopilot heartbeat (a ground
    station, a companion) simply follows the peer it was last heard from.
    ``peers_for(None)`` is every current peer (broadcast); ``peers_for(sysid)`` is that
    system id's peer, or every peer while it has not been heard (so a first command still
    reaches it); system id 0 is MAVLink's broadcast.
    """

    def __init__(self, rules: BindingRules | None = None) -> None:
        self.binder: Binder[Peer] = Binder(rules)
        self.soft: dict[int, Peer] = {}
        self.extra: list[Peer] = []

    @property
    def by_system(self) -> dict[int, Peer]:
        """System id -> peer (bound vehicles, then the rest by last frame)."""
        return {**self.soft, **self.binder.bound()}

    def heard(
        self, system_id: int, peer: Peer, autopilot_heartbeat: bool = False, now_s: float = 0.0
    ) -> BindingVerdict:
        """Account for a frame of ``system_id`` from ``peer``; says whether it is foreign."""
        verdict = self.binder.observe(system_id, peer, autopilot_heartbeat, now_s)
        if verdict is BindingVerdict.UNBOUND:
            self.soft[system_id] = peer
        elif verdict is not BindingVerdict.FOREIGN:
            self.soft.pop(system_id, None)
        if verdict.delivered and peer in self.extra:
            self.extra.remove(peer)
        return verdict

    def add(self, peer: Peer) -> None:
        """A peer that has sent nothing valid yet (a fresh TCP client)."""
        if peer not in self.extra and peer not in self.by_system.values():
            self.extra.append(peer)

    def forget(self, peer: Peer) -> None:
        """Remove a peer that went away (a TCP client that disconnected)."""
        self.binder.forget(peer)
        for sysid in [s for s, p in self.soft.items() if p == peer]:
            del self.soft[sysid]
        if peer in self.extra:
            self.extra.remove(peer)

    def all_peers(self) -> list[Peer]:
        """Every distinct current peer, in first-heard order."""
        return list(dict.fromkeys([*self.by_system.values(), *self.extra]))

    def peers_for(self, system_id: int | None) -> list[Peer]:
        """Where a frame for ``system_id`` (None or 0: everyone) should go."""
        if system_id:
            peer = self.binder.place_of(system_id)
            if peer is None:
                peer = self.soft.get(system_id)
            if peer is not None:
                return [peer]
        return self.all_peers()
