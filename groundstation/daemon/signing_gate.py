"""MAVLink 2 signing between the daemon and its vehicles (``--signing-*``, docs/daemon.md).

Keys come from files (read here, at start-up) or the ``FLOE_SIGNING_PASSPHRASE``
environment variable, never from the command line; a key is 32 raw bytes or 64 hex digits
in a key file, or SHA-256 of a passphrase (MAVProxy's ``signing setup``). A vehicle is
*signed* if it has a key: its own (``vehicle_settings: {SYSID: {signing_key_file: F}}``)
or the one for all vehicles.

The :class:`SigningGate` sits in the router (``Router.admit`` / ``Router.sign``):

* every frame heard on a vehicle link from a signed system id is checked
  (:class:`~groundstation.mavlink.signing.SigningState`, one per system id so each keeps its
  own streams); a refused frame is counted per ``(system id, link)`` and reason and never
  reaches the tlog, the routing table, ``--out`` or the session. Unsigned RADIO_STATUS
  (and RADIO) is let through (the local radio's own report, which a SiK radio cannot sign;
  ArduPilot does the same). Frames of unsigned system ids pass unchanged.
* every frame the daemon sends to a signed vehicle is signed with its key; a broadcast
  (the GCS heartbeat) is signed with the all-vehicles key if there is one. One timestamp
  counter (``max(last + 1, now)``) serves every key, so no receiver ever sees ours go back.
  The link id is the vehicle link's index. Frames passed through from ``--out`` links are
  forwarded unchanged (another ground station signs its own, or a signed vehicle drops
  them).
* with ``signing_setup``, a signed vehicle heard sending a HEARTBEAT of a vehicle (not of a
  ground station) without a good signature is sent SETUP_SIGNING (its key, our current
  timestamp) at most every ``SETUP_INTERVAL_S`` on the link it was heard on, until a good
  signature arrives from it.
  The frame is itself signed with the new key: a vehicle without a key ignores the
  signature, one that already has the key accepts it, as MAVProxy's ``signing setup``.

No key material is logged, journalled, or written anywhere; :meth:`SigningGate.describe`
names only the sources.
"""

from __future__ import annotations

import os
import time
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from domain.errors import ConfigError
from groundstation.daemon.config import DaemonConfig
from groundstation.mavlink.codec import mavlink2
from groundstation.mavlink.evidence import is_autopilot_heartbeat
from groundstation.mavlink.signing import (
    SigningKeyError,
    SigningState,
    parse_key_file_bytes,
    parse_passphrase_file_bytes,
    sign_frame,
    signing_timestamp,
)

__all__ = ["PASSPHRASE_ENV", "SETUP_INTERVAL_S", "SigningGate", "SigningKeys", "load_signing_keys"]

PASSPHRASE_ENV = "FLOE_SIGNING_PASSPHRASE"
SETUP_INTERVAL_S = 1.0
"""Wall seconds between two SETUP_SIGNING to one vehicle while it is not yet signing."""


@dataclass(frozen=True)
class SigningKeys:
    """The keys of a run: ``default`` for every vehicle, ``per_vehicle`` overriding it."""

    default: bytes | None = field(default=None, repr=False)
    per_vehicle: Mapping[int, bytes] = field(default_factory=dict, repr=False)
    setup: bool = False
    sources: Mapping[str, str] = field(default_factory=dict)
    """Where each key came from (``all`` or a system id -> a file path or the env variable);
    what the journal and the summary may show."""

    @property
    def enabled(self) -> bool:
        """True if any vehicle is signed."""
        return self.default is not None or bool(self.per_vehicle)

    def key_for(self, system_id: int) -> bytes | None:
        """The key of ``system_id`` (None: not signed)."""
        return self.per_vehicle.get(system_id, self.default)


def _read_key(path: str, passphrase: bool, where: str) -> bytes:
    try:
        data = Path(path).expanduser().read_bytes()
    except OSError as exc:
        raise ConfigError(f"{where}: cannot read {path}: {exc.strerror or exc}") from None
    try:
        return parse_passphrase_file_bytes(data) if passphrase else parse_key_file_bytes(data)
    except SigningKeyError as exc:
        raise ConfigError(f"{where}: {path}: {exc}") from None


def load_signing_keys(
    config: DaemonConfig, environ: Mapping[str, str] | None = None
) -> SigningKeys:
    """Read the key files ``config`` names (and the passphrase variable); one-line
    :class:`ConfigError` naming the key and the file on any problem, never the content."""
    env = os.environ if environ is None else environ
    sources: dict[str, str] = {}
    default: bytes | None = None
    signing = config.signing
    if signing.key_file and signing.passphrase_file:
        raise ConfigError("signing_key_file and signing_passphrase_file: give one, not both")
    if signing.key_file:
        default = _read_key(signing.key_file, False, "signing_key_file")
        sources["all"] = signing.key_file
    elif signing.passphrase_file:
        default = _read_key(signing.passphrase_file, True, "signing_passphrase_file")
        sources["all"] = signing.passphrase_file
    elif env.get(PASSPHRASE_ENV):
        try:
            from groundstation.mavlink.signing import key_from_passphrase

            default = key_from_passphrase(env[PASSPHRASE_ENV])
        except SigningKeyError as exc:
            raise ConfigError(f"{PASSPHRASE_ENV}: {exc}") from None
        sources["all"] = f"${PASSPHRASE_ENV}"
    per_vehicle: dict[int, bytes] = {}
    for sysid, settings in sorted(config.fleet.settings.items()):
        where = f"vehicle_settings.{sysid}"
        if settings.signing_key_file and settings.signing_passphrase_file:
            raise ConfigError(f"{where}: give signing_key_file or signing_passphrase_file")
        if settings.signing_key_file:
            per_vehicle[sysid] = _read_key(
                settings.signing_key_file, False, f"{where}.signing_key_file"
            )
            sources[str(sysid)] = settings.signing_key_file
        elif settings.signing_passphrase_file:
            per_vehicle[sysid] = _read_key(
                settings.signing_passphrase_file, True, f"{where}.signing_passphrase_file"
            )
            sources[str(sysid)] = settings.signing_passphrase_file
    if signing.setup and default is None and not per_vehicle:
        raise ConfigError("signing_setup: needs a signing key (signing_key_file, ...)")
    return SigningKeys(default, per_vehicle, signing.setup, sources)


