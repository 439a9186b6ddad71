"""The simulated SiK telemetry radio (``sitl/radio.py``), its grammar (``domain/radio_spec.py``)
and the simulator's use of it, in simulated time (no sockets, no wall clock)."""

from __future__ import annotations

import random
from typing import Any

import pytest

from domain.errors import ConfigError
from domain.radio_spec import (
    RadioSpec,
    RadioSpecError,
    parse_radio_spec,
    parse_scenario_radio,
    radio_assignments,
)
from domain.yaml_fields import FieldError
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, mavlink2
from sitl.loopback import MemoryClient
from sitl.radio import GilbertElliott, RadioEnd, SikRadioPair, SikTiming
from sitl.telemetry import StreamScheduler

M = mavlink2
VEHICLE, GROUND = RadioEnd.VEHICLE, RadioEnd.GROUND


def _attitude(enc: MavlinkEncoder) -> bytes:
    return enc.encode(M.MAVLink_attitude_message(0, 0.1, 0.2, 0.3, 0.0, 0.0, 0.0))


def _heartbeat(enc: MavlinkEncoder) -> bytes:
    return enc.encode(M.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))


def _run(
    radio: SikRadioPair, until_s: float, step_s: float,
    offer: dict[RadioEnd, Any], out: dict[RadioEnd, list[Any]] | None = None,
) -> None:
    """Advance in ``step_s`` steps; ``offer[end](t)`` gives the bytes that end writes then;
    decoded output per end into ``out``."""
    decoders = {VEHICLE: MavlinkDecoder(), GROUND: MavlinkDecoder()}
    t = radio.t_s
    while t < until_s - 1e-9:
        t = min(until_s, t + step_s)
        for end, make in offer.items():
            for data in make(t):
                radio.write(end, data, t)
        radio.advance(t)
        for end in (VEHICLE, GROUND):
            for chunk in radio.read(end):
                msgs = decoders[end].feed(chunk)
                if out is not None:
                    out.setdefault(end, []).extend(msgs)


# ---------------------------------------------------------------------- SiK's figures
def test_sik_timing_at_the_defaults() -> None:
    """tdm_init at 64 kbit/s: 9 ticks a byte, 157-tick packets overhead, a 114 ms window
    of 3 full packets, 4.2 ms silences; with ECC 118-byte packets at twice the cost."""
    t = SikTiming.of(RadioSpec())
    assert (t.ticks_per_byte, t.packet_latency, t.window, t.silence, t.max_data) == (
        9, 157, 7140, 260, 250)
    assert t.round_s == pytest.approx(0.2368)
    ecc = SikTiming.of(RadioSpec(ecc=True))
    assert ecc.max_data == 118 and ecc.ticks_per_byte == 18
    assert SikTiming.of(RadioSpec(window_ms=40)).window == 40 * 62  # MAX_WINDOW caps it


# ---------------------------------------------------------------------- throughput
@pytest.mark.parametrize(("spec", "bound_bytes_s", "least_bytes_s"), [
    (RadioSpec(loss=0.0), 57600 / 10, 4000),  # the serial rate binds (the air carries ~5.8 kB/s)
    (RadioSpec(loss=0.0, baud=19200), 19200 / 10, 1800),
    (RadioSpec(loss=0.0, air_kbps=32), 32000 / 8, 2500),  # the air binds
    (RadioSpec(loss=0.0, ecc=True), 64000 / 16, 2000),  # Golay: half the air rate
    # 4 kbit/s: one 45-byte packet (127 ms of air) a window, frames go in pieces
    (RadioSpec(loss=0.0, air_kbps=4), 4000 / 8, 60),
    (RadioSpec(loss=0.0, window_ms=20), 57600 / 10, 2000),  # 117-byte packets
])
def test_throughput_never_exceeds_the_serial_rate_nor_the_air(
    spec: RadioSpec, bound_bytes_s: float, least_bytes_s: float,
) -> None:
    radio = SikRadioPair(spec, 1)
    enc = MavlinkEncoder(1, 1)
    frame = _attitude(enc)  # 40 bytes
    per_step = 8  # 8 frames per 10 ms: 32 kB/s offered, far more than either rate
    out: dict[RadioEnd, list[Any]] = {}

    _run(radio, 60.0, 0.01, {VEHICLE: lambda t: [frame] * per_step}, out)
    assert len(out[GROUND]) >= 0.9 * radio.stats[VEHICLE].bytes_carried / len(frame)
    down = radio.stats[VEHICLE]
    elapsed = radio.t_s
    carried_rate = down.bytes_carried / elapsed
    assert carried_rate <= bound_bytes_s * 1.001
    assert carried_rate >= least_bytes_s  # and the link is used, not starved
    assert radio.summary()["air_pct"] <= 100.0
    # what was not carried was dropped and counted (the sender's queue filled up)
    assert down.line_dropped + down.rx_overflow > 0


