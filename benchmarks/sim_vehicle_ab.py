"""The built-in simulator's CPU per simulated vehicle-second, this tree against another, and
the same MAVLink bytes, frame for frame.

    git worktree add /tmp/base main     (or: git archive <commit> | tar -x -C /tmp/base)
    python benchmarks/sim_vehicle_ab.py --against-tree /tmp/base [--seconds 600]
        [--rounds 7] [--frames-out DIR]

Each tree gets one long-lived interpreter (``PYTHONPATH`` set to it) that runs a fixed,
socket-free script through :class:`sitl.server.SitlServer`: three vehicles (two with the
fast boot, one booting as ArduPlane SITL does) in gusty wind, advanced by fixed simulated
ticks of 0.5, 0.37 and 0.13 s in turn; a scripted ground station that asks for the
daemon's streams (REQUEST_DATA_STREAM: every group at 1 Hz; SET_MESSAGE_INTERVAL:
GLOBAL_POSITION_INT at 2 Hz, but ATTITUDE at 10 Hz from vehicle 2), uploads a fence (an inclusion
circle; FENCE_ACTION report-only or GUIDED; FENCE_ENABLE), sets the low-battery action,
uploads a mission (take-off, waypoints, loiter turns and time, a waypoint outside the
fence, loiter), arms and starts it, changes SIM_WIND_SPD in flight, and puts vehicle 2
back in AUTO after a scheduled mode fault (LOITER); vehicle 3 gets a battery fault
(low-battery RTL) and vehicle 1 a pack that runs flat (motor stop, glide, fall). The
server's downlink goes to a TCP client whose writes are sends on a local socket pair (a
system call each, as an asyncio transport's) and which keeps the byte stream (cut into
MAVLink frames to compare: the same frames, however many a write carries).

The first run of each tree is compared frame by frame: every frame the vehicles sent, in
order, must be byte-identical (exit 1 at the first difference, which is printed). Then the
two are asked for one run each, in turn (the order alternating every round), so a shared
machine's load weighs on both alike; the CPU (``time.process_time``) spent inside
``SitlServer.advance`` is divided by the simulated vehicle-seconds (3 x ``--seconds``).
Prints the minimum and median of each tree, their ratios, and the median of the rounds'
ratios (each round's two runs were back to back: the steadier figure on a busy host).
"""

from __future__ import annotations

import argparse
import hashlib
import statistics
import sys
import tempfile
from pathlib import Path

from tree_ab import ROOT, interleaved_rounds, ratio_line, tree_children

VEHICLES = 3

