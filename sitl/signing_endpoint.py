"""MAVLink 2 signing on a simulated vehicle, as ArduPlane does it (GCS_Signing.cpp).

* The vehicle starts with a key (``gcs sitl --signing-key FILE`` / passphrase) or none.
* SETUP_SIGNING addressed to it (target system its own or 0) installs the key and its
  ``initial_timestamp`` at once on every link; an all-zero key with a zero timestamp
  disables signing. It is ignored while the vehicle is armed (a key change in flight is a
  mistake; recent ArduPilot refuses it too, older releases took it). The key is kept in
  memory for the life of the ``gcs sitl`` process (it survives a simulated reboot, as
  ArduPilot keeps it in storage) and is never printed or logged.
* With a key, every received frame goes through :meth:`SigningState.check`: unsigned
  frames (except RADIO_STATUS and RADIO), bad signatures, replayed or stale timestamps are dropped
  and counted (:attr:`VehicleSigning.rejected`); everything the vehicle sends is signed
  (link id 0; one timestamp counter per vehicle, so it never goes backwards).
* Once a key is installed, a SETUP_SIGNING must itself pass the check (signed with the
  current key) to change it, as on ArduPilot.

Time is an argument (unix seconds, from the server's wall clock): signing timestamps are
real time even when the simulation runs faster.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from groundstation.mavlink.signing import KEY_LEN, SigningState, signing_timestamp

__all__ = ["VehicleSigning"]


@dataclass
class VehicleSigning:
    """Signing state of one simulated vehicle (``system_id``)."""

    system_id: int
    state: SigningState | None = None
    rejected: Counter[str] = field(default_factory=Counter)
    setups: int = 0

    @classmethod
    def with_key(cls, system_id: int, key: bytes | None, unix_s: float) -> VehicleSigning:
        """A vehicle that starts with ``key`` (None: unsigned until SETUP_SIGNING)."""
        out = cls(system_id)
        if key is not None:
            out.state = SigningState(key, timestamp=signing_timestamp(unix_s))
        return out

    @property
    def active(self) -> bool:
        """True while the vehicle has a key (signs and checks)."""
        return self.state is not None

    def admit(self, raw: bytes, unix_s: float) -> bool:
        """True if a received frame may reach the vehicle; a refusal is counted."""
        if self.state is None:
            return True
        verdict = self.state.check(raw, unix_s)
        if not verdict.accepted:
            self.rejected[verdict.value] += 1
        return verdict.accepted

    def setup(self, msg: Any, armed: bool) -> bool:
        """Handle an admitted SETUP_SIGNING; True if it was for this vehicle (consumed)."""
        target = int(getattr(msg, "target_system", 0) or 0)
        if target not in (0, self.system_id):
            return False
        if armed:
            return True
        key = bytes(msg.secret_key)
        if len(key) != KEY_LEN:
            key = key.ljust(KEY_LEN, b"\0")[:KEY_LEN]
        self.setups += 1
        if not any(key) and int(msg.initial_timestamp) == 0:
            self.state = None
            return True
        self.state = SigningState(key, timestamp=int(msg.initial_timestamp))
        return True

    def sign(self, frame: bytes, unix_s: float) -> bytes:
        """``frame`` signed with the vehicle's key (unchanged without one)."""
        if self.state is None:
            return frame
        return self.state.sign(frame, unix_s)
