"""MAVLink 2 message signing, sans-IO: keys, signing frames, checking frames.

The rules (MAVLink 2 signing specification; ArduPilot's GCS_Signing.cpp and pymavlink's
``MAVLink.signing`` behave the same way):

* A signed frame has bit 0x01 of ``incompat_flags`` set and 13 bytes after its CRC:
  ``link_id`` (1 byte), ``timestamp`` (6 bytes, little endian) and ``signature`` (6 bytes).
  The CRC covers the header with that flag set, so signing an unsigned frame recomputes it.
* ``signature = SHA-256(secret_key || header || payload || crc || link_id || timestamp)[:6]``
  where ``header`` is the 10 bytes from the 0xFD marker, the key is 32 bytes.
* ``timestamp`` counts 10 microsecond units since 2015-01-01 00:00:00 UTC (unix 1420070400).
  A signer never repeats or lowers it: each frame gets ``max(last + 1, now)``.
* A receiver keeps the last timestamp per stream ``(sysid, compid, link_id)``. A frame of a
  known stream must have a strictly larger timestamp (else: replay); the first frame of a new
  stream is accepted only if its timestamp is no more than one minute behind the receiver's
  own signing timestamp (which follows its clock and every accepted timestamp); at most
  ``max_streams`` streams are tracked (MAVLink's 16), a frame of one more is rejected.
* An unsigned frame is rejected unless ``accept_unsigned`` lets its message id through.
  ArduPilot lets RADIO_STATUS and RADIO through unsigned (a SiK radio injects them and
  cannot sign; they carry no command); :data:`UNSIGNED_ALLOWED` is that set.
* A SETUP_SIGNING with an all-zero key and a zero timestamp disables signing.

Keys: MAVProxy's ``signing setup PASSPHRASE`` uses ``SHA-256(passphrase UTF-8)``
(:func:`key_from_passphrase`). floe's key files hold either exactly 32 raw bytes or 64 hex
digits (surrounding whitespace ignored) (:func:`parse_key_file_bytes`).

Nothing here reads a clock or a file: the caller passes unix seconds and bytes.
"""

from __future__ import annotations

import enum
import hashlib
import hmac
import struct
from collections.abc import Callable
from dataclasses import dataclass, field

from groundstation.mavlink.codec import mavlink2

__all__ = [
    "KEY_LEN",
    "SIGNING_EPOCH_UNIX_S",
    "UNSIGNED_ALLOWED",
    "SigningKeyError",
    "SigningState",
    "Verdict",
    "frame_is_signed",
    "key_from_passphrase",
    "parse_key_file_bytes",
    "sign_frame",
    "signature_fields",
    "signing_timestamp",
]

KEY_LEN = 32
SIGNING_EPOCH_UNIX_S = 1420070400
"""2015-01-01 00:00:00 UTC: where MAVLink signing timestamps count from."""
TIMESTAMP_UNITS_PER_S = 100_000
"""Signing timestamps count 10 us units."""
NEW_STREAM_WINDOW = 60 * TIMESTAMP_UNITS_PER_S
"""A new stream's first timestamp may be at most one minute behind ours."""
MAX_STREAMS = 16
SIGNATURE_LEN = 13
HEADER_LEN = 10
IFLAG_SIGNED = 0x01
STX_V2 = 0xFD
UNSIGNED_ALLOWED = frozenset({mavlink2.MAVLINK_MSG_ID_RADIO_STATUS, mavlink2.MAVLINK_MSG_ID_RADIO})
"""Message ids accepted unsigned from a signed peer (ArduPilot: RADIO_STATUS, RADIO)."""


class SigningKeyError(ValueError):
    """A key file or passphrase that cannot give a 32-byte key; one-line message."""


class Verdict(enum.Enum):
    """What :meth:`SigningState.check` decided about one frame."""

    SIGNED_OK = "signed_ok"
    UNSIGNED_ALLOWED = "unsigned_allowed"
    UNSIGNED = "unsigned"
    BAD_SIGNATURE = "bad_signature"
    REPLAY = "replay"
    OLD_TIMESTAMP = "old_timestamp"
    TOO_MANY_STREAMS = "too_many_streams"
    MALFORMED = "malformed"

    @property
    def accepted(self) -> bool:
        """True for the verdicts that let the frame through."""
        return self in (Verdict.SIGNED_OK, Verdict.UNSIGNED_ALLOWED)


def key_from_passphrase(passphrase: str) -> bytes:
    """MAVProxy's ``signing setup PASSPHRASE``: ``SHA-256(passphrase.encode('utf-8'))``."""
    if not passphrase:
        raise SigningKeyError("the signing passphrase is empty")
    return hashlib.sha256(passphrase.encode("utf-8")).digest()


def parse_key_file_bytes(data: bytes) -> bytes:
    """A key file's content -> the 32-byte key: exactly 32 raw bytes, or 64 hex digits
    (whitespace around them ignored). The message never quotes the content."""
    if len(data) == KEY_LEN:
        return bytes(data)
    text = data.strip()
    if len(text) == 2 * KEY_LEN:
        try:
            return bytes.fromhex(text.decode("ascii"))
        except (UnicodeDecodeError, ValueError):
            pass
    raise SigningKeyError(
        f"a signing key file must hold 32 raw bytes or 64 hex digits (got {len(data)} bytes)"
    )


