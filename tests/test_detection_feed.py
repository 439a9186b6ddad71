"""The detection feed receiver: valid lines delivered over real UDP on 127.0.0.1 (port 0);
malformed, late and out-of-order lines dropped and counted; garbage bytes, NaN; the
simulator's own lines parse."""

from __future__ import annotations

import asyncio
import json
import socket
import time
from typing import Any

import numpy as np
import pytest

from groundstation.link.detection_feed import (
    DetectionFeed,
    FeedDetection,
    FeedError,
    FeedFilter,
    encode_detection,
    parse_line,
)


def line(**over: Any) -> bytes:
    obj: dict[str, Any] = {"v": 1, "kind": "detection", "time_s": 10.0, "vehicle": 2,
                           "target": "A", "lat_deg": 78.93, "lon_deg": 11.95, "sigma_m": 2.2}
    obj.update(over)
    return json.dumps(obj).encode()


def test_parse_valid_lines() -> None:
    det = parse_line(line())
    assert det == FeedDetection(10.0, "detection", 2, "A", 78.93, 11.95, 2.2)
    boat = parse_line(line(kind="boat", vehicle=None, target=None, sigma_m=0))
    assert boat.kind == "boat" and boat.vehicle is None and boat.target is None
    assert parse_line(line(target=7)).target == "7"
    assert parse_line(line(extra="ignored")).time_s == 10.0
    assert parse_line(line().decode()).vehicle == 2


MALFORMED: list[tuple[bytes, str]] = [
    (b"", "JSON"),
    (b"\xff\xfe\x00garbage", "UTF-8"),
    (b"not json", "JSON"),
    (b"[1, 2]", "object"),
    (b"{" * 5000, "longer"),
    (b"[" * 2000 + b"]" * 2000, "JSON"),
    (line(v=2), "v"),
    (line(v=True), "v"),
    (line(kind="iceberg"), "kind"),
    (line(time_s="10"), "time_s"),
    (line(time_s=None), "time_s"),
    (b'{"v":1,"kind":"detection","time_s":NaN,"vehicle":2,"target":"A","lat_deg":1,'
     b'"lon_deg":1,"sigma_m":1}', "time_s"),
    (b'{"v":1,"kind":"detection","time_s":1,"vehicle":2,"target":"A","lat_deg":Infinity,'
     b'"lon_deg":1,"sigma_m":1}', "lat_deg"),
    (line(lat_deg=91.0), "lat_deg"),
    (line(lon_deg=-180.5), "lon_deg"),
    (line(sigma_m=-1.0), "sigma_m"),
    (line(vehicle=0), "vehicle"),
    (line(vehicle=256), "vehicle"),
    (line(vehicle="2"), "vehicle"),
    (line(vehicle=True), "vehicle"),
    (line(target=""), "target"),
    (line(target=["A"]), "target"),
]


@pytest.mark.parametrize(("raw", "field"), MALFORMED)
def test_malformed_lines_raise_naming_the_field(raw: bytes, field: str) -> None:
    with pytest.raises(FeedError, match=field):
        parse_line(raw)
    for key in ("time_s", "lat_deg", "lon_deg", "sigma_m"):
        obj = json.loads(line())
        del obj[key]
        with pytest.raises(FeedError, match=key):
            parse_line(json.dumps(obj))


def test_filter_counts_malformed_out_of_order_and_late() -> None:
    f = FeedFilter(max_delay_s=5.0)
    got = f.feed(b"\n".join([
        line(time_s=10.0), line(time_s=10.0, target="B"),    # same tick: both fine
        line(time_s=9.0),                                   # vehicle 2 went backwards
        line(time_s=9.5, vehicle=3),                        # another vehicle: fine
        line(time_s=20.0, vehicle=1),
        line(time_s=14.0, vehicle=3),                       # 6 s behind the newest: late
        line(time_s=16.0, vehicle=3),                       # 4 s behind: fine
        b"garbage", b"", b"   ",
        line(kind="boat", vehicle=None, target=None, time_s=19.0),
    ]))
    assert [(d.vehicle, d.time_s) for d in got] == [
        (2, 10.0), (2, 10.0), (3, 9.5), (1, 20.0), (3, 16.0), (None, 19.0)]
    c = f.counters
    assert (c.datagrams, c.accepted, c.out_of_order, c.late, c.malformed) == (1, 6, 1, 1, 1)
    assert f.last_reason is not None and "malformed" in f.last_reason


