"""asyncio server for the built-in vehicles: TCP per vehicle, shared UDP, simulated clock.

* Vehicle i listens on TCP ``host:(base_port + 10 i)`` (``base_port`` 0: each vehicle binds
  an ephemeral port; :attr:`SitlServer.tcp_ports` tells which). Several clients may connect;
  every client gets everything the vehicle sends.
* With ``out`` set, one UDP socket (ephemeral port) is shared by all vehicles: each sends
  to ``out`` and to every address that has sent a datagram to the socket ("UDP replies go to
  whoever sent"); ground stations tell vehicles apart by system id. Incoming UDP messages
  go to the vehicle named by ``target_system`` (0 or none: all vehicles).
* The simulated clock advances ``speedup`` times the wall clock, by at most
  max(``max_step_s``, ``speedup * max_stall_s``) per tick (0.5 s, or 0.1 wall seconds'
  worth), so an overloaded or stalled host slows simulated time instead of making it jump
  (the achieved real-time factor is :attr:`SitlServer.realtime_factor`).
* ``wait_for_client``: a vehicle boots only when its first TCP client connects (as
  ArduPilot SITL does); otherwise all boot at once.
* Faults (:mod:`sitl.faults`) sit between the sockets and each vehicle. While a vehicle is
  dead (a ``kill`` fault) its TCP clients are disconnected and new ones closed at once, as
  when an ArduPilot SITL process dies.
* Answers addressed to the requester (a non-zero ``target_system``: COMMAND_ACK, mission
  protocol replies) go back only on the link the request came from (the TCP client, or the
  UDP address), as ArduPilot answers on the requesting channel; everything else (telemetry,
  STATUSTEXT, PARAM_VALUE, MISSION_CURRENT, the upload's timed re-requests) goes to every
  link of the vehicle.
* Signing (:mod:`sitl.signing_endpoint`): ``signing_keys`` gives vehicles a key at start;
  SETUP_SIGNING installs one. A vehicle with a key drops (and counts) what fails the
  MAVLink 2 signature check before its faults and autopilot see it, and signs all it sends.
* An optional feed (:class:`sitl.detections.DetectionSource`-like: ``step(t_s, positions)``
  returning datagrams) is given each vehicle's local position and its datagrams are sent
  to ``feed_address``.
* Radios (:mod:`sitl.radio`): ``radios`` gives vehicles a pair of SiK telemetry radios.
  Such a vehicle's link is then one serial channel, as over a real radio: what it sends
  (signed, as it would be) enters its radio's serial port, crosses the air in TDM slots and
  comes out of the ground radio to every TCP client and UDP peer; the frames its TCP
  clients and UDP peers send are merged into the ground radio's serial port, cross the
  air, and are decoded on the vehicle's side (answers go back through the radio to every
  client: one channel). The radios run on the simulated clock inside each tick: the vehicle
  steps every 0.1 s of it, and hears each frame at the moment the radio delivers it, so the
  link's timing does not depend on the speed-up. The radios' RADIO_STATUS (system 51)
  reach the ground station and the vehicle. :meth:`SitlServer.radio_stats` gives each
  link's figures. Without ``radios`` nothing changes, byte for byte.
* The simulator's journal: what the vehicles record (:class:`sitl.vehicle.SimEvent`: a
  battery run flat, a fall, a recovery on deck, a turnaround) is collected in
  :attr:`SitlServer.events` and logged on the ``sitl.events`` logger (printed on stdout as
  ``sitl: ...`` when logging is not configured, as under ``gcs sitl``).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from domain.radio_spec import RadioSpec
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder
from sitl.faults import VehicleFaults
from sitl.radio import RadioEnd, SikRadioPair
from sitl.ship import describe_watch
from sitl.signing_endpoint import VehicleSigning
from sitl.vehicle import SimEvent, SimVehicle, VehicleConfig

__all__ = ["Feed", "ServerOptions", "SitlServer"]

_MAX_CLIENT_BUFFER = 1 << 20
_EVENTS = logging.getLogger("sitl.events")
_RADIO = "radio"
"""The origin of what a vehicle hears through its radio (one channel: answers to all)."""
VEHICLE_STEP_S = 0.1
"""With a radio, the vehicle steps at most this far at once (its physics step)."""


class Feed(Protocol):
    """Something fed with the vehicles' positions that emits UDP datagrams."""

    def step(self, t_s: float, positions: dict[int, tuple[float, float]]) -> list[bytes]:
        """Datagrams to send after advancing to ``t_s``."""
        ...


