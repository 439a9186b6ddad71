"""Make the right :class:`~groundstation.link.base.Link` for a URL."""

from __future__ import annotations

from groundstation.link.base import Link, LinkOptions, ReceiveCallback
from groundstation.link.serial_link import SerialLink
from groundstation.link.tcp import TcpClientLink, TcpServerLink
from groundstation.link.udp import UdpInLink, UdpOutLink
from groundstation.link.url import LinkKind, LinkSpec, parse_link_url

__all__ = ["open_link"]

_CLASSES: dict[LinkKind, type[Link]] = {
    LinkKind.UDP_IN: UdpInLink,
    LinkKind.UDP_OUT: UdpOutLink,
    LinkKind.TCP_CLIENT: TcpClientLink,
    LinkKind.TCP_SERVER: TcpServerLink,
    LinkKind.SERIAL: SerialLink,
}


def open_link(
    url: str | LinkSpec,
    link_id: str | None = None,
    on_receive: ReceiveCallback | None = None,
    options: LinkOptions | None = None,
) -> Link:
    """Build (not start) the link for ``url``; raises ``LinkUrlError`` for a bad URL."""
    spec = url if isinstance(url, LinkSpec) else parse_link_url(url)
    return _CLASSES[spec.kind](spec, link_id=link_id, on_receive=on_receive, options=options)
