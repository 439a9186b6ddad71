"""A pair of SiK telemetry radios between one vehicle and the ground (sans-IO, simulated time).

Bytes go in at one end's serial port (:meth:`SikRadioPair.write`), cross the air in TDM time
slots, and come out of the other end's serial port (:meth:`SikRadioPair.read`) when
:meth:`SikRadioPair.advance` has run the simulated clock that far. Nothing here reads a
clock or a socket. The figures are SiK's (ArduPilot/SiK firmware, ``Firmware/radio``), for
the Si1000 boards (3DR/Holybro/mRo "SiK telemetry radio V2/V3"):

* **Serial ports** (``serial.c``): 8N1, so a byte takes 10 / baud s (57 600 baud: 5 760 B/s,
  173.6 us a byte), at both ends. The sender's UART is a FIFO feeding its radio at that rate
  (the autopilot or ground station waits; at most 64 KiB may queue, more is dropped and
  counted as ``line_dropped``). Each radio buffers what it receives from its serial port in
  ``rx_buf`` (``RX_BUFF_MAX`` 1 850 bytes): a byte arriving when it is full is dropped and
  counted (SiK's ``serial_rx_overflow``). What the radio receives over the air goes out of
  its serial port through ``tx_buf`` (``TX_BUFF_MAX`` 645 bytes): bytes that do not fit are
  discarded (``serial_tx_overflow``).
* **TDM** (``tdm.c``, ``tdm_init``; :class:`domain.radio_spec.SikTiming`), in SiK's 16 us
  ticks: ``ticks_per_byte`` =
  (8 + 8e6 / air_bps) // 16 + 1 (9 at 64 kbit/s); ``packet_latency`` (preamble, sync word,
  header and CRC, turnaround) = 13 bytes + 13 ticks, plus 3 bytes for the 16-nibble
  preamble (157 ticks, 2.5 ms); a packet of L data bytes plus the 2-byte TDM trailer takes
  ``packet_latency + (L + 2) ticks_per_byte`` (SiK's ``flight_time_estimate``); packets
  carry at most ``MAX_PACKET_LENGTH`` 252 - 2 = 250 data bytes; the transmit window is 3
  full packets (7 140 ticks, 114 ms), capped by ``MAX_WINDOW`` (131 ms); the silence between
  windows is 2 ``packet_latency``. The vehicle's radio transmits in one window, the ground's
  in the next: a round of 237 ms at 64 kbit/s. After each packet a radio waits one
  ``packet_latency`` (``transmit_wait``).
* **What a radio sends in its window** (``tdm_serial_loop``, ``packet.c`` with MAVLINK 1,
  SiK's default MAVLink framing): as many *whole* MAVLink frames from ``rx_buf`` as fit in
  the time left (a frame longer than a packet goes raw, in pieces). With nothing to send (no
  whole frame, or the next one does not fit in the time left) it sends an empty packet and
  yields the rest of its window: the other radio may use it (SiK's "bonus" ticks) until it
  too has nothing to send. Every 0.5 s an idle radio sends its statistics instead (4 bytes:
  its RSSI and noise, which the other reports as ``remrssi``/``remnoise``).
* **ECC** (``ECC`` 1, SiK's default is 0): Golay (24,12) doubles the cost of a byte and adds
  4 bytes to every packet; packets carry at most 252 / 2 - 8 = 118 data bytes.
* **Loss**: each air packet (empty and statistics packets included) is lost or not by a
  two-state Gilbert-Elliott chain shared by both directions, stepped once per packet: in
  the good state nothing is lost, in the bad state everything (the Gilbert case, h = 1,
  k = 0); P(good -> bad) = p = loss / (burst (1 - loss)), P(bad -> good) = r = 1 / burst,
  so the mean loss is p / (p + r) = ``loss`` and runs of lost packets are geometric with
  mean ``burst``. A lost packet loses every frame in it and counts as a receive error
  (``rxerrors``) at the other end; a lost empty packet gives no bonus. SiK has no
  retransmission (OPPRESEND 0).
* **RADIO_STATUS** (``mavlink.c``, ``MAVLink_report``): when a radio puts a HEARTBEAT from
  its own serial port on the air, it writes a RADIO_STATUS (id 109) into its own serial
  output, from system 51 and component 68 ('3', 'D'), unsigned, in the MAVLink version of
  that heartbeat (MAVLink 2 with the whole 9-byte payload), if its ``tx_buf`` has room: the
  ground station sees one per heartbeat it sends (1 Hz), the autopilot one per its own
  heartbeat. Fields: ``rssi``/``noise`` (this radio's averages, SiK's units: about
  1.9 per dB, dBm = rssi / 1.9 - 127), ``remrssi``/``remnoise`` (the other radio's, from its
  last statistics packet), ``txbuf`` = % of this radio's ``rx_buf`` free (its
  ``serial_read_space``; ArduPilot slows its streams below 50 %), ``rxerrors`` (lost
  packets, saturating at 65 535), ``fixed`` 0 (no Golay corrections are modelled).

Not modelled: frequency hopping and the TDM synchronisation (the radios are always in
step), duty cycle, listen-before-talk, AT commands, RTS/CTS flow control, AES; signal
strength is drawn around a fixed mean (rssi about 120, noise about 25), not from a
distance.

Latency from serial in to serial out: the frame's serial time in, the wait for a window of
the sending end (up to one round), the air time, and its serial time out: 20-300 ms at
the defaults (docs/sitl.md, "A telemetry radio").
"""

