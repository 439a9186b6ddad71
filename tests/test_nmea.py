"""The ship's NMEA 0183 reader (groundstation/link/nmea.py), its URLs and the conversion
of a fix into the core's BoatPosition (groundstation/daemon/ship_feed.py), on real
recordings (tests/data/nmea/, GPSD's corpus) and made-up streams."""

from __future__ import annotations

import math
import random
from pathlib import Path

import pynmea2
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from domain.geodesy import GeoOrigin
from groundstation.daemon.ship_feed import UERE_M, ShipFeed, boat_position
from groundstation.link.nmea import KNOT_M_S, MAX_LINE_BYTES, NmeaReader, ShipFix
from groundstation.link.nmea_source import NMEA_SERIAL_BAUD, parse_ship_url
from groundstation.link.url import LinkKind, LinkUrlError

DATA = Path(__file__).parent / "data" / "nmea"


def log_lines(name: str) -> list[bytes]:
    """The recording's NMEA lines (``#`` comment lines left out), each with its newline."""
    lines = (DATA / name).read_bytes().splitlines(keepends=True)
    return [line for line in lines if not line.startswith(b"#")]


def read_log(name: str, step_s: float = 0.1) -> tuple[NmeaReader, list[ShipFix]]:
    """Feed a recording line by line, one line every ``step_s`` of receiver time."""
    reader = NmeaReader()
    fixes: list[ShipFix] = []
    for i, line in enumerate(log_lines(name)):
        fixes += reader.feed(line, i * step_s)
    return reader, fixes


def sentence(body: str) -> bytes:
    """``$BODY*CS\\r\\n`` with its checksum."""
    checksum = 0
    for char in body.encode("ascii"):
        checksum ^= char
    return f"${body}*{checksum:02X}\r\n".encode("ascii")


# ------------------------------------------------------------------ recordings
def test_saab_r4_positions_course_speed_heading() -> None:
    reader, fixes = read_log("saab-r4.log")
    c = reader.counters
    assert c.dropped_total == 0
    assert c.ignored > 0  # !AIVDM/!AIVDO, $PFEC, ZDA, DTM, ROT: not errors
    first_gga = next(f for f in fixes if f.sentence == "GGA")
    # $GPGGA,130711,5012.790800,N,00806.879600,W,2,,,,,,,*6A
    assert first_gga.lat_deg == pytest.approx(50 + 12.7908 / 60, abs=1e-9)  # 50.21318
    assert first_gga.lat_deg == pytest.approx(50.21318, abs=1e-9)
    assert first_gga.lon_deg == pytest.approx(-(8 + 6.8796 / 60), abs=1e-9)  # -8.11466
    assert first_gga.hdop is None  # the field is empty
    assert first_gga.talker == "GP"
    # $GPVTG,3.0,T,,,0.50,N,,,D then $GPRMC,...,0.5,3.0,... : 0.5 knots at 3 degrees true
    rmc = next(f for f in fixes if f.sentence == "RMC")
    assert rmc.course_deg == pytest.approx(3.0)
    assert rmc.speed_m_s == pytest.approx(0.5 * 1852 / 3600)
    # $HEHDT,4.0,T (talker HE, a gyro): the next second's fixes carry it
    headed = [f for f in fixes if f.heading_deg is not None]
    assert headed[0].heading_deg == pytest.approx(4.0)
    assert headed[0].t_s > next(f for f in fixes if f.sentence == "RMC").t_s
    assert {f.sentence for f in fixes} == {"GGA", "RMC", "GLL"}


def test_hemisphere_empty_start_gives_no_fix_then_heading() -> None:
    reader, fixes = read_log("hemi.log")
    lines = log_lines("hemi.log")
    first_fix_line = next(i for i, line in enumerate(lines) if line.startswith(b"$GPGGA,1"))
    assert fixes, "the log ends with fixes"
    assert fixes[0].t_s == pytest.approx(first_fix_line * 0.1)  # nothing before it
    assert reader.counters.dropped["no_fix"] > 500  # the empty GGA/VTG/HDT start
    assert reader.counters.dropped_total == reader.counters.dropped["no_fix"]
    # $GPGGA,194050.00,4221.8237733,N,07101.9411707,W,1,00,3.3,...
    assert fixes[0].lat_deg == pytest.approx(42 + 21.8237733 / 60, abs=1e-10)
    assert fixes[0].lon_deg == pytest.approx(-(71 + 1.9411707 / 60), abs=1e-10)
    assert fixes[0].hdop == pytest.approx(3.3)
    # $GPHDT,274.07,T (a GPS compass) then GGA: the heading rides on the later fixes
    headed = [f for f in fixes if f.heading_deg is not None]
    assert headed and headed[0].heading_deg == pytest.approx(274.07)


