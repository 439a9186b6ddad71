"""Validation of the control API's request bodies and JSON-safe replies (no I/O).

Each parser returns the keyword arguments of the matching
:class:`~groundstation.daemon.control.contract.DaemonControl` method or raises
:class:`RequestError` whose message is the one-line reason (HTTP 400), naming the field::

    POST /api/targets       {id?, x_m, y_m | lat_deg, lon_deg, vx_m_s?, vy_m_s?, sigma0?}
    PUT  /api/targets/ID    {x_m, y_m | lat_deg, lon_deg}

Numbers must be finite JSON numbers (not strings, not booleans) within sane bounds
(``MAX_LOCAL_M`` for x_m/y_m, ``MAX_SPEED_M_S`` for vx_m_s/vy_m_s, ``MAX_SIGMA0`` for sigma0,
the globe for degrees); positions come in pairs, local metres or WGS-84 degrees, never both;
unknown fields are errors.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from typing import Any

from domain.errors import UsageError

__all__ = [
    "MAX_ID_CHARS",
    "RequestError",
    "check_id",
    "jsonable",
    "parse_move_body",
    "parse_target_body",
]

MAX_ID_CHARS = 64
MAX_LOCAL_M = 1.0e6  # 1000 km from the mission origin: far beyond any operating area
MAX_SPEED_M_S = 100.0  # icebergs drift at a few m/s, boats at ~10 m/s
MAX_SIGMA0 = 1.0e9  # m^2; a track is lost at (150 m)^2 already


class RequestError(UsageError):
    """A malformed request: the message is the one-line reason sent back (HTTP 400)."""


def jsonable(value: Any) -> Any:
    """``value`` with non-finite floats replaced by None and tuples by lists (browsers reject
    NaN/Infinity in JSON)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    return value


def _number(body: dict[str, Any], key: str, *, minimum: float | None = None,
            maximum: float | None = None) -> float | None:
    if key not in body or body[key] is None:
        return None
    value = body[key]
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise RequestError(f"{key}: expected a number, got {json.dumps(value)[:40]}")
    try:
        number = float(value)
    except OverflowError:  # a JSON integer of hundreds of digits
        raise RequestError(f"{key}: number too large") from None
    if not math.isfinite(number):
        raise RequestError(f"{key}: must be finite")
    if minimum is not None and number < minimum:
        raise RequestError(f"{key}: must be >= {minimum:g}, got {number:g}")
    if maximum is not None and number > maximum:
        raise RequestError(f"{key}: must be <= {maximum:g}, got {number:g}")
    return number


def _position(body: dict[str, Any]) -> dict[str, float]:
    local = [k for k in ("x_m", "y_m") if body.get(k) is not None]
    geo = [k for k in ("lat_deg", "lon_deg") if body.get(k) is not None]
    if local and geo:
        raise RequestError("position: give either x_m, y_m or lat_deg, lon_deg, not both")
    if len(local) == 2:
        x = _number(body, "x_m", minimum=-MAX_LOCAL_M, maximum=MAX_LOCAL_M)
        y = _number(body, "y_m", minimum=-MAX_LOCAL_M, maximum=MAX_LOCAL_M)
        assert x is not None and y is not None
        return {"x_m": x, "y_m": y}
    if len(geo) == 2:
        lat = _number(body, "lat_deg", minimum=-90.0, maximum=90.0)
        lon = _number(body, "lon_deg", minimum=-180.0, maximum=180.0)
        assert lat is not None and lon is not None
        return {"lat_deg": lat, "lon_deg": lon}
    if local or geo:
        missing = ({"x_m", "y_m"} - set(local)) or ({"lat_deg", "lon_deg"} - set(geo))
        raise RequestError(f"{sorted(missing)[0]}: missing (positions come in pairs)")
    raise RequestError("position: missing (x_m, y_m or lat_deg, lon_deg)")


def _check_keys(body: Any, allowed: Iterable[str]) -> dict[str, Any]:
    if not isinstance(body, dict):
        raise RequestError("body: expected a JSON object")
    allowed_set = set(allowed)
    for key in body:
        if key not in allowed_set:
            raise RequestError(f"{key}: unknown field (allowed: {', '.join(sorted(allowed_set))})")
    return body


def check_id(value: Any, what: str = "id") -> str:
    """A target/vehicle id: a non-empty string of printable characters, at most 64."""
    if not isinstance(value, str):
        raise RequestError(f"{what}: expected a string, got {json.dumps(value)[:40]}")
    text = value.strip()
    if not text or len(text) > MAX_ID_CHARS or not text.isprintable() or "/" in text:
        raise RequestError(f"{what}: must be 1-{MAX_ID_CHARS} printable characters, no '/'")
    return text


def parse_target_body(body: Any) -> tuple[str | None, dict[str, Any]]:
    """POST /api/targets body -> (id or None, keyword arguments of ``add_target``)."""
    body = _check_keys(body, ("id", "x_m", "y_m", "lat_deg", "lon_deg", "vx_m_s", "vy_m_s",
                              "sigma0"))
    target_id = None if body.get("id") is None else check_id(body["id"])
    kwargs: dict[str, Any] = _position(body)
    for key in ("vx_m_s", "vy_m_s"):
        kwargs[key] = _number(body, key, minimum=-MAX_SPEED_M_S, maximum=MAX_SPEED_M_S) or 0.0
    kwargs["sigma0"] = _number(body, "sigma0", minimum=0.0, maximum=MAX_SIGMA0)
    return target_id, kwargs


def parse_move_body(body: Any) -> dict[str, float | None]:
    """PUT/PATCH /api/targets/ID body -> keyword arguments of ``move_target`` (an
    operator's fix: the position, and ``sigma0`` in m^2 if given)."""
    body = _check_keys(body, ("x_m", "y_m", "lat_deg", "lon_deg", "sigma0"))
    kwargs: dict[str, float | None] = dict(_position(body))
    kwargs["sigma0"] = _number(body, "sigma0", minimum=0.0, maximum=MAX_SIGMA0)
    return kwargs
