"""``gcs sitl`` with MAVLink 2 signing, talked to by pymavlink's ``mavutil`` (as MAVProxy
does it): a vehicle started with a key signs what it sends and drops (and counts) unsigned
or wrongly signed commands; a keyless vehicle takes a key from SETUP_SIGNING (not while
armed). Real sockets on 127.0.0.1, ephemeral ports, bounded time."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavutil
from test_sitl_server import ServerThread, configs

from groundstation.commands import sitl as sitl_command
from groundstation.mavlink.codec import mavlink2
from groundstation.mavlink.signing import key_from_passphrase, signing_timestamp
from sitl.server import ServerOptions, SitlServer

KEY = key_from_passphrase("floe test passphrase")
OTHER = key_from_passphrase("another passphrase")
SET_MODE = 176
LOITER = 12


@pytest.fixture(autouse=True)
def mav2(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    monkeypatch.setenv("MAVLINK20", "1")
    yield


def connect(port: int, key: bytes | None = None) -> Any:
    conn = mavutil.mavlink_connection(
        f"tcp:127.0.0.1:{port}", dialect="ardupilotmega", source_system=255, source_component=190
    )
    if key is not None:
        conn.setup_signing(key, sign_outgoing=True, link_id=1)
    return conn


def first(conn: Any, kind: str, timeout_s: float, cond: Any = None) -> Any:
    """The first ``kind`` message (meeting ``cond``) within ``timeout_s`` wall s, or None."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        msg = conn.recv_match(type=kind, blocking=True, timeout=0.2)
        if msg is not None and (cond is None or cond(msg)):
            return msg
    return None


def set_mode_acked(conn: Any, timeout_s: float) -> bool:
    """True if a DO_SET_MODE reached the autopilot (it answers, whatever the result)."""
    conn.mav.command_long_send(1, 1, SET_MODE, 0, 1, LOITER, 0, 0, 0, 0, 0)
    return first(conn, "COMMAND_ACK", timeout_s, lambda m: m.command == SET_MODE) is not None


def test_vehicle_with_a_key_signs_and_rejects_unsigned_and_wrong_key() -> None:
    server = SitlServer(configs(1), ServerOptions(speedup=20.0, base_port=0,
                                                  signing_keys={1: KEY}))
    with ServerThread(server):
        port = server.tcp_ports[0]
        good = connect(port, KEY)
        hb = first(good, "HEARTBEAT", 10.0)
        assert hb is not None and hb._signed  # verified with the key by pymavlink
        assert set_mode_acked(good, 10.0)
        unsigned = connect(port)
        assert first(unsigned, "HEARTBEAT", 10.0) is not None  # it hears, but cannot command
        assert not set_mode_acked(unsigned, 1.5)
        wrong = connect(port, OTHER)
        assert first(wrong, "HEARTBEAT", 1.5) is None  # pymavlink refuses our signatures too
        wrong.mav.command_long_send(1, 1, SET_MODE, 0, 1, LOITER, 0, 0, 0, 0, 0)
        time.sleep(0.5)
        rejected = server.signing_rejected()[1]
        assert rejected.get("unsigned", 0) >= 1 and rejected.get("bad_signature", 0) >= 1
        # a replayed signed command (the same bytes again) is refused as a replay
        msg = good.mav.command_long_encode(1, 1, SET_MODE, 0, 1, LOITER, 0, 0, 0, 0, 0)
        frame = bytes(msg.pack(good.mav))
        good.write(frame)
        good.write(frame)
        time.sleep(0.5)
        assert server.signing_rejected()[1].get("replay", 0) >= 1
        for conn in (good, unsigned, wrong):
            conn.close()
    assert server.vehicles()[0].handler_errors == 0


def test_setup_signing_from_a_gcs_as_mavproxy_does() -> None:
    server = SitlServer(configs(1), ServerOptions(speedup=20.0, base_port=0))
    with ServerThread(server):
        port = server.tcp_ports[0]
        gcs = connect(port)
        hb = first(gcs, "HEARTBEAT", 10.0)
        assert hb is not None and not hb._signed
        # MAVProxy's `signing setup PASSPHRASE`: SETUP_SIGNING, then sign from now on
        stamp = signing_timestamp(time.time())
        gcs.mav.setup_signing_send(1, 1, list(KEY), stamp)
        gcs.setup_signing(KEY, sign_outgoing=True, link_id=0, initial_timestamp=stamp + 1)
        assert first(gcs, "HEARTBEAT", 10.0, lambda m: m._signed) is not None
        assert set_mode_acked(gcs, 10.0)
        other = connect(port)
        assert not set_mode_acked(other, 1.5)
        assert server.signing_rejected()[1].get("unsigned", 0) >= 1
        gcs.close()
        other.close()


def test_armed_vehicle_ignores_setup_signing() -> None:
    server = SitlServer(configs(1, airborne=True), ServerOptions(speedup=20.0, base_port=0))
    with ServerThread(server):
        gcs = connect(server.tcp_ports[0])
        assert first(gcs, "HEARTBEAT", 10.0) is not None
        gcs.mav.setup_signing_send(1, 1, list(KEY), signing_timestamp(time.time()))
        time.sleep(0.5)
        hb = first(gcs, "HEARTBEAT", 5.0)
        assert hb is not None and not hb._signed
        assert set_mode_acked(gcs, 10.0)  # unsigned commands still work
        gcs.close()


def test_gcs_sitl_signing_options(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.key"
    bad.write_text("secret-but-wrong-length")
    code = sitl_command.run(["--signing-key", str(bad), "--base-port", "0",
                             "--detections", "none", "--duration", "1"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "--signing-key" in err
    assert "secret-but-wrong-length" not in err
    phrase = tmp_path / "phrase"
    phrase.write_text("floe test passphrase\n")
    args = sitl_command.parse_options(["--signing-passphrase-file", str(phrase)])
    assert sitl_command.signing_key(args, environ={}) == KEY
    _, _, _, options = sitl_command.build(args)
    assert options.signing_keys == {1: KEY} and KEY.hex() not in repr(options)
    env_args = sitl_command.parse_options([])
    assert sitl_command.signing_key(
        env_args, environ={"FLOE_SIGNING_PASSPHRASE": "floe test passphrase"}) == KEY


def test_setup_signing_with_zero_key_and_timestamp_turns_signing_off() -> None:
    from sitl.signing_endpoint import VehicleSigning

    vehicle = VehicleSigning.with_key(1, KEY, time.time())
    assert vehicle.active
    setup = mavlink2.MAVLink_setup_signing_message(1, 1, [0] * 32, 0)
    assert vehicle.setup(setup, armed=False) and not vehicle.active
    other = mavlink2.MAVLink_setup_signing_message(2, 1, list(KEY), 5)
    assert not vehicle.setup(other, armed=False)  # addressed to another vehicle
    assert not vehicle.active
    assert vehicle.setup(mavlink2.MAVLink_setup_signing_message(1, 1, list(KEY), 5),
                         armed=True) and not vehicle.active  # armed: ignored
