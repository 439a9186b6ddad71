"""The grammar of telemetry-radio specs (``[VEHICLES:]sik[,key=value,...]`` | ``none``).

The radio is the MAVLink simulator's (:mod:`sitl.radio` models it); the grammar lives in
``domain`` because ``gcs sitl``, ``gcs run --vehicles sim:N`` (its config's ``sim_radio``)
and scenarios (``radio:``) all carry radio specs and check them when they are read, without
importing the simulator. :class:`SikTiming` is SiK's ``tdm_init`` arithmetic (packet
overhead, window, silence in 16 us ticks): the simulator's radio runs on it, and a spec
whose window cannot hold a single packet is refused here.

    sik                         a SiK radio pair at its defaults on every vehicle link
    sik,loss=0.05               ... losing 5 % of its air packets, in bursts
    sik,air=32,ecc=1            ... at 32 kbit/s in the air, with Golay error correction
    2:sik,loss=0.2,burst=5      vehicle 2 only
    1,3:none                    vehicles 1 and 3 without a radio (plain sockets)
    none | off                  no radio at all

``VEHICLES`` is ``all`` (the default), a system id or ``a,b,...``. Several specs apply in
order and a later one wins for the vehicles it names (a scenario's first, then the command
line's). Options, each changing one property of SiK's defaults (SiK firmware
``parameters.c``: SERIAL_SPEED 57, AIR_SPEED 64, ECC 0, MAX_WINDOW 131):

==========  =========================================================  ========
key         meaning                                                    default
==========  =========================================================  ========
baud        serial rate at both ends, 8N1 (a SiK SERIAL_SPEED)          57600
air         air data rate, kbit/s (rounded up to a Si1000 rate)         64
loss        mean air-packet loss, [0, 1)                                0.01
burst       mean length of a run of lost packets (>= 1)                 3
ecc         1: Golay error-correcting code (twice the air bytes)        0
window      MAX_WINDOW, ms: the longest transmit window (20..131)       131
buffer      serial receive buffer of each radio, bytes (256..65536)     1850
seed        the loss process's seed (default: from the run's seed)      -
==========  =========================================================  ========
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from typing import Any

from domain.errors import ConfigError
from domain.yaml_fields import FieldError

__all__ = [
    "AIR_RATES_KBPS",
    "SERIAL_BAUDS",
    "RadioSpec",
    "RadioSpecError",
    "SikTiming",
    "parse_radio_spec",
    "parse_scenario_radio",
    "radio_assignments",
]

SERIAL_BAUDS = (1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400)
"""The serial rates a SiK radio offers (SERIAL_SPEED 1, 2, 4, 9, 19, 38, 57, 115, 230)."""
AIR_RATES_KBPS = (2, 4, 8, 16, 19, 24, 32, 48, 64, 96, 128, 192, 250)
"""The Si1000 air data rates SiK offers (kbit/s); AIR_SPEED is rounded up to one of them."""


TICK_S = 16e-6
"""SiK's timer2 tick."""
MAX_PACKET_LENGTH = 252
TRAILER_BYTES = 2
PREAMBLE_NIBBLES = 16
PACKET_OVERHEAD = TRAILER_BYTES + 16
"""SiK sends nothing when fewer bytes than this fit in the time left (``tdm.c``)."""


class RadioSpecError(ConfigError):
    """A radio spec that cannot be understood (the message names the bad part)."""


@dataclass(frozen=True, slots=True)
class RadioSpec:
    """One SiK radio pair's settings (see the module docstring for each)."""

    baud: int = 57600
    air_kbps: int = 64
    loss: float = 0.01
    burst: float = 3.0
    ecc: bool = False
    window_ms: int = 131
    buffer_bytes: int = 1850
    seed: int | None = None

    def describe(self) -> str:
        """One line: ``SiK radio: 57600 baud, 64 kbit/s air, 1 % loss in bursts of 3 ..."""
        return (
            f"SiK radio: {self.baud} baud serial, {self.air_kbps} kbit/s air"
            f"{', Golay ECC' if self.ecc else ''}, {self.loss * 100:g} % packet loss in bursts"
            f" of {self.burst:g}, window {self.window_ms} ms, buffer {self.buffer_bytes} B"
            + (f", seed {self.seed}" if self.seed is not None else "")
        )


