"""`gcs sitl` command line: argument checking, what it serves, scenario wiring, and the
ArduPilot SITL launcher's command lines."""

from __future__ import annotations

import os
import stat
import sys
from pathlib import Path

import pytest

from domain.errors import UsageError
from groundstation.commands import sitl as cmd
from groundstation.commands.sitl_args import SitlOptions
from sitl.ardupilot import ardupilot_commands, default_defaults_file


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--count", "0"], "--count"),
        (["--speedup", "-3"], "--speedup"),
        (["--out", "udp:nohost"], "--out"),
        (["--home", "95,10"], "--home"),
        (["--fault", "1:loss:p=7"], "--fault"),
        (["--loss", "1.5"], "--loss"),
        (["--scenario", "no-such-scenario"], "no-such-scenario"),
        (["--detections", "udp:h:99999"], "--detections"),
        (["--ardupilot", "/nonexistent/arduplane"], "--ardupilot"),
    ],
)
def test_bad_arguments_exit_2_with_the_option_named(
    argv: list[str], needle: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cmd.run(["--base-port", "0", "--duration", "1", *argv]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err


def test_runs_for_a_duration_and_prints_ports(capsys: pytest.CaptureFixture[str]) -> None:
    status = cmd.run(
        [
            "--count",
            "2",
            "--base-port",
            "0",
            "--speedup",
            "50",
            "--duration",
            "10",
            "--fast-boot",
            "--detections",
            "none",
        ]
    )
    out = capsys.readouterr().out
    assert status == 0
    assert "vehicle 0 (system id 1): tcp:127.0.0.1:" in out
    assert "vehicle 1 (system id 2): tcp:127.0.0.1:" in out
    assert "stopped after 10" in out


def parse(argv: list[str]) -> SitlOptions:
    return cmd.parse_options(argv)


def test_scenario_sets_fleet_origin_launch_and_event_faults(tmp_path: Path) -> None:
    scenario = tmp_path / "s.yaml"
    scenario.write_text(
        "name: t\ndescription: t\nduration_s: 100\norigin: {lat_deg: 70.0, lon_deg: 20.0}\n"
        "fleet: {count: 2, speed_m_s: 18, turn_radius_m: 90, launch: {x_m: 100, y_m: 50}}\n"
        "targets:\n  list:\n    - {id: A, x_m: 800, y_m: 300}\n"
        "events:\n  - {t_s: 30, kind: vehicle_lost, vehicle: '2'}\n"
        "  - {t_s: 50, kind: vehicle_returned, vehicle: '2'}\n"
        "  - {t_s: 60, kind: override, vehicle: '1'}\n",
        encoding="utf-8",
    )
    configs, faults, feed, options = cmd.build(
        parse(["--scenario", str(scenario), "--base-port", "0", "--seed", "3"])
    )
    assert [c.system_id for c in configs] == [1, 2]
    assert configs[0].cruise_speed_m_s == 18 and configs[0].min_turn_radius_m == 90
    assert configs[0].origin.lat_deg == 70.0
    x, y, _ = configs[0].origin.to_local(configs[0].home_lat_deg, configs[0].home_lon_deg)
    assert (x, y) == pytest.approx((100, 50), abs=0.01)  # home = the launch point
    assert faults[2].link_down(40.0) and not faults[2].link_down(55.0)
    assert [e.kind for e in faults[1].events] == ["mode"]
    assert feed is not None and options.feed_address == ("127.0.0.1", 14600)


def test_default_home_is_ny_alesund() -> None:
    configs, _, feed, _ = cmd.build(parse(["--base-port", "0"]))
    assert (configs[0].home_lat_deg, configs[0].home_lon_deg) == (78.93, 11.92)
    assert feed is None  # no scenario: no world


def test_ardupilot_command_lines(tmp_path: Path) -> None:
    binary = tmp_path / "ardupilot" / "build" / "sitl" / "bin" / "arduplane"
    defaults = default_defaults_file(binary)
    assert (
        defaults
        == (tmp_path / "ardupilot" / "Tools" / "autotest" / "models" / "plane.parm").resolve()
    )
    launches = ardupilot_commands(binary, 3, 10.0, (78.93, 11.92), defaults, tmp_path / "w")
    assert [(x.instance, x.system_id, x.gcs_port, x.camera_port) for x in launches] == [
        (0, 1, 5760, 5762),
        (1, 2, 5770, 5772),
        (2, 3, 5780, 5782),
    ]
    argv = launches[2].argv
    assert argv[0] == str(binary) and "-S" in argv
    assert argv[argv.index("--model") + 1] == "plane"
    assert argv[argv.index("--speedup") + 1] == "10"
    assert argv[argv.index("-I") + 1] == "2"
    assert argv[argv.index("--sysid") + 1] == "3"
    assert argv[argv.index("--home") + 1] == "78.9300000,11.9200000,0,0"
    assert argv[argv.index("--defaults") + 1] == str(defaults)
    assert len({x.cwd for x in launches}) == 3


def test_gcs_sitl_ardupilot_honours_base_port(tmp_path: Path) -> None:
    """`gcs sitl --ardupilot BIN --base-port 6000 --count 2`: each instance is told its
    port (SITL's --base-port), and the launcher expects the ground station and camera
    there; the default stays ArduPilot's 5760. No ArduPilot binary is run."""
    from groundstation.commands.sitl_ardupilot import ardupilot_launches

    binary = tmp_path / "arduplane"
    defaults = tmp_path / "plane.parm"
    home = (78.93, 11.92)

    options = parse(["--ardupilot", str(binary), "--base-port", "6000", "--count", "2"])
    launches = ardupilot_launches(options, binary, defaults, 2, home)
    assert [(x.gcs_port, x.camera_port) for x in launches] == [(6000, 6002), (6010, 6012)]
    for launch in launches:
        argv = launch.argv
        assert argv[argv.index("--base-port") + 1] == str(launch.gcs_port)
        assert argv.index("-I") < argv.index("--base-port")  # the explicit port wins

    default = ardupilot_launches(parse(["--ardupilot", str(binary)]), binary, defaults, 1, home)
    assert default[0].gcs_port == 5760
    assert default[0].argv[default[0].argv.index("--base-port") + 1] == "5760"

    with pytest.raises(UsageError, match="--base-port: 0"):
        ardupilot_launches(parse(["--ardupilot", str(binary), "--base-port", "0"]),
                           binary, defaults, 1, home)


def _sitl_serial0_port(argv: list[str]) -> int:
    """The SERIAL0 port ArduPilot's SITL_cmdline.cpp arrives at for ``argv``: options are
    read in order; ``--base-port B`` sets the base port, ``-I i`` adds 10 i to it only if it
    is still the default (``if (_base_port == BASE_PORT) _base_port += _instance*10``)."""
    base_port = 5760
    for i, arg in enumerate(argv):
        if arg == "--base-port":
            base_port = int(argv[i + 1])
        elif arg == "-I" and base_port == 5760:
            base_port += 10 * int(argv[i + 1])
    return base_port


@pytest.mark.parametrize("base_port", [5750, 5740, 5760, 5700, 6000])
def test_ardupilot_instances_land_on_the_launchers_ports(tmp_path: Path, base_port: int) -> None:
    """Read as SITL reads its command line, every instance serves the port the launcher
    expects, also when B + 10 i is 5760 for some i > 0 (``--base-port 5750 --count 2``:
    with ``--base-port`` before ``-I``, instance 1 ended up on 5770)."""
    binary = tmp_path / "arduplane"
    launches = ardupilot_commands(
        binary, 8, 10.0, (78.93, 11.92), tmp_path / "plane.parm", tmp_path / "w",
        base_port=base_port,
    )
    assert [_sitl_serial0_port(x.argv) for x in launches] == [x.gcs_port for x in launches]
    assert [x.gcs_port for x in launches] == [base_port + 10 * i for i in range(8)]


def test_ardupilot_launcher_keeps_children_alive_then_stops_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tree = tmp_path / "ardupilot"
    binary = tree / "build" / "sitl" / "bin" / "arduplane"
    binary.parent.mkdir(parents=True)
    parm = tree / "Tools" / "autotest" / "models" / "plane.parm"
    parm.parent.mkdir(parents=True)
    parm.write_text("", encoding="utf-8")
    record = tmp_path / "argv.txt"
    binary.write_text(
        f"#!{sys.executable}\nimport sys, time\n"
        f"open({str(record)!r}, 'a').write(' '.join(sys.argv[1:]) + '\\n')\n"
        "time.sleep(60)\n",
        encoding="utf-8",
    )
    binary.chmod(binary.stat().st_mode | stat.S_IEXEC)
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        status = cmd.run(
            [
                "--ardupilot",
                str(binary),
                "--count",
                "2",
                "--speedup",
                "50",
                "--duration",
                "25",
                "--detections",
                "none",
            ]
        )
    finally:
        os.chdir(cwd)
    assert status == 0
    lines = record.read_text(encoding="utf-8").splitlines()
    assert len(lines) == 2 and {ln.split("--sysid ")[1] for ln in lines} == {"1", "2"}
    assert "ArduPlane SITL 1 (system id 2" in capsys.readouterr().out


def test_ctrl_c_stops_cleanly() -> None:
    import signal
    import subprocess

    proc = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys; from groundstation.cli import main; sys.exit(main(sys.argv[1:]))",
            "sitl",
            "--count",
            "2",
            "--base-port",
            "0",
            "--speedup",
            "10",
            "--detections",
            "none",
            "--out",
            "udp:127.0.0.1:9",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    lines = [proc.stdout.readline() for _ in range(3)]
    assert lines[0].startswith("vehicle 0 (system id 1): tcp:127.0.0.1:")
    assert "all vehicles -> udp:127.0.0.1:9" in lines[2]
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert "stopped after" in out and "Traceback" not in err


def test_port_in_use_is_a_clear_error(capsys: pytest.CaptureFixture[str]) -> None:
    import socket

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        status = cmd.run(["--base-port", str(port), "--duration", "1", "--detections", "none"])
    assert status == 1
    err = capsys.readouterr().err
    assert "cannot open a port" in err and "--base-port" in err and "Traceback" not in err


def test_sitl_out_takes_mavproxy_sending_spellings() -> None:
    from groundstation.commands.sitl_args import parse_udp_url

    assert parse_udp_url("udp:127.0.0.1:14550", "--out") == ("127.0.0.1", 14550)
    assert parse_udp_url("udpout:127.0.0.1:14551", "--out") == ("127.0.0.1", 14551)
    assert parse_udp_url("127.0.0.1:14550", "--out") == ("127.0.0.1", 14550)
    with pytest.raises(UsageError, match=r"udpin: \(listen\) is not supported"):
        parse_udp_url("udpin:0.0.0.0:14550", "--out")


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("tcp:127.0.0.1:5760", r"^--out: sends to udp:HOST:PORT; tcp: \(TCP\) is not supported$"),
        ("tcpin:0.0.0.0:5760", r"tcpin: \(TCP server\) is not supported"),
        ("serial:/dev/ttyUSB0:57600", r"serial: \(serial port\) is not supported"),
        ("foo bar:14550", r"got 'foo bar:14550' \(host 'foo bar' is not a valid host name"),
        ("udp:h:99999", r"got 'udp:h:99999' \(port 99999 is outside 1\.\.65535\)$"),
        ("udp:nohost", r"got 'udp:nohost' \(missing port"),
        ("::1:14550", r"write IPv6 addresses in brackets"),
    ],
)
def test_sitl_udp_addresses_are_read_as_out_urls(text: str, match: str) -> None:
    """The same reading as `gcs run --out` (link.url.parse_out_url): a TCP or serial URL, a
    host that is no host name, are one-line usage errors naming the option (a tcp: URL was
    taken as the host 'tcp:127.0.0.1'), and a bracketed IPv6 address is an address."""
    from groundstation.commands.sitl_args import parse_udp_url

    with pytest.raises(UsageError, match=match):
        parse_udp_url(text, "--out")
    assert parse_udp_url("[::1]:14550", "--detections") == ("::1", 14550)
    assert parse_udp_url("udpout://localhost:14600", "--detections") == ("localhost", 14600)
