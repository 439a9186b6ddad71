"""A telemetry radio's own reports: RADIO_STATUS (and ArduPilot's older RADIO, same fields).

A SiK radio injects these into the stream, unsigned, with its own ids (system 51, component
68: '3', 'D') or, when configured so, the vehicle's. They describe the radio link (signal
and noise levels at both ends, free space in the radio's transmit buffer, receive errors and
errors corrected), never the vehicle: the router keeps the latest one per vehicle link
(``Link.radio``, in the link's status) for the link budget, and hands none of them to the
daemon, so they keep no vehicle alive and bind no system id.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from groundstation.mavlink.telemetry import RADIO_MESSAGES

__all__ = ["RADIO_MESSAGES", "RadioReport", "is_radio_message", "radio_report"]



@dataclass(frozen=True, slots=True)
class RadioReport:
    """One RADIO_STATUS as received (``t_unix_s``): levels in the radio's units (SiK:
    0-255, roughly 1.9 x dBm + 127), ``txbuf`` in percent free, error counts."""

    t_unix_s: float
    system_id: int
    component_id: int
    rssi: int
    remrssi: int
    txbuf: int
    noise: int
    remnoise: int
    rxerrors: int
    fixed: int

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def is_radio_message(msg: Any) -> bool:
    """Whether ``msg`` is a radio's report (RADIO_STATUS or RADIO)."""
    try:
        return msg.get_type() in RADIO_MESSAGES
    except AttributeError:
        return False


def radio_report(msg: Any, t_unix_s: float) -> RadioReport | None:
    """The report of a RADIO_STATUS / RADIO message; None if a field is missing or bad."""
    try:
        return RadioReport(
            t_unix_s, int(msg.get_srcSystem()), int(msg.get_srcComponent()),
            int(msg.rssi), int(msg.remrssi), int(msg.txbuf), int(msg.noise),
            int(msg.remnoise), int(msg.rxerrors), int(msg.fixed),
        )  # fmt: skip
    except (AttributeError, TypeError, ValueError):
        return None
