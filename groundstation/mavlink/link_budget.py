"""What one vehicle link can carry, and how floe keeps within it (sans-IO, mission time).

docs/links.md, "Over a telemetry radio". Three pieces, fed by the daemon (no clock, no
socket here):

* :class:`RttEstimator`: the link's round-trip time from the transfer machines'
  request -> answer pairs, as TCP's retransmission timer (RFC 6298, section 2): on the
  first sample R, SRTT = R, RTTVAR = R / 2; on each later one
  RTTVAR = (1 - beta) RTTVAR + beta |SRTT - R| then SRTT = (1 - alpha) SRTT + alpha R with
  alpha = 1/8, beta = 1/4; RTO = SRTT + max(G, K RTTVAR) with K = 4 and G the clock
  granularity (10 ms). Karn's rule: a sample is only taken from a request sent once (a
  resent request's answer cannot be matched to one send), the machines see to that.
  The timeout a transfer uses is ``max(floor, RTO)``, at most ``ceiling``: the configured
  ``transfer_timeout_s`` stays the floor, so a loopback link keeps today's timers.
* :class:`LinkBudget`: the link's capacity in bit/s (configured, else from the serial
  rate, else a SiK radio's when one reports, else unlimited), the ground radio's latest
  RADIO_STATUS, and the *hold* rule: while the ground radio's ``txbuf`` (% free of its
  serial receive buffer) is below :data:`TXBUF_HOLD_PCT` (50, ArduPilot's
  ``handle_radio_status`` threshold for slowing its own streams), a new non-safety
  exchange waits, at most :data:`MAX_HOLD_S`, until a report at or above it arrives; a
  report older than :data:`RADIO_REPORT_STALE_S` holds nothing. Safety exchanges (mode
  changes, RTL, a home move for a return) are never held.
* :func:`stream_plan`: the telemetry floe asks for, within :data:`TELEMETRY_SHARE` (40 %)
  of a constrained link's downlink.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from groundstation.mavlink.codec import mavlink2

__all__ = [
    "MAX_HOLD_S",
    "RADIO_REPORT_STALE_S",
    "SIK_DOWNLINK_BPS",
    "TELEMETRY_SHARE",
    "TXBUF_HOLD_PCT",
    "LinkBudget",
    "RadioReading",
    "RttEstimator",
    "StreamPlan",
    "stream_plan",
]

M = mavlink2

ALPHA = 1.0 / 8.0
BETA = 1.0 / 4.0
K = 4.0
CLOCK_GRANULARITY_S = 0.010
TXBUF_HOLD_PCT = 50
"""Below this % free in the ground radio's serial buffer, non-safety exchanges wait."""
MAX_HOLD_S = 10.0
"""Longest wait for the radio's buffer to drain (mission s); then the exchange goes anyway,
so a radio stuck reporting a full buffer cannot stop floe commanding."""
RADIO_REPORT_STALE_S = 5.0
"""A RADIO_STATUS older than this (mission s) no longer holds anything."""
TELEMETRY_SHARE = 0.40
"""Share of a constrained downlink the requested telemetry may fill."""
SIK_DOWNLINK_BPS = 24_000.0
"""What a SiK radio at its defaults carries one way while the other way is busy: 64 kbit/s
in the air, half-duplex TDM with the two windows taking turns, less the preamble, packet
headers and turn-arounds (docs/sitl.md, "A telemetry radio": ~3 kB/s of MAVLink each
way)."""
MIN_RTT_SAMPLES = 3
"""Round trips measured before a constrained link's timeouts follow its RTO."""
MIN_RTO_S = 0.3
"""The shortest timeout on a constrained link. RFC 6298 (2.4) rounds the RTO up to 1 s
for the Internet's delayed acknowledgements; an autopilot answers a mission request
within one scheduler loop, and on a SiK radio at its defaults the measured RTO (SRTT +
4 RTTVAR) settles near 0.36 s (a TDM round is ~0.24 s), so the estimator, not this floor,
sets the timeout there. A timeout that comes early costs a duplicate request or item
(answered INVALID_SEQUENCE, or ignored), tens of bytes; one that comes late costs every
loss its lateness. ``benchmarks/sim_radio.py`` (6-item uploads at 5 % bursty loss, floe's
own machines in simulated time): p95 3.04 s with a 0.5 s floor, 2.82 s with 0.3 s."""
ACK_WAIT_S = 1.5
"""Mission seconds an upload on a constrained link waits for a lost final ACK before its
verifying download reads what the vehicle holds (:func:`ack_retries`)."""
PIPELINE_ITEMS = 8
"""Items a transfer keeps on their way on a constrained link: a download's outstanding item
requests (~300 B up), an upload's items sent ahead of the vehicle's requests (~400 B up,
``MissionUpload``'s ``window``)."""
MAVLINK2_OVERHEAD_BYTES = 12
"""Header and checksum of an unsigned MAVLink 2 frame (a signed one adds 13)."""