def test_every_byte_is_carried_dropped_lost_or_still_inside() -> None:
    radio = SikRadioPair(RadioSpec(air_kbps=16, loss=0.1, burst=2), 7)
    enc = MavlinkEncoder(1, 1)
    rng = random.Random(3)
    _run(radio, 30.0, 0.02, {VEHICLE: lambda t: [_attitude(enc)] * rng.randint(0, 6)})
    s = radio.stats[VEHICLE]
    inside = radio.ends[VEHICLE].rx_used + sum(len(d) for _, _, d in radio.ends[VEHICLE].line)
    assert s.rx_overflow > 0 and s.bytes_lost > 0
    assert s.bytes_offered == (s.bytes_carried + s.line_dropped + s.rx_overflow
                               + s.tx_overflow + s.bytes_lost + inside)


# ---------------------------------------------------------------------- latency
def test_latency_at_the_defaults_with_light_load() -> None:
    """A frame now and then from each side: one way 10-150 ms (p50 about 70 ms, the wait for
    the sender's window dominating); a request and its answer 50-300 ms, as SiK users see."""
    radio = SikRadioPair(RadioSpec(loss=0.0), 3)
    ground, vehicle = MavlinkEncoder(245, 190), MavlinkEncoder(1, 1)
    at_vehicle, at_ground = MavlinkDecoder(), MavlinkDecoder()
    rng = random.Random(1)
    sent: dict[int, float] = {}
    round_trips: list[float] = []
    t = 0.0
    for seq in range(400):
        t_next = t + rng.uniform(0.5, 1.5)
        sent[seq] = t
        request = M.MAVLink_command_long_message(1, 1, seq, 0, 0, 0, 0, 0, 0, 0, 0)
        radio.write(GROUND, ground.encode(request), t)
        while t < t_next:
            t = min(t_next, t + 0.001)
            radio.advance(t)
            for chunk in radio.read(VEHICLE):
                for msg in at_vehicle.feed(chunk):
                    answer = M.MAVLink_command_ack_message(msg.command, 0)
                    radio.write(VEHICLE, vehicle.encode(answer), t)
            for chunk in radio.read(GROUND):
                round_trips += [t - sent[m.command] for m in at_ground.feed(chunk)]
    round_trips.sort()
    n = len(round_trips)
    assert n == 400
    assert round_trips[int(0.05 * n)] >= 0.050
    assert 0.100 <= round_trips[n // 2] <= 0.250
    assert round_trips[-1] <= 0.300
    for end in (VEHICLE, GROUND):
        one_way = radio.stats[end]
        assert one_way.frames == 400
        assert one_way.latency_s(0.01) >= 0.010  # type: ignore[operator]
        assert 0.040 <= one_way.latency_s(0.5) <= 0.120  # type: ignore[operator]
        assert one_way.latency_s(0.99) <= 0.160  # type: ignore[operator]


# ---------------------------------------------------------------------- loss
def _runs(lost: list[bool]) -> list[int]:
    runs, n = [], 0
    for x in lost:
        if x:
            n += 1
        elif n:
            runs.append(n)
            n = 0
    return runs


def test_gilbert_elliott_mean_loss_and_bursts() -> None:
    chain = GilbertElliott(0.05, 4.0, random.Random(11))
    lost = [chain.lost() for _ in range(400_000)]
    assert sum(lost) / len(lost) == pytest.approx(0.05, rel=0.08)
    runs = _runs(lost)
    assert sum(runs) / len(runs) == pytest.approx(4.0, rel=0.08)
    # Bernoulli losses at 5 % would give runs of 1 / 0.95 = 1.05 packets on average
    bernoulli = random.Random(11)
    plain = _runs([bernoulli.random() < 0.05 for _ in range(400_000)])
    assert sum(plain) / len(plain) < 1.1


def test_the_radio_loses_packets_at_the_mean_rate_in_bursts() -> None:
    radio = SikRadioPair(RadioSpec(loss=0.05, burst=3), 5)
    enc = MavlinkEncoder(1, 1)
    _run(radio, 600.0, 0.05, {VEHICLE: lambda t: [_attitude(enc)]})
    sent = sum(radio.stats[e].packets for e in RadioEnd)
    lost = sum(radio.stats[e].packets_lost for e in RadioEnd)
    assert sent > 4000
    assert lost / sent == pytest.approx(0.05, rel=0.2)
    # frames are lost with the packets that carried them, and counted as rxerrors
    down = radio.stats[VEHICLE]
    assert 0 < down.bytes_lost < down.bytes_offered
    assert radio.status(GROUND)["rxerrors"] == down.packets_lost
    # the same seed gives the same losses
    again = SikRadioPair(RadioSpec(loss=0.05, burst=3), 5)
    _run(again, 600.0, 0.05, {VEHICLE: lambda t: [_attitude(enc)]})
    assert again.stats[VEHICLE].packets_lost == down.packets_lost


# ---------------------------------------------------------------------- buffer, RADIO_STATUS
def test_txbuf_falls_and_overflow_is_dropped_when_the_ground_offers_too_much() -> None:
    """At 8 kbit/s the link carries under 1 kB/s; the ground offers 3 kB/s (within its
    57 600 baud serial line): the ground radio's 1850-byte buffer fills, the bytes beyond it
    are dropped and counted, and its RADIO_STATUS tells the ground so (txbuf < 20 %)."""
    radio = SikRadioPair(RadioSpec(air_kbps=8, loss=0.0), 2)
    gcs = MavlinkEncoder(245, 190)
    out: dict[RadioEnd, list[Any]] = {}

    def offer(t: float) -> list[bytes]:
        frames = [_attitude(gcs)] * 3  # 120 B per 40 ms: 3 kB/s
        if round(t * 1000) % 1000 == 0:
            frames.insert(0, _heartbeat(gcs))
        return frames

    _run(radio, 0.12, 0.04, {GROUND: offer}, out)
    assert radio.txbuf_pct(GROUND) > 80
    _run(radio, 20.0, 0.04, {GROUND: offer}, out)
    up = radio.stats[GROUND]
    assert up.rx_overflow > 10_000
    assert up.bytes_carried / radio.t_s < 1000
    assert radio.txbuf_pct(GROUND) < 20
    # its heartbeats mostly drown in the full buffer too; those that get through say so
    txbufs = [m.txbuf for m in out[GROUND] if m.get_type() == "RADIO_STATUS"]
    assert txbufs and max(txbufs) < 20


def test_radio_status_about_once_a_second_from_51_68() -> None:
    """Each radio answers every HEARTBEAT it puts on the air with a RADIO_STATUS on its own
    serial port (SiK's MAVLink_report): the ground station and the autopilot, sending one
    heartbeat a second, each get one a second, unsigned, from system 51 component 68, in
    the heartbeat's MAVLink version."""
    radio = SikRadioPair(RadioSpec(), 9)
    gcs, autopilot = MavlinkEncoder(245, 190), MavlinkEncoder(1, 1)
    out: dict[RadioEnd, list[Any]] = {}

    def every_second(enc: MavlinkEncoder) -> Any:
        return lambda t: [_heartbeat(enc)] if round(t * 100) % 100 == 0 else []

    _run(radio, 60.0, 0.01, {GROUND: every_second(gcs), VEHICLE: every_second(autopilot)}, out)
    for end in (GROUND, VEHICLE):
        status = [m for m in out[end] if m.get_type() == "RADIO_STATUS"]
        assert 57 <= len(status) <= 61
        assert {(m.get_srcSystem(), m.get_srcComponent()) for m in status} == {(51, 68)}
        assert all(m.get_signed() is False for m in status)
        assert all(m.txbuf == 100 and m.fixed == 0 for m in status)
        assert all(80 <= m.rssi <= 160 and 80 <= m.remrssi <= 160 for m in status[3:])
        times = sorted({m.get_seq() for m in status})
        assert len(times) == len(status)  # its own sequence numbers
        assert status[0].get_msgbuf()[0] == 0xFD  # MAVLink 2, as the heartbeats
    # a MAVLink 1 heartbeat gets a MAVLink 1 RADIO_STATUS
    v1 = SikRadioPair(RadioSpec(), 9)
    mav1 = M.MAVLink(None, srcSystem=245, srcComponent=190)
    mav1.WIRE_PROTOCOL_VERSION = "1.0"
    frame = M.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3).pack(mav1, force_mavlink1=True)
    assert frame[0] == 0xFE
    got: dict[RadioEnd, list[Any]] = {}
    _run(v1, 3.0, 0.01, {GROUND: lambda t: [frame] if round(t * 100) == 50 else []}, got)
    [status_v1] = [m for m in got[GROUND] if m.get_type() == "RADIO_STATUS"]
    assert status_v1.get_msgbuf()[0] == 0xFE


