"""MAVLink 2 signing, sans-IO: keys, signing, checking, and interoperability with pymavlink's
own signing (``MAVLink.signing``) in both directions; the daemon's gate and key loading."""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

import pytest

from domain.errors import ConfigError
from groundstation.commands.run import build_config
from groundstation.daemon.config_parse import parse_config
from groundstation.daemon.signing_gate import SigningGate, SigningKeys, load_signing_keys
from groundstation.link.base import Received
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, mavlink2
from groundstation.mavlink.signing import (
    SIGNING_EPOCH_UNIX_S,
    SigningKeyError,
    SigningState,
    Verdict,
    key_from_passphrase,
    parse_key_file_bytes,
    parse_passphrase_file_bytes,
    signature_fields,
    signing_timestamp,
)

M = mavlink2
KEY = key_from_passphrase("correct horse")
OTHER = key_from_passphrase("wrong horse")
NOW_S = 1_780_000_000.0


def heartbeat(sysid: int = 1, compid: int = 1) -> bytes:
    return MavlinkEncoder(sysid, compid).encode(M.MAVLink_heartbeat_message(1, 3, 0, 0, 4, 3))


def pymav(key: bytes | None, sysid: int = 255, link_id: int = 0, unix_s: float = NOW_S) -> Any:
    mav = M.MAVLink(None, srcSystem=sysid, srcComponent=190)
    mav.robust_parsing = True
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.link_id = link_id
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = signing_timestamp(unix_s)
    return mav


def test_keys_as_mavproxy_and_key_files() -> None:
    assert key_from_passphrase("abc") == hashlib.sha256(b"abc").digest()
    assert parse_passphrase_file_bytes(b"abc\n") == hashlib.sha256(b"abc").digest()
    raw = bytes(range(32))
    assert parse_key_file_bytes(raw) == raw
    assert parse_key_file_bytes(raw.hex().encode() + b"\n") == raw
    for bad in (b"", b"short", b"zz" * 32, bytes(33)):
        with pytest.raises(SigningKeyError) as err:
            parse_key_file_bytes(bad)
        assert "short" not in str(err.value) and "zz" not in str(err.value)
    with pytest.raises(SigningKeyError):
        parse_passphrase_file_bytes(b"\n")


def test_timestamp_epoch_and_units() -> None:
    assert signing_timestamp(SIGNING_EPOCH_UNIX_S) == 0
    assert signing_timestamp(SIGNING_EPOCH_UNIX_S + 1.5) == 150_000  # 10 us units


def test_floe_signs_pymavlink_verifies() -> None:
    signer = SigningState(KEY, link_id=7)
    frames = [signer.sign(heartbeat(), NOW_S) for _ in range(3)]
    receiver = pymav(KEY)
    for frame in frames:
        msg = receiver.decode(bytearray(frame))
        assert msg.get_type() == "HEARTBEAT" and msg._signed and msg._link_id == 7
    stamps = [signature_fields(f)[1] for f in frames]  # type: ignore[index]
    assert stamps == sorted(set(stamps)) and stamps[0] >= signing_timestamp(NOW_S)
    wrong = pymav(OTHER)
    with pytest.raises(Exception, match="signature"):
        wrong.decode(bytearray(SigningState(KEY).sign(heartbeat(), NOW_S)))
    # floe's own decoder still parses signed frames (it does not check; the gate does)
    assert [m.get_type() for m in MavlinkDecoder().feed(frames[0])] == ["HEARTBEAT"]


def test_pymavlink_signs_floe_verifies_and_rejects_what_mavlink_rejects() -> None:
    sender = pymav(KEY, link_id=2)
    frames = [bytes(M.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(sender)) for _ in range(2)]
    checker = SigningState(KEY)
    assert checker.check(frames[0], NOW_S) is Verdict.SIGNED_OK
    assert checker.check(frames[0], NOW_S) is Verdict.REPLAY  # same timestamp again
    assert checker.check(frames[1], NOW_S) is Verdict.SIGNED_OK
    assert SigningState(OTHER).check(frames[1], NOW_S) is Verdict.BAD_SIGNATURE
    tampered = bytearray(frames[1])
    tampered[12] ^= 1
    assert SigningState(KEY).check(bytes(tampered), NOW_S) is Verdict.BAD_SIGNATURE
    assert checker.check(heartbeat(), NOW_S) is Verdict.UNSIGNED
    radio = MavlinkEncoder(51, 68).encode(M.MAVLink_radio_status_message(200, 190, 90, 80, 5, 0, 0))
    assert checker.check(radio, NOW_S) is Verdict.UNSIGNED_ALLOWED
    # a new stream more than a minute old is refused; within the minute it is taken
    old = pymav(KEY, sysid=9, unix_s=NOW_S - 61)
    assert checker.check(bytes(M.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(old)),
                         NOW_S) is Verdict.OLD_TIMESTAMP
    recent = pymav(KEY, sysid=10, unix_s=NOW_S - 30)
    assert checker.check(bytes(M.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(recent)),
                         NOW_S) is Verdict.SIGNED_OK


