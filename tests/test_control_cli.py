"""``gcs target`` and ``gcs vehicle`` against a running ControlServer with a fake daemon:
success, bad or missing token, refusals, bad options, daemon down (exit statuses 0/1/2)."""

from __future__ import annotations

import json
import socket
from collections.abc import Iterator

import pytest
from test_control_fake import ServerThread

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
    assert capsys.readouterr().out.strip() == "release: vehicle uav2 ok"
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
