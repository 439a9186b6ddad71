"""STATUSTEXT construction, chunked as ArduPilot does for texts longer than 50 bytes."""

from __future__ import annotations

from itertools import count
from typing import Any

from groundstation.mavlink.codec import mavlink2

__all__ = ["StatusTextFactory"]

_CHUNK = 50


class StatusTextFactory:
    """Builds STATUSTEXT messages; long texts get a shared non-zero ``id`` and ``chunk_seq``."""

    def __init__(self) -> None:
        self._ids = count(1)

    def make(self, text: str, severity: int = mavlink2.MAV_SEVERITY_INFO) -> list[Any]:
        """One message for a short text, several chunks for a long one."""
        data = text.encode("ascii", errors="replace")
        if len(data) <= _CHUNK:
            return [mavlink2.MAVLink_statustext_message(severity, data, 0, 0)]
        text_id = next(self._ids) % 65535 + 1
        chunks = [data[i : i + _CHUNK] for i in range(0, len(data), _CHUNK)]
        return [
            mavlink2.MAVLink_statustext_message(severity, chunk, text_id, seq)
            for seq, chunk in enumerate(chunks)
        ]