def test_streams_are_per_sysid_compid_link_and_capped() -> None:
    checker = SigningState(KEY, max_streams=3)
    signer = SigningState(KEY)
    late = signer.sign(heartbeat(), NOW_S)
    early_other_link = SigningState(KEY, link_id=1).sign(heartbeat(), NOW_S - 1)
    assert checker.check(late, NOW_S) is Verdict.SIGNED_OK
    assert checker.check(early_other_link, NOW_S) is Verdict.SIGNED_OK  # own stream
    assert checker.check(signer.sign(heartbeat(2), NOW_S), NOW_S) is Verdict.SIGNED_OK
    assert checker.check(signer.sign(heartbeat(3), NOW_S), NOW_S) is Verdict.TOO_MANY_STREAMS
    assert checker.check(b"\xfd\x00", NOW_S) is Verdict.MALFORMED


def test_signer_timestamps_never_go_back() -> None:
    signer = SigningState(KEY)
    a = signature_fields(signer.sign(heartbeat(), NOW_S))[1]  # type: ignore[index]
    b = signature_fields(signer.sign(heartbeat(), NOW_S - 100))[1]  # type: ignore[index]
    assert b == a + 1


def test_gate_checks_signed_vehicles_only_and_counts_per_link() -> None:
    keys = SigningKeys(per_vehicle={1: KEY}, sources={"1": "k1"})
    gate = SigningGate(keys, 245, now_unix_s=lambda: NOW_S)
    sent: list[tuple[bytes, int | None]] = []

    class FakeLink:
        def send(self, frame: bytes, system_id: int | None = None) -> bool:
            sent.append((frame, system_id))
            return True

    def rx(frame: bytes, link: str = "vehicles0") -> Received:
        return Received(MavlinkDecoder().feed(frame)[0], frame, link, NOW_S)

    vehicle = SigningState(KEY)
    assert gate.admit(FakeLink(), 0, rx(vehicle.sign(heartbeat(), NOW_S)))
    assert not gate.admit(FakeLink(), 0, rx(heartbeat()))
    assert not gate.admit(FakeLink(), 1, rx(SigningState(OTHER).sign(heartbeat(), NOW_S),
                                            "vehicles1"))
    assert gate.admit(FakeLink(), 0, rx(heartbeat(sysid=2)))  # sysid 2 has no key
    assert sent == []  # no SETUP_SIGNING without signing_setup
    summary = gate.summary()
    assert summary["rejected"] == {"1@vehicles0": {"unsigned": 1},
                                   "1@vehicles1": {"bad_signature": 1}}
    assert summary["accepted"] == {"1": 1}
    assert KEY.hex() not in repr(summary) and repr(KEY) not in repr(gate.keys)
    report = gate.take_report()
    assert [r["new"] for r in report] == [{"unsigned": 1}, {"bad_signature": 1}]
    assert gate.take_report() == []  # nothing new
    # frames to vehicle 1 are signed with its key; to 2 (no key) unchanged
    out = gate.sign(1, 3, heartbeat(245, 190))
    msg = pymav(KEY).decode(bytearray(out))
    assert msg._signed and msg._link_id == 3
    assert gate.sign(2, 0, heartbeat(245, 190)) == heartbeat(245, 190)
    assert gate.sign(None, 0, heartbeat(245, 190)) == heartbeat(245, 190)  # no default key


def test_gate_sends_setup_signing_until_the_vehicle_signs() -> None:
    now = [NOW_S]
    gate = SigningGate(SigningKeys(default=KEY, setup=True), 245, now_unix_s=lambda: now[0])
    sent: list[bytes] = []

    class FakeLink:
        def send(self, frame: bytes, system_id: int | None = None) -> bool:
            sent.append(frame)
            return True

    def rx(frame: bytes) -> Received:
        return Received(MavlinkDecoder().feed(frame)[0], frame, "vehicles0", now[0])

    gcs_heartbeat = MavlinkEncoder(255, 190).encode(M.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3))
    assert not gate.admit(FakeLink(), 0, rx(gcs_heartbeat))
    assert sent == []  # another ground station is refused but never sent a key
    assert not gate.admit(FakeLink(), 0, rx(heartbeat()))
    assert not gate.admit(FakeLink(), 0, rx(heartbeat()))  # within 1 s: not again
    now[0] += 1.5
    assert not gate.admit(FakeLink(), 0, rx(heartbeat()))
    assert len(sent) == 2
    keyless = pymav(None)
    setup = keyless.decode(bytearray(sent[0]))
    assert setup.get_type() == "SETUP_SIGNING" and setup.target_system == 1
    assert bytes(setup.secret_key) == KEY and setup.initial_timestamp >= signing_timestamp(NOW_S)
    assert pymav(KEY).decode(bytearray(sent[1]))._signed  # signed with the new key
    assert gate.admit(FakeLink(), 0, rx(SigningState(KEY).sign(heartbeat(), now[0])))
    now[0] += 5
    assert not gate.admit(FakeLink(), 0, rx(heartbeat()))
    assert len(sent) == 2  # it signs now: a later unsigned frame is refused, not re-keyed


