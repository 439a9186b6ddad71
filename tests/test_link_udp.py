"""UDP links over 127.0.0.1 with ephemeral ports: receive, reply per system id, errors."""

from __future__ import annotations

import asyncio
import time

import pytest
from link_fixtures import TIMEOUT_S, heartbeat, recv_message, statustext, udp_socket, wait_until

from groundstation.link import LinkError, LinkOptions, Received, open_link
from groundstation.link.udp import UdpInLink, UdpOutLink
from groundstation.mavlink.codec import mavlink2


def test_udpin_receives_and_replies_to_each_system_id() -> None:
    async def main() -> None:
        got: list[Received] = []
        link = open_link("udpin:127.0.0.1:0", link_id="veh", on_receive=got.append)
        assert isinstance(link, UdpInLink)
        a, b = udp_socket(), udp_socket()
        async with link:
            addr = link.local_address
            assert addr[0] == "127.0.0.1" and addr[1] != 0
            assert not link.connected
            # Nobody heard yet: nowhere to send.
            assert link.send(heartbeat(255)) is False
            frame_a, frame_b = heartbeat(1), heartbeat(2)
            t0 = time.time()
            a.sendto(frame_a, addr)
            b.sendto(frame_b, addr)
            await wait_until(lambda: len(got) == 2)
            by_sys = {rx.system_id: rx for rx in got}
            assert by_sys[1].raw == frame_a and by_sys[2].raw == frame_b
            assert by_sys[1].peer == a.getsockname() and by_sys[2].peer == b.getsockname()
            assert all(rx.link_id == "veh" for rx in got)
            assert all(rx.message.get_type() == "HEARTBEAT" for rx in got)
            assert all(t0 - 0.5 <= rx.t_unix_s <= time.time() + 0.5 for rx in got)
            assert link.connected

            # A frame for system 2 goes only to b; a broadcast goes to both.
            assert link.send(statustext(255, "for two"), 2)
            assert link.send(statustext(255, "for all"))
            msg, _ = await recv_message(a)
            assert msg.text == "for all"
            msg, _ = await recv_message(b)
            assert msg.text == "for two"
            msg, _ = await recv_message(b)
            assert msg.text == "for all"

            # A frame of system 2 from another address is foreign (issue 10.3): marked,
            # counted, and replies stay with the address system 2's autopilot is bound to.
            c = udp_socket()
            c.sendto(heartbeat(2), addr)
            await wait_until(lambda: len(got) == 3)
            assert got[-1].foreign and got[-1].peer == c.getsockname()
            assert link.send(statustext(255, "still b"), 2)
            msg, _ = await recv_message(b)
            assert msg.text == "still b"
            assert link.peers.all_peers() == [a.getsockname(), b.getsockname()]
            c.close()

            snap = link.snapshot()
            assert snap["link"] == "veh" and snap["url"] == "udpin:127.0.0.1:0"
            assert snap["connected"] is True and snap["frames_in"] == 3
            counters = link.counters
            assert counters.frames_in == 3 and counters.bad_frames == 0
            assert counters.foreign == 1
            assert counters.frames_out == 4  # "for two", "for all" x2, "still b"
            assert counters.frames_dropped == 1  # the first send, before any peer
            assert counters.bytes_in == 3 * len(frame_a)
        assert not link.running
        a.close()
        b.close()

    asyncio.run(main())


def test_udpout_sends_and_reads_replies() -> None:
    async def main() -> None:
        gcs = udp_socket()  # e.g. QGroundControl listening
        port = gcs.getsockname()[1]
        link = open_link(f"udpout:127.0.0.1:{port}")
        assert isinstance(link, UdpOutLink)
        async with link:
            assert link.connected
            frame = heartbeat(1)
            assert link.send(frame, 42)  # the system id does not matter for udpout
            msg, src = await recv_message(gcs)
            assert msg.get_srcSystem() == 1
            assert src == link.local_address
            assert link.local_address[0] == "127.0.0.1"  # bound to loopback only
            # The other side answers to the address it saw.
            reply = heartbeat(255, mavlink2.MAV_TYPE_GCS)
            gcs.sendto(reply, src)
            rx = await asyncio.wait_for(anext(aiter(link.frames())), TIMEOUT_S)
            assert rx.raw == reply and rx.system_id == 255
            assert link.counters.frames_out == 1 and link.counters.frames_in == 1
        gcs.close()

    asyncio.run(main())


