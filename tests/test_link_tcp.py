"""TCP links over 127.0.0.1 with ephemeral ports: reconnect with back-off, many clients."""

from __future__ import annotations

import asyncio
import socket
from typing import Any

import pytest
from link_fixtures import TIMEOUT_S, FakeVehicle, heartbeat, statustext, wait_until

from groundstation.link import LinkError, LinkOptions, Received, open_link
from groundstation.link.base import Backoff
from groundstation.link.tcp import TcpClientLink, TcpServerLink
from groundstation.mavlink.codec import MavlinkDecoder

FAST = LinkOptions(reconnect_initial_s=0.02, reconnect_max_s=0.1, connect_timeout_s=1.0)


def test_tcp_client_reconnects_after_the_server_restarts() -> None:
    async def main() -> None:
        vehicle = FakeVehicle(sysid=1)
        port = await vehicle.start()
        got: list[Received] = []
        link = open_link(f"tcp:127.0.0.1:{port}", on_receive=got.append, options=FAST)
        assert isinstance(link, TcpClientLink)
        async with link:
            await wait_until(lambda: len(got) == 1)
            assert got[0].system_id == 1 and link.connected
            assert link.send(statustext(255, "hello"))
            await wait_until(lambda: len(vehicle.received) == 1)
            assert vehicle.received[0].text == "hello"

            await vehicle.crash()
            await wait_until(lambda: not link.connected)
            assert link.send(statustext(255, "into the void")) is False
            assert link.counters.frames_dropped == 1
            await asyncio.sleep(0.15)  # a few refused attempts while the vehicle is down
            assert link.counters.reconnects == 0

            await vehicle.start(port)  # same port, like a restarted SITL
            await wait_until(lambda: len(got) == 2)
            assert link.connected
            assert link.counters.connects == 2 and link.counters.reconnects == 1
            assert link.send(statustext(255, "again"))
            await wait_until(lambda: len(vehicle.received) == 2)
            assert vehicle.received[1].text == "again"
        assert not link.connected
        await vehicle.crash()

    asyncio.run(main())


def test_tcp_client_waits_for_a_server_that_is_not_there_yet() -> None:
    async def main() -> None:
        vehicle = FakeVehicle(sysid=4)
        port = await vehicle.start()
        await vehicle.crash()  # the port is now free: nothing listens
        got: list[Received] = []
        link = open_link(f"tcp:127.0.0.1:{port}", on_receive=got.append, options=FAST)
        await link.start()  # returns at once; connects in the background
        assert link.running and not link.connected
        await asyncio.sleep(0.1)
        await vehicle.start(port)
        await wait_until(lambda: len(got) == 1)
        assert link.counters.connects == 1 and link.counters.reconnects == 0
        await link.stop()
        await vehicle.crash()

    asyncio.run(main())


def test_backoff_doubles_caps_and_resets() -> None:
    b = Backoff(0.5, 3.0)
    assert [b.next_delay_s() for _ in range(5)] == [0.5, 1.0, 2.0, 3.0, 3.0]
    b.reset()
    assert b.next_delay_s() == 0.5


def test_tcpin_serves_two_clients_and_replies_per_system_id() -> None:
    async def main() -> None:
        got: list[Received] = []
        link = open_link("tcpin:127.0.0.1:0", on_receive=got.append)
        assert isinstance(link, TcpServerLink)
        async with link:
            host, port = link.local_address
            r1, w1 = await asyncio.open_connection(host, port)
            r2, w2 = await asyncio.open_connection(host, port)
            await wait_until(lambda: link.client_count == 2)
            w1.write(heartbeat(1))
            w2.write(heartbeat(2))
            await wait_until(lambda: len(got) == 2)
            assert {rx.system_id for rx in got} == {1, 2}
            assert got[0].peer != got[1].peer

            assert link.send(statustext(255, "for two"), 2)
            assert link.send(statustext(255, "for all"))
            d1, d2 = MavlinkDecoder(), MavlinkDecoder()

            async def read_texts(
                reader: asyncio.StreamReader, dec: MavlinkDecoder, n: int
            ) -> list[str]:
                texts: list[str] = []
                while len(texts) < n:
                    data = await asyncio.wait_for(reader.read(4096), TIMEOUT_S)
                    msgs: list[Any] = dec.feed(data)
                    texts.extend(m.text for m in msgs)
                return texts

            assert await read_texts(r1, d1, 1) == ["for all"]
            assert await read_texts(r2, d2, 2) == ["for two", "for all"]

            # Client 2 leaves: it is forgotten, client 1 keeps working.
            w2.close()
            await wait_until(lambda: link.client_count == 1)
            assert 2 not in link.peers.by_system
            assert link.send(statustext(255, "still here"), 1)
            assert await read_texts(r1, d1, 1) == ["still here"]
            assert link.counters.connects == 2
            w1.close()

    asyncio.run(main())