from __future__ import annotations

import math
import random
from collections import deque
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

from domain.radio_spec import (
    PACKET_OVERHEAD,
    TICK_S,
    TRAILER_BYTES,
    RadioSpec,
    SikTiming,
)
from groundstation.mavlink.codec import mavlink2

__all__ = [
    "RADIO_COMPONENT_ID",
    "RADIO_SYSTEM_ID",
    "GilbertElliott",
    "RadioEnd",
    "RadioStats",
    "SikRadioPair",
    "SikTiming",
]

RADIO_SYSTEM_ID = 51  # '3'
RADIO_COMPONENT_ID = 68  # 'D'
STATS_BYTES = 4
STATS_PERIOD_S = 0.5
TX_BUFFER_BYTES = 645
LINE_LIMIT_BYTES = 65536
LATENCY_BIN_S = 0.001
LATENCY_BINS = 5000
_RADIO_STATUS_CRC_EXTRA = 185
_RSSI_MEAN, _NOISE_MEAN = 120.0, 25.0


class RadioEnd(IntEnum):
    """The two radios: the vehicle's (its serial port is the autopilot's telemetry port)
    and the ground station's."""

    VEHICLE = 0
    GROUND = 1


class GilbertElliott:
    """Two-state packet-loss chain: nothing lost in the good state, everything in the bad
    one; ``p`` = loss / (burst (1 - loss)) good -> bad, ``r`` = 1 / burst bad -> good per
    packet (mean loss ``loss``, mean run of losses ``burst``)."""

    def __init__(self, loss: float, burst: float, rng: random.Random) -> None:
        self.r = 1.0 / burst
        self.p = loss / (burst * (1.0 - loss)) if loss > 0 else 0.0
        self.rng = rng
        self.bad = self.p > 0 and rng.random() < loss

    def lost(self) -> bool:
        """Whether this packet is lost; then the chain steps."""
        lost = self.bad
        if self.bad:
            self.bad = self.rng.random() >= self.r
        elif self.p > 0:
            self.bad = self.rng.random() < self.p
        return lost