@dataclass
class ServerOptions:
    """Sockets and clock of a :class:`SitlServer`."""

    speedup: float = 1.0
    host: str = "127.0.0.1"
    base_port: int = 5760
    out: tuple[str, int] | None = None
    wait_for_client: bool = False
    tick_s: float = 0.01
    max_step_s: float = 0.5
    max_stall_s: float = 0.1
    feed_address: tuple[str, int] | None = None
    signing_keys: dict[int, bytes] = field(default_factory=dict, repr=False)
    """Key per system id the vehicles start with (no entry: unsigned until SETUP_SIGNING)."""
    radios: dict[int, RadioSpec] = field(default_factory=dict)
    """A SiK radio pair per system id on its link (no entry: plain sockets)."""
    radio_seed: int = 0
    """Vehicle ``sysid``'s radio loss is seeded ``radio_seed * 1000 + sysid`` (unless its
    spec has a seed)."""


@dataclass
class _Slot:
    index: int
    config: VehicleConfig
    faults: VehicleFaults
    encoder: MavlinkEncoder
    signing: VehicleSigning
    vehicle: SimVehicle | None = None
    server: asyncio.Server | None = None
    port: int = 0
    clients: set[asyncio.StreamWriter] = field(default_factory=set)
    events_seen: int = 0
    radio: SikRadioPair | None = None
    radio_decoder: MavlinkDecoder = field(default_factory=MavlinkDecoder)


class _Udp(asyncio.DatagramProtocol):
    def __init__(self, on_datagram: Callable[[bytes, Any], None]) -> None:
        self._on = on_datagram

    def datagram_received(self, data: bytes, addr: Any) -> None:
        self._on(data, addr)

    def error_received(self, exc: Exception) -> None:  # e.g. ICMP port unreachable
        pass