_CHILD = r'''
import logging, socket, sys, time
from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, mavlink2 as M
from sitl.faults import build_faults
from sitl.server import ServerOptions, SitlServer
from sitl.vehicle import VehicleConfig
from world.battery import BatteryModel
from world.wind import WindSpec

SECONDS = float(sys.argv[1])
FRAMES_OUT = sys.argv[2]
ORIGIN = GeoOrigin(78.2, 15.6)
logging.getLogger("sitl.events").addHandler(logging.NullHandler())  # stdout is the pipe
TICKS_S = (0.5, 0.37, 0.13)


class Writer:
    """A TCP client whose writes are real socket sends (one system call each, as an
    asyncio transport's with an empty buffer), and which keeps the byte stream received."""

    def __init__(self):
        self.sock, self.peer = socket.socketpair()
        self.peer.setblocking(False)
        self.stream = bytearray()
        self.transport = self

    def get_write_buffer_size(self):
        return 0

    def is_closing(self):
        return False

    def write(self, data):
        self.sock.sendall(data)

    def receive(self):
        """What arrived since the last call (also kept in ``stream``)."""
        got = bytearray()
        while True:
            try:
                chunk = self.peer.recv(1 << 16)
            except BlockingIOError:
                break
            got += chunk
        self.stream += got
        return bytes(got)

    def frames(self):
        """The stream cut into MAVLink 2 frames (header 10, payload, CRC 2, signature 13)."""
        self.receive()
        out, i, data = [], 0, bytes(self.stream)
        while i < len(data):
            assert data[i] == 0xFD, f"not a MAVLink 2 frame at byte {i}"
            end = i + 12 + data[i + 1] + (13 if data[i + 2] & 1 else 0)
            out.append(data[i:end])
            i = end
        return out

    def close(self):
        self.sock.close()
        self.peer.close()


def geodetic(x_m, y_m):
    lat, lon, _ = ORIGIN.to_geodetic(x_m, y_m)
    return round(lat * 1e7), round(lon * 1e7)


def mission(i):
    """(command, x_m, y_m, alt_m, param1, param2, param3) per item after home."""
    d = 300.0 * i
    return [
        (M.MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, 80.0, 0, 0, 0),
        (M.MAV_CMD_NAV_WAYPOINT, 1200.0 + d, 400.0, 100.0, 0, 0, 0),
        (M.MAV_CMD_NAV_LOITER_TURNS, 1500.0, -300.0 - d, 120.0, 2, 0, 150.0),
        (M.MAV_CMD_DO_CHANGE_SPEED, 0.0, 0.0, 0.0, 0, 20.0, 0),
        (M.MAV_CMD_NAV_WAYPOINT, -600.0, 900.0 + d, 90.0, 0, 0, 0),
        (M.MAV_CMD_NAV_LOITER_TIME, 0.0, 1300.0, 100.0, 40, 0, -1.0),
        (M.MAV_CMD_NAV_WAYPOINT, 3500.0, -200.0, 100.0, 0, 0, 0),
        (M.MAV_CMD_NAV_LOITER_UNLIM, 500.0, 500.0, 100.0, 0, 0, 0),
    ]


def configs():
    out = []
    for i in range(3):
        sysid = i + 1
        battery = BatteryModel(endurance_s=420.0) if sysid == 1 else None
        out.append(VehicleConfig(
            system_id=sysid, origin=ORIGIN, home_lat_deg=78.2, home_lon_deg=15.6,
            home_amsl_m=12.0, launch_x_m=40.0 * i, launch_y_m=-30.0 * i,
            launch_heading_rad=0.4 * i, fast_boot=sysid != 3, unix_time_at_zero_s=1.7e9,
            params={"CRASH_DETECT": 1} if sysid == 1 else {},
            wind=WindSpec(7.0, 250.0, 1.5), wind_seed=11, battery=battery))
    return out


class Gcs:
    """The scripted ground station of one vehicle."""

    def __init__(self, server, slot):
        self.server, self.slot = server, slot
        self.sysid = slot.config.system_id
        self.enc = MavlinkEncoder(255, 190)
        self.up = MavlinkDecoder()
        self.down = MavlinkDecoder()
        self.writer = Writer()
        slot.clients.add(self.writer)
        self.uploads = {}

    def send(self, msg):
        for m in self.up.feed(self.enc.encode(msg)):
            self.server._inbound(self.slot, m, self.writer)
        self.server._service(self.slot)

    def items(self, mission_type):
        if mission_type == M.MAV_MISSION_TYPE_FENCE:
            lat, lon = geodetic(0.0, 0.0)
            return [M.MAVLink_mission_item_int_message(
                self.sysid, 1, 0, M.MAV_FRAME_GLOBAL, M.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION,
                0, 1, 1700.0, 0, 0, 0, lat, lon, 0.0, mission_type)]
        lat0, lon0 = geodetic(0.0, 0.0)
        out = [M.MAVLink_mission_item_int_message(
            self.sysid, 1, 0, M.MAV_FRAME_GLOBAL, M.MAV_CMD_NAV_WAYPOINT, 0, 1,
            0, 0, 0, 0, lat0, lon0, 12.0, 0)]
        for seq, (cmd, x, y, alt, p1, p2, p3) in enumerate(mission(self.sysid - 1), start=1):
            lat, lon = geodetic(x, y) if (x or y) else (0, 0)
            out.append(M.MAVLink_mission_item_int_message(
                self.sysid, 1, seq, M.MAV_FRAME_GLOBAL_RELATIVE_ALT, cmd, 0, 1,
                float(p1), float(p2), float(p3), 0.0, lat, lon, alt, 0))
        return out

    def upload(self, mission_type):
        items = self.items(mission_type)
        self.uploads[mission_type] = items
        self.send(M.MAVLink_mission_count_message(self.sysid, 1, len(items), mission_type))

    def param(self, name, value):
        self.send(M.MAVLink_param_set_message(self.sysid, 1, name.encode(), float(value),
                                              M.MAV_PARAM_TYPE_REAL32))

    def command(self, cmd, *params):
        p = list(params) + [0.0] * (7 - len(params))
        self.send(M.MAVLink_command_long_message(self.sysid, 1, cmd, 0, *p))

    def react(self):
        """Answer the vehicle's mission requests."""
        new = self.writer.receive()
        if new:
            for msg in self.down.feed(new):
                if msg.get_type() in ("MISSION_REQUEST", "MISSION_REQUEST_INT"):
                    items = self.uploads.get(int(getattr(msg, "mission_type", 0) or 0))
                    if items is not None and msg.seq < len(items):
                        self.send(items[msg.seq])


def script(gcs, t_s):
    """What the ground station of ``gcs`` does at ``t_s`` (called once per tick)."""
    i = gcs.sysid
    steps = {
        3.0: lambda: gcs.send(M.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3)),
        3.4: lambda: gcs.send(M.MAVLink_request_data_stream_message(i, 1, 0, 1, 1)),
        3.5: lambda: (gcs.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 33, 5e5) if i != 2
                      else gcs.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 30, 1e5)),
        4.0: lambda: gcs.param("BATT_FS_LOW_ACT", 2),
        5.0: lambda: gcs.upload(M.MAV_MISSION_TYPE_FENCE),
        8.0: lambda: gcs.param("FENCE_ACTION", 0 if i == 1 else 6),
        9.0: lambda: gcs.param("FENCE_ENABLE", 1) if i != 3 else None,
        10.0: lambda: gcs.upload(M.MAV_MISSION_TYPE_MISSION),
        30.0: lambda: gcs.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1),
        31.0: lambda: gcs.command(M.MAV_CMD_DO_SET_MODE, 1, 10),
        150.0: lambda: gcs.param("SIM_WIND_SPD", 11) if i == 1 else None,
        240.0: lambda: gcs.command(M.MAV_CMD_DO_SET_MODE, 1, 10) if i == 2 else None,
        300.0: lambda: gcs.command(M.MAV_CMD_REQUEST_MESSAGE, 242) if i == 3 else None,
    }
    for at_s, act in steps.items():
        if gcs.last_t < at_s <= t_s:
            act()


def run():
    faults = build_faults(["2:mode:at=200,mode=LOITER", "3:battery:at=260,pct=14"],
                          [1, 2, 3], 7)
    server = SitlServer(configs(), ServerOptions(speedup=25.0, base_port=0), faults, None)
    for slot in server.slots:
        server._boot(slot)
    stations = [Gcs(server, slot) for slot in server.slots]
    for g in stations:
        g.last_t = 0.0
    cpu_s = 0.0
    t_s, k = 0.0, 0
    while t_s < SECONDS:
        t_s = min(SECONDS, t_s + TICKS_S[k % 3])
        k += 1
        c0 = time.process_time()
        server.advance(t_s)
        cpu_s += time.process_time() - c0
        for g in stations:
            g.react()
            script(g, t_s)
            g.last_t = t_s
    frames = [g.writer.frames() for g in stations]
    for g in stations:
        g.writer.close()
    return cpu_s, frames, server


cpu_s, frames, server = run()
with open(FRAMES_OUT, "w") as f:
    for sysid, vehicle_frames in enumerate(frames, start=1):
        for data in vehicle_frames:
            f.write(f"{sysid} {data.hex()}\n")
    for event in server.events:
        f.write(f"event {event.t_s!r} {event.system_id} {event.kind} {event.text}\n")
print("ready", flush=True)
for _ in sys.stdin:
    cpu_s, _, _ = run()
    print(cpu_s, flush=True)
'''


