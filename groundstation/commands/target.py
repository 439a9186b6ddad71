"""``gcs target``: add, move, remove and list the targets of a running daemon.

    gcs target add ICE7 --x 1200 --y -300 [--vx 0.5 --vy -0.2 --sigma0 5]
    gcs target add --lat 78.94 --lon 11.93          # the daemon names it
    gcs target move ICE7 --x 1210 --y -310
    gcs target remove ICE7
    gcs target list [--json]

A client of the daemon's control API (docs/control.md). Without ``--api URL`` (or
``$FLOE_API``) it finds the running daemon itself: the newest live one whose
``control.json`` is in a run folder under ``--run-dir`` (default ``runs``), and says which
(:mod:`groundstation.commands.daemon_finder`); writes use that file's token unless
``--token`` (or, with ``--api``/``$FLOE_API``, ``$FLOE_TOKEN``) gives one.
Exit status: 0 done, 1 refused by the daemon (unknown id, outside
the operating area ...) or daemon unreachable, 2 user error (bad option, missing or wrong
token, request rejected as malformed).

This module also holds the small HTTP client shared with ``gcs vehicle``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import urllib.error
import urllib.parse
import urllib.request
from typing import Any

from domain.errors import UsageError

__all__ = ["ApiClient", "ApiError", "add_api_options", "connect", "run", "table"]

EXIT_REFUSED = 1
PROBE_TIMEOUT_S = 1.0
EXIT_USAGE = 2


class ApiError(UsageError):
    """A failed call: one-line message and the exit status it maps to."""

    def __init__(self, message: str, status: int) -> None:
        super().__init__(message)
        self.status = status


def add_api_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--api",
        default=None,
        metavar="URL",
        help="control API of the daemon (default $FLOE_API, else the newest running daemon "
        "found through the control.json of its run folder)",
    )
    p.add_argument(
        "--token",
        default=None,
        help="write token printed by 'gcs run' (default: the found daemon's control.json; "
        "$FLOE_TOKEN with --api/$FLOE_API)",
    )
    p.add_argument(
        "--run-dir",
        default=None,
        metavar="DIR",
        help="where gcs run writes its run folders, searched for control.json (default runs)",
    )
    p.add_argument("--timeout", type=float, default=5.0, help="seconds to wait (default 5)")


def connect(args: argparse.Namespace, prog: str) -> ApiClient:
    """The client of the daemon chosen by ``--api``/``$FLOE_API`` or found through its
    ``control.json`` (:func:`groundstation.commands.daemon_finder.find_daemon`); the choice
    of a found daemon is said on stderr."""
    from groundstation.commands.daemon_finder import find_daemon

    if not (math.isfinite(args.timeout) and args.timeout > 0):
        raise ApiError("--timeout: must be a positive number of seconds", EXIT_USAGE)

    def is_live(url: str) -> bool:
        try:
            body = ApiClient(url, None, min(args.timeout, PROBE_TIMEOUT_S)).get("/api/server")
        except ApiError:
            return False
        return isinstance(body, dict) and "limits" in body

    try:
        found = find_daemon(args.api, args.token, args.run_dir, is_live)
    except LookupError as exc:
        raise ApiError(str(exc), EXIT_REFUSED) from None
    if found.note is not None:
        print(f"{prog}: {found.note}", file=sys.stderr, flush=True)
    return ApiClient(found.url, found.token, args.timeout)


class ApiClient:
    """Blocking JSON client of the control API (stdlib only)."""

    def __init__(self, api: str, token: str | None, timeout_s: float = 5.0) -> None:
        base = api.strip().rstrip("/")
        parsed = urllib.parse.urlsplit(base)
        if parsed.scheme not in ("http", "https") or not parsed.hostname:
            raise ApiError(f"--api: expected http://HOST:PORT, got {base!r}", EXIT_USAGE)
        try:
            parsed.port  # noqa: B018 - validates the port
        except ValueError:
            raise ApiError(f"--api: bad port in {base!r}", EXIT_USAGE) from None
        if not (math.isfinite(timeout_s) and timeout_s > 0):
            raise ApiError("--timeout: must be a positive number of seconds", EXIT_USAGE)
        self.base = base
        self.token = token
        self.timeout_s = timeout_s

    def get(self, path: str) -> Any:
        return self.request("GET", path)

    def write(self, method: str, path: str, body: dict[str, Any] | None = None) -> Any:
        if not self.token:
            raise ApiError(
                "no token: pass the token printed by 'gcs run' with --token or FLOE_TOKEN "
                "(a daemon found through its control.json needs neither)",
                EXIT_USAGE,
            )
        reply = self.request(method, path, body)
        if isinstance(reply, dict) and reply.get("ok") is False:
            raise ApiError(f"refused: {reply.get('error') or 'no reason given'}", EXIT_REFUSED)
        return reply

    def request(self, method: str, path: str, body: dict[str, Any] | None = None) -> Any:
        headers = {"Accept": "application/json"}
        data = None
        if body is not None:
            data = json.dumps(body).encode()
            headers["Content-Type"] = "application/json"
        if method != "GET" and self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        req = urllib.request.Request(self.base + path, data=data, method=method, headers=headers)
        try:
            with urllib.request.urlopen(req, timeout=self.timeout_s) as resp:
                return self._decode(resp.read())
        except urllib.error.HTTPError as exc:
            raise self._http_error(exc) from None
        except urllib.error.URLError as exc:
            reason = exc.reason
            if isinstance(reason, ConnectionRefusedError):
                raise ApiError(
                    f"daemon not running at {self.base} (connection refused; start "
                    "'gcs run', or leave out --api/FLOE_API to find the running daemon)",
                    EXIT_REFUSED,
                ) from None
            if isinstance(reason, TimeoutError):
                raise ApiError(
                    f"no answer from {self.base} within {self.timeout_s:g} s", EXIT_REFUSED
                ) from None
            raise ApiError(
                f"cannot reach the daemon at {self.base}: {reason}", EXIT_REFUSED
            ) from None
        except TimeoutError:
            raise ApiError(
                f"no answer from {self.base} within {self.timeout_s:g} s", EXIT_REFUSED
            ) from None
        except (ConnectionError, OSError) as exc:
            raise ApiError(f"connection to {self.base} failed: {exc}", EXIT_REFUSED) from None

    def _decode(self, raw: bytes) -> Any:
        try:
            return json.loads(raw)
        except (UnicodeDecodeError, json.JSONDecodeError):
            raise ApiError(
                f"{self.base} did not answer JSON: is it a floe daemon?", EXIT_REFUSED
            ) from None

    def _http_error(self, exc: urllib.error.HTTPError) -> ApiError:
        try:
            reason = str(json.loads(exc.read()).get("error") or exc.reason)
        except (ValueError, AttributeError, OSError):
            reason = str(exc.reason)
        reason = " ".join(reason.split())
        if exc.code == 401:
            return ApiError(
                f"token rejected by {self.base}: pass the token printed by "
                "'gcs run' with --token or FLOE_TOKEN",
                EXIT_USAGE,
            )
        if exc.code in (400, 413):
            return ApiError(f"bad request: {reason}", EXIT_USAGE)
        if exc.code == 404 and reason.lower() in ("not found", ""):
            return ApiError(
                f"{self.base} has no control API here: is it a floe daemon?", EXIT_REFUSED
            )
        if exc.code in (404, 409):
            return ApiError(f"refused: {reason}", EXIT_REFUSED)
        return ApiError(f"daemon error (HTTP {exc.code}): {reason}", EXIT_REFUSED)


def table(rows: list[list[str]], header: list[str]) -> str:
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    lines = [
        "  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
        for r in [header, *rows]
    ]
    return "\n".join(lines)


def _fmt(value: Any, digits: int = 1) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.{digits}f}"
    return str(value)


def _finite(value: float | None, option: str) -> float | None:
    if value is not None and not math.isfinite(value):
        raise ApiError(f"{option}: must be a finite number", EXIT_USAGE)
    return value


def _position(args: argparse.Namespace) -> dict[str, float]:
    x, y = _finite(args.x, "--x"), _finite(args.y, "--y")
    lat, lon = _finite(args.lat, "--lat"), _finite(args.lon, "--lon")
    local, geo = (x is not None or y is not None), (lat is not None or lon is not None)
    if local and geo:
        raise ApiError("give either --x/--y or --lat/--lon, not both", EXIT_USAGE)
    if local:
        if x is None or y is None:
            raise ApiError(
                f"{'--y' if y is None else '--x'}: missing (--x and --y go together)", EXIT_USAGE
            )
        return {"x_m": x, "y_m": y}
    if geo:
        if lat is None or lon is None:
            raise ApiError(
                f"{'--lon' if lon is None else '--lat'}: missing (--lat and --lon go together)",
                EXIT_USAGE,
            )
        if not -90.0 <= lat <= 90.0:
            raise ApiError("--lat: must be in [-90, 90] degrees", EXIT_USAGE)
        if not -180.0 <= lon <= 180.0:
            raise ApiError("--lon: must be in [-180, 180] degrees", EXIT_USAGE)
        return {"lat_deg": lat, "lon_deg": lon}
    raise ApiError("position missing: give --x X --y Y (local metres) or --lat --lon", EXIT_USAGE)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        allow_abbrev=False,
        prog="gcs target",
        description="Add, move, remove or list the targets of the "
        "running daemon (through its control API).",
    )
    sub = p.add_subparsers(dest="action", required=True, metavar="ACTION")

    def position_options(sp: argparse.ArgumentParser) -> None:
        sp.add_argument("--x", type=float, help="east of the mission origin (m)")
        sp.add_argument("--y", type=float, help="north of the mission origin (m)")
        sp.add_argument("--lat", type=float, help="latitude (deg, WGS-84)")
        sp.add_argument("--lon", type=float, help="longitude (deg, WGS-84)")

    add = sub.add_parser("add", allow_abbrev=False, help="add a target")
    add.add_argument("id", nargs="?", default=None, help="target id (default: daemon names it)")
    position_options(add)
    add.add_argument("--vx", type=float, default=None, help="drift east (m/s)")
    add.add_argument("--vy", type=float, default=None, help="drift north (m/s)")
    add.add_argument("--sigma0", type=float, default=None, help="initial uncertainty (m^2)")
    move = sub.add_parser("move", allow_abbrev=False,
                          help="an operator's fix: the target is here now (the track is "
                          "re-seated there, not gated as a measurement)")
    move.add_argument("id", help="target id")
    position_options(move)
    move.add_argument("--sigma0", type=float, default=None,
                      help="uncertainty of the fix (m^2; default: the daemon's, one camera fix)")
    remove = sub.add_parser("remove", allow_abbrev=False, help="remove a target")
    remove.add_argument("id", help="target id")
    lst = sub.add_parser("list", allow_abbrev=False, help="list the targets")
    lst.add_argument("--json", action="store_true", help="print the API's JSON")
    for sp in (add, move, remove, lst):
        add_api_options(sp)
    return p


def _quote(target_id: str) -> str:
    return urllib.parse.quote(target_id, safe="")


def _list(client: ApiClient, as_json: bool) -> int:
    body = client.get("/api/targets")
    targets = body.get("targets") or [] if isinstance(body, dict) else []
    if as_json:
        print(json.dumps(body, indent=2))
        return 0
    now = body.get("t") if isinstance(body, dict) else None
    rows = []
    for t in targets:
        seen = t.get("last_seen_s")
        if isinstance(now, int | float) and isinstance(seen, int | float):
            ago = f"{now - seen:.0f} s ago"
        elif t.get("status") == "tentative":
            ago = "at birth"  # born of one detection, none accepted since
        elif t.get("status") == "prior":
            ago = "never (listed)"
        else:
            ago = "never"
        rows.append(
            [
                str(t.get("id")),
                _fmt(t.get("x_m")),
                _fmt(t.get("y_m")),
                _fmt(t.get("vx_m_s"), 2),
                _fmt(t.get("vy_m_s"), 2),
                _fmt(t.get("sigma")),
                ago,
                _fmt(t.get("lost")),
                str(t.get("status") or "-"),
            ]
        )
    print(table(rows, ["id", "x_m", "y_m", "vx_m_s", "vy_m_s", "sigma", "last seen", "lost",
                       "status"]))
    if not rows:
        print("(no targets)")
    return 0


def _execute(args: argparse.Namespace) -> int:
    client = connect(args, "gcs target")
    if args.action == "list":
        return _list(client, args.json)
    if args.action == "add":
        body: dict[str, Any] = _position(args)
        if args.id is not None:
            body["id"] = args.id
        for option, key in (("vx", "vx_m_s"), ("vy", "vy_m_s"), ("sigma0", "sigma0")):
            value = _finite(getattr(args, option), f"--{option}")
            if value is not None:
                body[key] = value
        if body.get("sigma0", 0.0) < 0:
            raise ApiError("--sigma0: must be >= 0", EXIT_USAGE)
        reply = client.write("POST", "/api/targets", body)
        print(f"added target {reply.get('target', args.id)}")
    elif args.action == "move":
        fix: dict[str, Any] = dict(_position(args))
        sigma0 = _finite(args.sigma0, "--sigma0")
        if sigma0 is not None:
            if sigma0 < 0:
                raise ApiError("--sigma0: must be >= 0", EXIT_USAGE)
            fix["sigma0"] = sigma0
        reply = client.write("PUT", f"/api/targets/{_quote(args.id)}", fix)
        print(f"moved target {args.id}: now at ({_fmt(reply.get('x_m'))}, "
              f"{_fmt(reply.get('y_m'))}) m, sigma {_fmt(reply.get('sigma'), 2)} m^2")
    else:
        client.write("DELETE", f"/api/targets/{_quote(args.id)}")
        print(f"removed target {args.id}")
    return 0


def run(argv: list[str]) -> int:
    try:
        args = _parser().parse_args(argv)
    except SystemExit as exc:  # argparse already printed the usage error
        return int(exc.code or 0) if not isinstance(exc.code, str) else EXIT_USAGE
    try:
        return _execute(args)
    except ApiError as exc:
        print(f"gcs target: error: {exc}", file=sys.stderr)
        return exc.status