def test_humminbird_talker_in_vtg_speed_and_time_going_backward() -> None:
    reader, fixes = read_log("humminbird-M37.log")
    assert reader.counters.dropped_total == 0
    assert {f.talker for f in fixes} == {"IN"}
    # $INRMC,194101,A,4426.1130,N,07140.5596,W,5.2,77.3,...
    assert (fixes[0].sentence, fixes[0].course_deg) == ("RMC", 77.3)
    assert fixes[0].lat_deg == pytest.approx(44 + 26.1130 / 60)
    assert fixes[0].lon_deg == pytest.approx(-(71 + 40.5596 / 60))
    assert fixes[0].speed_m_s == pytest.approx(5.2 * KNOT_M_S)
    # without its RMCs, the VTG gives the motion: $INVTG,77.5,T,93.3,M,5.2,N,9.7,K then
    # $INGGA,194104,...,2,10,0.9,...
    reader = NmeaReader()
    lines = [line for line in log_lines("humminbird-M37.log") if b"RMC" not in line]
    vtg_fixes = [fix for i, line in enumerate(lines) for fix in reader.feed(line, i * 0.1)]
    gga = next(f for f in vtg_fixes if f.sentence == "GGA")
    assert gga.course_deg == pytest.approx(77.5)
    assert gga.speed_m_s == pytest.approx(5.2 * KNOT_M_S)  # knots win over the 9.7 km/h
    assert gga.hdop == pytest.approx(0.9)
    # the receiver's clock orders the fixes, though the sentences' own time goes backward
    times = [f.t_s for f in fixes]
    assert times == sorted(times)


def test_sounder_gll_talker_ec() -> None:
    reader, fixes = read_log("sounder.log")
    assert fixes and {f.talker for f in fixes} == {"EC"}
    assert {f.sentence for f in fixes} == {"GLL"}
    # $ECGLL,5119.881,N,00125.169,E,...
    assert fixes[0].lat_deg == pytest.approx(51 + 19.881 / 60)
    assert fixes[0].lon_deg == pytest.approx(1 + 25.169 / 60)
    assert reader.counters.ignored == sum(1 for line in log_lines("sounder.log")
                                          if line.startswith(b"$SDDBT"))


def test_tcp_torture_write_boundaries() -> None:
    """The ``|`` cookies are write boundaries: the sentence split across reads is whole."""
    data = b"".join(log_lines("tcp-torture.log"))
    reader = NmeaReader()
    fixes: list[ShipFix] = []
    for chunk in data.split(b"|"):
        fixes += reader.feed(chunk, 1.0)
    # $GPGGA,|19322|1.00,|2037.|72792,N,08704.08478,W,1,04,1.7,...
    gga = next(f for f in fixes if f.sentence == "GGA")
    assert gga.lat_deg == pytest.approx(20 + 37.72792 / 60)
    assert gga.lon_deg == pytest.approx(-(87 + 4.08478 / 60))
    assert gga.hdop == pytest.approx(1.7)
    assert reader.counters.dropped["garbage"] == 1  # the first line is a sentence's tail
    assert reader.counters.dropped_total == 1
    whole = NmeaReader()
    assert whole.feed(data.replace(b"|", b""), 1.0) == fixes