def ack_retries(timeout_s: float) -> int:
    """Silent timeouts of ``timeout_s`` an upload on a constrained link waits for its final
    ACK (:class:`~groundstation.mavlink.mission_upload.MissionUpload`'s ``ack_retries``):
    as few as cover :data:`ACK_WAIT_S` (ArduPlane re-requests a lost last item after 1 s;
    the wait must outlast that and its way back), at least 1."""
    return max(1, math.ceil(ACK_WAIT_S / timeout_s) - 1)


class RttEstimator:
    """Smoothed round-trip time and retransmission timeout (RFC 6298; module docstring)."""

    def __init__(self, floor_s: float, ceiling_s: float = 8.0) -> None:
        if not (0.0 < floor_s <= ceiling_s and math.isfinite(ceiling_s)):
            raise ValueError(f"need 0 < floor_s <= ceiling_s, got {floor_s}, {ceiling_s}")
        self.floor_s = floor_s
        self.ceiling_s = ceiling_s
        self.srtt_s: float | None = None
        self.rttvar_s: float | None = None
        self.samples = 0

    def sample(self, rtt_s: float) -> None:
        """One round trip (mission s); a negative or non-finite one is ignored."""
        if not (math.isfinite(rtt_s) and rtt_s >= 0.0):
            return
        if self.srtt_s is None or self.rttvar_s is None:
            self.srtt_s, self.rttvar_s = rtt_s, rtt_s / 2.0
        else:
            self.rttvar_s = (1.0 - BETA) * self.rttvar_s + BETA * abs(self.srtt_s - rtt_s)
            self.srtt_s = (1.0 - ALPHA) * self.srtt_s + ALPHA * rtt_s
        self.samples += 1

    @property
    def rto_s(self) -> float | None:
        """SRTT + max(G, K RTTVAR), None before the first sample."""
        if self.srtt_s is None or self.rttvar_s is None:
            return None
        return self.srtt_s + max(CLOCK_GRANULARITY_S, K * self.rttvar_s)

    def timeout_s(self, floor_s: float | None = None) -> float:
        """The timeout a transfer uses: max(floor, RTO), at most the ceiling."""
        floor = self.floor_s if floor_s is None else floor_s
        rto = self.rto_s
        return min(max(floor, floor if rto is None else rto), max(self.ceiling_s, floor))


@dataclass(frozen=True)
class RadioReading:
    """The ground radio's RADIO_STATUS as floe reads it."""

    t_s: float
    txbuf_pct: int
    rssi: int
    remrssi: int
    rxerrors: int


