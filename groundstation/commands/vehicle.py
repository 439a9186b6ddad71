"""``gcs vehicle``: launch, resume, release and list the vehicles of a running daemon.

    gcs vehicle launch uav1      # arm when ready, take off, hand over to floe
    gcs vehicle release uav2     # stop commanding it (the operator flies it)
    gcs vehicle resume uav2      # give it back to floe
    gcs vehicle rtl uav2         # send it home (RTL); resume gives it back
    gcs vehicle release --all    # every vehicle (also rtl --all, resume --all)
    gcs vehicle list [--json]

Every action prints what happened (per vehicle with ``--all``), and exits 1 if the daemon
refused it (with ``--all``: refused for any vehicle), naming why.

A vehicle is named by its id, its name or its MAVLink system id. Same ``--api``/``--token``/
``--run-dir`` options (the running daemon is found through its ``control.json``) and exit
statuses as ``gcs target`` (docs/control.md).
"""

from __future__ import annotations

import argparse
import json
import sys
import urllib.parse
from typing import Any

from groundstation.commands.target import ApiClient, ApiError, add_api_options, connect, table

__all__ = ["run"]

ACTIONS = {
    "launch": "arm a vehicle on the ground when its pre-arm checks pass, take off, take over",
    "resume": "give a released or overridden vehicle back to floe",
    "release": "stop commanding a vehicle (it keeps flying its current mission)",
    "rtl": "send a vehicle home (RTL); floe stops planning it until resumed",
}
FLEET = ("release", "rtl", "resume")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        allow_abbrev=False,
        prog="gcs vehicle",
        description="Launch, resume, release or list the vehicles of "
        "the running daemon (through its control API).",
    )
    sub = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    for action, text in ACTIONS.items():
        sp = sub.add_parser(action, help=text, allow_abbrev=False)
        if action in FLEET:
            sp.add_argument("id", nargs="?", default=None,
                            help="vehicle id, name or system id (or --all)")
            sp.add_argument("--all", action="store_true",
                            help="every vehicle, each as it alone would be")
        else:
            sp.add_argument("id", help="vehicle id, name or system id")
        add_api_options(sp)
    lst = sub.add_parser("list", help="list the vehicles", allow_abbrev=False)
    lst.add_argument("--json", action="store_true", help="print the API's JSON")
    add_api_options(lst)
    return p


def _fmt(value: Any, fmt: str = "{}") -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    return fmt.format(value)


def _list(client: ApiClient, as_json: bool) -> int:
    body = client.get("/api/vehicles")
    if as_json:
        print(json.dumps(body, indent=2))
        return 0
    vehicles = (body.get("vehicles") or []) if isinstance(body, dict) else []
    rows = [
        [
            str(v.get("id")),
            _fmt(v.get("name")),
            _fmt(v.get("system_id")),
            _fmt(v.get("mode")),
            _fmt(v.get("armed")),
            _fmt(v.get("status")),
            _fmt(v.get("link")),
            _fmt(v.get("battery_pct"), "{:.0f}%"),
            _fmt(v.get("target")),
            " ".join(str(t) for t in v.get("route") or []) or "-",
        ]
        for v in vehicles
    ]
    print(
        table(
            rows,
            [
                "id",
                "name",
                "sysid",
                "mode",
                "armed",
                "status",
                "link",
                "battery",
                "target",
                "route",
            ],
        )
    )
    if not rows:
        print("(no vehicles)")
    for v in vehicles:
        wanted = v.get("launch_wanted")
        if isinstance(wanted, dict):
            vid = v.get("id")
            why = (f"relief of {wanted['relieves']}" if wanted.get("relieves") is not None
                   else wanted.get("reason"))
            print(f"vehicle {vid}: launch wanted ({why}): catapult it, or "
                  f"'gcs vehicle launch {vid}'")
        if v.get("launch_held"):
            vid = v.get("id")
            print(f"vehicle {vid}: {v['launch_held']}; floe will not launch it on its own "
                  f"('gcs vehicle launch {vid}' launches it)")
    return 0


def _fleet(client: ApiClient, action: str) -> int:
    """``ACTION --all``: one line per vehicle; exit 1 if any was refused."""
    reply = client.write("POST", f"/api/fleet/{action}")
    results = reply.get("results") if isinstance(reply, dict) else None
    if not isinstance(results, list):
        raise ApiError("the daemon gave no per-vehicle answer", 1)
    refused = 0
    for r in results:
        if not isinstance(r, dict):
            continue
        if r.get("ok"):
            print(f"{action} vehicle {r.get('vehicle')}: {r.get('what') or 'done'}")
        else:
            refused += 1
            print(f"{action} vehicle {r.get('vehicle')}: refused: {r.get('error')}",
                  file=sys.stderr)
    if not results:
        print(f"{action} --all: the daemon has no vehicle")
    print(f"{action} --all: {len(results) - refused} done, {refused} refused")
    return 1 if refused else 0


def run(argv: list[str]) -> int:
    try:
        args = _parser().parse_args(argv)
    except SystemExit as exc:  # argparse already printed the usage error
        return int(exc.code or 0) if not isinstance(exc.code, str) else 2
    try:
        client = connect(args, "gcs vehicle")
        if args.action == "list":
            return _list(client, args.json)
        if getattr(args, "all", False):
            if args.id is not None:
                raise ApiError("give a vehicle or --all, not both", 2)
            return _fleet(client, args.action)
        if args.id is None:
            raise ApiError(f"{args.action}: give a vehicle id, name or system id, or --all", 2)
        ref = urllib.parse.quote(args.id, safe="")
        reply = client.write("POST", f"/api/vehicles/{ref}/{args.action}")
        vehicle = reply.get("vehicle", args.id) if isinstance(reply, dict) else args.id
        what = reply.get("what") if isinstance(reply, dict) else None
        print(what or f"{args.action}: vehicle {vehicle} ok")
        return 0
    except ApiError as exc:
        print(f"gcs vehicle: error: {exc}", file=sys.stderr)
        return exc.status