@dataclass(frozen=True, slots=True)
class SikTiming:
    """SiK's TDM figures for one air rate (``tdm_init``), in 16 us ticks."""

    ticks_per_byte: int
    packet_latency: int
    silence: int
    window: int
    max_data: int

    @classmethod
    def of(cls, spec: RadioSpec) -> SikTiming:
        """``tdm_init``'s arithmetic (integer, as the firmware does it)."""
        tpb = (8 + 8_000_000 // (spec.air_kbps * 1000)) // 16 + 1
        latency = (8 + 10 // 2) * tpb + 13
        if spec.ecc:
            max_data = MAX_PACKET_LENGTH // 2 - (6 + TRAILER_BYTES)
            tpb *= 2
            latency += 4 * tpb
        else:
            max_data = MAX_PACKET_LENGTH - TRAILER_BYTES
        silence = 2 * latency
        window = 3 * (latency + max_data * tpb)
        window = min(window, (1_000_000 // 16) * 4 // 10)  # 0.4 s, US rules when hopping
        window = min(window, spec.window_ms * (1000 // 16), 0x1FFF)
        latency += ((PREAMBLE_NIBBLES - 10) // 2) * tpb
        return cls(tpb, latency, silence, window, max_data)

    def flight_ticks(self, data_bytes: int) -> int:
        """Air time of a packet with ``data_bytes`` (SiK's ``flight_time_estimate``)."""
        return self.packet_latency + (data_bytes + TRAILER_BYTES) * self.ticks_per_byte

    @property
    def max_fit(self) -> int:
        """The most data bytes one packet can carry in a whole window (a longer frame goes
        raw, in pieces: SiK's ``packet_set_max_xmit``)."""
        room = (self.window - self.packet_latency) // self.ticks_per_byte - (TRAILER_BYTES + 1)
        return max(1, min(self.max_data, room))

    @property
    def round_s(self) -> float:
        """Both windows and both silences."""
        return 2 * (self.window + self.silence) * TICK_S


def _number(spec: str, key: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise RadioSpecError(f"radio {spec!r}: {key}={text!r} is not a number") from None
    if value != value or value in (float("inf"), float("-inf")):
        raise RadioSpecError(f"radio {spec!r}: {key}={text!r} is not a finite number")
    return value


def _integer(spec: str, key: str, text: str, low: int, high: int) -> int:
    value = _number(spec, key, text)
    if value != int(value) or not low <= value <= high:
        raise RadioSpecError(f"radio {spec!r}: {key} must be a whole number in {low}..{high}")
    return int(value)


def _option(spec: str, radio: RadioSpec, key: str, text: str) -> RadioSpec:
    if key == "baud":
        baud = _integer(spec, key, text, 1, 10**7)
        if baud not in SERIAL_BAUDS:
            raise RadioSpecError(f"radio {spec!r}: baud must be one of SiK's serial rates "
                                 f"({', '.join(map(str, SERIAL_BAUDS))})")
        return replace(radio, baud=baud)
    if key == "air":
        kbps = _number(spec, key, text)
        if not 0 < kbps <= AIR_RATES_KBPS[-1]:
            raise RadioSpecError(f"radio {spec!r}: air must be in (0, {AIR_RATES_KBPS[-1]}] "
                                 "kbit/s")
        return replace(radio, air_kbps=next(r for r in AIR_RATES_KBPS if r >= kbps))
    if key == "loss":
        loss = _number(spec, key, text)
        if not 0 <= loss < 1:
            raise RadioSpecError(f"radio {spec!r}: loss must be in [0, 1), got {text}")
        return replace(radio, loss=loss)
    if key == "burst":
        burst = _number(spec, key, text)
        if not 1 <= burst <= 1000:
            raise RadioSpecError(f"radio {spec!r}: burst must be in [1, 1000] packets")
        return replace(radio, burst=burst)
    if key == "ecc":
        if text not in ("0", "1"):
            raise RadioSpecError(f"radio {spec!r}: ecc must be 0 or 1")
        return replace(radio, ecc=text == "1")
    if key == "window":
        return replace(radio, window_ms=_integer(spec, key, text, 20, 131))
    if key == "buffer":
        return replace(radio, buffer_bytes=_integer(spec, key, text, 256, 65536))
    if key == "seed":
        return replace(radio, seed=_integer(spec, key, text, 0, 2**31 - 1))
    raise RadioSpecError(f"radio {spec!r}: unknown option {key!r} "
                         "(baud, air, loss, burst, ecc, window, buffer, seed)")


def _vehicles(spec: str, who: str, count: int) -> list[int] | None:
    """None for ``all``; else the system ids (each 1..count)."""
    if who == "all":
        return None
    try:
        ids = [int(s) for s in who.split(",")]
    except ValueError:
        raise RadioSpecError(f"radio {spec!r}: vehicles must be 'all' or system ids") from None
    bad = [s for s in ids if not 1 <= s <= count]
    if bad:
        raise RadioSpecError(f"radio {spec!r}: no vehicle with system id {bad[0]} (1..{count})")
    return ids


def parse_radio_spec(spec: str, count: int = 255) -> tuple[list[int] | None, RadioSpec | None]:
    """``[VEHICLES:]KIND[,key=value,...]`` -> (system ids or None for all, the radio or
    None for no radio). Raises :class:`RadioSpecError` naming the bad part."""
    if not isinstance(spec, str) or not spec.strip():
        raise RadioSpecError(f"radio {spec!r}: expected [VEHICLES:]sik[,key=value,...] or none")
    who, sep, body = spec.strip().rpartition(":")
    vehicles = _vehicles(spec, who.strip(), count) if sep else None
    kind, *pairs = [p.strip() for p in body.split(",")]
    if kind in ("none", "off"):
        if pairs:
            raise RadioSpecError(f"radio {spec!r}: {kind} takes no options")
        return vehicles, None
    if kind != "sik":
        raise RadioSpecError(f"radio {spec!r}: unknown radio {kind!r} (sik, none or off)")
    radio = RadioSpec()
    seen: set[str] = set()
    for pair in pairs:
        key, eq, value = pair.partition("=")
        key = key.strip()
        if not eq or not key:
            raise RadioSpecError(f"radio {spec!r}: option {pair!r} is not key=value")
        if key in seen:
            raise RadioSpecError(f"radio {spec!r}: {key} given twice")
        seen.add(key)
        radio = _option(spec, radio, key, value.strip())
    p_enter = radio.loss / (radio.burst * (1.0 - radio.loss))
    if p_enter > 1.0:
        raise RadioSpecError(f"radio {spec!r}: loss={radio.loss:g} needs burst >= "
                             f"{radio.loss / (1.0 - radio.loss):.3g}")
    timing = SikTiming.of(radio)
    if (timing.window - timing.packet_latency) // timing.ticks_per_byte < PACKET_OVERHEAD:
        raise RadioSpecError(f"radio {spec!r}: at {radio.air_kbps} kbit/s no packet fits a "
                             f"{radio.window_ms} ms window; raise air or window")
    return vehicles, radio


def radio_assignments(specs: Iterable[str], system_ids: Sequence[int]) -> dict[int, RadioSpec]:
    """Each vehicle's radio after ``specs`` in order (a later spec wins for the vehicles it
    names); vehicles without one are left out. Raises :class:`RadioSpecError`."""
    count = max(system_ids, default=0)
    out: dict[int, RadioSpec | None] = {}
    for spec in specs:
        vehicles, radio = parse_radio_spec(spec, count)
        for sysid in system_ids if vehicles is None else vehicles:
            out[sysid] = radio
    return {sysid: radio for sysid, radio in out.items() if radio is not None}


def parse_scenario_radio(value: Any) -> tuple[str, ...]:
    """A scenario's ``radio:``: one spec or a list of them (checked, kept as text)."""
    if value is None:
        return ()
    items = [value] if isinstance(value, str) else value
    if not isinstance(items, list):
        raise FieldError("radio", f"must be a radio spec or a list of them, got {value!r}")
    for i, item in enumerate(items):
        where = "radio" if isinstance(value, str) else f"radio[{i}]"
        if not isinstance(item, str):
            raise FieldError(where, f"must be a radio spec string, got {item!r}")
        try:
            parse_radio_spec(item)
        except RadioSpecError as exc:
            raise FieldError(where, str(exc)) from exc
    return tuple(items)