@dataclass
class LinkBudget:
    """One vehicle link's capacity, radio report, round-trip time and hold rule."""

    timeout_floor_s: float = 1.5
    configured_bps: float | None = None
    """From configuration (``--link-rate``) or the serial port's baud rate."""
    rtt: RttEstimator = field(init=False)
    radio: RadioReading | None = None
    held_s: float = 0.0
    """Mission seconds exchanges spent waiting for the radio's buffer."""
    holds: int = 0

    def __post_init__(self) -> None:
        self.rtt = RttEstimator(self.timeout_floor_s)

    @property
    def capacity_bps(self) -> float | None:
        """Downlink capacity: configured, else a SiK radio's once one reported, else None
        (unlimited)."""
        if self.configured_bps is not None:
            return self.configured_bps
        if self.radio is not None:
            return SIK_DOWNLINK_BPS
        return None

    def on_radio_status(self, t_s: float, msg: object) -> RadioReading | None:
        """A RADIO_STATUS (or RADIO) from the link's ground radio: remembered; unreadable
        fields leave the last report as it was."""
        values = []
        for name in ("txbuf", "rssi", "remrssi", "rxerrors"):
            value = getattr(msg, name, None)
            if isinstance(value, bool) or not isinstance(value, int):
                return None
            values.append(value)
        if not 0 <= values[0] <= 100:
            return None
        self.radio = RadioReading(t_s, values[0], values[1], values[2], values[3])
        return self.radio

    def congested(self, t_s: float) -> bool:
        """True while a fresh radio report says the ground radio's buffer is below
        :data:`TXBUF_HOLD_PCT` % free."""
        radio = self.radio
        return (radio is not None and t_s - radio.t_s <= RADIO_REPORT_STALE_S
                and radio.txbuf_pct < TXBUF_HOLD_PCT)

    def transfer_timeout_s(self, configured_s: float | None = None) -> float:
        """The per-attempt timeout of a transfer now (mission s).

        Unlimited link, or fewer than :data:`MIN_RTT_SAMPLES` round trips measured: the
        configured timeout, or the RTO when that is longer (a slow link sends no duplicate
        request). A constrained link with a measured RTT: the RTO, at least
        :data:`MIN_RTO_S` (RFC 6298's floor), so a lost request is re-sent one RTO later.
        """
        configured = self.timeout_floor_s if configured_s is None else configured_s
        rto = self.rtt.rto_s
        if self.capacity_bps is None or rto is None or self.rtt.samples < MIN_RTT_SAMPLES:
            return self.rtt.timeout_s(configured)
        return min(max(MIN_RTO_S, rto), self.rtt.ceiling_s)

    @property
    def pipeline(self) -> int:
        """Items a transfer keeps on their way (download requests, upload items ahead of
        the requests): 1 on an unlimited link (as floe always did), :data:`PIPELINE_ITEMS`
        on a constrained one."""
        return 1 if self.capacity_bps is None else PIPELINE_ITEMS

    def streams(self, position_hz: float, signed: bool = False) -> StreamPlan:
        """The telemetry to ask for on this link (:func:`stream_plan`)."""
        return stream_plan(position_hz, self.capacity_bps, signed=signed)


# -------------------------------------------------------------------------- streams

_PAYLOAD_BYTES: dict[int, int] = {
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 28,
    M.MAVLINK_MSG_ID_SYS_STATUS: 31,
    M.MAVLINK_MSG_ID_MISSION_CURRENT: 18,
    M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 2,
    M.MAVLINK_MSG_ID_VFR_HUD: 20,
    M.MAVLINK_MSG_ID_ATTITUDE: 28,
    M.MAVLINK_MSG_ID_BATTERY_STATUS: 54,
    M.MAVLINK_MSG_ID_WIND: 12,
    M.MAVLINK_MSG_ID_GPS_RAW_INT: 52,
    M.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT: 26,
    M.MAVLINK_MSG_ID_SYSTEM_TIME: 12,
    M.MAVLINK_MSG_ID_HEARTBEAT: 9,
}
"""Largest MAVLink 2 payloads (extensions included) of what a vehicle streams."""