@dataclass
class RadioStats:
    """One direction's counters (``down``: vehicle -> ground, ``up``: ground -> vehicle)."""

    bytes_offered: int = 0
    """Written to the sending radio's serial port."""
    bytes_carried: int = 0
    """Received over the air and put out (or queued to go out at the serial rate) of the
    receiving radio's serial port (its own RADIO_STATUS not counted)."""
    line_dropped: int = 0
    """Dropped before the radio: the sender's serial queue was over 64 KiB."""
    rx_overflow: int = 0
    """Dropped by the sending radio: its serial receive buffer was full."""
    tx_overflow: int = 0
    """Discarded by the receiving radio: its serial transmit buffer was full."""
    bytes_lost: int = 0
    """Data bytes in lost air packets."""
    packets: int = 0
    """Air packets sent (data, empty and statistics)."""
    data_packets: int = 0
    packets_lost: int = 0
    air_ticks: int = 0
    """Air time of every packet sent, 16 us ticks."""
    data_air_ticks: int = 0
    """Air time of the packets that carried data."""
    latency_bins: list[int] = field(default_factory=lambda: [0] * (LATENCY_BINS + 1))
    """Frames delivered by latency (serial in -> serial out), 1 ms bins; the last: more."""

    def latency_s(self, q: float) -> float | None:
        """The q-quantile (0..1) of the frames' latency (bin upper edge), None if none."""
        total = sum(self.latency_bins)
        if total == 0:
            return None
        rank = q * total
        seen = 0
        for i, n in enumerate(self.latency_bins):
            seen += n
            if seen >= rank and n:
                return (i + 1) * LATENCY_BIN_S
        return (LATENCY_BINS + 1) * LATENCY_BIN_S  # pragma: no cover - rank <= total

    @property
    def frames(self) -> int:
        """Frames delivered whole."""
        return sum(self.latency_bins)


@dataclass
class _End:
    line: deque[tuple[float, float, bytes]] = field(default_factory=deque)
    line_free_s: float = 0.0
    rx: deque[tuple[float, bytes, bool]] = field(default_factory=deque)
    rx_used: int = 0
    txq: deque[tuple[float, bytes]] = field(default_factory=deque)
    tx_free_s: float = 0.0
    yielded: bool = False
    bonus: bool = False
    stats_due_s: float = 0.0
    report: int = 0
    seq: int = 0
    rssi: float = _RSSI_MEAN
    noise: float = _NOISE_MEAN
    rem_rssi: float = 0.0
    rem_noise: float = 0.0
    rx_errors: int = 0
    reports: int = 0