def test_the_vehicle_slows_its_streams_as_arduplane_on_a_full_radio_buffer() -> None:
    streams = StreamScheduler(0.0)
    for _ in range(40):
        streams.radio_status(10)
    assert streams.slowdown_s == pytest.approx(2.04)  # +60 ms each, until 2 s is passed
    due = [t for t in (0.1 * i for i in range(100)) if M.MAVLINK_MSG_ID_ATTITUDE in
           streams.due(t)]
    assert len(due) == 4  # 1 Hz became one per 3.04 s over 10 s
    for _ in range(10):
        streams.radio_status(100)
    assert streams.slowdown_s == pytest.approx(1.64)
    heartbeats = [t for t in (0.1 * i for i in range(100, 200)) if M.MAVLINK_MSG_ID_HEARTBEAT
                  in streams.due(t)]
    assert len(heartbeats) == 10  # HEARTBEAT keeps its 1 Hz


# ---------------------------------------------------------------------- grammar
@pytest.mark.parametrize(("text", "vehicles", "radio"), [
    ("sik", None, RadioSpec()),
    ("sik,loss=0.05", None, RadioSpec(loss=0.05)),
    ("sik, air=30 ,ecc=1", None, RadioSpec(air_kbps=32, ecc=True)),
    ("2:sik,baud=115200,burst=5,window=60,buffer=4096,seed=4", [2],
     RadioSpec(baud=115200, burst=5.0, window_ms=60, buffer_bytes=4096, seed=4)),
    ("1,3:none", [1, 3], None),
    ("off", None, None),
    ("all:sik", None, RadioSpec()),
])
def test_radio_specs_accepted(text: str, vehicles: list[int] | None,
                              radio: RadioSpec | None) -> None:
    assert parse_radio_spec(text, 3) == (vehicles, radio)