_NEEDED_HZ: tuple[tuple[int, float], ...] = (
    (M.MAVLINK_MSG_ID_SYS_STATUS, 1.0),  # battery, sensors health
    (M.MAVLINK_MSG_ID_MISSION_CURRENT, 1.0),  # the item flown (set current, loiter end)
    (M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 1.0),  # landed state
    (M.MAVLINK_MSG_ID_VFR_HUD, 1.0),  # airspeed, ground speed (cruise, wind)
    (M.MAVLINK_MSG_ID_ATTITUDE, 0.5),  # time_boot_ms between positions (reboots)
    (M.MAVLINK_MSG_ID_BATTERY_STATUS, 0.5),
    (M.MAVLINK_MSG_ID_WIND, 0.5),
    (M.MAVLINK_MSG_ID_GPS_RAW_INT, 0.5),  # the panel's GPS fix, satellites, HDOP
)
"""What floe reads besides the position, at the rates it needs on a constrained link."""
_NOT_NEEDED: tuple[int, ...] = (
    M.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT,
    M.MAVLINK_MSG_ID_SYSTEM_TIME,
)
"""Streamed by the groups floe asks for, read by nothing in floe: off on a constrained link."""
_GROUPS: tuple[int, ...] = (
    M.MAV_DATA_STREAM_EXTENDED_STATUS,
    M.MAV_DATA_STREAM_EXTRA1,
    M.MAV_DATA_STREAM_EXTRA2,
    M.MAV_DATA_STREAM_EXTRA3,
)
MIN_POSITION_HZ = 1.0


@dataclass(frozen=True)
class StreamPlan:
    """REQUEST_DATA_STREAM rates per group (Hz, whole) and SET_MESSAGE_INTERVAL per message
    (Hz; 0 disables), sent in that order (the per-message intervals win); ``bytes_s``: the
    downlink the plan asks for."""

    groups: tuple[tuple[int, int], ...]
    intervals: tuple[tuple[int, float], ...]
    bytes_s: float


def _frame_bytes(msg_id: int, signed: bool) -> int:
    return _PAYLOAD_BYTES[msg_id] + MAVLINK2_OVERHEAD_BYTES + (13 if signed else 0)


def _groups(position_hz: float) -> tuple[tuple[int, int], ...]:
    return (*((g, 1) for g in _GROUPS),
            (M.MAV_DATA_STREAM_POSITION, max(1, round(position_hz))))


def stream_plan(position_hz: float, capacity_bps: float | None, *,
                share: float = TELEMETRY_SHARE, signed: bool = False) -> StreamPlan:
    """The telemetry to ask for.

    Unlimited link (``capacity_bps`` None): every group at 1 Hz and the position at
    ``position_hz``, as floe always did. Constrained link: the same groups (an older
    autopilot only knows those), then per message what floe reads at the rate it needs
    (``_NEEDED_HZ``), the position at ``position_hz``, what it does not read off. If that
    exceeds ``share`` x capacity, every rate but the position's is scaled down by one
    factor, then the position's, down to 1 Hz.
    """
    position_hz = max(MIN_POSITION_HZ, position_hz)
    pos = M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT
    if capacity_bps is None:
        groups = _groups(position_hz)
        per_s = sum(_frame_bytes(m, signed) for m in _PAYLOAD_BYTES if m not in (
            pos, M.MAVLINK_MSG_ID_HEARTBEAT)) + position_hz * _frame_bytes(pos, signed)
        return StreamPlan(groups, ((pos, position_hz),), float(per_s))
    budget_bytes_s = share * capacity_bps / 8.0
    fixed = _frame_bytes(M.MAVLINK_MSG_ID_HEARTBEAT, signed) * 1.0
    rest = sum(hz * _frame_bytes(m, signed) for m, hz in _NEEDED_HZ)
    pos_bytes = _frame_bytes(pos, signed)
    scale = 1.0
    room = budget_bytes_s - fixed - position_hz * pos_bytes
    if room < rest:
        scale = max(0.1, room / rest) if room > 0 else 0.1
        room_for_pos = budget_bytes_s - fixed - scale * rest
        position_hz = max(MIN_POSITION_HZ, min(position_hz, room_for_pos / pos_bytes))
    intervals = ((pos, position_hz), *((m, hz * scale) for m, hz in _NEEDED_HZ),
                 *((m, 0.0) for m in _NOT_NEEDED))
    groups = _groups(position_hz)
    bytes_s = fixed + scale * rest + position_hz * pos_bytes
    return StreamPlan(groups, intervals, bytes_s)
