"""The ship's NMEA 0183 stream, sans-IO: bytes in, ship fixes out (docs/ship.md).

:class:`NmeaReader` is pure, in the manner of h11: :meth:`NmeaReader.feed` takes the bytes
of one read (any chunking: a sentence split across reads, several per read, CR/LF or LF or
CR, garbage between) and the receiver's clock at reception (``now_s``, the daemon's mission
time), and returns the :class:`ShipFix` es those bytes completed. It never raises for bad
input; every sentence it could not use is counted by reason in :class:`NmeaCounters`.

**Framing.** A line ends at LF or CR (empty lines are skipped). A sentence starts at the
line's last ``$`` or ``!``; bytes before it are garbage (counted once per line). A line
longer than :data:`MAX_LINE_BYTES` (NMEA's own limit is 82 characters) is dropped whole,
and a partial line never grows past it (the reader skips to the next end of line), so a
stream without newlines cannot grow memory. Framing depends only on the bytes, so every
chunking of a stream gives the same fixes and counts.

**Sentences** (any talker: ``GP``, ``GN``, ``IN``, ``HE``, ``EC``, ``II``...), parsed and
checksum-checked by pynmea2 (a checksum is required):

* ``GGA``: position; fix quality 0 (no fix) or empty fields are dropped (``no_fix``);
  HDOP where given.
* ``RMC``: position, speed over ground (knots) and course over ground (degrees true);
  status ``V`` is dropped (``no_fix``).
* ``GLL``: position; status ``V`` is dropped.
* ``VTG``: course over ground (degrees true) and speed (knots, else km/h); mode ``N`` or
  both empty is ``no_fix``.
* ``HDT``: true heading (the gyro's or a GPS compass's).

Everything else (``ZDA``, ``GSA``, ``GSV``, depth, AIS ``!AIVDM``/``!AIVDO``, proprietary
``$P...``) is ``ignored``: counted, not an error.

**Fusion.** Every position sentence (GGA, RMC, GLL) gives one fix, carrying the latest
course/speed (RMC's own, else VTG's) and heading (HDT) if they were received within
:attr:`NmeaReader.max_age_s` (reception time, mission s) of the position, else None; and
the HDOP of the fix's GGA, or of the latest GGA within ``max_age_s`` for RMC/GLL. NMEA times
of day are not used: receivers send them backward or not at all, and the receiver's clock
orders the fixes.

**Sanity.** Latitude beyond 90, longitude beyond 180, speed above :data:`MAX_SPEED_M_S`,
course or heading outside [0, 360], negative HDOP, or a non-finite number drops the
sentence (``absurd``); a field pynmea2 cannot convert drops it as ``malformed``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import pynmea2

__all__ = [
    "DROP_REASONS",
    "KNOT_M_S",
    "MAX_LINE_BYTES",
    "MAX_SPEED_M_S",
    "NmeaCounters",
    "NmeaReader",
    "ShipFix",
]

MAX_LINE_BYTES = 256
"""A line longer than this is dropped (NMEA 0183 allows 82 characters; some devices more)."""
MAX_SPEED_M_S = 50.0
"""A speed over ground above this (97 knots) is not a ship's: the sentence is dropped."""
KNOT_M_S = 1852.0 / 3600.0
"""One knot in m/s (one nautical mile, 1852 m, per hour)."""
KMH_M_S = 1.0 / 3.6
DEFAULT_MAX_AGE_S = 3.0
"""Course, speed, heading and HDOP older than this (reception time) are not fused."""

DROP_REASONS = ("garbage", "too_long", "non_ascii", "checksum", "malformed", "no_fix",
                "absurd")
"""Why a sentence (or a run of bytes) was dropped; the keys of ``NmeaCounters.dropped``."""

_POSITION = frozenset({"GGA", "RMC", "GLL"})
_USED = _POSITION | {"VTG", "HDT"}
_TERMINATORS = b"\r\n"


@dataclass(frozen=True, slots=True)
class ShipFix:
    """One position of the ship, fused with its recent motion.

    ``t_s``: the receiver's clock at reception of the position sentence (mission s).
    ``course_deg``: course over ground, degrees true (clockwise from north), None if unknown
    or stale; ``speed_m_s``: speed over ground; ``heading_deg``: the bow's true heading
    (HDT); ``hdop``: horizontal dilution of precision (GGA). ``sentence`` is the position
    sentence's type and ``talker`` its talker id (``GP``, ``IN``...)."""

    t_s: float
    lat_deg: float
    lon_deg: float
    course_deg: float | None = None
    speed_m_s: float | None = None
    heading_deg: float | None = None
    hdop: float | None = None
    sentence: str = ""
    talker: str = ""


