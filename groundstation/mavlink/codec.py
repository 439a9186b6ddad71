"""MAVLink 2 codec: bytes in, messages out, and messages in, bytes out.

pymavlink is used only as a codec here. The ardupilotmega dialect module for MAVLink 2 is
imported directly: `pymavlink.mavutil` would pick MAVLink 1 unless an environment variable
were set before its import.

The decoder is robust: garbage bytes and frames with a bad CRC never raise; they are counted
(``bad_frames``, ``bad_bytes``) and the parser resynchronises on the next start marker.

Signed MAVLink 2 frames decode like any other (``get_msgbuf()`` keeps the 13 signature
bytes); the decoder does not check signatures: ``groundstation.mavlink.signing`` does, at
the edge that knows the keys (the daemon's signing gate, the simulator's vehicles).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, TypeAlias

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

MAVLinkMessage: TypeAlias = mavlink2.MAVLink_message

__all__ = [
    "MAVLinkMessage",
    "MavlinkDecoder",
    "MavlinkEncoder",
    "mavlink2",
]


@dataclass
class MavlinkDecoder:
    """Incremental, never-raising MAVLink 2 (and 1) frame decoder for one byte stream.

    Feed it whatever a transport received; it returns every complete, valid message.
    """

    bad_frames: int = 0
    bad_bytes: int = 0
    messages: int = 0
    _mav: Any = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._mav = mavlink2.MAVLink(None)
        self._mav.robust_parsing = True

    def feed(self, data: bytes) -> list[MAVLinkMessage]:
        """Parse ``data`` (any chunking) and return the valid messages it completed."""
        out: list[MAVLinkMessage] = []
        if not data:
            return out
        try:
            parsed = self._mav.parse_buffer(data) or []
        except Exception:  # pymavlink may raise on pathological input; never propagate
            self.bad_frames += 1
            self.bad_bytes += len(data)
            self._mav = mavlink2.MAVLink(None)
            self._mav.robust_parsing = True
            return out
        for msg in parsed:
            if isinstance(msg, mavlink2.MAVLink_bad_data) or msg.get_type() == "BAD_DATA":
                self.bad_frames += 1
                self.bad_bytes += len(getattr(msg, "data", b"") or b"")
                continue
            self.messages += 1
            out.append(msg)
        return out


class MavlinkEncoder:
    """Packs messages as MAVLink 2 frames from one (system id, component id).

    Keeps the per-source sequence number that MAVLink expects.
    """

    def __init__(self, system_id: int, component_id: int) -> None:
        if not (0 < system_id < 256 and 0 <= component_id < 256):
            raise ValueError(f"invalid MAVLink source {system_id}/{component_id}")
        self.system_id = system_id
        self.component_id = component_id
        self._mav = mavlink2.MAVLink(None, srcSystem=system_id, srcComponent=component_id)

    def encode(self, msg: MAVLinkMessage) -> bytes:
        """Return the wire bytes of ``msg`` sent from this source; the frame's sequence
        number is this source's next one (0..255, wrapping), as ``MAVLink.send`` counts
        (``pack`` alone does not: every frame was sequence 0)."""
        frame = bytes(msg.pack(self._mav))
        self._mav.seq = (self._mav.seq + 1) % 256
        return frame

    @property
    def mav(self) -> Any:
        """The underlying pymavlink ``MAVLink`` object (for its ``*_encode`` helpers)."""
        return self._mav
