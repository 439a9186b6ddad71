"""``gcs target`` and ``gcs vehicle`` against a running ControlServer with a fake daemon:
success, bad or missing token, refusals, bad options, daemon down (exit statuses 0/1/2)."""

from __future__ import annotations

import json
import socket
from collections.abc import Iterator

import pytest
from test_control_fake import ServerThread

from domain.errors import UsageError
from groundstation.commands import target, vehicle

TOKEN = "cli-token"


@pytest.fixture(scope="module")
def server() -> Iterator[ServerThread]:
    with ServerThread(token=TOKEN) as srv:
        yield srv


@pytest.fixture(autouse=True)
def no_env(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("FLOE_API", raising=False)
    monkeypatch.delenv("FLOE_TOKEN", raising=False)


def one_line_error(capsys: pytest.CaptureFixture[str], *words: str) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    for word in words:
        assert word in err, err
    return err


def test_target_add_move_remove_list(server: ServerThread,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    api = ["--api", server.url, "--token", TOKEN]
    assert target.run(["add", "ICE7", "--x", "120", "--y", "-40", "--vx", "0.5",
                       "--sigma0", "4", *api]) == 0
    assert capsys.readouterr().out.strip() == "added target ICE7"
    assert target.run(["add", "--lat", "78.94", "--lon", "11.93", *api]) == 0
    assert capsys.readouterr().out.strip().startswith("added target T")
    assert target.run(["move", "ICE7", "--x", "130", "--y", "-45", *api]) == 0
    assert target.run(["remove", "B", *api]) == 0
    capsys.readouterr()
    assert target.run(["list", "--api", server.url]) == 0  # reads need no token
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[:3] == ["id", "x_m", "y_m"]
    ids = [line.split()[0] for line in out[1:]]
    assert "ICE7" in ids and "B" not in ids and "A" in ids
    assert target.run(["list", "--json", "--api", server.url]) == 0
    body = json.loads(capsys.readouterr().out)
    ice7 = next(t for t in body["targets"] if t["id"] == "ICE7")
    assert (ice7["x_m"], ice7["y_m"]) == (130.0, -45.0)
    calls = server.call(lambda: list(server.control.calls))
    assert ("add", "ICE7", 120.0, -40.0, None, None, 0.5, 0.0, 4.0) in calls


def test_vehicle_actions_and_list(server: ServerThread,
                                  capsys: pytest.CaptureFixture[str],
                                  monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FLOE_API", server.url)  # the environment works like the options
    monkeypatch.setenv("FLOE_TOKEN", TOKEN)
    assert vehicle.run(["release", "X8-2"]) == 0
    assert capsys.readouterr().out.strip() == "vehicle uav2 released"  # what happened
    assert vehicle.run(["resume", "2"]) == 0
    assert vehicle.run(["launch", "uav1"]) == 0
    capsys.readouterr()
    held = "came down in FBWA while the operator had it"
    server.call(lambda: server.control.vehicles[2].update(status="on_ground", launch_held=held))
    assert vehicle.run(["list"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[:4] == ["id", "name", "sysid", "mode"]
    assert [line.split()[0] for line in out[1:4]] == ["uav1", "uav2", "uav3"]
    # why floe holds a launch, and what launches it
    assert out[-1] == (f"vehicle uav3: {held}; floe will not launch it on its own "
                       "('gcs vehicle launch uav3' launches it)")
    calls = server.call(lambda: list(server.control.calls))
    assert calls[-3:] == [("vehicle", "uav2", "release"), ("vehicle", "uav2", "resume"),
                          ("vehicle", "uav1", "launch")]


def test_bad_or_missing_token_is_a_user_error(server: ServerThread,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    before = server.call(lambda: len(server.control.calls))
    assert target.run(["remove", "A", "--api", server.url, "--token", "nope"]) == 2
    one_line_error(capsys, "token rejected", "--token")
    assert vehicle.run(["launch", "uav1", "--api", server.url, "--token", "nope"]) == 2
    one_line_error(capsys, "token rejected")
    assert target.run(["remove", "A", "--api", server.url]) == 2
    one_line_error(capsys, "no token")
    assert server.call(lambda: len(server.control.calls)) == before


def test_refusals_exit_1(server: ServerThread, capsys: pytest.CaptureFixture[str]) -> None:
    api = ["--api", server.url, "--token", TOKEN]
    assert target.run(["remove", "NOPE", *api]) == 1
    one_line_error(capsys, "refused", "NOPE")
    assert vehicle.run(["launch", "uav9", *api]) == 1
    one_line_error(capsys, "refused", "uav9")
    server.call(lambda: setattr(server.control, "refuse", "outside the operating area"))
    try:
        assert target.run(["add", "FAR", "--x", "9e5", "--y", "0", *api]) == 1
        one_line_error(capsys, "refused: outside the operating area")
    finally:
        server.call(lambda: setattr(server.control, "refuse", None))


@pytest.mark.parametrize(("argv", "words"), [
    (["add", "X", "--x", "1"], ["--y", "missing"]),
    (["add", "X"], ["position missing"]),
    (["add", "X", "--x", "1", "--y", "2", "--lat", "3", "--lon", "4"], ["not both"]),
    (["add", "X", "--lat", "91", "--lon", "4"], ["--lat"]),
    (["add", "X", "--x", "nan", "--y", "2"], ["--x", "finite"]),
    (["add", "X", "--x", "1", "--y", "2", "--sigma0", "-3"], ["--sigma0"]),
    (["add", "X", "--x", "1", "--y", "2", "--api", "ftp://host"], ["--api"]),
    (["move", "X", "--lon", "4"], ["--lat", "missing"]),
])
def test_bad_options_exit_2_before_any_request(argv: list[str], words: list[str],
                                               capsys: pytest.CaptureFixture[str]) -> None:
    assert target.run([*argv, "--token", TOKEN, "--api", "http://127.0.0.1:9"]
                      if "--api" not in argv else [*argv, "--token", TOKEN]) == 2
    one_line_error(capsys, *words)


def test_argparse_errors_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert target.run(["add", "X", "--x", "east"]) == 2
    assert vehicle.run(["explode", "uav1"]) == 2
    assert vehicle.run([]) == 2
    capsys.readouterr()
    assert target.run(["--help"]) == 0


def test_daemon_down(capsys: pytest.CaptureFixture[str]) -> None:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()  # nothing listens there now
    api = f"http://127.0.0.1:{port}"
    assert target.run(["list", "--api", api]) == 1
    one_line_error(capsys, "daemon not running", api)
    assert vehicle.run(["launch", "uav1", "--api", api, "--token", TOKEN]) == 1
    one_line_error(capsys, "daemon not running")


def test_something_else_on_the_port(capsys: pytest.CaptureFixture[str]) -> None:
    """A server that is not a floe daemon: answered with a clear error, not a traceback."""
    import http.server
    import threading

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            self.send_response(200)
            self.end_headers()
            self.wfile.write(b"<html>hello</html>")

        def log_message(self, *args: object) -> None:
            pass

    httpd = http.server.HTTPServer(("127.0.0.1", 0), Handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    try:
        assert target.run(["list", "--api", f"http://127.0.0.1:{httpd.server_port}"]) == 1
        one_line_error(capsys, "floe daemon")
    finally:
        httpd.shutdown()
        httpd.server_close()


def test_a_move_says_where_the_track_is_now_and_a_refusal_exits_1(
        capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 29: ``gcs target move`` printed "moved target B7" and exited 0 whatever the
    daemon did. It prints the daemon's answer (the re-seated track), and a refusal (even
    one answered ``ok: false`` with status 200) is exit 1 with the reason."""
    with ServerThread(token=TOKEN) as srv:
        api = ["--api", srv.url, "--token", TOKEN]
        assert target.run(["move", "A", "--x", "130", "--y", "-45", "--sigma0", "7", *api]) == 0
        assert capsys.readouterr().out.strip() == (
            "moved target A: now at (130.0, -45.0) m, sigma 7.00 m^2")
        srv.call(lambda: setattr(srv.control, "refuse", "position is outside the area"))
        assert target.run(["move", "A", "--x", "1", "--y", "2", *api]) == 1
        one_line_error(capsys, "refused: position is outside the area")


def test_tentative_tracks_do_not_read_never_seen(capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 29: tentative tracks (born of a detection) read "last seen never"."""
    with ServerThread(token=TOKEN) as srv:
        assert target.run(["list", "--api", srv.url]) == 0
        rows = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()[1:]}
        assert "at birth" in rows["C"] and rows["C"].split()[-1] == "tentative"
        assert "never (listed)" in rows["B"]
        assert "never" not in rows["C"]


def test_fleet_actions_answer_per_vehicle(capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 29: release/RTL/resume all, each vehicle's answer on its own line; exit 1
    when any vehicle refused."""
    with ServerThread(token=TOKEN) as srv:
        api = ["--api", srv.url, "--token", TOKEN]
        assert vehicle.run(["release", "--all", *api]) == 0
        out = capsys.readouterr().out.splitlines()
        assert out == ["release vehicle uav1: vehicle uav1 released",
                       "release vehicle uav2: vehicle uav2 released",
                       "release vehicle uav3: vehicle uav3 released",
                       "release --all: 3 done, 0 refused"]
        srv.call(lambda: srv.control.vehicles[1].update(status="active"))
        assert vehicle.run(["resume", "--all", *api]) == 1  # uav2 is active already
        captured = capsys.readouterr()
        assert "resume --all: 2 done, 1 refused" in captured.out
        assert "resume vehicle uav2: refused: vehicle uav2 is active already" in captured.err
        assert vehicle.run(["rtl", "--all", *api]) == 0
        assert srv.call(lambda: [v["status"] for v in srv.control.vehicles]) == ["home"] * 3
        assert srv.call(lambda: srv.control.calls[-3:]) == [
            ("fleet", "release"), ("fleet", "resume"), ("fleet", "rtl")]
        capsys.readouterr()
        assert vehicle.run(["rtl", "uav1", "--all", *api]) == 2
        one_line_error(capsys, "a vehicle or --all, not both")
        assert vehicle.run(["release", *api]) == 2
        one_line_error(capsys, "give a vehicle")


@pytest.mark.parametrize(("name", "argv"), [
    ("run", ["--vehicle", "sim:3"]), ("simulate", ["--uav", "2"]),
    ("replay", ["runs/x", "--spe", "2"]), ("plan", ["-", "--work", "2"]),
    ("sitl", ["--vehicle", "2"]), ("target", ["list", "--js"]),
    ("vehicle", ["list", "--js"]), ("report", ["x", "--ou", "y"]),
    ("campaign", ["--spe", "x"]), ("campaign_report", ["x", "--ou", "y"]),
])
def test_no_option_is_guessed_from_a_prefix(name: str, argv: list[str],
                                            capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 29: ``gcs run --vehicle sim:3`` ran as ``--vehicles`` (argparse's prefix
    matching) and launched a fleet. Every parser refuses an option it does not know, a
    prefix of one included (parsed only: nothing runs)."""
    import importlib

    module = importlib.import_module(f"groundstation.commands.{name}")
    parser = module._parser()
    assert parser.allow_abbrev is False
    with pytest.raises((SystemExit, UsageError)) as raised:
        parser.parse_args(argv)
    if isinstance(raised.value, SystemExit):
        assert raised.value.code == 2
        err = capsys.readouterr().err
        assert "unrecognized arguments" in err or "are required: --out" in err, err