def test_tcpin_on_a_taken_port_is_a_link_error() -> None:
    async def main() -> None:
        first = open_link("tcpin:127.0.0.1:0")
        assert isinstance(first, TcpServerLink)
        async with first:
            port = first.local_address[1]
            second = open_link(f"tcpin:127.0.0.1:{port}")
            with pytest.raises(LinkError, match="cannot listen on TCP"):
                await second.start()

    asyncio.run(main())


def test_a_server_that_drops_every_connection_does_not_make_the_client_spin() -> None:
    async def main() -> None:
        accepted = 0

        async def drop(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
            nonlocal accepted
            accepted += 1
            writer.transport.abort()

        server = await asyncio.start_server(drop, "127.0.0.1", 0)
        port = server.sockets[0].getsockname()[1]
        link = open_link(f"tcp:127.0.0.1:{port}", options=FAST)
        async with link:
            await asyncio.sleep(0.4)
        server.close()
        await server.wait_closed()
        # Back-off 0.02, 0.04, 0.08, then 0.1 s: about 6 attempts in 0.4 s, not 20.
        assert 2 <= accepted <= 8
        assert link.counters.connects == accepted
        assert link.counters.reconnects == accepted - 1

    asyncio.run(main())


def test_client_socket_has_keepalive() -> None:
    async def main() -> None:
        vehicle = FakeVehicle(sysid=1)
        port = await vehicle.start()
        link = open_link(f"tcp:127.0.0.1:{port}", options=FAST)
        assert isinstance(link, TcpClientLink)
        async with link:
            await wait_until(lambda: link.connected)
            assert link._proto is not None and link._proto.transport is not None
            sock = link._proto.transport.get_extra_info("socket")
            assert sock.getsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE) == 1
            if hasattr(socket, "TCP_USER_TIMEOUT"):
                assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_USER_TIMEOUT) == 30_000
        await vehicle.crash()

    asyncio.run(main())


@pytest.mark.parametrize("closing", [False, True])
def test_a_peer_closing_while_the_owner_shuts_down_is_not_a_lost_link(
    closing: bool, caplog: pytest.LogCaptureFixture
) -> None:
    """The embedded simulator closes its TCP ports as ``gcs run`` stops: after
    ``begin_close`` that is no lost link: nothing logged, no reconnect attempt."""
    connects: list[int] = []

    async def main() -> None:
        vehicle = FakeVehicle(sysid=2)
        port = await vehicle.start()
        got: list[Received] = []
        link = open_link(f"tcp:127.0.0.1:{port}", on_receive=got.append, options=FAST)
        async with link:
            await wait_until(lambda: len(got) == 1)
            if closing:
                link.begin_close()
            await vehicle.crash()
            await wait_until(lambda: not link.connected)
            await asyncio.sleep(0.2)  # a reconnect (FAST back-off) would have been tried
            connects.append(link.counters.connects)

    with caplog.at_level("INFO", logger="groundstation.link"):
        asyncio.run(main())
    lost = [r for r in caplog.records if "lost TCP" in r.getMessage()]
    tried = [r for r in caplog.records if "cannot open" in r.getMessage()]
    if closing:
        assert not lost and not tried and connects == [1]
    else:
        assert len(lost) == 1 and lost[0].levelname == "WARNING"
