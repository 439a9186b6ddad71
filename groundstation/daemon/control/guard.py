"""Who may talk to the control API, and how much: origins, limits, write rate, rejections.

Pure rules (no sockets; time is an argument) used by ``server.py``.

Origin rule (WebSocket upgrade and every state-changing request)::

    allowed  <=>  no Origin header                      (curl, scripts, gcs target/vehicle)
              or  Origin == http://<Host header>         (the page's own origin)
              or  Origin is http://127.0.0.1|localhost|[::1]:PORT, PORT the bound port,
                  and the server listens on loopback or on every address
              or  Origin is in the allow-list             (--http-allow-origin URL)

Origins compare as (scheme, lower-case host, port), default ports filled in (80, 443);
``Origin: null`` (sandboxed frames, file:// pages) is never allowed.
"""

from __future__ import annotations

import ipaddress
import logging
import math
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from typing import Any
from urllib.parse import urlsplit

__all__ = [
    "ControlLimits",
    "OriginPolicy",
    "RejectLog",
    "WriteRateLimiter",
    "is_loopback",
    "parse_origin",
]

Origin = tuple[str, str, int]
DEFAULT_PORTS = {"http": 80, "https": 443}
LOOPBACK_NAMES = ("127.0.0.1", "localhost", "::1")
WILDCARD_HOSTS = ("0.0.0.0", "::", "")


def is_loopback(host: str) -> bool:
    """True when ``host`` only accepts connections from this machine (127.0.0.0/8, ::1,
    ``localhost``). Unknown host names and wildcard addresses (0.0.0.0, ::) are not."""
    name = host.strip().strip("[]").lower()
    if name == "localhost" or name.endswith(".localhost"):
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


def parse_origin(text: str) -> Origin:
    """``scheme://host[:port]`` -> (scheme, host, port); raises ValueError with the reason.

    Only http and https; no user, path (a lone ``/`` is tolerated), query or fragment."""
    try:
        parts = urlsplit(text.strip())
        port = parts.port
    except ValueError as exc:
        raise ValueError(f"not an origin URL: {text!r} ({exc})") from None
    scheme = parts.scheme.lower()
    if scheme not in DEFAULT_PORTS:
        raise ValueError(f"expected http://HOST[:PORT] or https://..., got {text!r}")
    if not parts.hostname or parts.username is not None or parts.password is not None:
        raise ValueError(f"expected scheme://HOST[:PORT], got {text!r}")
    if parts.path not in ("", "/") or parts.query or parts.fragment:
        raise ValueError(f"an origin has no path, query or fragment: {text!r}")
    return scheme, parts.hostname.lower(), port if port is not None else DEFAULT_PORTS[scheme]


def _try_origin(text: str) -> Origin | None:
    try:
        return parse_origin(text)
    except ValueError:
        return None


class OriginPolicy:
    """The origin rule of the module docstring for a server bound to ``bound_host``."""

    def __init__(self, bound_host: str, allow: Iterable[str] = ()) -> None:
        self.bound_host = bound_host
        self.allow = frozenset(parse_origin(text) for text in allow)
        host = bound_host.strip().strip("[]").lower()
        self._loopback_forms = is_loopback(host) or host in WILDCARD_HOSTS

    def allowed(self, origin: str | None, host_header: str | None, port: int) -> bool:
        """Apply the rule; ``origin`` None means the request carried no Origin header."""
        if origin is None:
            return True
        wanted = _try_origin(origin)
        if wanted is None:
            return False
        if wanted in self.allow:
            return True
        if host_header and wanted == _try_origin(f"http://{host_header}"):
            return True
        scheme, host, origin_port = wanted
        return (self._loopback_forms and scheme == "http" and origin_port == port
                and host in LOOPBACK_NAMES)


@dataclass(frozen=True)
class ControlLimits:
    """What one control API accepts (``gcs run`` flags ``--http-max-targets`` ...).

    ``max_targets``: targets the daemon may hold for a POST /api/targets to be accepted;
    ``max_ws_clients``: simultaneous WebSocket pages; ``max_writes_per_s``: sustained rate of
    authorised writes (bursts of twice that); ``header_timeout_s``: a request's headers, and
    then its body, must arrive within this; ``max_body_bytes``: request body size."""

    max_targets: int = 100
    max_ws_clients: int = 16
    max_writes_per_s: float = 20.0
    header_timeout_s: float = 5.0
    max_body_bytes: int = 64 * 1024

    def __post_init__(self) -> None:
        if not 1 <= self.max_targets <= 100_000:
            raise ValueError(f"max_targets: expected 1..100000, got {self.max_targets}")
        if not 1 <= self.max_ws_clients <= 10_000:
            raise ValueError(f"max_ws_clients: expected 1..10000, got {self.max_ws_clients}")
        for name in ("max_writes_per_s", "header_timeout_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0 < value <= 10_000):
                raise ValueError(f"{name}: expected a number > 0, got {value}")
        if not 1024 <= self.max_body_bytes <= 16 * 1024 * 1024:
            raise ValueError(f"max_body_bytes: expected 1 KiB..16 MiB, got {self.max_body_bytes}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


class WriteRateLimiter:
    """Token bucket: ``rate_per_s`` tokens per second, at most ``burst``; one per write.

    ``allow(now_s)`` takes a token when there is one (time is the caller's monotonic
    clock)."""

    def __init__(self, rate_per_s: float, burst: float | None = None) -> None:
        self.rate_per_s = rate_per_s
        self.burst = burst if burst is not None else max(1.0, 2.0 * rate_per_s)
        self._tokens = self.burst
        self._last_s: float | None = None

    def allow(self, now_s: float) -> bool:
        if self._last_s is not None:
            elapsed_s = max(0.0, now_s - self._last_s)
            self._tokens = min(self.burst, self._tokens + elapsed_s * self.rate_per_s)
        self._last_s = now_s
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return True
        return False


class RejectLog:
    """Counts refused requests by kind and logs at most one warning per kind every
    ``every_s`` seconds, so a flood cannot fill the log: a burst of refusals is its first
    line at once and, when ``every_s`` has passed, one summary line saying how many more
    were refused (:meth:`flush`, called about once a second; or the next refusal's line)."""

    def __init__(self, logger: logging.Logger, every_s: float = 10.0) -> None:
        self.logger = logger
        self.every_s = every_s
        self.counts: dict[str, int] = {}
        self._last_logged_s: dict[str, float] = {}
        self._unlogged: dict[str, int] = {}

    def note(self, kind: str, message: str, now_s: float) -> None:
        self.counts[kind] = self.counts.get(kind, 0) + 1
        last_s = self._last_logged_s.get(kind)
        if last_s is not None and now_s - last_s < self.every_s:
            self._unlogged[kind] = self._unlogged.get(kind, 0) + 1
            return
        unlogged = self._unlogged.pop(kind, 0)
        more = f" (+{unlogged} more not logged)" if unlogged else ""
        self.logger.warning("control API refused (%s): %s%s", kind, message, more)
        self._last_logged_s[kind] = now_s

    def flush(self, now_s: float) -> None:
        """Log the summary of each kind whose ``every_s`` window has closed with refusals
        not logged: ``control API refused (KIND): N more in the last S s``."""
        for kind, unlogged in list(self._unlogged.items()):
            last_s = self._last_logged_s.get(kind, now_s)
            if now_s - last_s < self.every_s:
                continue
            del self._unlogged[kind]
            self.logger.warning("control API refused (%s): %d more in the last %.0f s",
                                kind, unlogged, now_s - last_s)
            self._last_logged_s[kind] = now_s