def test_filter_with_a_clock() -> None:
    now = [100.0]
    f = FeedFilter(max_delay_s=2.0, clock=lambda: now[0])
    assert f.check(line(time_s=97.0)) is None and f.counters.late == 1
    assert f.check(line(time_s=98.5)) is not None
    now[0] = 200.0
    assert f.check(line(time_s=150.0, vehicle=5)) is None
    assert f.counters.late == 2 and f.counters.accepted == 1
    with pytest.raises(ValueError, match="max_delay_s"):
        FeedFilter(max_delay_s=float("nan"))


def test_encode_round_trips_and_refuses_bad_values() -> None:
    raw = encode_detection(3.5, 78.9, 11.9, vehicle=1, target="X", sigma_m=1.5)
    assert raw.endswith(b"\n") and raw.count(b"\n") == 1
    assert parse_line(raw.strip()) == FeedDetection(3.5, "detection", 1, "X", 78.9, 11.9, 1.5)
    boat = encode_detection(4.0, 78.9, 11.9, kind="boat")
    assert parse_line(boat.strip()).kind == "boat"
    with pytest.raises(FeedError, match="time_s"):
        encode_detection(float("nan"), 78.9, 11.9)
    with pytest.raises(FeedError, match="lat_deg"):
        encode_detection(1.0, 100.0, 11.9)
    with pytest.raises(FeedError, match="kind"):
        encode_detection(1.0, 1.0, 1.0, kind="ship")


def test_simulator_lines_are_accepted() -> None:
    from domain.geodesy import GeoOrigin
    from sitl.detections import DetectionSource as SimFeed
    from world.model import Boat, Camera, Iceberg, World

    world = World([Iceberg("A", 10.0, 0.0, 0.0, 0.0, 0.0)], Boat(0.0, 0.0, 0.0, 5.0),
                  Camera(150.0, 2.0, 5.0), np.random.default_rng(0))
    sim = SimFeed(world, GeoOrigin(78.93, 11.92))
    datagrams = sim.step(2.0, {1: (0.0, 0.0)})
    f = FeedFilter()
    got = [d for dg in datagrams for d in f.feed(dg)]
    assert f.counters.malformed == 0 and f.counters.accepted == len(datagrams) >= 5
    assert {d.kind for d in got} == {"detection", "boat"}
    assert all(d.target == "A" and d.vehicle == 1 for d in got if d.kind == "detection")


def test_udp_receiver_delivers_and_counts() -> None:
    async def main() -> tuple[list[FeedDetection], dict[str, int]]:
        got: list[FeedDetection] = []

        def consumer(det: FeedDetection) -> None:
            if det.target == "boom":
                raise RuntimeError("consumer bug")
            got.append(det)

        feed = DetectionFeed("127.0.0.1", 0, consumer)
        await feed.start()
        host, port = feed.address
        assert host == "127.0.0.1" and port != 0
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            for payload in (
                encode_detection(1.0, 78.93, 11.95, vehicle=1, target="A", sigma_m=2.0),
                encode_detection(2.0, 78.93, 11.95, vehicle=1, target="boom"),
                encode_detection(0.5, 78.93, 11.95, vehicle=1, target="A"),  # out of order
                bytes(range(11, 256)),                                        # garbage
                b'{"v":1,"kind":"boat","time_s":NaN}\n',
                encode_detection(3.0, 78.93, 11.95, vehicle=2, target=None)
                + encode_detection(3.0, 78.92, 11.9, kind="boat"),           # two lines
            ):
                sock.sendto(payload, (host, port))
            deadline = time.monotonic() + 3.0
            while feed.counters.datagrams < 6 and time.monotonic() < deadline:
                await asyncio.sleep(0.005)
        finally:
            sock.close()
            await feed.stop()
        return got, feed.counters.as_dict()

    got, counters = asyncio.run(main())
    assert [(d.time_s, d.kind, d.target) for d in got] == [
        (1.0, "detection", "A"), (3.0, "detection", None), (3.0, "boat", None)]
    assert counters == {"datagrams": 6, "accepted": 4, "late": 0, "out_of_order": 1,
                        "malformed": 2, "callback_errors": 1}