def test_key_loading_errors_are_one_line_and_never_quote_the_key(tmp_path: Path) -> None:
    good = tmp_path / "key.hex"
    good.write_text(KEY.hex() + "\n")
    phrase = tmp_path / "phrase.txt"
    phrase.write_text("correct horse\n")
    bad = tmp_path / "bad.key"
    bad.write_text("not-a-key-secret")
    keys = load_signing_keys(
        parse_config({
            "vehicles": ["sim:2"],
            "signing_passphrase_file": str(phrase),
            "vehicle_settings": {2: {"signing_key_file": str(good)}},
        }, {}),
        environ={},
    )
    assert keys.key_for(1) == KEY and keys.key_for(2) == KEY and keys.key_for(3) == KEY
    assert keys.sources == {"all": str(phrase), "2": str(good)}
    env_keys = load_signing_keys(parse_config({"vehicles": ["sim:1"]}, {}),
                                 environ={"FLOE_SIGNING_PASSPHRASE": "correct horse"})
    assert env_keys.default == KEY and env_keys.sources == {"all": "$FLOE_SIGNING_PASSPHRASE"}
    assert not load_signing_keys(parse_config({"vehicles": ["sim:1"]}, {}), environ={}).enabled
    sim1 = {"vehicles": ["sim:1"]}
    for config, words in (
        (parse_config({**sim1, "signing_key_file": str(bad)}, {}), "signing_key_file"),
        (parse_config({**sim1, "signing_key_file": str(tmp_path / "nope")}, {}), "cannot read"),
        (parse_config({**sim1, "signing_setup": True}, {}), "signing_setup"),
    ):
        with pytest.raises(ConfigError) as err:
            load_signing_keys(config, environ={})
        text = str(err.value)
        assert words in text and "\n" not in text and "not-a-key-secret" not in text


def test_config_carries_paths_never_keys(tmp_path: Path) -> None:
    key_file = tmp_path / "k"
    key_file.write_bytes(KEY)
    yaml_file = tmp_path / "c.yaml"
    yaml_file.write_text(f"vehicle_settings:\n  3: {{signing_key_file: {key_file}}}\n")
    config = build_config(["--config", str(yaml_file), "--vehicles", "sim:3",
                           "--signing-passphrase-file", str(key_file), "--signing-setup"])
    data = config.to_dict()
    assert data["signing"]["passphrase_file"] == str(key_file) and data["signing"]["setup"] is True
    assert data["fleet"]["settings"][3] == {"signing_key_file": str(key_file)}
    assert KEY.hex() not in repr(data)
    yaml_file.write_text("vehicle_settings:\n  3: {signing_key_file: 5}\n")
    with pytest.raises(ConfigError, match=r"vehicle_settings\.3\.signing_key_file"):
        build_config(["--config", str(yaml_file), "--vehicles", "sim:1"])


def test_unsigned_radio_reports_pass_like_on_ardupilot() -> None:
    checker = SigningState(KEY)
    radio = MavlinkEncoder(51, 68).encode(M.MAVLink_radio_message(200, 190, 90, 80, 5, 0, 0))
    assert checker.check(radio, NOW_S) is Verdict.UNSIGNED_ALLOWED
    command = MavlinkEncoder(255, 190).encode(
        M.MAVLink_command_long_message(1, 1, 176, 0, 1, 12, 0, 0, 0, 0, 0))
    assert checker.check(command, NOW_S) is Verdict.UNSIGNED


def test_gcs_run_bad_key_file_is_one_line_exit_2(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    from groundstation.commands.run import run

    bad = tmp_path / "bad.key"
    bad.write_text("secret-words-wrong-size")
    code = run(["--vehicles", "sim:1", "--signing-key", str(bad), "--run-dir", str(tmp_path),
                "--http", "off", "--detections", "off", "--status", "quiet"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "signing_key_file" in err
    assert "secret-words-wrong-size" not in err