class SigningGate:
    """Checks frames from signed vehicles and signs frames to them (module docstring)."""

    def __init__(
        self,
        keys: SigningKeys,
        gcs_system_id: int,
        now_unix_s: Callable[[], float] = time.time,
    ) -> None:
        self.keys = keys
        self.gcs_system_id = gcs_system_id
        self.now_unix_s = now_unix_s
        self.timestamp = signing_timestamp(now_unix_s())
        self.checkers: dict[int, SigningState] = {}
        self.accepted: Counter[int] = Counter()
        self.rejected: dict[tuple[int, str], Counter[str]] = {}
        self.setups_sent: Counter[int] = Counter()
        self.confirmed: set[int] = set()
        self._last_setup_s: dict[int, float] = {}
        self._reported: dict[tuple[int, str], Counter[str]] = {}
        self._encoder = mavlink2.MAVLink(
            None, srcSystem=gcs_system_id, srcComponent=mavlink2.MAV_COMP_ID_MISSIONPLANNER
        )

    # ------------------------------------------------------------------ outgoing
    def _next_timestamp(self) -> int:
        self.timestamp = max(self.timestamp + 1, signing_timestamp(self.now_unix_s()))
        return self.timestamp

    def sign(self, system_id: int | None, link_index: int, frame: bytes) -> bytes:
        """``frame`` as it goes out to ``system_id`` (None: broadcast) on vehicle link
        number ``link_index``: signed with that vehicle's key (broadcast: the all-vehicles
        key), unchanged if there is none."""
        key = self.keys.default if system_id is None else self.keys.key_for(system_id)
        if key is None:
            return frame
        return sign_frame(frame, key, link_index & 0xFF, self._next_timestamp())

    def keyed_only(self) -> list[int]:
        """System ids with their own key (a broadcast signed with the all-vehicles key, or
        unsigned, does not reach them: send them the heartbeat one by one)."""
        return [s for s, k in self.keys.per_vehicle.items() if k != self.keys.default]

    # ------------------------------------------------------------------ incoming
    def admit(self, link: Any, link_index: int, rx: Any) -> bool:
        """True if the frame ``rx`` heard on ``link`` may go on (module docstring)."""
        sysid = int(rx.system_id)
        key = self.keys.key_for(sysid)
        if key is None:
            return True
        checker = self.checkers.get(sysid)
        if checker is None:
            checker = self.checkers[sysid] = SigningState(key)
        verdict = checker.check(rx.raw, self.now_unix_s())
        if verdict.value == "signed_ok":
            self.confirmed.add(sysid)
            self.accepted[sysid] += 1
        if verdict.accepted:
            return True
        self.rejected.setdefault((sysid, str(rx.link_id)), Counter())[verdict.value] += 1
        if self.keys.setup and sysid not in self.confirmed and is_autopilot_heartbeat(rx.message):
            self._maybe_setup(link, link_index, sysid, key)
        return False

    def _maybe_setup(self, link: Any, link_index: int, sysid: int, key: bytes) -> None:
        now = self.now_unix_s()
        if now - self._last_setup_s.get(sysid, -1e18) < SETUP_INTERVAL_S:
            return
        self._last_setup_s[sysid] = now
        msg = mavlink2.MAVLink_setup_signing_message(sysid, 0, list(key), self._next_timestamp())
        frame = bytes(msg.pack(self._encoder))
        link.send(self.sign(sysid, link_index, frame), sysid)
        self.setups_sent[sysid] += 1

    # ------------------------------------------------------------------ reports
    def summary(self) -> dict[str, Any]:
        """Counts for the daemon summary: refused frames per ``SYSID@LINK`` and reason,
        good signatures per system id, SETUP_SIGNING sent; key sources, never keys."""
        return {
            "sources": dict(self.keys.sources),
            "accepted": {str(k): v for k, v in sorted(self.accepted.items())},
            "rejected": {
                f"{s}@{link}": dict(c) for (s, link), c in sorted(self.rejected.items())
            },
            "setups_sent": {str(k): v for k, v in sorted(self.setups_sent.items())},
        }

    def take_report(self) -> list[dict[str, Any]]:
        """Refusals since the last call, one entry per ``(system id, link)`` that had any
        (the daemon journals them as ``signing_rejected`` at most every few seconds)."""
        out: list[dict[str, Any]] = []
        for (sysid, link), counts in sorted(self.rejected.items()):
            seen = self._reported.setdefault((sysid, link), Counter())
            new = counts - seen
            if new:
                out.append(
                    {"system_id": sysid, "link": link, "new": dict(new), "total": dict(counts)}
                )
                self._reported[(sysid, link)] = Counter(counts)
        return out
