"""Typed reading of nested YAML mappings with errors that name the offending field.

A scenario or config file is user input: every problem must come back as one line naming
the dotted path of the field (``fleet.count: must be an integer >= 1, got 0``), never as a
traceback.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from domain.errors import ConfigError

__all__ = ["FieldError", "Fields"]


class FieldError(ConfigError):
    """A field of a user file is missing, unknown or invalid."""

    def __init__(self, path: str, message: str) -> None:
        super().__init__(f"{path}: {message}" if path else message)
        self.path = path
        self.message = message


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
        self, key: str, default: int | None = None, *, minimum: int | None = None
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

    def range_pair(self, key: str, default: tuple[float, float]) -> tuple[float, float]:
        value = self.raw(key)
        if value is None:
            return default
        if not isinstance(value, list) or len(value) != 2:
            raise FieldError(self._sub(key), f"must be a [low, high] pair, got {value!r}")
        low = check_number(f"{self._sub(key)}[0]", value[0])
        high = check_number(f"{self._sub(key)}[1]", value[1])
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
    """Return ``value`` as a finite float within bounds, or raise FieldError naming ``path``."""
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
