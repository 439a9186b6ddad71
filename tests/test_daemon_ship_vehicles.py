"""The daemon's vehicle side of the ship watch, end to end over real MAVLink on 127.0.0.1:
a SetHome reaches a vehicle as DO_SET_HOME and is verified by HOME_POSITION (``home_set``
in the journal), and the ship's beacon (GLOBAL_POSITION_INT from system 17) reaches every
vehicle link with the ship's position.

The peer is a minimal scripted ArduPlane-shaped vehicle in a thread, so the tests see every
frame it received: HEARTBEAT (FBWA, armed), GLOBAL_POSITION_INT
(flying at 100 m, 22 m/s), SYS_STATUS and HOME_POSITION; it answers PARAM_REQUEST_READ,
DO_SET_HOME (COMMAND_ACK, then HOME_POSITION at the new home) and REQUEST_MESSAGE 242, and
keeps what it received. The test feeds the decision core's commands directly: it asserts on
the journal and on what the peer received. The last tests run the built-in simulator with
the real watch core (ship-watch, --launch): only the core's launch orders launch, and the
homes the vehicles confirmed (the simulator answers DO_SET_HOME too) are the API's.
"""

from __future__ import annotations

import asyncio
import itertools
import socket
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from daemon_run import events, run_gcs

from domain.geodesy import GeoOrigin
from groundstation.commands.run import build_config
from groundstation.core import commands as cmd
from groundstation.core import events as ev
from groundstation.daemon.control.controller import DaemonController
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.journal import read_journal
from groundstation.daemon.startup import run_daemon
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, MAVLinkMessage, mavlink2

M = mavlink2
ORIGIN = GeoOrigin(78.2, 15.6)
SPEEDUP = 5.0
HOME_ALT_M = 20.0
FBWA = 5