# ------------------------------------------------------------------ sentences
def test_checksum_rejects() -> None:
    reader = NmeaReader()
    good = b"$GPGGA,130711,5012.790800,N,00806.879600,W,2,,,,,,,*6A\r\n"
    assert len(reader.feed(good, 0.0)) == 1
    assert reader.feed(good.replace(b"*6A", b"*6B"), 0.0) == []
    assert reader.feed(good.replace(b"5012.79", b"5012.78"), 0.0) == []  # a flipped digit
    assert reader.feed(good.replace(b"*6A", b""), 0.0) == []  # no checksum
    assert reader.counters.dropped["checksum"] == 3
    assert reader.counters.fixes == 1


@pytest.mark.parametrize("talker", ["GP", "GN", "IN", "II", "GL"])
def test_any_talker(talker: str) -> None:
    reader = NmeaReader()
    data = (sentence(f"{talker}HDT,90.0,T")
            + sentence(f"{talker}RMC,120000,A,7855.0000,N,01157.0000,E,10.0,90.0,010125,,")
            )
    fixes = reader.feed(data, 5.0)
    assert len(fixes) == 1 and fixes[0].talker == talker
    assert fixes[0].heading_deg == pytest.approx(90.0)
    assert fixes[0].speed_m_s == pytest.approx(10 * KNOT_M_S)


def test_vtg_kmh_only_and_rmc_void() -> None:
    reader = NmeaReader()
    data = (sentence("GPVTG,45.0,T,,M,,N,36.0,K,A")
            + sentence("GPRMC,120000,V,7855.0000,N,01157.0000,E,,,010125,,")
            + sentence("GPGGA,120000,7855.0000,N,01157.0000,E,1,08,0.9,5,M,,M,,"))
    fixes = reader.feed(data, 2.0)
    assert len(fixes) == 1 and fixes[0].sentence == "GGA"
    assert fixes[0].speed_m_s == pytest.approx(10.0)  # 36 km/h
    assert fixes[0].course_deg == pytest.approx(45.0)
    assert reader.counters.dropped["no_fix"] == 1  # the RMC with status V


@pytest.mark.parametrize("body, reason", [
    ("GPGGA,120000,9100.0000,N,01157.0000,E,1,08,0.9,5,M,,M,,", "absurd"),  # lat 91
    ("GPGGA,120000,7855.0000,N,18100.0000,E,1,08,0.9,5,M,,M,,", "absurd"),  # lon 181
    ("GPGGA,120000,7875.0000,N,01157.0000,E,1,08,0.9,5,M,,M,,", "absurd"),  # 75 minutes
    ("GPRMC,120000,A,7855.0000,N,01157.0000,E,200.0,90.0,010125,,", "absurd"),  # 103 m/s
    ("GPRMC,120000,A,7855.0000,N,01157.0000,E,nan,90.0,010125,,", "absurd"),
    ("GPHDT,400.0,T", "absurd"),
    ("GPVTG,45.0,T,,M,inf,N,,K,A", "absurd"),
    ("GPGGA,120000,7855.0000,N,01157.0000,E,1,08,-1,5,M,,M,,", "absurd"),  # HDOP < 0
    ("GPGGA,120000,7855.0000,X,01157.0000,E,1,08,0.9,5,M,,M,,", "malformed"),
    ("GPGGA,120000,78x5.0000,N,01157.0000,E,1,08,0.9,5,M,,M,,", "malformed"),
    ("GPGGA,120000,7855.0000,N,01157.0000,E,0,08,0.9,5,M,,M,,", "no_fix"),  # quality 0
    ("GPGGA,,,,,,1,,,,M,,M,,", "no_fix"),  # empty position
    ("GPVTG,,T,,M,,N,,K,N", "no_fix"),
    ("GPHDT,,T", "no_fix"),
    ("GPGGA,120000", "no_fix"),  # truncated, valid checksum
])
def test_bad_values_are_counted_and_dropped(body: str, reason: str) -> None:
    reader = NmeaReader()
    assert reader.feed(sentence(body), 0.0) == []
    assert reader.counters.dropped[reason] == 1, reader.counters.dropped
    assert reader.counters.dropped_total == 1
    assert reader.counters.valid == 0


