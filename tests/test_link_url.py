"""Link URL parsing: pymavlink's forms, and one-line errors for bad ones."""

from __future__ import annotations

import asyncio
import sys

import pytest

from groundstation.link import LinkError, LinkKind, LinkUrlError, open_link, parse_link_url
from groundstation.link.url import DEFAULT_SERIAL_BAUD


@pytest.mark.parametrize(
    ("url", "kind", "host", "port"),
    [
        ("udpin:0.0.0.0:14550", LinkKind.UDP_IN, "0.0.0.0", 14550),
        ("udp:127.0.0.1:14551", LinkKind.UDP_IN, "127.0.0.1", 14551),
        ("udpin::14550", LinkKind.UDP_IN, "0.0.0.0", 14550),
        ("udpin:127.0.0.1:0", LinkKind.UDP_IN, "127.0.0.1", 0),
        ("udpout:192.168.1.255:14550", LinkKind.UDP_OUT, "192.168.1.255", 14550),
        ("udpout:localhost:14550", LinkKind.UDP_OUT, "localhost", 14550),
        ("tcp:127.0.0.1:5760", LinkKind.TCP_CLIENT, "127.0.0.1", 5760),
        ("tcp:sitl-host.local:5770", LinkKind.TCP_CLIENT, "sitl-host.local", 5770),
        ("tcpin:0.0.0.0:5760", LinkKind.TCP_SERVER, "0.0.0.0", 5760),
        ("TCP://127.0.0.1:5760", LinkKind.TCP_CLIENT, "127.0.0.1", 5760),
        ("udpin:[::1]:14550", LinkKind.UDP_IN, "::1", 14550),
        ("  udpin:127.0.0.1:14550  ", LinkKind.UDP_IN, "127.0.0.1", 14550),
    ],
)
def test_network_forms(url: str, kind: LinkKind, host: str, port: int) -> None:
    spec = parse_link_url(url)
    assert (spec.kind, spec.host, spec.port) == (kind, host, port)
    assert spec.device is None and spec.baud is None
    assert spec.url == url
    # The canonical spelling parses back to the same thing.
    again = parse_link_url(spec.canonical)
    assert (again.kind, again.host, again.port) == (kind, host, port)


@pytest.mark.parametrize(
    ("url", "device", "baud"),
    [
        ("/dev/ttyUSB0,57600", "/dev/ttyUSB0", 57600),
        (
            "/dev/serial/by-id/usb-SiK_radio-if00,115200",
            "/dev/serial/by-id/usb-SiK_radio-if00",
            115200,
        ),
        ("COM3,57600", "COM3", 57600),
        ("com12,921600", "com12", 921600),
        ("/dev/ttyACM0", "/dev/ttyACM0", DEFAULT_SERIAL_BAUD),
        ("COM4", "COM4", DEFAULT_SERIAL_BAUD),
        ("serial:/dev/ttyUSB0:57600", "/dev/ttyUSB0", 57600),
        ("serial:/dev/ttyUSB0,57600", "/dev/ttyUSB0", 57600),
        ("serial:COM3:115200", "COM3", 115200),
        ("serial:/dev/ttyUSB1", "/dev/ttyUSB1", DEFAULT_SERIAL_BAUD),
    ],
)
def test_serial_forms(url: str, device: str, baud: int) -> None:
    spec = parse_link_url(url)
    assert (spec.kind, spec.device, spec.baud) == (LinkKind.SERIAL, device, baud)
    assert spec.host is None and spec.port is None
    assert parse_link_url(spec.canonical).device == device


def test_listening_flag() -> None:
    assert parse_link_url("udpin:0.0.0.0:1").listens
    assert parse_link_url("tcpin:0.0.0.0:1").listens
    assert not parse_link_url("udpout:127.0.0.1:1").listens
    assert not parse_link_url("tcp:127.0.0.1:1").listens
    assert not parse_link_url("/dev/ttyUSB0").listens


@pytest.mark.parametrize(
    ("url", "fragment"),
    [
        ("", "empty"),
        ("   ", "empty"),
        ("tcp:localhost", "port"),
        ("tcp::5760", "missing host"),
        ("udpout:127.0.0.1:0", "outside 1..65535"),
        ("udpin:0.0.0.0:70000", "outside 0..65535"),
        ("udpin:0.0.0.0:fast", "not a number"),
        ("udpin:0.0.0.0:", "missing port"),
        ("zmq:127.0.0.1:5760", "unknown scheme 'zmq'"),
        ("127.0.0.1:14550", "no scheme"),
        ("localhost:14550", "no scheme"),
        ("udpin:exa mple:14550", "not a valid host"),
        ("udpin:::1:14550", "brackets"),
        ("udpin:[::1:14550", "unclosed"),
        ("udpin:[nope]:14550", "not an IPv6 address"),
        ("/dev/ttyUSB0,fast", "baud rate 'fast'"),
        ("/dev/ttyUSB0,0", "out of range"),
        ("serial:", "missing serial device"),
        ("serial:/dev/tty USB0:57600", "white space"),
        ("justtext", "no scheme"),
    ],
)
def test_bad_urls_raise_one_line_errors(url: str, fragment: str) -> None:
    with pytest.raises(LinkUrlError) as info:
        parse_link_url(url)
    message = str(info.value)
    assert fragment in message
    assert "\n" not in message
    assert message.startswith("bad link URL")


def test_non_string_is_an_error() -> None:
    with pytest.raises(LinkUrlError, match="not a string"):
        parse_link_url(14550)  # type: ignore[arg-type]


def test_link_url_error_is_a_value_error() -> None:
    assert issubclass(LinkUrlError, ValueError)


def test_serial_without_its_package_is_a_clear_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "serial_asyncio_fast", None)  # as if not installed
    link = open_link("/dev/ttyUSB0,57600")  # building the link needs nothing

    async def main() -> None:
        with pytest.raises(LinkError, match="pip install pyserial-asyncio-fast"):
            await link.start()

    asyncio.run(main())
    assert not link.running
