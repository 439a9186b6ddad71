"""``gcs run`` with MAVLink 2 signing against the built-in vehicles: signed round trip
(heartbeats verified, a mission uploaded), SETUP_SIGNING as MAVProxy sends it, and a
vehicle with the wrong key or none refused and counted. Key material never reaches the run
folder. 127.0.0.1, ephemeral ports, bounded time."""

from __future__ import annotations

import asyncio
import itertools
from pathlib import Path

import pytest
from daemon_run import events, run_gcs, status_text

from domain.geodesy import GeoOrigin
from groundstation.commands.run import build_config, run_daemon
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.journal import read_journal
from groundstation.mavlink.signing import key_from_passphrase
from sitl.server import ServerOptions, SitlServer
from sitl.vehicle import VehicleConfig

PHRASE = "floe daemon passphrase"
KEY = key_from_passphrase(PHRASE)
OTHER = key_from_passphrase("not the daemon's")


def phrase_file(tmp_path: Path) -> Path:
    path = tmp_path / "phrase.txt"
    path.write_text(PHRASE + "\n")
    return path


def no_key_in_run_folder(daemon: Daemon, tmp_path: Path) -> None:
    files = [path for path in daemon.run_dir.rglob("*") if path.is_file()]
    assert any(path.parent.name == "params" for path in files)  # the parameter snapshot too
    for path in files:
        data = path.read_bytes()
        assert KEY not in data and KEY.hex().encode() not in data and PHRASE.encode() not in data


@pytest.mark.timeout(90)
def test_signed_round_trip_with_the_built_in_vehicle(tmp_path: Path) -> None:
    phrase = phrase_file(tmp_path)
    daemon, journal = run_gcs(
        tmp_path / "runs", "--vehicles", "sim:1", "--scenario", "default", "--sim-airborne",
        "--speedup", "50", "--duration", "60", "--signing-passphrase-file", str(phrase),
    )  # fmt: skip
    assert events(journal, "vehicle_joined", vehicle="1")
    assert events(journal, "upload", vehicle="1", ok=True)  # the vehicle took signed frames
    signing = daemon.summary()["signing"]
    assert signing["accepted"]["1"] > 50 and signing["rejected"] == {}
    assert signing["sources"] == {"all": str(phrase)}
    start = events(journal, "start")[0]
    assert start["signing"] == {"keys": {"all": str(phrase)}, "setup": False}
    assert start["config"]["signing"]["passphrase_file"] == str(phrase)
    assert "signing on; refused frames: none" in status_text(daemon)
    no_key_in_run_folder(daemon, tmp_path)


@pytest.mark.timeout(90)
def test_signing_setup_keys_a_keyless_vehicle_before_it_is_used(tmp_path: Path) -> None:
    key_file = tmp_path / "key.hex"
    key_file.write_text(KEY.hex())
    daemon, journal = run_gcs(
        tmp_path / "runs", "--vehicles", "sim:1", "--scenario", "default",
        "--speedup", "50", "--duration", "150", "--signing-key", str(key_file),
        "--signing-setup",
    )  # fmt: skip
    signing = daemon.summary()["signing"]
    assert signing["setups_sent"]["1"] >= 1
    # before the key was taken its unsigned frames were refused, never delivered
    assert signing["rejected"]["1@vehicles0"].get("unsigned", 0) >= 1
    assert signing["accepted"]["1"] > 50
    seen = events(journal, "vehicle_seen", vehicle="1")
    assert seen  # the session only began once the vehicle signed
    assert events(journal, "launch", vehicle="1") and events(journal, "upload", vehicle="1",
                                                               ok=True)
    no_key_in_run_folder(daemon, tmp_path)


def _external(keys: dict[int, bytes]) -> SitlServer:
    origin = GeoOrigin(78.93, 11.92)
    configs = [
        VehicleConfig(system_id=i, origin=origin, home_lat_deg=78.93, home_lon_deg=11.92,
                      fast_boot=True, airborne=True)
        for i in (1, 2, 3)
    ]
    # 10x: this simulator runs on its own clock beside the daemon's monotonic x K, and at
    # 20x a starved suite worker (four beside two busy loops) left it too far behind for
    # the counts below within the daemon's 60 mission s
    return SitlServer(configs, ServerOptions(speedup=10.0, base_port=0, signing_keys=keys))


@pytest.mark.timeout(60)
def test_wrong_key_and_unsigned_vehicles_are_refused_and_counted(tmp_path: Path) -> None:
    """Vehicle 1 has another key, vehicle 2 none, vehicle 3 the daemon's: only 3 is used."""
    phrase = phrase_file(tmp_path)
    targets = tmp_path / "targets.yaml"
    targets.write_text("- {id: A, x_m: 900.0, y_m: 300.0, sigma0: 5.0}\n")
    server = _external({1: OTHER, 3: KEY})

    async def main() -> Daemon:
        await server.start()
        runner = asyncio.create_task(server.run())
        try:
            ports = server.tcp_ports
            config = build_config([
                "--vehicles", *[f"tcp:127.0.0.1:{port}" for port in ports],
                "--scenario", "none", "--origin", "78.93,11.92", "--speedup", "10",
                "--duration", "60", "--targets", str(targets),
                "--signing-passphrase-file", str(phrase),
                "--run-dir", str(tmp_path / "runs"), "--http", "off", "--detections", "off",
                "--status", "quiet",
            ])  # fmt: skip
            return await run_daemon(config, print_fn=lambda _: None, install_signals=False)
        finally:
            server.stop()
            await runner
            await server.close()

    daemon = asyncio.run(asyncio.wait_for(main(), 45.0))
    journal = read_journal(daemon.run_dir / "journal.jsonl")
    assert set(daemon.sessions) == {3}  # nothing refused reached a session
    assert [e["system_id"] for e in events(journal, "vehicle_seen")] == [3]
    assert events(journal, "upload", vehicle="3", ok=True, target="A")
    signing = daemon.summary()["signing"]
    assert signing["accepted"]["3"] > 20 and "3@vehicles2" not in signing["rejected"]
    rejected = signing["rejected"]
    assert rejected["1@vehicles0"]["bad_signature"] > 10
    assert rejected["2@vehicles1"]["unsigned"] > 10
    assert set(daemon.router.routes) == {3} and daemon.router.counters.refused > 20
    lines = events(journal, "signing_rejected")
    assert {(e["system_id"], e["link"]) for e in lines} == {(1, "vehicles0"), (2, "vehicles1")}
    # rate-limited: one line per vehicle/link every 5 mission s at most. A report's lines
    # are stamped with the report's time (stamped as written, a starved process once put
    # two lines of one report 0.3 s apart, and the next pair 4.8 s apart), so reports are
    # 5 s apart to the journal's millisecond
    for key in ((1, "vehicles0"), (2, "vehicles1")):
        times = [e["t"] for e in lines if (e["system_id"], e["link"]) == key]
        assert len(times) >= 5 and all(b - a >= 4.999 for a, b in itertools.pairwise(times))
    # the vehicle with the other key refused the daemon's signed heartbeats in turn
    assert server.signing_rejected()[1].get("bad_signature", 0) >= 1
    assert server.signing_rejected()[3] == {}  # it took every signed frame the daemon sent
    no_key_in_run_folder(daemon, tmp_path)