class ScriptedPlane(threading.Thread):
    """See the module docstring. Serves one TCP connection on 127.0.0.1 (ephemeral port)."""

    def __init__(self, system_id: int = 1) -> None:
        super().__init__(daemon=True)
        self.system_id = system_id
        self.server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.server.bind(("127.0.0.1", 0))
        self.server.listen(1)
        self.server.settimeout(0.1)
        self.port = int(self.server.getsockname()[1])
        self.enc = MavlinkEncoder(system_id, 1)
        self.dec = MavlinkDecoder()
        lat, lon, _ = ORIGIN.to_geodetic(300.0, 200.0)
        self.position = (lat, lon)
        self.home = [ORIGIN.lat_deg, ORIGIN.lon_deg, HOME_ALT_M]
        self.received: list[MAVLinkMessage] = []
        self.stop = threading.Event()
        self.t0 = time.monotonic()
        self.lock = threading.Lock()

    def boot_ms(self) -> int:
        return int((time.monotonic() - self.t0) * SPEEDUP * 1000)

    def send(self, conn: socket.socket, msg: MAVLinkMessage) -> None:
        conn.sendall(self.enc.encode(msg))

    def home_position(self) -> MAVLinkMessage:
        lat, lon, alt = self.home
        return M.MAVLink_home_position_message(
            round(lat * 1e7), round(lon * 1e7), round(alt * 1000), 0.0, 0.0, 0.0,
            [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0)  # fmt: skip

    def telemetry(self, conn: socket.socket) -> None:
        lat, lon = self.position
        self.send(conn, M.MAVLink_heartbeat_message(
            M.MAV_TYPE_FIXED_WING, M.MAV_AUTOPILOT_ARDUPILOTMEGA,
            M.MAV_MODE_FLAG_SAFETY_ARMED | M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, FBWA,
            M.MAV_STATE_ACTIVE, 3))  # fmt: skip
        self.send(conn, M.MAVLink_global_position_int_message(
            self.boot_ms(), round(lat * 1e7), round(lon * 1e7), 120_000, 100_000, 2200, 0, 0,
            0))  # fmt: skip
        self.send(conn, M.MAVLink_sys_status_message(0, 0, 0, 0, 12_300, 450, 80, 0, 0, 0, 0,
                                                     0, 0))

    def answer(self, conn: socket.socket, msg: MAVLinkMessage) -> None:
        kind = msg.get_type()
        if kind == "PARAM_REQUEST_READ":
            name = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode()
            if name.rstrip("\x00") == "AIRSPEED_CRUISE":
                self.send(conn, M.MAVLink_param_value_message(
                    b"AIRSPEED_CRUISE", 22.0, M.MAV_PARAM_TYPE_REAL32, 1, 65535))
        elif kind == "COMMAND_INT" and msg.command == M.MAV_CMD_DO_SET_HOME:
            self.home = [msg.x * 1e-7, msg.y * 1e-7, float(msg.z)]
            self.send(conn, M.MAVLink_command_ack_message(
                msg.command, M.MAV_RESULT_ACCEPTED, 0, 0, msg.get_srcSystem(),
                msg.get_srcComponent()))  # fmt: skip
            self.send(conn, self.home_position())
        elif kind == "COMMAND_LONG" and msg.command == M.MAV_CMD_REQUEST_MESSAGE:
            self.send(conn, M.MAVLink_command_ack_message(
                msg.command, M.MAV_RESULT_ACCEPTED, 0, 0, msg.get_srcSystem(),
                msg.get_srcComponent()))  # fmt: skip
            if int(msg.param1) == M.MAVLINK_MSG_ID_HOME_POSITION:
                self.send(conn, self.home_position())

    def run(self) -> None:
        conn: socket.socket | None = None
        while conn is None and not self.stop.is_set():
            try:
                conn, _ = self.server.accept()
            except TimeoutError:
                continue
        if conn is None:
            return
        conn.settimeout(0.01)
        next_s = 0.0
        sent_home = False
        with conn:
            while not self.stop.is_set():
                now = time.monotonic()
                try:
                    if now >= next_s:
                        self.telemetry(conn)
                        if not sent_home:
                            self.send(conn, self.home_position())
                            sent_home = True
                        next_s = now + 0.05
                    data = conn.recv(65536)
                except TimeoutError:
                    continue
                except OSError:
                    return
                if not data:
                    return
                for msg in self.dec.feed(data):
                    with self.lock:
                        self.received.append(msg)
                    try:
                        self.answer(conn, msg)
                    except OSError:
                        return

    def got(self, kind: str, system_id: int | None = None) -> list[MAVLinkMessage]:
        with self.lock:
            return [m for m in self.received if m.get_type() == kind
                    and (system_id is None or m.get_srcSystem() == system_id)]


def run_with(tmp_path: Path, plane: ScriptedPlane, script: Any, *args: str,
             timeout_s: float = 40.0) -> tuple[Daemon, list[dict[str, Any]]]:
    """The daemon on the scripted plane's link; ``script(daemon)`` (a coroutine) drives it
    and returns when the test has what it needs; then the daemon stops."""
    config = build_config([
        "--vehicles", f"tcp:127.0.0.1:{plane.port}", "--origin",
        f"{ORIGIN.lat_deg},{ORIGIN.lon_deg}", "--speedup", str(SPEEDUP), "--run-dir",
        str(tmp_path), "--http", "off", "--detections", "off", "--status", "quiet",
        "--duration", "400", *args,
    ])  # fmt: skip

    async def main() -> Daemon:
        tasks: list[asyncio.Task[None]] = []

        async def drive(daemon: Daemon) -> None:
            await script(daemon)
            daemon.request_stop("test done")

        def started(daemon: Daemon) -> None:
            tasks.append(asyncio.create_task(drive(daemon)))

        try:
            return await run_daemon(config, print_fn=lambda _: None, install_signals=False,
                                    on_started=started)
        finally:
            for task in tasks:
                task.cancel()

    plane.start()
    try:
        daemon = asyncio.run(asyncio.wait_for(main(), timeout_s))
    finally:
        plane.stop.set()
        plane.join(5.0)
    return daemon, read_journal(daemon.run_dir / "journal.jsonl")


async def until(check: Any, timeout_s: float = 20.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not check():
        assert time.monotonic() < deadline, "timed out"
        await asyncio.sleep(0.02)


@pytest.mark.timeout(90)
def test_set_home_reaches_the_vehicle_and_is_verified_by_home_position(tmp_path: Path) -> None:
    plane = ScriptedPlane()
    target = (1500.0, -800.0)

    async def script(daemon: Daemon) -> None:
        await until(lambda: 1 in daemon.sessions and daemon.sessions[1].flying())
        # its home is not known yet (the HOME_POSITION it sent came before the session):
        # the exchange asks for it first, and keeps its altitude
        daemon._execute(cmd.SetHome(daemon.clock.now_s(), "1", *target))
        path = daemon.run_dir / "journal.jsonl"
        await until(lambda: bool(events(read_journal(path), "home_set")))

    daemon, journal = run_with(tmp_path, plane, script, "--ship-beacon", "off")
    assert not events(journal, "task_error")
    (order,) = events(journal, "set_home", vehicle="1")
    assert (order["x_m"], order["y_m"]) == target
    (done,) = events(journal, "home_set", vehicle="1")
    assert done["x_m"] == pytest.approx(target[0], abs=0.05)
    assert done["y_m"] == pytest.approx(target[1], abs=0.05)
    assert done["error_m"] < 0.05 and done["t"] >= order["t"]
    asked = [m for m in plane.got("COMMAND_LONG") if m.command == M.MAV_CMD_REQUEST_MESSAGE]
    assert asked and asked[0].param1 == M.MAVLINK_MSG_ID_HOME_POSITION
    (sent,) = plane.got("COMMAND_INT")
    lat, lon, _ = ORIGIN.to_geodetic(*target)
    assert (sent.x, sent.y) == (round(lat * 1e7), round(lon * 1e7))
    assert sent.frame == M.MAV_FRAME_GLOBAL and sent.param1 == 0.0
    assert sent.z == pytest.approx(HOME_ALT_M)  # the vehicle's home altitude, kept
    assert sent.get_srcSystem() == 245
    # nothing else was commanded: no mode change, no mission, to a vehicle flown by hand
    commanding = [m for m in plane.got("COMMAND_LONG") if m.command == M.MAV_CMD_DO_SET_MODE]
    assert commanding == [] and plane.got("MISSION_COUNT") == []
    assert daemon.sessions[1].status == "manual"


@pytest.mark.timeout(90)
def test_the_ship_beacon_reaches_the_vehicle_link(tmp_path: Path) -> None:
    plane = ScriptedPlane()
    ship = (-400.0, 250.0)

    async def script(daemon: Daemon) -> None:
        await until(lambda: 1 in daemon.sessions)
        assert plane.got("GLOBAL_POSITION_INT", 17) == []  # no ship known: no beacon
        # the ship steams east at 5 m/s, bow east (ENU heading 0)
        daemon.core_event(ev.BoatPosition(daemon.clock.now_s(), *ship, 5.0, 0.0, 0.0, 10.0,
                                          "test"))
        await until(lambda: len(plane.got("GLOBAL_POSITION_INT", 17)) >= 2)

    _, journal = run_with(tmp_path, plane, script)
    assert not events(journal, "task_error")
    beacons = plane.got("GLOBAL_POSITION_INT", 17)
    first = beacons[0]
    assert first.get_srcComponent() == M.MAV_COMP_ID_USER1
    x_m, y_m, _ = ORIGIN.to_local(first.lat * 1e-7, first.lon * 1e-7)
    # where the ship is (predicted by its velocity from the fix: at most a few s at 5 m/s)
    assert 0.0 <= x_m - ship[0] <= 5.0 * 1.0 * SPEEDUP + 1.0 and y_m == pytest.approx(ship[1],
                                                                                    abs=0.05)
    assert (first.vx, first.vy) == (0, 500)  # north, east cm/s
    assert first.hdg == 9000  # east, compass degrees x 100
    # about 1 Hz of mission time
    gaps_ms = [b.time_boot_ms - a.time_boot_ms for a, b in itertools.pairwise(beacons)]
    assert all(900 <= g <= 1500 for g in gaps_ms), gaps_ms
    assert not [m for m in plane.received if m.get_srcSystem() == 17
                and m.get_type() == "HEARTBEAT"]  # the beacon is no vehicle


@pytest.mark.timeout(120)
def test_with_a_watch_on_station_only_the_core_s_orders_launch(tmp_path: Path) -> None:
    """The built-in simulator's vehicles on deck, the ship-watch scenario (3 on station),
    ``--launch``: the spares report themselves on deck, the core orders three launches and
    floe carries out exactly those; the fourth stays on deck, ready, never armed."""
    daemon, journal = run_gcs(tmp_path, "--vehicles", "sim:4", "--scenario", "ship-watch",
                              "--launch", "--speedup", "50", "--duration", "100",
                              "--ship-beacon", "off", timeout_s=100.0)
    assert not events(journal, "task_error")
    decks = [e for e in events(journal, "input") if e["kind"] == "VehicleOnDeck"]
    assert {e["vehicle"] for e in decks} == {"1", "2", "3", "4"}
    assert all(e["ready"] for e in decks)
    orders = events(journal, "launch_order")
    assert len(orders) == 3 and all(e["reason"] == "on station" for e in orders)
    ordered = {e["vehicle"] for e in orders}
    for launch in events(journal, "launch"):  # the controller's: each after its order
        order = next(e for e in orders if e["vehicle"] == launch["vehicle"])
        assert launch["t"] >= order["t"]
    assert {e["vehicle"] for e in events(journal, "launch")} == ordered
    assert {e["vehicle"] for e in events(journal, "launch_wanted", action="launch")} == ordered
    spare = ({"1", "2", "3", "4"} - ordered).pop()
    assert not events(journal, "armed", vehicle=spare, armed=True)
    assert daemon.by_name[spare].status == "on_ground"
    assert {e["vehicle"] for e in events(journal, "vehicle_joined")} == ordered
    reports = [e for e in events(journal, "input") if e["kind"] == "BatteryReport"]
    assert {e["vehicle"] for e in reports} == {"1", "2", "3", "4"}
    # the API: no launch is wanted of anyone now (the ordered ones fly), and each vehicle's
    # home is the last one it confirmed (the simulator answers DO_SET_HOME), or None
    state = DaemonController(daemon).state()
    assert all(v["launch_wanted"] is None for v in state["vehicles"])
    assert not events(journal, "home_set_failed")
    confirmed = {e["vehicle"]: [e["x_m"], e["y_m"]] for e in events(journal, "home_set")}
    assert set(confirmed) >= ordered  # the ship moves: the flying ones' homes follow it
    assert {v["id"]: v["home"] for v in state["vehicles"]} == {
        name: confirmed.get(name) for name in ("1", "2", "3", "4")}


@pytest.mark.timeout(120)
def test_without_launch_the_operator_is_asked_and_the_api_shows_it(tmp_path: Path) -> None:
    """The same without ``--launch``: nothing is armed; each ordered spare is asked for
    (journal, console) and the API's vehicle says ``launch_wanted``."""
    daemon, journal = run_gcs(tmp_path, "--vehicles", "sim:4", "--scenario", "ship-watch",
                              "--no-launch", "--speedup", "50", "--duration", "40",
                              "--ship-beacon", "off", timeout_s=100.0)
    assert not events(journal, "task_error")
    orders = events(journal, "launch_order")
    assert len(orders) == 3
    asked = events(journal, "launch_wanted", action="ask")
    assert {e["vehicle"] for e in asked} == {e["vehicle"] for e in orders}
    assert not events(journal, "launch") and not events(journal, "armed", armed=True)
    state = DaemonController(daemon).state()
    wanted = {v["id"]: v["launch_wanted"] for v in state["vehicles"]}
    assert {k for k, w in wanted.items() if w is not None} == {e["vehicle"] for e in orders}
    assert all(w == {"reason": "on station", "relieves": None}
               for w in wanted.values() if w is not None)