@pytest.mark.parametrize(("text", "problem"), [
    ("", "expected [VEHICLES:]sik"),
    ("wifi", "unknown radio 'wifi'"),
    ("sik,loss=1", "loss must be in [0, 1)"),
    ("sik,loss=abc", "loss='abc' is not a number"),
    ("sik,loss=nan", "not a finite number"),
    ("sik,loss=0.9", "needs burst >= 9"),
    ("sik,baud=50000", "baud must be one of SiK's serial rates"),
    ("sik,air=0", "air must be in (0, 250]"),
    ("sik,ecc=2", "ecc must be 0 or 1"),
    ("sik,burst=0.5", "burst must be in [1, 1000]"),
    ("sik,window=5", "window must be a whole number in 20..131"),
    ("sik,window=200", "window must be a whole number in 20..131"),
    ("sik,air=2", "at 2 kbit/s no packet fits a 131 ms window; raise air or window"),
    ("sik,air=8,window=20", "at 8 kbit/s no packet fits a 20 ms window"),
    ("sik,speed=3", "unknown option 'speed'"),
    ("sik,loss", "is not key=value"),
    ("sik,loss=0.1,loss=0.2", "loss given twice"),
    ("4:sik", "no vehicle with system id 4 (1..3)"),
    ("x:sik", "vehicles must be 'all' or system ids"),
    ("none,loss=0.1", "none takes no options"),
])
def test_radio_specs_refused(text: str, problem: str) -> None:
    with pytest.raises(RadioSpecError) as info:
        parse_radio_spec(text, 3)
    assert problem in str(info.value)
    assert "\n" not in str(info.value)
    assert isinstance(info.value, ConfigError)


