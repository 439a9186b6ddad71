"""One bound link per vehicle (issue 10.3): forged frames elsewhere are foreign; a binding
moves only after the bound place fell silent and the vehicle's own heartbeats came on the
new one. Rules unit-tested on the pure Binder, then through the router and a udpin link."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

from link_fixtures import (
    FakeVehicle,
    attitude,
    drain_socket,
    heartbeat,
    recv_message,
    recv_one,
    statustext,
    sys_status,
    udp_socket,
    wait_until,
)

from groundstation.link import LinkOptions, Received, Router, TlogReader, TlogWriter, open_link
from groundstation.link.binding import Binder, BindingRules, BindingVerdict
from groundstation.link.udp import UdpInLink
from groundstation.mavlink.codec import mavlink2


def test_binder_binds_on_the_first_autopilot_heartbeat_only() -> None:
    b: Binder[str] = Binder()
    assert b.observe(1, "A", False, 0.0) is BindingVerdict.UNBOUND  # telemetry never binds
    assert b.observe(1, "B", True, 0.1) is BindingVerdict.BOUND
    assert b.observe(1, "A", True, 0.2) is BindingVerdict.FOREIGN
    assert b.observe(1, "A", False, 0.3) is BindingVerdict.FOREIGN
    assert b.observe(1, "B", False, 0.4) is BindingVerdict.OWN
    assert b.observe(0, "A", True, 0.5) is BindingVerdict.UNBOUND  # broadcast id never binds
    assert b.bound() == {1: "B"} and b.place_of(2) is None
    assert b.forget("B") == [1] and b.place_of(1) is None


def test_binder_rebinds_only_after_silence_and_consistent_heartbeats() -> None:
    rules = BindingRules(rebind_after_s=10.0, evidence_heartbeats=3, evidence_span_s=2.0)
    b: Binder[str] = Binder(rules)
    assert b.observe(1, "A", True, 0.0) is BindingVerdict.BOUND
    # Heartbeats on B while A is alive: foreign, and A's frames clear the evidence.
    for t in (1.0, 2.0, 3.0):
        assert b.observe(1, "B", True, t) is BindingVerdict.FOREIGN
    assert b.observe(1, "A", False, 3.5) is BindingVerdict.OWN
    # A silent since 3.5. Three heartbeats spanning 2 s, but A not silent for 10 s yet.
    for t in (10.0, 11.0, 12.0):
        assert b.observe(1, "B", True, t) is BindingVerdict.FOREIGN
    # Silent long enough, but a 6 s gap in B's heartbeats restarts the evidence.
    assert b.observe(1, "B", True, 18.0) is BindingVerdict.FOREIGN
    assert b.observe(1, "B", True, 19.0) is BindingVerdict.FOREIGN
    # Two heartbeats spanning 1 s are not enough; the third, 2 s after the first, is.
    assert b.observe(1, "B", True, 20.0) is BindingVerdict.REBOUND
    assert b.place_of(1) == "B"
    assert b.observe(1, "A", True, 20.5) is BindingVerdict.FOREIGN  # now A is the foreign one


def test_binder_needs_heartbeats_not_any_frames_as_evidence() -> None:
    b: Binder[str] = Binder(BindingRules(rebind_after_s=1.0))
    b.observe(7, "A", True, 0.0)
    for k in range(50):  # a flood of telemetry on B after A went silent
        assert b.observe(7, "B", False, 5.0 + k * 0.1) is BindingVerdict.FOREIGN
    assert b.place_of(7) == "A"


def _router(tmp_path: Path, clock: list[float]) -> tuple[Router, list[Received], list[Any]]:
    delivered: list[Received] = []
    notices: list[Any] = []
    router = Router(
        on_vehicle_frame=delivered.append,
        tlog=TlogWriter(tmp_path / "flight.tlog"),
        rules=BindingRules(rebind_after_s=10.0),
        now_s=lambda: clock[0],
        on_notice=lambda event, fields: notices.append((event, fields)),
    )
    return router, delivered, notices


def test_forged_frame_on_another_link_is_not_delivered_and_commands_stay(tmp_path: Path) -> None:
    async def main() -> None:
        clock = [0.0]
        router, delivered, _ = _router(tmp_path, clock)
        a = open_link("udpin:127.0.0.1:0", link_id="radio")
        b = open_link("udpin:127.0.0.1:0", link_id="other")
        qgc = udp_socket()
        out = open_link(f"udpout:127.0.0.1:{qgc.getsockname()[1]}", link_id="qgc")
        router.add_vehicle_link(a)
        router.add_vehicle_link(b)
        router.add_out_link(out)
        vehicle, forger = udp_socket(), udp_socket()
        async with router:
            assert isinstance(a, UdpInLink) and isinstance(b, UdpInLink)
            vehicle.sendto(heartbeat(1), a.local_address)
            await wait_until(lambda: len(delivered) == 1)
            assert router.link_for(1) is a
            # The forger needs a route to receive anything: it speaks as system 9 first.
            forger.sendto(heartbeat(9), b.local_address)
            await wait_until(lambda: len(delivered) == 2)
            # A forged low battery, a forged heartbeat and telemetry of system 1 on link b.
            forged = [sys_status(1, 5), heartbeat(1), attitude(1)]
            for frame in forged:
                forger.sendto(frame, b.local_address)
            await wait_until(lambda: b.counters.foreign == 3)
            await asyncio.sleep(0.05)
            assert len(delivered) == 2  # none of them reached the daemon
            assert a.counters.foreign == 0 and router.counters.foreign == 3
            assert router.link_for(1) is a
            # The command goes to the vehicle, never to the forger.
            assert router.send_to(1, statustext(255, "RTL"))
            msg, _ = await recv_message(vehicle)
            assert msg.text == "RTL"
            await asyncio.sleep(0.05)
            assert drain_socket(forger) == []
            # MAVProxy on --out still sees the raw traffic, forged frames included.
            seen = [(await recv_one(qgc))[1] for _ in range(5)]
            assert seen[2:] == forged
        router.tlog.close()  # type: ignore[union-attr]
        records = list(TlogReader(tmp_path / "flight.tlog"))
        raw_by_link = [(r.link_number, bytes(r.message.get_msgbuf())) for r in records]
        for frame in forged:
            assert (1, frame) in raw_by_link  # recorded as received on the second link
        for s in (vehicle, forger, qgc):
            s.close()

    asyncio.run(main())


def test_rebinding_after_silence_and_consistent_heartbeats(tmp_path: Path) -> None:
    async def main() -> None:
        clock = [0.0]
        router, delivered, notices = _router(tmp_path, clock)
        a = open_link("udpin:127.0.0.1:0", link_id="radio")
        b = open_link("udpin:127.0.0.1:0", link_id="lte")
        router.add_vehicle_link(a)
        router.add_vehicle_link(b)
        old_path, new_path = udp_socket(), udp_socket()
        async with router:
            assert isinstance(a, UdpInLink) and isinstance(b, UdpInLink)

            async def beat(sock: Any, link: UdpInLink, t_s: float) -> None:
                clock[0] = t_s
                before = link.counters.frames_in
                sock.sendto(heartbeat(1), link.local_address)
                await wait_until(lambda: link.counters.frames_in == before + 1)

            await beat(old_path, a, 0.0)
            # The radio dies at t = 0; the vehicle is heard on the LTE link from t = 4.
            for t in (4.0, 5.0, 6.0, 7.0, 8.0, 9.0):
                await beat(new_path, b, t)
            assert router.link_for(1) is a and len(delivered) == 1  # not silent long enough
            await beat(new_path, b, 10.0)  # 10 s of silence and 7 heartbeats over 6 s
            assert router.link_for(1) is b
            assert len(delivered) == 2 and delivered[-1].link_id == "lte"
            assert notices == [
                ("link_rebound", {"system_id": 1, "link": "lte", "previous": "radio"})
            ]
            assert router.counters.rebinds == 1 and b.counters.foreign == 6
            assert router.send_to(1, statustext(255, "via lte"))
            msg, _ = await recv_message(new_path)
            assert msg.text == "via lte"
            # The radio comes back: now its frames are the foreign ones.
            await beat(old_path, a, 11.0)
            assert a.counters.foreign == 1 and len(delivered) == 2
        router.tlog.close()  # type: ignore[union-attr]
        old_path.close()
        new_path.close()

    asyncio.run(main())


def test_udpin_address_binding_follows_the_same_rule() -> None:
    async def main() -> None:
        clock = [0.0]
        got: list[Received] = []
        notices: list[Any] = []
        link = open_link("udpin:127.0.0.1:0", link_id="fleet", on_receive=got.append)
        assert isinstance(link, UdpInLink)
        link.now_s = lambda: clock[0]
        link.on_notice = lambda event, fields: notices.append((event, fields))
        home, intruder = udp_socket(), udp_socket()

        async def send(sock: Any, frame: bytes, t_s: float) -> Received:
            clock[0] = t_s
            n = len(got)
            sock.sendto(frame, link.local_address)
            await wait_until(lambda: len(got) == n + 1)
            return got[-1]

        async with link:
            assert not (await send(home, heartbeat(3), 0.0)).foreign
            # A GCS heartbeat with the same id from elsewhere: foreign, replies stay home.
            gcs_hb = heartbeat(3, mavlink2.MAV_TYPE_GCS)
            assert (await send(intruder, gcs_hb, 1.0)).foreign
            assert (await send(intruder, attitude(3), 1.5)).foreign
            assert link.peers.peers_for(3) == [home.getsockname()]
            # Heartbeats from the intruder while home is silent, but too early: foreign.
            for t in (6.0, 7.0, 8.0):
                assert (await send(intruder, heartbeat(3), t)).foreign
            assert link.counters.foreign == 5 and notices == []
            # Home silent for 10 s and three heartbeats over 2 s: the address moves.
            assert (await send(intruder, heartbeat(3), 10.0)).foreign is False
            assert link.peers.peers_for(3) == [intruder.getsockname()]
            assert notices and notices[0][0] == "peer_rebound"
            assert notices[0][1]["system_id"] == 3
            assert link.send(statustext(255, "moved"), 3)
            msg, _ = await recv_message(intruder)
            assert msg.text == "moved"
            # A system that never sent an autopilot heartbeat follows its last address.
            assert not (await send(home, heartbeat(200, mavlink2.MAV_TYPE_GCS), 11.0)).foreign
            assert not (await send(intruder, heartbeat(200, mavlink2.MAV_TYPE_GCS), 12.0)).foreign
            assert link.peers.peers_for(200) == [intruder.getsockname()]
        home.close()
        intruder.close()

    asyncio.run(main())


def test_a_reconnecting_tcp_link_keeps_its_binding(tmp_path: Path) -> None:
    async def main() -> None:
        clock = [0.0]
        router, delivered, notices = _router(tmp_path, clock)
        vehicle = FakeVehicle(sysid=1)
        port = await vehicle.start()
        fast = LinkOptions(reconnect_initial_s=0.02, reconnect_max_s=0.1, connect_timeout_s=1.0)
        tcp = open_link(f"tcp:127.0.0.1:{port}", link_id="sitl", options=fast)
        other = open_link("udpin:127.0.0.1:0", link_id="other")
        router.add_vehicle_link(tcp)
        router.add_vehicle_link(other)
        forger = udp_socket()
        async with router:
            assert isinstance(other, UdpInLink)
            await wait_until(lambda: len(delivered) == 1)
            assert router.link_for(1) is tcp
            await vehicle.crash()
            await wait_until(lambda: not tcp.connected)
            forger.sendto(heartbeat(1), other.local_address)  # during the outage
            await wait_until(lambda: other.counters.foreign == 1)
            await vehicle.start(port)  # same port: the link reconnects (new socket)
            clock[0] = 1.0
            await wait_until(lambda: len(delivered) == 2)
            assert tcp.counters.reconnects == 1
            assert router.link_for(1) is tcp and notices == []
            assert router.send_to(1, statustext(255, "after reconnect"))
            await wait_until(lambda: len(vehicle.received) == 1)
            assert vehicle.received[0].text == "after reconnect"
        router.tlog.close()  # type: ignore[union-attr]
        await vehicle.crash()
        forger.close()

    asyncio.run(main())