@dataclass
class NmeaCounters:
    """What the reader did with every sentence: ``sentences`` framed (lines starting with
    ``$`` or ``!``), ``valid`` used (a position, motion or heading), ``ignored`` (types
    floe does not use), ``fixes`` given, ``dropped`` by reason (:data:`DROP_REASONS`;
    ``garbage`` counts lines or line heads that are not a sentence)."""

    bytes: int = 0
    sentences: int = 0
    valid: int = 0
    ignored: int = 0
    fixes: int = 0
    dropped: dict[str, int] = field(default_factory=lambda: dict.fromkeys(DROP_REASONS, 0))

    def as_dict(self) -> dict[str, object]:
        return {"bytes": self.bytes, "sentences": self.sentences, "valid": self.valid,
                "ignored": self.ignored, "fixes": self.fixes, "dropped": dict(self.dropped)}

    @property
    def dropped_total(self) -> int:
        return sum(self.dropped.values())


class _Drop(Exception):
    """A sentence is dropped for ``reason`` (internal to the reader)."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


def _number(text: object) -> float | None:
    """A field as a finite float; None when empty; :class:`_Drop` when not a number."""
    if text is None:
        return None
    if not isinstance(text, str):
        text = str(text)
    text = text.strip()
    if not text:
        return None
    try:
        value = float(text)
    except ValueError:
        raise _Drop("malformed") from None
    if not math.isfinite(value):
        raise _Drop("absurd")
    return value


def _angle_deg(text: object) -> float | None:
    value = _number(text)
    if value is not None and not 0.0 <= value <= 360.0:
        raise _Drop("absurd")
    return None if value is None else value % 360.0


def _speed(value: float | None, unit_m_s: float) -> float | None:
    if value is None:
        return None
    speed = value * unit_m_s
    if not 0.0 <= speed <= MAX_SPEED_M_S:
        raise _Drop("absurd")
    return speed


def _coordinate(text: str, hemisphere: str, limit_deg: float, positive: str,
                negative: str) -> float:
    """NMEA ``(d)ddmm.mmmm`` and its hemisphere letter -> signed degrees."""
    text, hemisphere = text.strip(), hemisphere.strip().upper()
    if not text or not hemisphere:
        raise _Drop("no_fix")
    if hemisphere not in (positive, negative):
        raise _Drop("malformed")
    whole = text.partition(".")[0]
    if len(whole) < 3 or not whole.isdigit():
        raise _Drop("malformed")
    value = _number(text)
    assert value is not None
    degrees = math.floor(value / 100.0)
    minutes = value - 100.0 * degrees
    if not 0.0 <= minutes < 60.0:
        raise _Drop("absurd")
    signed = degrees + minutes / 60.0
    if signed > limit_deg:
        raise _Drop("absurd")
    return -signed if hemisphere == negative else signed


@dataclass(slots=True)
class _Seen:
    value: float
    t_s: float


@dataclass(slots=True)
class _Motion:
    course_deg: float | None
    speed_m_s: float | None
    t_s: float


class NmeaReader:
    """Feed bytes with the reception time; get :class:`ShipFix` es (see the module doc)."""

    def __init__(self, max_age_s: float = DEFAULT_MAX_AGE_S,
                 max_line_bytes: int = MAX_LINE_BYTES) -> None:
        if not (math.isfinite(max_age_s) and max_age_s >= 0.0):
            raise ValueError(f"max_age_s must be finite and >= 0, got {max_age_s}")
        if max_line_bytes < 16:
            raise ValueError(f"max_line_bytes must be >= 16, got {max_line_bytes}")
        self.max_age_s = max_age_s
        self.max_line_bytes = max_line_bytes
        self.counters = NmeaCounters()
        self.last_drop: str | None = None
        """The last dropped sentence's reason and text (for a warning), None before one."""
        self._buffer = bytearray()
        self._skipping = False  # inside an over-long line: drop bytes up to its end
        self._motion: _Motion | None = None
        self._heading: _Seen | None = None
        self._hdop: _Seen | None = None

    @property
    def buffered_bytes(self) -> int:
        """Bytes of an unfinished line held (never more than ``max_line_bytes``)."""
        return len(self._buffer)

    def feed(self, data: bytes, now_s: float) -> list[ShipFix]:
        """The fixes completed by ``data``, received at ``now_s`` (mission s)."""
        self.counters.bytes += len(data)
        fixes: list[ShipFix] = []
        start = 0
        n = len(data)
        while start < n:
            end = _next_terminator(data, start)
            if end < 0:
                self._append(data[start:])
                break
            self._append(data[start:end])
            if self._skipping:
                self._skipping = False
            elif self._buffer:
                line = bytes(self._buffer)
                self._buffer.clear()
                fix = self._line(line, now_s)
                if fix is not None:
                    fixes.append(fix)
            start = end + 1
        return fixes

    def _append(self, chunk: bytes) -> None:
        if self._skipping or not chunk:
            return
        if len(self._buffer) + len(chunk) > self.max_line_bytes:
            self._buffer.clear()
            self._skipping = True
            self._drop("too_long", f"a line longer than {self.max_line_bytes} bytes")
            return
        self._buffer += chunk

    def _drop(self, reason: str, text: str) -> None:
        self.counters.dropped[reason] += 1
        self.last_drop = f"{reason}: {text[:90]}"

    def _line(self, line: bytes, now_s: float) -> ShipFix | None:
        start = max(line.rfind(b"$"), line.rfind(b"!"))
        if start < 0:
            self._drop("garbage", repr(line[:40]))
            return None
        if start > 0 and line[:start].strip():
            self._drop("garbage", repr(line[:min(start, 40)]))
        sentence = line[start:]
        self.counters.sentences += 1
        if any(b > 126 or (b < 32 and b != 9) for b in sentence):
            self._drop("non_ascii", repr(sentence[:40]))
            return None
        text = sentence.decode("ascii").strip()
        address = text[1:].partition(",")[0].partition("*")[0]
        if not address.isalnum() or not (len(address) == 5 or address[0] == "P"):
            self._drop("malformed", text)
            return None
        kind = address[2:] if len(address) == 5 else ""
        if text.startswith("!") or address.startswith("P") or kind not in _USED:
            self.counters.ignored += 1
            return None
        try:
            msg = pynmea2.parse(text, check=True)
        except pynmea2.ChecksumError:
            self._drop("checksum", text)
            return None
        except (pynmea2.ParseError, ValueError, TypeError, IndexError, AttributeError):
            self._drop("malformed", text)
            return None
        try:
            fix = self._sentence(msg, kind, text[1:3], now_s)
        except _Drop as drop:
            self._drop(drop.reason, text)
            return None
        except (ValueError, TypeError, IndexError, AttributeError, ArithmeticError):
            self._drop("malformed", text)
            return None
        self.counters.valid += 1
        if fix is not None:
            self.counters.fixes += 1
        return fix

    def _recent(self, seen_t_s: float, now_s: float) -> bool:
        return abs(now_s - seen_t_s) <= self.max_age_s

    def _sentence(self, msg: pynmea2.NMEASentence, kind: str, talker: str,
                  now_s: float) -> ShipFix | None:
        data = [str(f) for f in msg.data]
        if kind == "VTG":
            # VTG,course T,T,course M,M,speed kn,N,speed km/h,K[,mode]
            fields = data + [""] * (9 - len(data))
            if fields[8].strip().upper() == "N":
                raise _Drop("no_fix")
            course = _angle_deg(fields[0])
            knots = _number(fields[4])
            speed = (_speed(knots, KNOT_M_S) if knots is not None
                     else _speed(_number(fields[6]), KMH_M_S))
            if course is None and speed is None:
                raise _Drop("no_fix")
            self._motion = _Motion(course, speed, now_s)
            return None
        if kind == "HDT":
            heading = _angle_deg(data[0] if data else "")
            if heading is None:
                raise _Drop("no_fix")
            self._heading = _Seen(heading, now_s)
            return None
        if kind == "GGA":
            # GGA,time,lat,N,lon,E,quality,sats,hdop,...
            fields = data + [""] * (8 - len(data))
            quality = _number(fields[5])
            if quality is None or quality == 0:
                raise _Drop("no_fix")
            lat = _coordinate(fields[1], fields[2], 90.0, "N", "S")
            lon = _coordinate(fields[3], fields[4], 180.0, "E", "W")
            hdop = _number(fields[7])
            if hdop is not None and hdop < 0:
                raise _Drop("absurd")
            if hdop is not None:
                self._hdop = _Seen(hdop, now_s)
            return self._fix(now_s, lat, lon, hdop, kind, talker)
        if kind == "RMC":
            # RMC,time,status,lat,N,lon,E,speed kn,course T,date,...
            fields = data + [""] * (8 - len(data))
            if fields[1].strip().upper() != "A":
                raise _Drop("no_fix")
            lat = _coordinate(fields[2], fields[3], 90.0, "N", "S")
            lon = _coordinate(fields[4], fields[5], 180.0, "E", "W")
            speed = _speed(_number(fields[6]), KNOT_M_S)
            course = _angle_deg(fields[7])
            if speed is not None or course is not None:
                self._motion = _Motion(course, speed, now_s)
            return self._fix(now_s, lat, lon, None, kind, talker)
        # GLL,lat,N,lon,E,time,status[,mode]
        fields = data + [""] * (6 - len(data))
        if fields[5].strip().upper() != "A":
            raise _Drop("no_fix")
        lat = _coordinate(fields[0], fields[1], 90.0, "N", "S")
        lon = _coordinate(fields[2], fields[3], 180.0, "E", "W")
        return self._fix(now_s, lat, lon, None, kind, talker)

    def _fix(self, now_s: float, lat: float, lon: float, hdop: float | None, kind: str,
             talker: str) -> ShipFix:
        course = speed = heading = None
        if self._motion is not None and self._recent(self._motion.t_s, now_s):
            course, speed = self._motion.course_deg, self._motion.speed_m_s
        if self._heading is not None and self._recent(self._heading.t_s, now_s):
            heading = self._heading.value
        if hdop is None and self._hdop is not None and self._recent(self._hdop.t_s, now_s):
            hdop = self._hdop.value
        return ShipFix(now_s, lat, lon, course, speed, heading, hdop, kind, talker)


def _next_terminator(data: bytes, start: int) -> int:
    """Index of the next CR or LF at or after ``start``, -1 if none."""
    cr = data.find(_TERMINATORS[:1], start)
    lf = data.find(_TERMINATORS[1:], start)
    if cr < 0:
        return lf
    if lf < 0:
        return cr
    return min(cr, lf)