def test_later_specs_win_per_vehicle() -> None:
    radios = radio_assignments(["sik", "2:sik,loss=0.2", "3:none"], [1, 2, 3])
    assert radios == {1: RadioSpec(), 2: RadioSpec(loss=0.2)}
    assert radio_assignments(["sik", "off"], [1, 2]) == {}
    assert radio_assignments([], [1, 2]) == {}


def test_scenario_radio_field() -> None:
    assert parse_scenario_radio(None) == ()
    assert parse_scenario_radio("sik,loss=0.05") == ("sik,loss=0.05",)
    assert parse_scenario_radio(["sik", "2:none"]) == ("sik", "2:none")
    with pytest.raises(FieldError, match=r"radio\[1\].*unknown radio"):
        parse_scenario_radio(["sik", "lora"])
    with pytest.raises(FieldError, match="radio: must be a radio spec"):
        parse_scenario_radio({"kind": "sik"})


# ---------------------------------------------------------------------- the simulator
def _served(radios: dict[int, RadioSpec], tick_s: float, until_s: float = 120.0) -> Any:
    """One airborne vehicle served through ``radios`` and advanced in ``tick_s`` steps of
    simulated time (5 ms: the 1x server; 0.5 s: 100x), a ground station on it sending a
    heartbeat a second and a PARAM_REQUEST_READ every 2 s."""
    from domain.geodesy import GeoOrigin
    from sitl.server import ServerOptions, SitlServer
    from sitl.vehicle import SimVehicle, VehicleConfig

    config = VehicleConfig(system_id=1, origin=GeoOrigin(78.93, 11.92), home_lat_deg=78.93,
                           home_lon_deg=11.92, airborne=True, fast_boot=True)
    server = SitlServer([config], ServerOptions(base_port=0, radios=radios))
    slot = server.slots[0]
    client = MemoryClient()
    slot.clients.add(client)  # type: ignore[arg-type]
    slot.vehicle = SimVehicle(config, 0.0)
    gcs = MavlinkEncoder(245, 190)
    asked: dict[int, float] = {}
    t = 0.0
    while t < until_s - 1e-9:
        t = round(t + tick_s, 6)
        if t % 1.0 < tick_s - 1e-9:
            frames = [_heartbeat(gcs)]
            if int(t) % 2 == 0:
                asked[int(t)] = t
                frames.append(gcs.encode(M.MAVLink_param_request_read_message(
                    1, 1, b"WP_LOITER_RAD", -1)))
            for data in frames:
                if slot.radio is not None:
                    slot.radio.write(GROUND, data, server.t_s)
                else:
                    for msg in MavlinkDecoder().feed(data):
                        server._inbound(slot, msg, client)
        server.advance(t)
    return server, client


