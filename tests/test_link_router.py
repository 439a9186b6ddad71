"""Router: system id learning, targeted sends, broadcast, --out forwarding, tlog of all."""

from __future__ import annotations

import asyncio
from pathlib import Path

from link_fixtures import heartbeat, recv_one, statustext, udp_socket, wait_until

from groundstation.link import Received, Router, TlogReader, TlogWriter, open_link
from groundstation.link.udp import UdpInLink, UdpOutLink
from groundstation.mavlink.codec import MavlinkEncoder, mavlink2


def test_router_learns_system_ids_and_forwards_both_ways(tmp_path: Path) -> None:
    async def main() -> None:
        from_vehicles: list[Received] = []
        from_out: list[Received] = []
        tlog = TlogWriter(tmp_path / "flight.tlog")
        router = Router(
            on_vehicle_frame=from_vehicles.append, on_out_frame=from_out.append, tlog=tlog
        )
        fleet = open_link("udpin:127.0.0.1:0", link_id="fleet")
        lone = open_link("udpin:127.0.0.1:0", link_id="lone")
        qgc = udp_socket()  # another ground station listening, like QGroundControl
        out = open_link(f"udpout:127.0.0.1:{qgc.getsockname()[1]}", link_id="qgc")
        router.add_vehicle_link(fleet)
        router.add_vehicle_link(lone)
        router.add_out_link(out)
        v1, v2, v3 = udp_socket(), udp_socket(), udp_socket()
        async with router:
            assert isinstance(fleet, UdpInLink) and isinstance(lone, UdpInLink)
            # Two vehicles on one UDP link, a third on another.
            v1.sendto(heartbeat(1), fleet.local_address)
            v2.sendto(heartbeat(2), fleet.local_address)
            v3.sendto(heartbeat(3), lone.local_address)
            await wait_until(lambda: len(from_vehicles) == 3)
            assert router.routes == {1: fleet, 2: fleet, 3: lone}
            assert router.link_for(2) is fleet and router.link_for(9) is None

            # Every vehicle frame is copied, unchanged, to the out link.
            seen_by_qgc = {}
            for _ in range(3):
                msg, data, _ = await recv_one(qgc)
                seen_by_qgc[msg.get_srcSystem()] = data
            assert seen_by_qgc == {rx.system_id: rx.raw for rx in from_vehicles}
            assert router.counters.forwarded_to_out == 3

            # The daemon's own frames: one vehicle, then everyone.
            assert router.send_to(2, statustext(255, "to two"))
            assert router.send_to(9, statustext(255, "nobody")) is False
            assert router.broadcast(heartbeat(255, mavlink2.MAV_TYPE_GCS)) == 2
            m, _, _ = await recv_one(v2)
            assert m.text == "to two"
            for v in (v1, v2, v3):
                m, _, _ = await recv_one(v)
                assert m.get_type() == "HEARTBEAT"

            # Commands from the other ground station reach the vehicle they target.
            gcs = MavlinkEncoder(255, 190)
            arm = gcs.encode(gcs.mav.command_long_encode(3, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
            upload = gcs.encode(gcs.mav.mission_count_encode(1, 1, 4, 0))
            gcs_hb = heartbeat(250, mavlink2.MAV_TYPE_GCS)
            assert isinstance(out, UdpOutLink)
            qgc_addr = out.local_address
            qgc.sendto(arm, qgc_addr)
            qgc.sendto(upload, qgc_addr)
            qgc.sendto(gcs_hb, qgc_addr)
            await wait_until(lambda: len(from_out) == 3)
            m, data, _ = await recv_one(v3)
            assert data == arm
            m, data, _ = await recv_one(v1)
            assert data == upload
            for v in (v1, v2, v3):  # no target: every vehicle
                m, data, _ = await recv_one(v)
                assert data == gcs_hb
            assert [rx.message.get_type() for rx in from_out] == [
                "COMMAND_LONG",
                "MISSION_COUNT",
                "HEARTBEAT",
            ]
            assert router.counters.passed_to_vehicles == 3
            # Frames from the out link never become routes to vehicles.
            assert 250 not in router.routes and 255 not in router.routes
        tlog.close()

        # The tlog holds everything: 3 vehicle frames, 2 own frames sent, 3 from QGC.
        records = list(TlogReader(tmp_path / "flight.tlog"))
        assert [r.message.get_type() for r in records] == [
            "HEARTBEAT",
            "HEARTBEAT",
            "HEARTBEAT",
            "STATUSTEXT",
            "HEARTBEAT",
            "COMMAND_LONG",
            "MISSION_COUNT",
            "HEARTBEAT",
        ]
        # Link numbers: vehicle frames by link (fleet 0, lone 1), everything sent 3.
        by_vehicle = {r.message.get_srcSystem(): r.link_number for r in records[:3]}
        assert by_vehicle == {1: 0, 2: 0, 3: 1}
        assert [r.link_number for r in records[3:]] == [3, 3, 3, 3, 3]
        for s in (qgc, v1, v2, v3):
            s.close()

    asyncio.run(main())


def test_router_start_failure_stops_links_already_started() -> None:
    async def main() -> None:
        first = open_link("udpin:127.0.0.1:0")
        router = Router()
        router.add_vehicle_link(first)
        taken = udp_socket()
        router.add_vehicle_link(open_link(f"udpin:127.0.0.1:{taken.getsockname()[1]}"))
        try:
            await router.start()
        except Exception as exc:
            assert "cannot listen" in str(exc)
        else:
            raise AssertionError("start should fail")
        assert not first.running
        taken.close()

    asyncio.run(main())