def parse_passphrase_file_bytes(data: bytes) -> bytes:
    """A passphrase file's content -> the key: its first line (UTF-8, end of line removed),
    hashed as MAVProxy does."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise SigningKeyError("the signing passphrase file is not UTF-8 text") from None
    lines = text.splitlines()
    return key_from_passphrase(lines[0] if lines else "")


def signing_timestamp(unix_s: float) -> int:
    """Unix seconds -> MAVLink signing timestamp (10 us units since 2015-01-01 UTC)."""
    return max(0, int((unix_s - SIGNING_EPOCH_UNIX_S) * TIMESTAMP_UNITS_PER_S))


def frame_is_signed(frame: bytes) -> bool:
    """True if ``frame`` is a MAVLink 2 frame with the signed flag set."""
    return len(frame) > HEADER_LEN and frame[0] == STX_V2 and bool(frame[2] & IFLAG_SIGNED)


def signature_fields(frame: bytes) -> tuple[int, int] | None:
    """``(link_id, timestamp)`` of a signed frame, None if it is not one."""
    if not frame_is_signed(frame) or len(frame) != HEADER_LEN + frame[1] + 2 + SIGNATURE_LEN:
        return None
    block = frame[-SIGNATURE_LEN:]
    return block[0], int.from_bytes(block[1:7], "little")


def _signature(key: bytes, body: bytes, link_id: int, timestamp: int) -> bytes:
    """``body`` is header + payload + CRC; returns the 6 signature bytes."""
    digest = hashlib.sha256()
    digest.update(key)
    digest.update(body)
    digest.update(bytes([link_id]))
    digest.update(timestamp.to_bytes(6, "little"))
    return digest.digest()[:6]


def sign_frame(frame: bytes, key: bytes, link_id: int, timestamp: int) -> bytes:
    """Return ``frame`` (a valid MAVLink 2 frame, signed or not) signed with ``key``.

    Sets the signed flag, recomputes the CRC (it covers the flag) with the message's
    CRC_EXTRA, and appends link id, timestamp and signature. A MAVLink 1 frame or a frame
    of an unknown message id is returned unchanged (it cannot be signed).
    """
    if len(key) != KEY_LEN or not 0 <= link_id < 256 or not 0 <= timestamp < 1 << 48:
        raise ValueError("bad signing parameters")
    if len(frame) < HEADER_LEN + 2 or frame[0] != STX_V2:
        return bytes(frame)
    length = frame[1]
    msg_id = frame[7] | frame[8] << 8 | frame[9] << 16
    msg_type = mavlink2.mavlink_map.get(msg_id)
    if msg_type is None or len(frame) < HEADER_LEN + length + 2:
        return bytes(frame)
    header = bytearray(frame[:HEADER_LEN])
    header[2] |= IFLAG_SIGNED
    payload = bytes(frame[HEADER_LEN : HEADER_LEN + length])
    crc = mavlink2.x25crc(bytes(header[1:]) + payload)
    crc.accumulate(bytes([msg_type.crc_extra]))
    body = bytes(header) + payload + struct.pack("<H", crc.crc)
    return body + bytes([link_id]) + timestamp.to_bytes(6, "little") + _signature(
        key, body, link_id, timestamp
    )


def _message_id(frame: bytes) -> int:
    if frame[0] == STX_V2:
        return frame[7] | frame[8] << 8 | frame[9] << 16
    return frame[5] if len(frame) > 5 else -1


@dataclass
class SigningState:
    """One signing key as one MAVLink endpoint uses it: signs what it sends, checks what it
    receives (see the module docstring for the rules).

    ``timestamp`` is this endpoint's signing timestamp: it never goes down; it follows
    ``now`` (given by the caller), each frame signed (+1) and each accepted timestamp.
    ``streams`` is the last accepted timestamp per ``(sysid, compid, link_id)``.
    """

    key: bytes
    link_id: int = 0
    timestamp: int = 0
    accept_unsigned: Callable[[int], bool] = field(
        default=lambda msg_id: msg_id in UNSIGNED_ALLOWED
    )
    max_streams: int = MAX_STREAMS
    streams: dict[tuple[int, int, int], int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if len(self.key) != KEY_LEN:
            raise SigningKeyError(f"a signing key has {KEY_LEN} bytes, got {len(self.key)}")

    def advance(self, unix_s: float) -> None:
        """Let the signing timestamp follow the clock (never backwards)."""
        self.timestamp = max(self.timestamp, signing_timestamp(unix_s))

    def sign(self, frame: bytes, unix_s: float | None = None, link_id: int | None = None) -> bytes:
        """Sign ``frame`` with the next timestamp (``max(last + 1, now)``)."""
        if unix_s is not None:
            self.advance(unix_s)
        self.timestamp += 1
        return sign_frame(frame, self.key, self.link_id if link_id is None else link_id,
                          self.timestamp)

    def check(self, frame: bytes, unix_s: float | None = None) -> Verdict:
        """Decide whether a received, CRC-valid ``frame`` is let through. Never raises."""
        if unix_s is not None:
            self.advance(unix_s)
        if len(frame) < 6:
            return Verdict.MALFORMED
        if not frame_is_signed(frame):
            return Verdict.UNSIGNED_ALLOWED if self.accept_unsigned(_message_id(frame)) else (
                Verdict.UNSIGNED
            )
        fields = signature_fields(frame)
        if fields is None:
            return Verdict.MALFORMED
        link_id, stamp = fields
        body = bytes(frame[:-SIGNATURE_LEN])
        expected = _signature(self.key, body, link_id, stamp)
        if not hmac.compare_digest(expected, bytes(frame[-6:])):
            return Verdict.BAD_SIGNATURE
        stream = (frame[5], frame[6], link_id)
        last = self.streams.get(stream)
        if last is None:
            if len(self.streams) >= self.max_streams:
                return Verdict.TOO_MANY_STREAMS
            if stamp + NEW_STREAM_WINDOW < self.timestamp:
                return Verdict.OLD_TIMESTAMP
        elif stamp <= last:
            return Verdict.REPLAY
        self.streams[stream] = stamp
        self.timestamp = max(self.timestamp, stamp)
        return Verdict.SIGNED_OK