def test_the_simulator_serves_a_vehicle_through_its_radio_at_any_speed_up() -> None:
    """Ticked at 1x (5 ms) or 100x (0.5 s), the link behaves alike: the ground station
    hears the vehicle's telemetry, its own radio's RADIO_STATUS once a second, and its
    answers; the radio's figures agree within a few per cent."""
    figures = []
    for tick_s in (0.005, 0.5):
        server, client = _served({1: RadioSpec(loss=0.0)}, tick_s)
        kinds = [(m.get_srcSystem(), m.get_type()) for m in client.msgs]
        assert kinds.count((51, "RADIO_STATUS")) >= 115
        assert kinds.count((1, "PARAM_VALUE")) >= 58
        assert kinds.count((1, "GLOBAL_POSITION_INT")) >= 115
        [stats] = server.radio_stats().values()
        figures.append(stats)
        assert server.describe_radios() == [
            "radio: SiK radio: 57600 baud serial, 64 kbit/s air, 0 % packet loss in bursts "
            "of 3, window 131 ms, buffer 1850 B on every vehicle link"]
    slow, fast = figures
    for direction in ("down", "up"):
        assert fast[direction]["bytes_offered"] == pytest.approx(
            slow[direction]["bytes_offered"], rel=0.03)
        assert fast[direction]["latency_p50_s"] == pytest.approx(
            slow[direction]["latency_p50_s"], abs=0.02)
        assert slow[direction]["bytes_dropped"] == fast[direction]["bytes_dropped"] == 0
    assert 2.0 < slow["air_pct"] < 40.0


def test_without_a_radio_the_link_is_as_before() -> None:
    server, client = _served({}, 0.05, until_s=20.0)
    assert server.radio_stats() == {} and server.describe_radios() == []
    assert not [m for m in client.msgs if m.get_type() == "RADIO_STATUS"]
    assert [m for m in client.msgs if m.get_type() == "PARAM_VALUE"]