def test_udp_send_error_is_counted_not_raised() -> None:
    async def main() -> None:
        gcs = udp_socket()
        link = open_link(f"udpout:127.0.0.1:{gcs.getsockname()[1]}")
        async with link:
            # A datagram larger than UDP allows: the socket refuses it (EMSGSIZE).
            assert link.send(b"\xfd" * 70_000) is False
            assert link.counters.send_errors == 1
            assert link.counters.frames_out == 0
            # The link keeps working.
            assert link.send(heartbeat(1))
            msg, _ = await recv_message(gcs)
            assert msg.get_type() == "HEARTBEAT"
        gcs.close()

    asyncio.run(main())


def test_garbage_and_bad_crc_are_counted_not_raised() -> None:
    async def main() -> None:
        got: list[Received] = []

        def callback(rx: Received) -> None:
            got.append(rx)
            raise RuntimeError("a buggy consumer must not break the link")

        link = open_link("udpin:127.0.0.1:0", on_receive=callback)
        assert isinstance(link, UdpInLink)
        sender = udp_socket()
        async with link:
            addr = link.local_address
            good = heartbeat(7)
            bad_crc = bytearray(good)
            bad_crc[-1] ^= 0xFF
            sender.sendto(b"this is not mavlink at all", addr)
            sender.sendto(bytes(bad_crc), addr)
            sender.sendto(good, addr)
            sender.sendto(good, addr)
            await wait_until(lambda: len(got) == 2)
            assert [rx.raw for rx in got] == [good, good]
            assert link.counters.bad_frames == 2
            assert link.counters.bad_bytes >= len(b"this is not mavlink at all")
            assert link.counters.frames_in == 2
            # A start marker with a huge length must not swallow the next datagrams.
            sender.sendto(b"\xfd\xff" + good, addr)
            sender.sendto(good, addr)
            await wait_until(lambda: len(got) == 3)
            assert link.counters.bad_frames == 3
            assert link.counters.bad_bytes >= len(b"this is not mavlink at all") + 2
        sender.close()

    asyncio.run(main())


def test_frames_iterator_ends_on_stop_and_overflow_is_counted() -> None:
    async def main() -> None:
        link = open_link("udpin:127.0.0.1:0", options=LinkOptions(rx_queue_size=2))
        assert isinstance(link, UdpInLink)
        sender = udp_socket()
        await link.start()
        frames = link.frames()
        first = asyncio.ensure_future(anext(frames))
        await asyncio.sleep(0)  # the iterator creates its queue
        for _ in range(5):
            sender.sendto(heartbeat(3), link.local_address)
        rx = await asyncio.wait_for(first, TIMEOUT_S)
        assert rx.system_id == 3
        await wait_until(lambda: link.counters.frames_in == 5)
        # The iterator took one; two fit its queue. The five may be drained in one loop
        # turn (before the iterator ran: three overflow) or the first one alone (two).
        assert 2 <= link.counters.rx_overflow <= 3
        await link.stop()
        rest = [rx async for rx in frames]
        assert len(rest) <= 2  # what was queued (the stop marker may replace one), then end
        sender.close()

    asyncio.run(main())


def test_listening_on_a_taken_port_is_a_link_error() -> None:
    async def main() -> None:
        taken = udp_socket()
        link = open_link(f"udpin:127.0.0.1:{taken.getsockname()[1]}")
        with pytest.raises(LinkError, match=r"cannot listen on UDP 127\.0\.0\.1"):
            await link.start()
        assert not link.running
        taken.close()

    asyncio.run(main())


def test_the_old_inline_path_stays_selectable_for_benchmarks() -> None:
    async def main() -> None:
        got: list[Received] = []
        link = open_link(
            "udpin:127.0.0.1:0", on_receive=got.append, options=LinkOptions(fair=False)
        )
        assert isinstance(link, UdpInLink)
        sender = udp_socket()
        async with link:
            sender.sendto(heartbeat(4) + heartbeat(4), link.local_address)
            await wait_until(lambda: len(got) == 2)
            assert link.pending == 0 and link._drain_task is None  # decoded in the callback
            assert link.counters.frames_in == 2 and link.counters.rx_dropped == 0
        sender.close()

    asyncio.run(main())
