"""Link URLs: pymavlink's connection strings, parsed into a :class:`LinkSpec`.

Accepted forms (``HOST`` may be a name, an IPv4 address or a bracketed IPv6 address):

==============================  ==========================================================
``udpin:HOST:PORT``             listen for UDP datagrams on HOST:PORT; replies go to the
``udp:HOST:PORT``               address each system id was last heard from (pymavlink's
                                ``udp:`` is a listener too)
``udpout:HOST:PORT``            send UDP datagrams to HOST:PORT (replies are read from the
                                same socket)
``tcp:HOST:PORT``               connect to a TCP server; reconnect with back-off
``tcpin:HOST:PORT``             listen for TCP clients, any number of them
``serial:DEVICE:BAUD``          a serial port, e.g. ``serial:/dev/ttyUSB0:57600``
``DEVICE,BAUD`` / ``DEVICE``    pymavlink's serial forms: ``/dev/ttyUSB0,57600``,
                                ``COM3,57600``; the baud rate defaults to 57600
==============================  ==========================================================

The ``scheme://`` spelling (``udpin://0.0.0.0:14550``) is accepted too. Listening forms
accept port 0 (an ephemeral port, used by tests) and an empty host (all interfaces); the
sending and connecting forms need a host and a port from 1 to 65535.

Every problem raises :class:`LinkUrlError` with a one-line message naming it.

``--out`` (and ``gcs replay --serve``) links are parsed by :func:`parse_out_url`, which
follows MAVProxy's ``--out``: ``udp:`` and ``udpout:`` *send* to HOST:PORT, ``udpin:``
listens, ``tcpin:`` serves, ``tcp:`` connects. Only ``udp:`` differs from
:func:`parse_link_url` (where, as pymavlink's ``--master``, it listens).
"""

from __future__ import annotations

import enum
import ipaddress
import re
from dataclasses import dataclass

from domain.errors import ConfigError

__all__ = [
    "DEFAULT_SERIAL_BAUD",
    "LinkKind",
    "LinkSpec",
    "LinkUrlError",
    "describe_out_link",
    "parse_link_url",
    "parse_out_url",
]

DEFAULT_SERIAL_BAUD = 57600
"""Baud rate of a serial URL without one (MAVProxy's default; SiK telemetry radios)."""

_MAX_BAUD = 20_000_000
_HOSTNAME_RE = re.compile(
    r"^(?=.{1,253}$)[A-Za-z0-9_]([A-Za-z0-9_-]{0,62})(\.[A-Za-z0-9_-]{1,63})*\.?$"
)
_WINDOWS_PORT_RE = re.compile(r"^(\\\\\.\\)?COM[0-9]+$", re.IGNORECASE)
_SUPPORTED = "udpin:, udp:, udpout:, tcp:, tcpin:, serial:, or DEVICE,BAUD"


class LinkUrlError(ConfigError):
    """A link URL that cannot be used; ``str()`` is a one-line message for the user."""


class LinkKind(enum.StrEnum):
    """What a link does with its socket or port."""

    UDP_IN = "udpin"
    UDP_OUT = "udpout"
    TCP_CLIENT = "tcp"
    TCP_SERVER = "tcpin"
    SERIAL = "serial"


@dataclass(frozen=True, slots=True)
class LinkSpec:
    """A parsed link URL.

    ``host``/``port`` are set for the network kinds, ``device``/``baud`` for serial.
    ``url`` is the text the user gave (for messages); :attr:`canonical` is normalised.
    """

    kind: LinkKind
    url: str
    host: str | None = None
    port: int | None = None
    device: str | None = None
    baud: int | None = None

    @property
    def listens(self) -> bool:
        """True for the kinds that wait for peers (udpin, tcpin)."""
        return self.kind in (LinkKind.UDP_IN, LinkKind.TCP_SERVER)

    @property
    def canonical(self) -> str:
        """The URL in floe's preferred spelling, e.g. ``udpin:0.0.0.0:14550``."""
        if self.kind is LinkKind.SERIAL:
            return f"serial:{self.device}:{self.baud}"
        host = self.host or ""
        if ":" in host:
            host = f"[{host}]"
        return f"{self.kind.value}:{host}:{self.port}"


def _err(url: str, problem: str) -> LinkUrlError:
    return LinkUrlError(f"bad link URL {url!r}: {problem}")


def _parse_port(url: str, text: str, *, allow_zero: bool) -> int:
    if not text:
        raise _err(url, "missing port")
    if not text.isdigit():
        raise _err(url, f"port {text!r} is not a number")
    port = int(text)
    low = 0 if allow_zero else 1
    if not low <= port <= 65535:
        raise _err(url, f"port {port} is outside {low}..65535")
    return port


def _parse_host(url: str, text: str, *, allow_empty: bool) -> str:
    if text.startswith("[") and text.endswith("]"):
        inner = text[1:-1]
        try:
            return str(ipaddress.IPv6Address(inner))
        except ValueError:
            raise _err(url, f"{inner!r} is not an IPv6 address") from None
    if not text:
        if allow_empty:
            return "0.0.0.0"
        raise _err(url, "missing host")
    if ":" in text:
        raise _err(url, f"host {text!r} contains ':' (write IPv6 addresses in brackets)")
    if not _HOSTNAME_RE.match(text):
        raise _err(url, f"host {text!r} is not a valid host name or address")
    return text