def test_gcs_sitl_and_gcs_run_take_sim_radio(capsys: pytest.CaptureFixture[str]) -> None:
    from groundstation.commands import sitl as sitl_command
    from groundstation.commands.run import build_config
    from sitl.server import SitlServer

    options = sitl_command.parse_options(["--count", "3", "--sim-radio", "sik,loss=0.05",
                                          "--sim-radio", "3:none", "--detections", "none"])
    configs, faults, feed, server_options = sitl_command.build(options)
    assert server_options.radios == {1: RadioSpec(loss=0.05), 2: RadioSpec(loss=0.05)}
    assert SitlServer(configs, server_options, faults, feed).describe_radios() == [
        "radio: SiK radio: 57600 baud serial, 64 kbit/s air, 5 % packet loss in bursts of 3, "
        "window 131 ms, buffer 1850 B on vehicle 1, 2"]
    assert sitl_command.run(["--sim-radio", "sik,air=500"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("gcs sitl: error: --sim-radio: radio 'sik,air=500': air must be in "
                   "(0, 250] kbit/s")
    assert sitl_command.run(["--count", "2", "--sim-radio", "5:sik", "--duration", "1"]) == 2
    assert "no vehicle with system id 5 (1..2)" in capsys.readouterr().err

    config = build_config(["--vehicles", "sim:2", "--sim-radio", "sik,loss=0.05"])
    assert config.sim.radio == ("sik,loss=0.05",)
    with pytest.raises(ConfigError, match=r"^--sim-radio: radio '3:sik': no vehicle with "
                                          r"system id 3 \(1\.\.2\)$"):
        build_config(["--vehicles", "sim:2", "--sim-radio", "3:sik"])
    from groundstation.daemon.config_parse import parse_config

    assert parse_config({"vehicles": ["sim:1"], "sim_radio": "sik"}, {}).sim.radio == ("sik",)
    with pytest.raises(ConfigError, match=r"^sim_radio: radio 'sik,ecc=yes': ecc must be 0"):
        parse_config({"vehicles": ["sim:1"], "sim_radio": "sik,ecc=yes"}, {})


def test_tcp_clients_and_udp_out_share_the_radio_over_real_sockets() -> None:
    """Over 127.0.0.1 at 50x: a TCP client and the UDP ``out`` peer of one vehicle both hear
    it through its radio; the UDP peer's request is answered to both (one channel), and the
    ground radio's RADIO_STATUS reaches both."""
    import asyncio
    import socket

    from domain.geodesy import GeoOrigin
    from sitl.server import ServerOptions, SitlServer
    from sitl.vehicle import VehicleConfig

    async def main() -> tuple[list[Any], list[Any]]:
        udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        udp.bind(("127.0.0.1", 0))
        udp.setblocking(False)
        config = VehicleConfig(system_id=1, origin=GeoOrigin(78.93, 11.92), home_lat_deg=78.93,
                               home_lon_deg=11.92, airborne=True, fast_boot=True)
        server = SitlServer([config], ServerOptions(
            speedup=50.0, base_port=0, out=udp.getsockname(), radios={1: RadioSpec()},
            max_step_s=0.25, max_stall_s=0.005))  # a loaded host slows it, never jumps
        await server.start()
        runner = asyncio.create_task(server.run(30.0))
        reader, writer = await asyncio.open_connection("127.0.0.1", server.tcp_ports[0])
        gcs = MavlinkEncoder(245, 190)
        tcp_msgs: list[Any] = []
        udp_msgs: list[Any] = []
        tcp_dec, udp_dec = MavlinkDecoder(), MavlinkDecoder()
        loop = asyncio.get_running_loop()
        sent_s = -1.0
        while not runner.done():
            if server.t_s - sent_s >= 1.0:  # a heartbeat and a request a simulated second
                sent_s = server.t_s
                request = M.MAVLink_param_request_read_message(1, 1, b"WP_RADIUS", -1)
                for data in (_heartbeat(gcs), gcs.encode(request)):
                    await loop.sock_sendto(udp, data, ("127.0.0.1", server.udp_port or 0))
            try:
                data = await asyncio.wait_for(reader.read(65536), 0.01)
                tcp_msgs += tcp_dec.feed(data)
            except TimeoutError:
                pass
            while True:
                try:
                    udp_msgs += udp_dec.feed(udp.recv(65536))
                except BlockingIOError:
                    break
        writer.close()
        await server.close()
        udp.close()
        return tcp_msgs, udp_msgs

    tcp_msgs, udp_msgs = asyncio.run(asyncio.wait_for(main(), 60.0))
    for msgs in (tcp_msgs, udp_msgs):
        kinds = [(m.get_srcSystem(), m.get_type()) for m in msgs]
        # about one of each a simulated second (fewer if this loop lags the simulator)
        assert kinds.count((51, "RADIO_STATUS")) >= 10
        assert kinds.count((1, "PARAM_VALUE")) >= 10
        assert kinds.count((1, "HEARTBEAT")) >= 25


def test_a_vehicle_throttles_its_streams_when_its_radio_fills_up() -> None:
    """Every stream at 10 Hz (REQUEST_DATA_STREAM ALL) over a 16 kbit/s radio: the
    vehicle's radio overflows at first, its RADIO_STATUS (txbuf) slow the vehicle's streams
    down as ArduPlane's do, and from then on nothing more is dropped."""
    from domain.geodesy import GeoOrigin
    from sitl.server import ServerOptions, SitlServer
    from sitl.vehicle import SimVehicle, VehicleConfig

    config = VehicleConfig(system_id=1, origin=GeoOrigin(78.93, 11.92), home_lat_deg=78.93,
                           home_lon_deg=11.92, airborne=True, fast_boot=True)
    server = SitlServer([config], ServerOptions(base_port=0, radios={
        1: RadioSpec(air_kbps=16, loss=0.0)}))
    slot = server.slots[0]
    slot.vehicle = vehicle = SimVehicle(config, 0.0)
    radio = slot.radio
    assert radio is not None
    gcs = MavlinkEncoder(245, 190)
    radio.write(GROUND, gcs.encode(M.MAVLink_request_data_stream_message(1, 1, 0, 10, 1)), 0.0)
    dropped: dict[int, int] = {}
    t = 0.0
    for step in range(1, 2401):
        t = step * 0.05
        if step % 20 == 0:
            radio.write(GROUND, _heartbeat(gcs), server.t_s)
        server.advance(t)
        if step % 400 == 0:
            dropped[step // 20] = radio.stats[VEHICLE].rx_overflow
    assert dropped[20] > 1000  # it overflowed before the reports had their effect
    assert vehicle.streams.slowdown_s >= 0.1
    assert dropped[120] == dropped[40]  # then nothing more
    assert radio.status(VEHICLE)["sent"] >= 100  # the vehicle heard its radio every second