def first_difference(a: Path, b: Path) -> tuple[int, str, str] | None:
    """The first differing line of two frame dumps (1-based line, both texts), or None."""
    with a.open() as fa, b.open() as fb:
        for n, (la, lb) in enumerate(zip(fa, fb, strict=False), start=1):
            if la != lb:
                return n, la.strip(), lb.strip()
    na, nb = sum(1 for _ in a.open()), sum(1 for _ in b.open())
    if na != nb:
        return min(na, nb) + 1, f"<{na} lines>", f"<{nb} lines>"
    return None


def main() -> int:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.split("\n\n")[0])
    parser.add_argument("--against-tree", type=Path, required=True, metavar="DIR")
    parser.add_argument("--seconds", type=float, default=600.0, help="simulated seconds")
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--frames-out", type=Path, default=None, metavar="DIR",
                        help="keep the two frame dumps here (default: a temporary folder)")
    args = parser.parse_args()
    trees = {"other tree": args.against_tree.resolve(), "this tree": ROOT}
    with tempfile.TemporaryDirectory() as tmp:
        out_dir = args.frames_out or Path(tmp)
        out_dir.mkdir(parents=True, exist_ok=True)
        dumps = {name: out_dir / f"{name.replace(' ', '-')}.frames" for name in trees}
        child_args = {name: [str(args.seconds), str(dumps[name])] for name in trees}
        with tree_children(trees, _CHILD, child_args, timeout_s=120.0) as procs:
            diff = first_difference(dumps["other tree"], dumps["this tree"])
            lines = sum(1 for _ in dumps["this tree"].open())
            digest = hashlib.sha256(dumps["this tree"].read_bytes()).hexdigest()[:16]
            if diff is not None:
                n, theirs, ours = diff
                print(f"frames DIFFER at line {n} of {lines}:\n  other: {theirs[:200]}\n"
                      f"  this:  {ours[:200]}")
                return 1
            print(f"frames identical: {lines} lines (frames and journal), sha256 {digest}")
            cpu = interleaved_rounds(procs, args.rounds)
    vehicle_s = VEHICLES * args.seconds
    print(f"{VEHICLES} vehicles x {args.seconds:g} simulated s: CPU in SitlServer.advance per "
          f"simulated vehicle-second, {args.rounds} rounds")
    for name, values in cpu.items():
        print(f"   {name:<12} min {1e3 * min(values) / vehicle_s:.3f} ms, "
              f"median {1e3 * statistics.median(values) / vehicle_s:.3f} ms")
    old, new = cpu["other tree"], cpu["this tree"]
    print(f"{ratio_line(old, new)} "
          f"(CPU saved: {100 * (1 - statistics.median(new) / statistics.median(old)):.0f} %)")
    paired = statistics.median(a / b for a, b in zip(old, new, strict=True))
    print(f"   ratio of each round's pair, median {paired:.2f} "
          f"(CPU saved: {100 * (1 - 1 / paired):.0f} %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