class SitlServer:
    """Serves N :class:`SimVehicle` over TCP/UDP in simulated time."""

    def __init__(
        self,
        configs: list[VehicleConfig],
        options: ServerOptions,
        faults: dict[int, VehicleFaults] | None = None,
        feed: Feed | None = None,
    ) -> None:
        faults = faults or {}
        self.options = options
        self.feed = feed
        self.slots = [
            _Slot(
                i,
                c,
                faults.get(c.system_id) or VehicleFaults(c.system_id),
                MavlinkEncoder(c.system_id, c.component_id),
                VehicleSigning.with_key(
                    c.system_id, options.signing_keys.get(c.system_id), time.time()
                ),
            )
            for i, c in enumerate(configs)
        ]
        for slot in self.slots:
            spec = options.radios.get(slot.config.system_id)
            if spec is not None:
                seed = options.radio_seed * 1000 + slot.config.system_id
                slot.radio = SikRadioPair(spec, seed, 0.0)
        self.t_s = 0.0
        self._wall0 = 0.0
        self._last_wall = 0.0
        self._udp: asyncio.DatagramTransport | None = None
        self._feed_udp: asyncio.DatagramTransport | None = None
        self._udp_peers: dict[Any, None] = {}
        self._udp_decoders: dict[Any, MavlinkDecoder] = {}
        self._stop = asyncio.Event()
        self._behind = False
        self.bytes_out = 0
        self.messages_in = 0
        self.bad_frames = 0
        self.udp_port: int | None = None
        self.events: list[SimEvent] = []
        """Every vehicle's recorded events, in the order the simulator saw them."""

    # ----------------------------------------------------------------- setup
    @property
    def tcp_ports(self) -> list[int]:
        """Actual TCP port of each vehicle (after :meth:`start`)."""
        return [s.port for s in self.slots]

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per wall second since start."""
        wall = time.monotonic() - self._wall0
        return self.t_s / wall if wall > 0 else 0.0

    def vehicles(self) -> list[SimVehicle]:
        """The booted vehicles."""
        return [s.vehicle for s in self.slots if s.vehicle is not None]

    async def start(self) -> None:
        """Bind every socket and boot the vehicles (unless waiting for clients)."""
        opts = self.options
        loop = asyncio.get_running_loop()
        for slot in self.slots:
            port = opts.base_port + 10 * slot.index if opts.base_port else 0
            slot.server = await asyncio.start_server(self._client_handler(slot), opts.host, port)
            slot.port = slot.server.sockets[0].getsockname()[1]
        if opts.out is not None:
            transport, _ = await loop.create_datagram_endpoint(
                lambda: _Udp(self._on_udp), local_addr=(opts.host, 0)
            )
            self._udp = transport
            self.udp_port = transport.get_extra_info("sockname")[1]
            self._udp_peers[opts.out] = None
        if self.feed is not None and opts.feed_address is not None:
            transport, _ = await loop.create_datagram_endpoint(
                lambda: _Udp(lambda d, a: None), remote_addr=opts.feed_address
            )
            self._feed_udp = transport
        self._wall0 = self._last_wall = time.monotonic()
        if not opts.wait_for_client:
            for slot in self.slots:
                self._boot(slot)

    def describe(self) -> list[str]:
        """What is served, one line per endpoint."""
        host = self.options.host
        lines = [
            f"vehicle {s.index} (system id {s.config.system_id}): tcp:{host}:{s.port}"
            for s in self.slots
        ]
        if self.options.out is not None:
            lines.append(
                f"all vehicles -> udp:{self.options.out[0]}:{self.options.out[1]} "
                f"(from udp:{host}:{self.udp_port})"
            )
        if self._feed_udp is not None and self.options.feed_address is not None:
            addr = self.options.feed_address
            lines.append(f"detection feed -> udp:{addr[0]}:{addr[1]}")
        lines += self.describe_radios()
        if self.slots:
            c = self.slots[0].config
            lines += describe_watch(c.battery, c.ship, c.watch)
        lines.append(
            f"speed-up {self.options.speedup:g}x"
            + (", vehicles boot when a TCP client connects" if self.options.wait_for_client else "")
        )
        return lines

    def describe_radios(self) -> list[str]:
        """One line per distinct radio: which vehicles' links go through it."""
        groups: dict[RadioSpec, list[int]] = {}
        for s in self.slots:
            if s.radio is not None:
                groups.setdefault(s.radio.spec, []).append(s.config.system_id)
        if not groups:
            return []
        every = len(self.slots)
        return [
            f"radio: {spec.describe()} "
            + ("on every vehicle link" if len(ids) == every
               else "on vehicle " + ", ".join(map(str, ids)))
            for spec, ids in groups.items()
        ]

    def radio_stats(self) -> dict[int, dict[str, Any]]:
        """Each radio link's figures by system id (:meth:`SikRadioPair.summary`: per
        direction bytes offered/carried/dropped, packets lost, air time %, latency)."""
        return {s.config.system_id: s.radio.summary() for s in self.slots if s.radio}

    def _boot(self, slot: _Slot) -> None:
        if slot.vehicle is None:
            slot.vehicle = SimVehicle(slot.config, self.t_s)

    # ------------------------------------------------------------------ I/O
    def _client_handler(
        self, slot: _Slot
    ) -> Callable[[asyncio.StreamReader, asyncio.StreamWriter], Any]:
        async def handler(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
            await self._serve_client(slot, reader, writer)

        return handler

    async def _serve_client(
        self, slot: _Slot, reader: asyncio.StreamReader, writer: asyncio.StreamWriter
    ) -> None:
        if slot.vehicle is not None and not slot.vehicle.alive:
            writer.close()  # the autopilot process is dead: nobody answers
            return
        slot.clients.add(writer)
        self._boot(slot)
        decoder = MavlinkDecoder()
        try:
            while not self._stop.is_set():
                data = await reader.read(65536)
                if not data:
                    break
                msgs = decoder.feed(data)
                self.bad_frames = max(self.bad_frames, decoder.bad_frames)
                if slot.radio is not None:  # into the ground radio's serial port
                    for msg in msgs:
                        slot.radio.write(RadioEnd.GROUND, bytes(msg.get_msgbuf()), self.t_s)
                    continue
                for msg in msgs:
                    self._inbound(slot, msg, writer)
                self._service(slot)
        except (ConnectionError, OSError):
            pass
        finally:
            slot.clients.discard(writer)
            writer.close()

    def _on_udp(self, data: bytes, addr: Any) -> None:
        self._udp_peers[addr] = None
        decoder = self._udp_decoders.setdefault(addr, MavlinkDecoder())
        for msg in decoder.feed(data):
            target = getattr(msg, "target_system", 0) or 0
            for slot in self.slots:
                if slot.vehicle is not None and target in (0, slot.config.system_id):
                    if slot.radio is not None:
                        slot.radio.write(RadioEnd.GROUND, bytes(msg.get_msgbuf()), self.t_s)
                    else:
                        self._inbound(slot, msg, ("udp", addr))
        for slot in self.slots:
            if slot.radio is None:
                self._service(slot)

    def _inbound(self, slot: _Slot, msg: Any, origin: Any, t_s: float | None = None) -> None:
        self.messages_in += 1
        if not slot.signing.admit(bytes(msg.get_msgbuf()), time.time()):
            return
        if msg.get_type() == "SETUP_SIGNING":
            vehicle = slot.vehicle
            armed = vehicle is not None and bool(vehicle.autopilot.armed)
            if slot.signing.setup(msg, armed):
                return
        slot.faults.send_up((msg, origin), self.t_s if t_s is None else t_s)

    def signing_rejected(self) -> dict[int, dict[str, int]]:
        """Frames each vehicle dropped for failing the signature check, by reason."""
        return {s.config.system_id: dict(s.signing.rejected) for s in self.slots}

    def _service(self, slot: _Slot, t_s: float | None = None) -> None:
        """Deliver due uplink messages, run due faults, flush due downlink messages (at
        ``t_s``, default the server's time)."""
        vehicle = slot.vehicle
        if vehicle is None:
            return
        t = self.t_s if t_s is None else t_s
        out: list[Any] = []
        for event in slot.faults.due_events(t):
            out += vehicle.apply_fault(event, t)
        self._downlink(slot, out, None, t)
        for msg, origin in slot.faults.up.pop_due(t):
            # answers addressed to the requester (COMMAND_ACK, mission protocol) go back on
            # the link the request came from, as ArduPilot does; the rest to every link
            replies = vehicle.receive(msg, t)
            self._downlink(slot, replies, origin, t)

    def _downlink(
        self, slot: _Slot, msgs: list[Any], origin: Any = None, t_s: float | None = None
    ) -> None:
        t = self.t_s if t_s is None else t_s
        if origin is None:
            sent = [(msg, None) for msg in msgs]
        else:
            sent = [(msg, origin if getattr(msg, "target_system", 0) else None) for msg in msgs]
        run: list[bytes] = []  # consecutive frames to one destination: sent together
        run_dest: Any = None
        for msg, dest in slot.faults.pass_down(sent, t):
            try:
                data = slot.encoder.encode(msg)
            except Exception:  # a message that cannot be packed is dropped, never fatal
                continue
            if slot.signing.active:
                data = slot.signing.sign(data, time.time())
            if slot.radio is not None:  # into the vehicle radio's serial port
                slot.radio.write(RadioEnd.VEHICLE, data, t)
                continue
            if run and dest is not run_dest:
                self._send(slot, run, run_dest)
                run = []
            run.append(data)
            run_dest = dest
        if run:
            self._send(slot, run, run_dest)

    def _send(self, slot: _Slot, frames: list[bytes], dest: Any = None) -> None:
        """Send ``frames``, in order, to ``dest`` (None: every link of the vehicle). Each
        UDP datagram is one frame; a TCP client gets them in one write (fewer system calls,
        the same byte stream) when its buffer has room for them all (so that each frame
        would have passed the buffer check alone), else frame by frame, each checked."""
        if dest is not None:  # one link only
            if isinstance(dest, tuple):
                if self._udp is not None:
                    for data in frames:
                        self._udp.sendto(data, dest[1])
                        self.bytes_out += len(data)
            elif not dest.is_closing():
                data = b"".join(frames)
                dest.write(data)
                self.bytes_out += len(data)
            return
        joined = frames[0] if len(frames) == 1 else b"".join(frames)
        for writer in list(slot.clients):
            if writer.is_closing():
                slot.clients.discard(writer)
                continue
            self._write_checked(writer, frames, joined)
        udp = self._udp
        if udp is None or not self._udp_peers:
            return
        udp_backlog = getattr(udp, "get_write_buffer_size", None)
        for data in frames:
            if udp_backlog is None or udp_backlog() < _MAX_CLIENT_BUFFER:
                for peer in self._udp_peers:
                    udp.sendto(data, peer)
                    self.bytes_out += len(data)

    def _write_checked(self, writer: Any, frames: list[bytes], joined: bytes) -> None:
        """Write the frames a TCP client's buffer takes: each one while the buffer holds
        less than ``_MAX_CLIENT_BUFFER`` (a write grows it by at most its length, so with
        room for them all, one write of ``joined`` sends exactly those frames)."""
        if writer.transport.get_write_buffer_size() + len(joined) < _MAX_CLIENT_BUFFER:
            writer.write(joined)
            self.bytes_out += len(joined)
            return
        for data in frames:
            if writer.transport.get_write_buffer_size() < _MAX_CLIENT_BUFFER:
                writer.write(data)
                self.bytes_out += len(data)

    # ------------------------------------------------------------------ loop
    def tick(self, end_s: float | None = None) -> None:
        """Advance the simulated clock to now, never past ``end_s`` (simulated s), and run
        every vehicle and the feed."""
        now = time.monotonic()
        speedup = self.options.speedup
        cap_s = max(self.options.max_step_s, speedup * self.options.max_stall_s)
        want_s = (now - self._last_wall) * speedup
        self._behind = want_s > cap_s
        self._last_wall = now
        t_s = self.t_s + min(want_s, cap_s)
        self.advance(t_s if end_s is None else min(t_s, end_s))

    def advance(self, t_s: float) -> None:
        """Run every vehicle, radio and the feed to simulated time ``t_s`` (never back)."""
        self.t_s = max(self.t_s, t_s)
        for slot in self.slots:
            if slot.radio is not None:
                self._tick_radio(slot, slot.radio, self.t_s)
            if slot.vehicle is None:
                continue
            if slot.radio is None:
                self._service(slot)
                self._downlink(slot, slot.vehicle.step(self.t_s))
            self._journal(slot)
            if not slot.vehicle.alive:
                for writer in list(slot.clients):
                    writer.close()
                slot.clients.clear()
        if self.feed is not None:
            positions = {
                s.config.system_id: (s.vehicle.airframe.x_m, s.vehicle.airframe.y_m)
                for s in self.slots
                if s.vehicle is not None and not s.vehicle.airframe.on_ground
            }
            for datagram in self.feed.step(self.t_s, positions):
                if self._feed_udp is not None:
                    self._feed_udp.sendto(datagram)

    def _tick_radio(self, slot: _Slot, radio: SikRadioPair, t_end_s: float) -> None:
        """Run a radio link to ``t_end_s``: the vehicle steps every
        :data:`VEHICLE_STEP_S`, and hears what its radio delivers when it delivers it."""
        vehicle = slot.vehicle
        t_s = radio.t_s
        while True:
            step_to = t_end_s if vehicle is None else min(t_end_s, max(vehicle.t_s, t_s)
                                                          + VEHICLE_STEP_S)
            while True:
                t_s = radio.advance(step_to, stop_on=RadioEnd.VEHICLE)
                for data in radio.read(RadioEnd.VEHICLE):
                    msgs = slot.radio_decoder.feed(data)
                    if vehicle is None:
                        continue
                    for msg in msgs:
                        self._inbound(slot, msg, _RADIO, t_s)
                    self._service(slot, t_s)
                for data in radio.read(RadioEnd.GROUND):
                    self._send(slot, [data])
                if t_s >= step_to:
                    break
            if vehicle is not None:
                self._service(slot, step_to)
                self._downlink(slot, vehicle.step(step_to), None, step_to)
            if step_to >= t_end_s:
                return

    def _journal(self, slot: _Slot) -> None:
        """Collect and log what the vehicle recorded since the last tick."""
        vehicle = slot.vehicle
        if vehicle is None or len(vehicle.events) == slot.events_seen:
            return
        for event in vehicle.events[slot.events_seen:]:
            self.events.append(event)
            if _EVENTS.hasHandlers():
                _EVENTS.info("%s", event.text)
            else:
                print(f"sitl: {event.text}", flush=True)
        slot.events_seen = len(vehicle.events)

    async def run(self, duration_s: float | None = None) -> None:
        """Tick until :meth:`stop` or ``duration_s`` simulated seconds (the last tick ends
        on it: a late tick at 50x would otherwise overshoot it by up to 5 s)."""
        while not self._stop.is_set():
            self.tick(duration_s)
            if duration_s is not None and self.t_s >= duration_s:
                break
            if self._behind:  # overloaded: yield to I/O, then tick again at once
                await asyncio.sleep(0)
                continue
            # a plain sleep, not wait_for(stop.wait()): a stop waits at most one tick, and
            # each of the 200 ticks a wall second costs 60 us less (a task and a timeout less)
            await asyncio.sleep(self.options.tick_s)

    def stop(self) -> None:
        """Ask :meth:`run` to return."""
        self._stop.set()

    async def close(self) -> None:
        """Close every socket."""
        self._stop.set()
        for slot in self.slots:
            for writer in list(slot.clients):
                writer.close()
            if slot.server is not None:
                slot.server.close()
                with contextlib.suppress(Exception):
                    await asyncio.wait_for(slot.server.wait_closed(), 1.0)
        for transport in (self._udp, self._feed_udp):
            if transport is not None:
                transport.close()