def test_ignored_sentences_and_garbage_never_raise() -> None:
    reader = NmeaReader()
    data = (b"!AIVDM,1,1,,B,13aGhtw0R<OJf=6LgQ?Ad1FF05`L,0*24\r\n"
            b"$PFEC,AIcmd,0,35,A,01062011,130711*05\r\n"
            + sentence("GPZDA,130711,01,06,2011,01,00")
            + sentence("GPGSV,3,1,12,28,14,150,41")
            + b"hello world\n\x00\x01\x02\n"
            + b"$GPGGA,120000,7855.0\xc3\xa9000,N*00\r\n"  # non-ASCII
            + b"$GPGGA,1200\r\n"  # truncated: no checksum
            + b"$GP\n$\n*\n,,,,\n")
    assert reader.feed(data, 0.0) == []
    c = reader.counters
    assert c.ignored == 4
    assert c.dropped["non_ascii"] == 1
    assert c.dropped["checksum"] == 1  # the truncated GGA
    assert c.dropped["malformed"] == 2  # "$GP", "$": no address
    assert c.dropped["garbage"] == 4
    assert c.fixes == 0 and c.valid == 0


def test_fusion_only_with_recent_motion() -> None:
    reader = NmeaReader(max_age_s=3.0)
    reader.feed(sentence("GPVTG,90.0,T,,M,10.0,N,,K,A") + sentence("GPHDT,80.0,T"), 10.0)
    gga = sentence("GPGGA,120000,7855.0000,N,01157.0000,E,1,08,0.9,5,M,,M,,")
    (fresh,) = reader.feed(gga, 12.5)
    assert fresh.course_deg == 90.0 and fresh.heading_deg == 80.0
    (stale,) = reader.feed(gga, 13.5)  # 3.5 s after the VTG and HDT
    assert stale.course_deg is None and stale.speed_m_s is None and stale.heading_deg is None
    assert stale.hdop == pytest.approx(0.9)


def test_cr_only_lf_only_and_crlf_frame_alike() -> None:
    body = [sentence("GPHDT,10.0,T").rstrip(),
            sentence("GPGGA,120000,7855.0000,N,01157.0000,E,1,08,0.9,5,M,,M,,").rstrip()]
    results = []
    for end in (b"\r\n", b"\n", b"\r"):
        reader = NmeaReader()
        results.append(reader.feed(end.join(body) + end, 1.0))
    assert results[0] == results[1] == results[2]
    assert len(results[0]) == 1


# ------------------------------------------------------------------ chunking
def _stream() -> bytes:
    return (b"junk before\r\n"
            + b"".join(log_lines("saab-r4.log")[:14])
            + b"\xff\xfe garbage $GPG"  # a broken sentence, then the next line is whole
            + b"\r\n" + sentence("GNRMC,120001,A,7855.0010,N,01157.0020,E,3.0,45.0,010125,,")
            + b"\n")


def test_every_split_point_gives_the_same_fixes() -> None:
    stream = _stream()
    whole = NmeaReader()
    expected = whole.feed(stream, 7.0)
    assert len(expected) >= 4
    for cut in range(len(stream) + 1):
        reader = NmeaReader()
        got = reader.feed(stream[:cut], 7.0) + reader.feed(stream[cut:], 7.0)
        assert got == expected, cut
        assert reader.counters == whole.counters, cut


def test_random_chunkings_give_the_same_fixes() -> None:
    stream = _stream() * 3
    expected = NmeaReader().feed(stream, 7.0)
    rng = random.Random(27)
    for _ in range(200):
        reader = NmeaReader()
        got: list[ShipFix] = []
        i = 0
        while i < len(stream):
            n = rng.choice([1, 1, 2, 3, 7, 40, 200])
            got += reader.feed(stream[i:i + n], 7.0)
            i += n
        assert got == expected


def test_a_long_line_without_newline_stays_bounded() -> None:
    reader = NmeaReader()
    blob = bytes(random.Random(1).randrange(32, 127) for _ in range(10_000))
    for i in range(0, len(blob), 100):
        assert reader.feed(blob[i:i + 100], 0.0) == []
        assert reader.buffered_bytes <= MAX_LINE_BYTES
    assert reader.feed(b"$" + b"A" * 20_000, 0.0) == []  # one read longer than the cap
    assert reader.buffered_bytes <= MAX_LINE_BYTES
    assert reader.counters.dropped["too_long"] == 1  # one line, dropped once
    # the next end of line resynchronises: the following sentence is read
    fixes = reader.feed(b"\n" + sentence("GPGGA,120000,7855.0000,N,01157.0000,E,1,08,0.9,5,"
                                         "M,,M,,"), 1.0)
    assert len(fixes) == 1


