"""Asyncio MAVLink transports (udpin/udpout/tcp/tcpin/serial), routing and tlogs; the
detection feed's JSON lines over UDP (:mod:`.detection_feed`, not imported here).

Public entry points: :func:`parse_link_url`, :func:`parse_out_url` (``--out``),
:func:`open_link` (raises :class:`~domain.errors.LinkError`), :class:`Router`,
:class:`TlogWriter`, :class:`TlogReader`. Importing this package has no side effects.
"""

from domain.errors import LinkError  # the one error tree's, re-exported for the link's users
from groundstation.link.base import (
    Link,
    LinkCounters,
    LinkOptions,
    ReceiveCallback,
    Received,
)
from groundstation.link.binding import BindingRules
from groundstation.link.factory import open_link
from groundstation.link.router import Router, RouterCounters
from groundstation.link.tlog import TlogReader, TlogRecord, TlogWriter
from groundstation.link.url import (
    LinkKind,
    LinkSpec,
    LinkUrlError,
    describe_out_link,
    parse_link_url,
    parse_out_url,
)

__all__ = [
    "BindingRules",
    "Link",
    "LinkCounters",
    "LinkError",
    "LinkKind",
    "LinkOptions",
    "LinkSpec",
    "LinkUrlError",
    "ReceiveCallback",
    "Received",
    "Router",
    "RouterCounters",
    "TlogReader",
    "TlogRecord",
    "TlogWriter",
    "describe_out_link",
    "open_link",
    "parse_link_url",
    "parse_out_url",
]