def _split_host_port(url: str, rest: str) -> tuple[str, str]:
    if rest.startswith("["):
        close = rest.find("]")
        if close < 0:
            raise _err(url, "unclosed '[' in host")
        host, after = rest[: close + 1], rest[close + 1 :]
        if not after.startswith(":"):
            raise _err(url, "expected ':PORT' after the host")
        return host, after[1:]
    host, sep, port = rest.rpartition(":")
    if not sep:
        raise _err(url, "missing port: expected HOST:PORT")
    return host, port


def _parse_baud(url: str, text: str) -> int:
    if not text.isdigit():
        raise _err(url, f"baud rate {text!r} is not a number")
    baud = int(text)
    if not 0 < baud <= _MAX_BAUD:
        raise _err(url, f"baud rate {baud} is out of range")
    return baud


def _serial(url: str, device: str, baud_text: str | None) -> LinkSpec:
    if not device:
        raise _err(url, "missing serial device")
    if any(c.isspace() for c in device):
        raise _err(url, f"serial device {device!r} contains white space")
    baud = DEFAULT_SERIAL_BAUD if baud_text is None else _parse_baud(url, baud_text)
    return LinkSpec(LinkKind.SERIAL, url, device=device, baud=baud)


def _looks_like_device(text: str) -> bool:
    head = text.split(",", 1)[0]
    return head.startswith("/") or bool(_WINDOWS_PORT_RE.match(head))


def _parse_serial_rest(url: str, rest: str) -> LinkSpec:
    """``serial:`` followed by ``DEVICE``, ``DEVICE:BAUD`` or ``DEVICE,BAUD``."""
    if "," in rest:
        device, _, baud = rest.rpartition(",")
        return _serial(url, device, baud)
    device, sep, baud = rest.rpartition(":")
    if sep and baud.isdigit() and device:
        return _serial(url, device, baud)
    return _serial(url, rest, None)


def parse_link_url(url: str) -> LinkSpec:
    """Parse one link URL (see the module docstring for the forms).

    Raises :class:`LinkUrlError` with a message such as
    ``bad link URL 'tcp:localhost': expected HOST:PORT``.
    """
    if not isinstance(url, str):
        raise LinkUrlError(f"bad link URL {url!r}: not a string")
    text = url.strip()
    if not text:
        raise LinkUrlError("bad link URL '': empty")
    if _looks_like_device(text):
        device, sep, baud = text.partition(",")
        return _serial(url, device, baud if sep else None)
    scheme, sep, rest = text.partition(":")
    if not sep:
        raise _err(url, f"no scheme; use {_SUPPORTED}")
    scheme = scheme.lower()
    if rest.startswith("//"):
        rest = rest[2:]
    if scheme == "serial":
        return _parse_serial_rest(url, rest)
    kinds = {
        "udpin": LinkKind.UDP_IN,
        "udp": LinkKind.UDP_IN,
        "udpout": LinkKind.UDP_OUT,
        "tcp": LinkKind.TCP_CLIENT,
        "tcpin": LinkKind.TCP_SERVER,
    }
    kind = kinds.get(scheme)
    if kind is None:
        if scheme.isdigit() or "." in scheme or scheme == "localhost":
            raise _err(url, f"no scheme; did you mean udpin:{text} or tcp:{text}?")
        raise _err(url, f"unknown scheme {scheme!r}; use {_SUPPORTED}")
    listens = kind in (LinkKind.UDP_IN, LinkKind.TCP_SERVER)
    host_text, port_text = _split_host_port(url, rest)
    host = _parse_host(url, host_text, allow_empty=listens)
    port = _parse_port(url, port_text, allow_zero=listens)
    return LinkSpec(kind, url, host=host, port=port)


def parse_out_url(url: str) -> LinkSpec:
    """Parse an ``--out`` URL as MAVProxy's ``--out`` reads it: ``udp:HOST:PORT`` sends
    (it is ``udpout:``); every other form as :func:`parse_link_url`.

    ``LinkSpec.url`` keeps the user's text; :attr:`LinkSpec.canonical` names what is done
    (``udp:127.0.0.1:14550`` -> ``udpout:127.0.0.1:14550``).
    """
    if isinstance(url, str):
        text = url.strip()
        scheme, sep, rest = text.partition(":")
        if sep and scheme.lower() == "udp":
            spec = parse_link_url("udpout:" + rest)
            return LinkSpec(spec.kind, url, host=spec.host, port=spec.port)
    return parse_link_url(url)


def describe_out_link(spec: LinkSpec) -> str:
    """One line saying what an ``--out`` link does, e.g. ``sends UDP to 127.0.0.1:14550``."""
    host = spec.host or ""
    where = f"[{host}]:{spec.port}" if ":" in host else f"{host}:{spec.port}"
    if spec.kind is LinkKind.UDP_OUT:
        return f"sends UDP to {where} (replies read from the same socket)"
    if spec.kind is LinkKind.UDP_IN:
        return f"listens on UDP {where}; sends to the ground stations heard there"
    if spec.kind is LinkKind.TCP_SERVER:
        return f"serves TCP on {where} to any number of clients"
    if spec.kind is LinkKind.TCP_CLIENT:
        return f"connects to TCP {where} (reconnects with back-off)"
    return f"serial {spec.device} at {spec.baud} baud"