# ------------------------------------------------------------------ BoatPosition
def test_boat_position_enu_velocity_heading_sigma() -> None:
    origin = GeoOrigin(78.9, 11.9)
    fix = ShipFix(42.0, 78.91, 11.95, course_deg=30.0, speed_m_s=4.0, heading_deg=45.0,
                  hdop=1.2, sentence="RMC", talker="GP")
    event = boat_position(fix, origin)
    x_m, y_m, _ = origin.to_local(78.91, 11.95)
    assert (event.t_s, event.x_m, event.y_m) == (42.0, x_m, y_m)
    assert event.vx_m_s == pytest.approx(4.0 * math.sin(math.radians(30)))  # east: 2.0
    assert event.vy_m_s == pytest.approx(4.0 * math.cos(math.radians(30)))  # north: 3.46
    assert event.heading_rad == pytest.approx(math.radians(45))  # 45 deg true: NE
    assert event.sigma_m == pytest.approx(1.2 * UERE_M)
    assert event.source == "nmea"
    west = boat_position(ShipFix(0.0, 78.9, 11.9, 270.0, 1.0, 270.0), origin)
    assert west.vx_m_s == pytest.approx(-1.0) and west.vy_m_s == pytest.approx(0.0, abs=1e-12)
    assert west.heading_rad == pytest.approx(-math.pi)  # wrapped to [-pi, pi)
    still = boat_position(ShipFix(0.0, 78.9, 11.9, None, 0.0), origin)
    assert (still.vx_m_s, still.vy_m_s, still.heading_rad, still.sigma_m) == (0, 0, None, None)
    unknown = boat_position(ShipFix(0.0, 78.9, 11.9, None, 2.0), origin)
    assert unknown.vx_m_s is None and unknown.vy_m_s is None


def test_pynmea2_builds_what_the_reader_reads() -> None:
    """A sentence written by pynmea2 itself (as a sender would) round-trips."""
    msg = pynmea2.RMC("GN", "RMC", ("120000", "A", "7855.1234", "N", "01157.5678", "E",
                                    "5.5", "123.4", "010125", "", ""))
    (fix,) = NmeaReader().feed(str(msg).encode() + b"\r\n", 3.0)
    assert fix.lat_deg == pytest.approx(78 + 55.1234 / 60)
    assert fix.lon_deg == pytest.approx(11 + 57.5678 / 60)
    assert fix.course_deg == pytest.approx(123.4)


# ------------------------------------------------------------------ URLs, silence
def test_ship_urls() -> None:
    udp = parse_ship_url("udp:127.0.0.1:10110")
    assert (udp.kind, udp.host, udp.port) == (LinkKind.UDP_IN, "127.0.0.1", 10110)
    tcp = parse_ship_url("tcp:nmea.local:10110")
    assert (tcp.kind, tcp.host, tcp.port) == (LinkKind.TCP_CLIENT, "nmea.local", 10110)
    serial = parse_ship_url("serial:/dev/ttyUSB0")
    assert (serial.kind, serial.device, serial.baud) == (LinkKind.SERIAL, "/dev/ttyUSB0",
                                                          NMEA_SERIAL_BAUD)
    assert parse_ship_url("serial:/dev/ttyUSB0:38400").baud == 38400
    assert parse_ship_url("serial:/dev/ttyS1").device == "/dev/ttyS1"
    for bad in ("udpout:127.0.0.1:10110", "tcpin:0.0.0.0:10110", "tcp:host", "nmea",
                "udp:127.0.0.1:99999", "serial:"):
        with pytest.raises(LinkUrlError) as info:
            parse_ship_url(bad)
        assert "\n" not in str(info.value)


class _Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def now_s(self) -> float:
        return self.t

    def wall_s(self, mission_s: float) -> float:
        return mission_s


