"""Typed reading of nested YAML mappings with errors that name the offending field.

A scenario or config file is user input: every problem must come back as one line naming
the dotted path of the field (``fleet.count: must be an integer >= 1, got 0``), never as a
traceback.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from domain.errors import ConfigError
from domain.limits import MAX_FILE_BYTES, MAX_YAML_DEPTH, MAX_YAML_NODES

__all__ = ["FieldError", "Fields", "load_yaml_file", "load_yaml_text"]


_EXPONENT = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE]\d+")


class FieldError(ConfigError):
    """A field of a user file is missing, unknown or invalid."""

    def __init__(self, path: str, message: str) -> None:
        super().__init__(f"{path}: {message}" if path else message)
        self.path = path
        self.message = message


def load_yaml_file(path: Path | str, what: str) -> Any:
    """Read and parse a user's YAML file; every failure is a :class:`ConfigError` whose
    message starts with ``what`` (e.g. ``--config ice.yaml``): missing or unreadable file,
    larger than :data:`MAX_FILE_BYTES`, not UTF-8 text, not YAML, nested deeper than
    :data:`MAX_YAML_DEPTH` or holding more than :data:`MAX_YAML_NODES` values."""
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise ConfigError(f"{what}: cannot read {path}: {exc.strerror or exc}") from None
    if len(raw) > MAX_FILE_BYTES:
        raise ConfigError(f"{what}: larger than {MAX_FILE_BYTES // (1024 * 1024)} MiB")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"{what}: not UTF-8 text (byte {exc.start} is 0x{raw[exc.start]:02x}); "
            "is it a binary file?"
        ) from None
    return load_yaml_text(text, what)


def load_yaml_text(text: str, what: str) -> Any:
    """Parse YAML text with the limits of :func:`load_yaml_file`."""
    if "\x00" in text:
        raise ConfigError(f"{what}: holds NUL characters; is it a binary file?")
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{what}: not valid YAML: {yaml_error_text(exc)}") from None
    except RecursionError:
        raise ConfigError(f"{what}: nested deeper than {MAX_YAML_DEPTH} levels") from None
    _check_shape(data, what)
    return data


def yaml_error_text(exc: yaml.YAMLError) -> str:
    """PyYAML's error on one line, keeping where it is (1-based line and column, as an
    editor shows them): ``line 2, column 4: mapping values are not allowed here``, and
    the construct it was in: ``line 2, column 2: expected ',' or ']', but got ':'
    (while parsing a flow sequence that started at line 1, column 4)``."""
    if not isinstance(exc, yaml.MarkedYAMLError):
        return str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    problem = " ".join((exc.problem or "").split()) or type(exc).__name__
    mark = exc.problem_mark
    text = f"line {mark.line + 1}, column {mark.column + 1}: {problem}" if mark else problem
    if exc.context:
        context = " ".join(exc.context.split())
        where = exc.context_mark
        if where is not None and (mark is None or (where.line, where.column) !=
                                  (mark.line, mark.column)):
            context += f" that started at line {where.line + 1}, column {where.column + 1}"
        text += f" ({context})"
    return text


def _check_shape(data: Any, what: str) -> None:
    """Depth and size limits, checked iteratively (no recursion, aliases counted per use)."""
    stack: list[tuple[Any, int]] = [(data, 0)]
    nodes = 0
    while stack:
        value, depth = stack.pop()
        nodes += 1
        if nodes > MAX_YAML_NODES:
            raise ConfigError(f"{what}: more than {MAX_YAML_NODES} values")
        if isinstance(value, Mapping | list | tuple):
            if depth >= MAX_YAML_DEPTH:
                raise ConfigError(f"{what}: nested deeper than {MAX_YAML_DEPTH} levels")
            children = value.values() if isinstance(value, Mapping) else value
            stack.extend((child, depth + 1) for child in children)


class Fields:
    """A view of one mapping at a dotted ``path``; tracks which keys were read.

    Call :meth:`done` after reading to reject keys nobody asked for (typos are errors).
    """

    def __init__(self, data: Any, path: str = "") -> None:
        if data is None:
            data = {}
        if not isinstance(data, Mapping):
            raise FieldError(path, f"must be a mapping, got {type(data).__name__}")
        for key in data:
            if not isinstance(key, str):
                raise FieldError(path, f"keys must be strings, got {key!r}")
        self._data: Mapping[str, Any] = data
        self._path = path
        self._seen: set[str] = set()

    def _sub(self, key: str) -> str:
        return f"{self._path}.{key}" if self._path else key

    def has(self, key: str) -> bool:
        return key in self._data and self._data[key] is not None

    def raw(self, key: str, default: Any = None) -> Any:
        self._seen.add(key)
        return self._data.get(key, default)

    def path_of(self, key: str) -> str:
        return self._sub(key)

    def number(
        self,
        key: str,
        default: float | None = None,
        *,
        minimum: float | None = None,
        maximum: float | None = None,
        exclusive_minimum: bool = False,
    ) -> float:
        value = self.raw(key)
        if value is None:
            if default is None:
                raise FieldError(self._sub(key), "is required")
            return default
        return check_number(
            self._sub(key), value, minimum=minimum, maximum=maximum,
            exclusive_minimum=exclusive_minimum,
        )

    def optional_number(
        self, key: str, *, minimum: float | None = None, exclusive_minimum: bool = False
    ) -> float | None:
        if not self.has(key):
            self._seen.add(key)
            return None
        return self.number(key, minimum=minimum, exclusive_minimum=exclusive_minimum)

    def integer(
        self,
        key: str,
        default: int | None = None,
        *,
        minimum: int | None = None,
        maximum: int | None = None,
    ) -> int:
        value = self.raw(key)
        if value is None:
            if default is None:
                raise FieldError(self._sub(key), "is required")
            return default
        if isinstance(value, bool) or not isinstance(value, int):
            raise FieldError(self._sub(key), f"must be an integer, got {value!r}")
        if minimum is not None and value < minimum:
            raise FieldError(self._sub(key), f"must be an integer >= {minimum}, got {value}")
        if maximum is not None and value > maximum:
            raise FieldError(
                self._sub(key), f"must be an integer <= {maximum} (floe's limit), got {value}"
            )
        return value

    def boolean(self, key: str, default: bool) -> bool:
        value = self.raw(key)
        if value is None:
            return default
        if not isinstance(value, bool):
            raise FieldError(self._sub(key), f"must be true or false, got {value!r}")
        return value

    def string(self, key: str, default: str | None = None, *, choices: Sequence[str] = ()) -> str:
        value = self.raw(key)
        if value is None:
            if default is None:
                raise FieldError(self._sub(key), "is required")
            return default
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            value = str(value)
        if not isinstance(value, str):
            raise FieldError(self._sub(key), f"must be a string, got {value!r}")
        if choices and value not in choices:
            raise FieldError(self._sub(key), f"must be one of {', '.join(choices)}, got {value!r}")
        return value

    def sub(self, key: str) -> Fields:
        return Fields(self.raw(key), self._sub(key))

    def items(self, key: str) -> list[Any]:
        value = self.raw(key)
        if value is None:
            return []
        if not isinstance(value, list):
            raise FieldError(self._sub(key), f"must be a list, got {type(value).__name__}")
        return value

    def range_pair(
        self, key: str, default: tuple[float, float], *, limit: float | None = None
    ) -> tuple[float, float]:
        """A ``[low, high]`` pair, each within ``[-limit, limit]`` if given."""
        value = self.raw(key)
        if value is None:
            return default
        if not isinstance(value, list) or len(value) != 2:
            raise FieldError(self._sub(key), f"must be a [low, high] pair, got {value!r}")
        lo = None if limit is None else -limit
        low = check_number(f"{self._sub(key)}[0]", value[0], minimum=lo, maximum=limit)
        high = check_number(f"{self._sub(key)}[1]", value[1], minimum=lo, maximum=limit)
        if high < low:
            raise FieldError(self._sub(key), f"low {low} is above high {high}")
        return low, high

    def done(self) -> None:
        unknown = sorted(set(self._data) - self._seen)
        if unknown:
            raise FieldError(self._sub(unknown[0]), "unknown field")


def check_number(
    path: str,
    value: Any,
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    exclusive_minimum: bool = False,
) -> float:
    """Return ``value`` as a finite float within bounds, or raise FieldError naming ``path``.

    A string in exponent form without a sign (``1e12``, which YAML 1.1 reads as text) is
    taken as the number it spells."""
    if isinstance(value, str) and _EXPONENT.fullmatch(value.strip()):
        value = float(value)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise FieldError(path, f"must be a number, got {value!r}")
    number = float(value)
    if not math.isfinite(number):
        raise FieldError(path, f"must be finite, got {value!r}")
    if minimum is not None:
        if exclusive_minimum and number <= minimum:
            raise FieldError(path, f"must be > {minimum:g}, got {number:g}")
        if not exclusive_minimum and number < minimum:
            raise FieldError(path, f"must be >= {minimum:g}, got {number:g}")
    if maximum is not None and number > maximum:
        raise FieldError(path, f"must be <= {maximum:g}, got {number:g}")
    return number
