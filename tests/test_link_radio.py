"""A telemetry radio's RADIO_STATUS / RADIO describe the radio, never the vehicle: the
router keeps them as the link's radio report and hands none on (no binding, no vehicle
frame, no keep-alive of a binding); the reducer never counts them as heard."""

from __future__ import annotations

import asyncio

from link_fixtures import heartbeat, udp_socket, wait_until

from domain.geodesy import GeoOrigin
from groundstation.link import Received, Router, open_link
from groundstation.link.binding import BindingRules
from groundstation.link.udp import UdpInLink
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, mavlink2
from groundstation.mavlink.telemetry import VehicleTelemetry

M = mavlink2


def radio_status(sysid: int, compid: int, rssi: int = 180) -> bytes:
    return MavlinkEncoder(sysid, compid).encode(
        M.MAVLink_radio_status_message(rssi, 170, 90, 40, 35, 3, 1))


def test_radio_reports_are_the_links_and_reach_no_vehicle() -> None:
    clock = [0.0]

    async def main() -> None:
        got: list[Received] = []
        router = Router(on_vehicle_frame=got.append, now_s=lambda: clock[0],
                        rules=BindingRules(rebind_after_s=10.0))
        a = open_link("udpin:127.0.0.1:0", link_id="a")
        b = open_link("udpin:127.0.0.1:0", link_id="b")
        router.add_vehicle_link(a)
        router.add_vehicle_link(b)
        vehicle, radio = udp_socket(), udp_socket()
        async with router:
            assert isinstance(a, UdpInLink) and isinstance(b, UdpInLink)
            # a radio heard first binds nothing, whatever ids it carries
            radio.sendto(radio_status(51, 68), a.local_address)
            radio.sendto(radio_status(1, 1), a.local_address)
            await wait_until(lambda: a.counters.radio_frames == 2)
            assert router.routes == {} and got == []
            assert a.radio is not None and (a.radio.system_id, a.radio.rssi) == (1, 180)
            assert a.snapshot()["radio"]["remrssi"] == 170
            # the vehicle binds to link a; then goes silent there. A radio keeps sending
            # its ids on link a: that keeps no binding, so the vehicle's heartbeats on
            # link b rebind it after 10 s as if a were silent
            vehicle.sendto(heartbeat(1), a.local_address)
            await wait_until(lambda: len(got) == 1)
            assert router.routes == {1: a}
            for t in (5.0, 11.0, 12.0, 13.0):
                clock[0] = t
                radio.sendto(radio_status(1, 1), a.local_address)
                vehicle.sendto(heartbeat(1), b.local_address)
                await asyncio.sleep(0.05)
            await wait_until(lambda: router.routes.get(1) is b)
            assert all(rx.message.get_type() == "HEARTBEAT" for rx in got)
            assert router.counters.radio == a.counters.radio_frames == 6

    asyncio.run(main())


def test_the_reducer_never_hears_a_radio() -> None:
    tel = VehicleTelemetry(1, GeoOrigin(78.0, 15.0))
    [msg] = MavlinkDecoder().feed(radio_status(1, 1))
    assert tel.receive(msg, 3.0) == []
    assert tel.snapshot().last_heard_s is None and tel.radio_messages == 1
    assert tel.link_status(3.0, 5.0) == "lost"
    [beat] = MavlinkDecoder().feed(heartbeat(1))
    tel.receive(beat, 4.0)
    [msg] = MavlinkDecoder().feed(radio_status(1, 1))
    tel.receive(msg, 20.0)
    assert tel.snapshot().last_heard_s == 4.0 and tel.link_status(20.0, 5.0) == "lost"