class _Host:
    def __init__(self) -> None:
        self.clock = _Clock()
        self.sessions: dict[int, object] = {}
        self.origin_or_none: GeoOrigin | None = GeoOrigin(78.9, 11.9)
        self.fixes: list[object] = []
        self.lines: list[tuple[str, dict[str, object]]] = []

    def ship_fix(self, event: object) -> None:
        self.fixes.append(event)

    def journal(self, event: str, *, logged: bool = False, **fields: object) -> None:
        self.lines.append((event, fields))


def test_silence_warned_once_garbage_counts_as_silent_and_restored(
        caplog: pytest.LogCaptureFixture) -> None:
    host = _Host()
    feed = ShipFeed(host, parse_ship_url("udp:127.0.0.1:0"), silent_after_s=10.0)  # type: ignore[arg-type]
    gga = sentence("GPGGA,120000,7855.0000,N,01157.0000,E,1,08,0.9,5,M,,M,,")
    host.clock.t = 1.0
    feed.on_bytes(gga)
    assert len(host.fixes) == 1
    for t in (2.0, 5.0, 9.0, 10.9):
        host.clock.t = t
        feed.on_bytes(gga.replace(b"*", b"0*"))  # bad checksums only
        assert not feed.check_silence(t)
    host.clock.t = 11.0
    assert feed.check_silence(11.0)
    assert feed.check_silence(30.0)  # still silent: told once
    silent = [f for e, f in host.lines if e == "ship_feed_silent"]
    assert len(silent) == 1
    assert silent[0]["sentences"] == 4 and silent[0]["valid"] == 0
    assert "4 sentences, none valid" in caplog.text
    host.clock.t = 31.0
    feed.on_bytes(gga)
    assert [e for e, _ in host.lines] == ["ship_feed_silent", "ship_feed_restored"]
    assert not feed.silent
    summary = feed.summary()
    assert summary["fixes"] == 2 and summary["dropped"]["checksum"] == 4  # type: ignore[index]


def test_no_origin_fixes_are_counted() -> None:
    host = _Host()
    host.origin_or_none = None
    feed = ShipFeed(host, parse_ship_url("udp:127.0.0.1:0"))  # type: ignore[arg-type]
    feed.on_bytes(sentence("GPGGA,120000,7855.0000,N,01157.0000,E,1,08,0.9,5,M,,M,,"))
    assert host.fixes == [] and feed.no_origin == 1


# ------------------------------------------------------------------ never an exception
@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=600))
def test_random_bytes_never_raise(data: bytes) -> None:
    reader = NmeaReader()
    reader.feed(data, 0.0)
    reader.feed(data + b"\r\n", 1.0)
    assert reader.buffered_bytes <= MAX_LINE_BYTES


_MUTATIONS = st.lists(st.tuples(st.integers(0, 100), st.sampled_from(
    [*"0123456789.,-+NSEWAVTMK*$! ", "nan", "inf", "1e999", ""])), max_size=4)


@settings(max_examples=200, deadline=None)
@given(st.sampled_from([b"HEHDT,4.0,T", b"GPVTG,3.0,T,,,0.50,N,,,D",
                        b"GPRMC,130711.00,A,5012.790800,N,00806.879600,W,0.5,3.0,010611,,A",
                        b"GPGGA,194050.00,4221.8237733,N,07101.9411707,W,1,00,3.3,10.835,M,"
                        b"-33.320,M,,", b"INGLL,4426.1130,N,07140.5579,W,194102,A"]),
       _MUTATIONS)
def test_mutated_sentences_with_good_checksums_never_raise(
        body: bytes, mutations: list[tuple[int, str]]) -> None:
    """Past the checksum, into pynmea2 and the field checks: counted, never raised."""
    text = body.decode()
    for position, insert in mutations:
        i = position % (len(text) + 1)
        text = text[:i] + insert + text[i + 1:]
    reader = NmeaReader()
    fixes = reader.feed(sentence(text), 0.0)
    c = reader.counters
    assert c.valid + c.ignored + c.dropped_total >= 1
    for fix in fixes:
        assert -90 <= fix.lat_deg <= 90 and -180 <= fix.lon_deg <= 180
        assert fix.speed_m_s is None or 0 <= fix.speed_m_s <= 50