class SikRadioPair:
    """The vehicle's radio and the ground's, in simulated time (see the module docstring).

    ``write(end, data, t_s)``: bytes from that end's serial side at ``t_s`` (whole MAVLink
    frames, or any bytes); ``advance(t_s)`` runs the radios to ``t_s`` (never backwards);
    ``read(end)``: what that end's serial port has put out by then, one chunk per frame.
    """

    def __init__(self, spec: RadioSpec, seed: int, t_s: float = 0.0) -> None:
        self.spec = spec
        self.timing = SikTiming.of(spec)
        self.byte_s = 10.0 / spec.baud
        self.rng = random.Random(seed if spec.seed is None else spec.seed)
        self.chain = GilbertElliott(spec.loss, spec.burst, self.rng)
        self.t0_s = t_s
        self.t_s = t_s
        self.ends = (_End(line_free_s=t_s, tx_free_s=t_s), _End(line_free_s=t_s, tx_free_s=t_s))
        self.stats = {RadioEnd.VEHICLE: RadioStats(), RadioEnd.GROUND: RadioStats()}
        """Counters by the sending end (VEHICLE: down, GROUND: up)."""
        self._cursor = 0  # ticks since t0: the next TDM decision
        self._window = -1

    # ------------------------------------------------------------------ serial side
    def write(self, end: RadioEnd, data: bytes, t_s: float) -> None:
        """``data`` leaves ``end``'s serial side (the autopilot or the ground station) at
        ``t_s``; it reaches the radio at the serial rate after what is queued before it."""
        if not data:
            return
        stats = self.stats[end]
        stats.bytes_offered += len(data)
        e = self.ends[end]
        start = max(e.line_free_s, t_s, self.t_s)
        if (start - max(t_s, self.t_s)) / self.byte_s + len(data) > LINE_LIMIT_BYTES:
            stats.line_dropped += len(data)
            return
        e.line_free_s = start + len(data) * self.byte_s
        e.line.append((e.line_free_s, t_s, bytes(data)))

    def read(self, end: RadioEnd) -> list[bytes]:
        """What ``end``'s serial port has put out by the time reached (oldest first)."""
        q = self.ends[end].txq
        out: list[bytes] = []
        while q and q[0][0] <= self.t_s + 1e-12:
            out.append(q.popleft()[1])
        return out

    def next_output_s(self, end: RadioEnd) -> float:
        """When ``end``'s serial port next puts something out, as far as decided (inf:
        nothing decided)."""
        q = self.ends[end].txq
        return q[0][0] if q else math.inf

    def txbuf_pct(self, end: RadioEnd) -> int:
        """% of ``end``'s serial receive buffer free (SiK's ``serial_read_space``)."""
        size = self.spec.buffer_bytes
        space = size - self.ends[end].rx_used
        return (100 * (space // 8)) // (size // 8)

    # ------------------------------------------------------------------ the clock
    def advance(self, t_s: float, stop_on: RadioEnd | None = None) -> float:
        """Run the radios to ``t_s``; with ``stop_on``, stop early when that end's serial
        port puts something out (read it, then advance again). Returns the time reached."""
        while True:
            c_s = self.t0_s + self._cursor * TICK_S
            if stop_on is not None:
                q = self.ends[stop_on].txq
                due = next((d for d, _ in q if d > self.t_s + 1e-12), None)
                if due is not None and due <= min(c_s, t_s):
                    self.t_s = max(self.t_s, due)
                    return self.t_s
            if c_s > t_s:
                self.t_s = max(self.t_s, t_s)
                return self.t_s
            self.t_s = max(self.t_s, c_s)
            self._decide(self._cursor)

    def _admit(self, which: RadioEnd, t_s: float) -> None:
        """Bytes whose serial arrival is complete by ``t_s`` enter the radio's buffer."""
        e = self.ends[which]
        size = self.spec.buffer_bytes
        while e.line and e.line[0][0] <= t_s + 1e-12:
            _, t_write, data = e.line.popleft()
            free = size - e.rx_used
            if len(data) > free:
                self.stats[which].rx_overflow += len(data) - free
                data = data[:free]
                whole = False
            else:
                whole = True
            if data:
                e.rx.append((t_write, data, whole))
                e.rx_used += len(data)

    def _decide(self, c: int) -> None:
        """One TDM decision at tick ``c``: who may send, and what."""
        tm = self.timing
        half = tm.window + tm.silence
        k, phase = divmod(c, half)
        if k != self._window:
            self._window = k
            for e in self.ends:
                e.yielded = e.bonus = False
        c_s = self.t0_s + c * TICK_S
        for which in RadioEnd:
            self._admit(which, c_s)
            self._report(which, c_s)
        next_window = (k + 1) * half
        if phase >= tm.window:  # silence
            self._cursor = next_window
            return
        owner = RadioEnd.VEHICLE if k % 2 == 0 else RadioEnd.GROUND
        other = RadioEnd(1 - owner)
        if not self.ends[owner].yielded:
            sender = owner
        elif self.ends[other].bonus and not self.ends[other].yielded:
            sender = other
        else:
            self._cursor = next_window
            return
        remaining = k * half + tm.window - c
        max_xmit = (remaining - tm.packet_latency) // tm.ticks_per_byte
        if remaining < tm.packet_latency or max_xmit < PACKET_OVERHEAD:
            self._cursor = next_window
            return
        max_xmit = min(max_xmit - (TRAILER_BYTES + 1), tm.max_data)
        self._send(sender, sender == owner, max_xmit, c)

    def _take(self, which: RadioEnd, max_xmit: int) -> list[tuple[float, bytes, bool]]:
        """Whole frames from the front of the buffer that fit (a frame longer than a packet
        goes raw, in pieces, as SiK does when it loses the framing)."""
        e = self.ends[which]
        parts: list[tuple[float, bytes, bool]] = []
        total = 0
        while e.rx:
            t_write, data, whole = e.rx[0]
            if len(data) > self.timing.max_fit:
                room = max_xmit - total
                if room <= 0:
                    break
                piece, rest = data[:room], data[room:]
                parts.append((t_write, piece, False))
                e.rx[0] = (t_write, rest, whole)
                e.rx_used -= len(piece)
                break
            if total + len(data) > max_xmit:
                break
            e.rx.popleft()
            parts.append((t_write, data, whole))
            e.rx_used -= len(data)
            total += len(data)
        return parts

    def _send(self, sender: RadioEnd, owner: bool, max_xmit: int, c: int) -> None:
        tm = self.timing
        e = self.ends[sender]
        receiver = RadioEnd(1 - sender)
        r = self.ends[receiver]
        c_s = self.t0_s + c * TICK_S
        parts = self._take(sender, max_xmit)
        kind = "data"
        if not parts:
            if owner and c_s >= e.stats_due_s and max_xmit >= STATS_BYTES:
                kind = "stats"
                e.stats_due_s = c_s + STATS_PERIOD_S
            else:
                kind = "empty"
                e.yielded = True
        length = sum(len(p[1]) for p in parts) if parts else (STATS_BYTES if kind == "stats"
                                                              else 0)
        ticks = tm.flight_ticks(length)
        stats = self.stats[sender]
        stats.packets += 1
        stats.air_ticks += ticks
        if parts:
            stats.data_packets += 1
            stats.data_air_ticks += ticks
            for _, data, whole in parts:
                version = _heartbeat_version(data) if whole else 0
                if version:
                    e.report = version
        arrive_s = c_s + ticks * TICK_S
        if self.chain.lost():
            stats.packets_lost += 1
            stats.bytes_lost += length if parts else 0
            r.rx_errors = min(r.rx_errors + 1, 0xFFFF)
        else:
            r.rssi = (self.rng.gauss(_RSSI_MEAN, 4.0) + 7 * r.rssi) / 8
            if kind == "stats":
                r.rem_rssi, r.rem_noise = e.rssi, e.noise
            elif kind == "empty" and owner:
                r.bonus = True
            for t_write, data, whole in parts:
                self._serial_out(receiver, data, arrive_s, t_write if whole else None, True)
        if owner:
            e.noise = (self.rng.gauss(_NOISE_MEAN, 2.0) + 3 * e.noise) / 4
        self._cursor = c + ticks + tm.packet_latency
        self._report(sender, c_s)

    def _tx_used(self, e: _End, t_s: float) -> int:
        used = 0.0
        for due, data in reversed(e.txq):
            if due <= t_s:
                break
            used += min(len(data), (due - t_s) / self.byte_s)
        return math.ceil(used - 1e-9)

    def _serial_out(
        self, which: RadioEnd, data: bytes, t_s: float, t_write: float | None,
        traffic: bool,
    ) -> None:
        """Put bytes in ``which``'s serial transmit buffer at ``t_s`` (what does not fit is
        discarded); ``traffic``: data from the other radio (a RADIO_STATUS is not), counted;
        ``t_write``: a whole frame's write time, its latency recorded."""
        e = self.ends[which]
        stats = self.stats[RadioEnd(1 - which)]
        free = max(TX_BUFFER_BYTES - self._tx_used(e, t_s), 0)
        if len(data) > free:
            if traffic:
                stats.tx_overflow += len(data) - free
            data = data[:free]
            t_write = None
        if not data:
            return
        e.tx_free_s = max(e.tx_free_s, t_s) + len(data) * self.byte_s
        e.txq.append((e.tx_free_s, data))
        if traffic:
            stats.bytes_carried += len(data)
        if t_write is not None:
            stats.latency_bins[min(int((e.tx_free_s - t_write) / LATENCY_BIN_S),
                                   LATENCY_BINS)] += 1

    def _report(self, which: RadioEnd, t_s: float) -> None:
        """A pending RADIO_STATUS goes out once the serial transmit buffer has room."""
        e = self.ends[which]
        if not e.report:
            return
        frame = self.radio_status_frame(which)
        if TX_BUFFER_BYTES - self._tx_used(e, t_s) < len(frame):
            return  # MAVLink_report: no room, try again next time round
        e.seq = (e.seq + 1) & 0xFF
        e.report = 0
        e.reports += 1
        self._serial_out(which, frame, t_s, None, False)

    def radio_status_frame(self, which: RadioEnd) -> bytes:
        """The RADIO_STATUS ``which`` would send now, in its last heartbeat's version."""
        e = self.ends[which]
        payload = bytes([
            e.rx_errors & 0xFF, e.rx_errors >> 8, 0, 0,  # rxerrors, fixed (uint16 LE)
            _byte(e.rssi), _byte(e.rem_rssi), self.txbuf_pct(which),
            _byte(e.noise), _byte(e.rem_noise),
        ])
        msg_id = mavlink2.MAVLINK_MSG_ID_RADIO_STATUS
        if e.report == 1:
            header = bytes([0xFE, len(payload), e.seq, RADIO_SYSTEM_ID, RADIO_COMPONENT_ID,
                            msg_id])
        else:
            header = bytes([0xFD, len(payload), 0, 0, e.seq, RADIO_SYSTEM_ID,
                            RADIO_COMPONENT_ID, msg_id, 0, 0])
        crc = mavlink2.x25crc(header[1:] + payload)
        crc.accumulate(bytes([_RADIO_STATUS_CRC_EXTRA]))
        return header + payload + bytes([crc.crc & 0xFF, crc.crc >> 8])

    # ------------------------------------------------------------------ figures
    def status(self, which: RadioEnd) -> dict[str, int]:
        """The fields of the RADIO_STATUS ``which`` would send now."""
        e = self.ends[which]
        return {"rssi": _byte(e.rssi), "remrssi": _byte(e.rem_rssi),
                "txbuf": self.txbuf_pct(which), "noise": _byte(e.noise),
                "remnoise": _byte(e.rem_noise), "rxerrors": e.rx_errors, "fixed": 0,
                "sent": e.reports}

    def summary(self) -> dict[str, Any]:
        """Plain figures since the start: per direction (``down``, ``up``) the bytes and
        packets, air time (% of the elapsed time) and latency p50/p95 (s); ``air_pct``:
        the air busy with either radio's packets, ``data_air_pct``: with data."""
        elapsed_s = max(self.t_s - self.t0_s, 1e-9)
        out: dict[str, Any] = {"elapsed_s": round(elapsed_s, 3)}
        busy = data = 0
        for name, end in (("down", RadioEnd.VEHICLE), ("up", RadioEnd.GROUND)):
            s = self.stats[end]
            busy += s.air_ticks
            data += s.data_air_ticks
            out[name] = {
                "bytes_offered": s.bytes_offered, "bytes_carried": s.bytes_carried,
                "bytes_dropped": s.line_dropped + s.rx_overflow + s.tx_overflow,
                "rx_overflow": s.rx_overflow, "tx_overflow": s.tx_overflow,
                "line_dropped": s.line_dropped, "bytes_lost": s.bytes_lost,
                "frames": s.frames, "packets": s.packets, "data_packets": s.data_packets,
                "packets_lost": s.packets_lost,
                "air_pct": 100.0 * s.air_ticks * TICK_S / elapsed_s,
                "latency_p50_s": s.latency_s(0.5), "latency_p95_s": s.latency_s(0.95),
                "serial_pct": 100.0 * s.bytes_offered * self.byte_s / elapsed_s,
            }
        out["air_pct"] = 100.0 * busy * TICK_S / elapsed_s
        out["data_air_pct"] = 100.0 * data * TICK_S / elapsed_s
        out["vehicle_radio"] = self.status(RadioEnd.VEHICLE)
        out["ground_radio"] = self.status(RadioEnd.GROUND)
        return out


def _byte(value: float) -> int:
    return max(0, min(255, round(value)))


def _heartbeat_version(frame: bytes) -> int:
    """1 or 2 if ``frame`` looks like a MAVLink 1 or 2 HEARTBEAT (SiK's
    ``check_response``), else 0."""
    if len(frame) >= 6 and frame[0] == 0xFE and frame[1] == 9 and frame[5] == 0:
        return 1
    if len(frame) >= 10 and frame[0] == 0xFD and frame[1] <= 9 and frame[7:10] == b"\0\0\0":
        return 2
    return 0
