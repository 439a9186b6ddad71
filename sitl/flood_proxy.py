"""A TCP proxy in front of one vehicle that floods its link (trust tests, fuzz benchmark).

``python -m sitl.flood_proxy --upstream PORT [--rate 20000] [--at 5] [--for 3]`` listens on
127.0.0.1 (``--port``, default ephemeral), prints ``listening PORT`` and, for each client
(a ground station), connects to the vehicle at ``--upstream`` and relays both ways. From
``--at`` wall seconds after the first client connected, for ``--for`` seconds, it also
writes ``--rate`` frames per second towards the client, in bursts every 10 ms: with
``--mix flood`` benign ones (:func:`sitl.forge.flood_chunk`, system id ``--sysid``,
component ``--compid``); with ``--mix fuzz`` a seeded mixture of random bytes (20 %),
wrong-length frames with a valid CRC (20 %), random valid frames (40 %, from component
``--compid`` or other system ids) and forged state frames (20 %, ``--compid``). On exit
(stdin closed, or ``--exit-after`` seconds) it prints ``flood FRAMES SECONDS START_UNIX
END_UNIX``. A client that cannot keep up is not waited for beyond 1 MiB of backlog: the
excess is dropped and counted as not sent (the kernel and the link decide, as with radio).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import random
import sys
import time

from sitl.forge import (
    flood_chunk,
    forged_frames,
    random_bytes,
    random_valid_frame,
    wrong_length_frame,
)

__all__ = ["fuzz_pool", "main", "split_frames"]

_BURST_S = 0.01
_MAX_BACKLOG = 1 << 20


def split_frames(buf: bytes) -> tuple[bytes, bytes]:
    """(complete MAVLink frames and stray bytes, the incomplete frame at the end)."""
    i, n = 0, len(buf)
    while i < n:
        marker = buf[i]
        if marker == 0xFD:
            if i + 3 > n:
                break
            size = 12 + buf[i + 1] + (13 if buf[i + 2] & 1 else 0)
        elif marker == 0xFE:
            if i + 2 > n:
                break
            size = 8 + buf[i + 1]
        else:
            i += 1
            continue
        if i + size > n:
            break
        i += size
    return buf[:i], buf[i:]


def fuzz_pool(sysid: int, compid: int, seed: int, size: int = 4000) -> list[bytes]:
    """Pieces (one frame, or a few noise bytes, each) for ``--mix fuzz``."""
    rng = random.Random(seed)
    pool: list[bytes] = []
    forged = forged_frames(sysid, compid, seed=seed)
    while len(pool) < size:
        r = rng.random()
        if r < 0.2:
            pool.append(random_bytes(rng, rng.randrange(1, 60)))
        elif r < 0.4:
            pool.append(wrong_length_frame(rng, sysid, compid))
        elif r < 0.8:
            who = (sysid, compid) if rng.random() < 0.5 else (rng.randrange(2, 250), 1)
            pool.append(random_valid_frame(rng, *who))
        else:
            pool.append(rng.choice(forged))
    return pool


class _Proxy:
    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        self.clients: list[asyncio.StreamWriter] = []
        self.first_client = asyncio.get_running_loop().create_future()
        self.sent = 0
        self.start_unix = 0.0
        self.end_unix = 0.0

    async def handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            up_r, up_w = await asyncio.open_connection("127.0.0.1", self.args.upstream)
        except OSError:
            writer.close()
            return
        self.clients.append(writer)
        if not self.first_client.done():
            self.first_client.set_result(time.monotonic())

        async def pump(src: asyncio.StreamReader, dst: asyncio.StreamWriter, framed: bool) -> None:
            pending = b""
            with contextlib.suppress(OSError, ConnectionError):
                while data := await src.read(65536):
                    if framed:  # whole frames only, so flood bursts never split one
                        whole, pending = split_frames(pending + data)
                        data = whole
                    dst.write(data)
                    await dst.drain()
            dst.close()

        await asyncio.gather(pump(reader, up_w, False), pump(up_r, writer, True))
        if writer in self.clients:
            self.clients.remove(writer)

    async def flood(self) -> None:
        args = self.args
        t0 = await self.first_client
        await asyncio.sleep(max(0.0, t0 + args.at - time.monotonic()))
        per_burst = max(1, round(args.rate * _BURST_S))
        if args.mix == "fuzz":
            pool = fuzz_pool(args.sysid, args.compid, args.seed)
            chunks = [
                b"".join(pool[(k * per_burst + i) % len(pool)] for i in range(per_burst))
                for k in range(max(1, len(pool) // per_burst))
            ]
        else:
            chunks = [flood_chunk(args.sysid, args.compid, per_burst)]
        burst = 0
        start = time.monotonic()
        self.start_unix = time.time()
        next_t = start
        while time.monotonic() - start < args.duration:
            for w in list(self.clients):
                if w.is_closing():
                    continue
                if w.transport.get_write_buffer_size() < _MAX_BACKLOG:
                    w.write(chunks[burst % len(chunks)])
                    self.sent += per_burst
            burst += 1
            next_t += _BURST_S
            await asyncio.sleep(max(0.0, next_t - time.monotonic()))
        self.end_unix = time.time()


async def _amain(args: argparse.Namespace) -> None:
    proxy = _Proxy(args)
    server = await asyncio.start_server(proxy.handle, "127.0.0.1", args.port)
    print(f"listening {server.sockets[0].getsockname()[1]}", flush=True)
    flood = asyncio.create_task(proxy.flood())
    loop = asyncio.get_running_loop()
    if args.exit_after > 0:
        await asyncio.sleep(args.exit_after)
    else:  # until stdin closes (the parent ends)
        await loop.run_in_executor(None, sys.stdin.read)
    flood.cancel()
    server.close()
    span = max(0.0, proxy.end_unix - proxy.start_unix)
    print(f"flood {proxy.sent} {span:.3f} {proxy.start_unix:.3f} {proxy.end_unix:.3f}", flush=True)


def main(argv: list[str] | None = None) -> int:
    """Run the proxy (see the module docstring)."""
    p = argparse.ArgumentParser(allow_abbrev=False, prog="python -m sitl.flood_proxy",
                                description=__doc__)
    p.add_argument("--upstream", type=int, required=True, help="the vehicle's TCP port")
    p.add_argument("--port", type=int, default=0, help="port to listen on (0: ephemeral)")
    p.add_argument("--rate", type=float, default=20_000.0, help="flood frames per second")
    p.add_argument("--at", type=float, default=5.0, help="flood start, s after first client")
    p.add_argument("--for", dest="duration", type=float, default=3.0, help="flood seconds")
    p.add_argument("--sysid", type=int, default=1)
    p.add_argument("--compid", type=int, default=191)
    p.add_argument("--mix", choices=("flood", "fuzz"), default="flood")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--exit-after", type=float, default=0.0, help="seconds (0: stdin EOF)")
    args = p.parse_args(argv)
    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(_amain(args))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
