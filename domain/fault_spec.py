"""The grammar of fault specs (``VEHICLES:KIND[:key=value,...]``), parsed and validated.

Faults are the MAVLink simulator's (``sitl.faults`` applies them); the grammar lives in
``domain`` because scenarios (``world``) and the daemon's config both carry fault specs and
validate them when they are loaded, without importing the simulator. See ``sitl/faults.py``
for what each kind does.

    1:loss:p=0.2,dir=up       all:delay:s=0.3,jitter=0.1       2:dup:p=0.05
    3:reorder:p=0.1           1:drop:at=60,for=20              2:reboot:at=120
    1:mode:at=90,mode=FBWA    3:battery:at=200,pct=10
    1:airspeed:at=120         1:airspeed:at=120,for=60
"""

from __future__ import annotations

from typing import Any

from domain.errors import ConfigError
from domain.modes import ArduPlaneMode
from domain.yaml_fields import FieldError

__all__ = [
    "FAULT_KINDS",
    "SIM_MODES",
    "FaultError",
    "fault_mode",
    "parse_fault_spec",
    "parse_scenario_faults",
]

FAULT_KINDS = (
    "loss", "dup", "reorder", "delay", "drop", "kill", "reboot", "mode", "battery", "airspeed",
)
SIM_MODES = {m.name: int(m) for m in ArduPlaneMode if m <= 16 and m != 14}
"""Name -> number of the modes the built-in vehicle flies (ArduPlane's up to INITIALISING,
no AVOID_ADSB, no QuadPlane): the simulator's mode table and what ``mode=`` may name."""


class FaultError(ConfigError):
    """A fault spec that cannot be understood (the message names the bad part)."""


def fault_mode(text: str) -> int:
    """The mode number a ``mode=`` option names (a name such as FBWA, or a number)."""
    name = text.upper()
    return int(name) if name.isdigit() else SIM_MODES[name]


def _number(key: str, text: str, spec: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise FaultError(f"fault {spec!r}: {key}={text!r} is not a number") from None


def _probability(key: str, text: str, spec: str) -> float:
    p = _number(key, text, spec)
    if not 0.0 <= p <= 1.0:
        raise FaultError(f"fault {spec!r}: {key} must be in [0, 1], got {p}")
    return p


def parse_fault_spec(spec: str, count_: int) -> list[tuple[int, str, dict[str, str]]]:
    """Split ``VEHICLES:KIND[:k=v,...]`` into (sysid, kind, options) per vehicle; validates."""
    parts = spec.split(":")
    if len(parts) not in (2, 3):
        raise FaultError(f"fault {spec!r}: expected VEHICLES:KIND[:key=value,...]")
    who, kind = parts[0].strip(), parts[1].strip()
    if kind not in FAULT_KINDS:
        raise FaultError(f"fault {spec!r}: unknown kind {kind!r} (one of {', '.join(FAULT_KINDS)})")
    if who == "all":
        sysids = list(range(1, count_ + 1))
    else:
        try:
            sysids = [int(s) for s in who.split(",")]
        except ValueError:
            raise FaultError(f"fault {spec!r}: vehicles must be 'all' or system ids") from None
        bad = [s for s in sysids if not 1 <= s <= count_]
        if bad:
            raise FaultError(f"fault {spec!r}: no vehicle with system id {bad[0]} (1..{count_})")
    options: dict[str, str] = {}
    if len(parts) == 3 and parts[2].strip():
        for pair in parts[2].split(","):
            key, sep, value = pair.partition("=")
            if not sep:
                raise FaultError(f"fault {spec!r}: option {pair!r} is not key=value")
            options[key.strip()] = value.strip()
    _validate(kind, options, spec)
    return [(s, kind, options) for s in sysids]


_ALLOWED = {
    "loss": {"p", "dir"},
    "dup": {"p", "dir"},
    "reorder": {"p", "dir"},
    "delay": {"s", "jitter", "dir"},
    "drop": {"at", "for"},
    "kill": {"at", "for"},
    "reboot": {"at"},
    "mode": {"at", "mode"},
    "battery": {"at", "pct"},
    "airspeed": {"at", "for"},
}
_REQUIRED = {
    "loss": {"p"},
    "dup": {"p"},
    "reorder": {"p"},
    "delay": {"s"},
    "drop": {"at", "for"},
    "kill": {"at", "for"},
    "reboot": {"at"},
    "mode": {"at", "mode"},
    "battery": {"at", "pct"},
    "airspeed": {"at"},
}


def _validate(kind: str, options: dict[str, str], spec: str) -> None:
    unknown = set(options) - _ALLOWED[kind]
    if unknown:
        raise FaultError(f"fault {spec!r}: unknown option {sorted(unknown)[0]!r} for {kind}")
    missing = _REQUIRED[kind] - set(options)
    if missing:
        raise FaultError(f"fault {spec!r}: {kind} needs {sorted(missing)[0]}=...")
    if options.get("dir", "both") not in ("up", "down", "both"):
        raise FaultError(f"fault {spec!r}: dir must be up, down or both")
    if "p" in options:
        _probability("p", options["p"], spec)
    for key in ("s", "jitter", "at", "for", "pct"):
        if key in options and _number(key, options[key], spec) < 0:
            raise FaultError(f"fault {spec!r}: {key} must be >= 0")
    if "pct" in options and _number("pct", options["pct"], spec) > 100:
        raise FaultError(f"fault {spec!r}: pct must be <= 100")
    if (
        kind == "mode"
        and options["mode"].upper() not in SIM_MODES
        and not (options["mode"].isdigit() and int(options["mode"]) in SIM_MODES.values())
    ):
        raise FaultError(f"fault {spec!r}: unknown mode {options['mode']!r}")


def parse_scenario_faults(items: list[Any]) -> tuple[str, ...]:
    """``--fault`` specs (``VEHICLES:KIND[:key=value,...]``) applied by the MAVLink simulator
    (``gcs sitl``, ``gcs run --vehicles sim:N``); the offline simulator has no links."""
    specs: list[str] = []
    for i, item in enumerate(items):
        if not isinstance(item, str):
            raise FieldError(f"faults[{i}]", f"must be a fault spec string, got {item!r}")
        try:
            parse_fault_spec(item, 255)
        except FaultError as exc:
            raise FieldError(f"faults[{i}]", str(exc)) from exc
        specs.append(item)
    return tuple(specs)
