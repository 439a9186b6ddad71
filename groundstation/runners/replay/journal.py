"""Reading a run's ``journal.jsonl`` for replay and reports, robustly.

A journal is JSON lines, one object a line (``groundstation/daemon/journal.py``,
``gcs simulate``). A crash can leave the last line cut short; a disk problem can damage
one in the middle. :func:`load_journal` keeps every complete object, and lists what it
could not read (:attr:`LoadedJournal.damaged`, line numbers from 1) instead of failing:
the caller reports it. Only a missing, unreadable or empty file is an error
(:class:`JournalError`, a one-line message).

The decision core's configuration is in the ``start`` record: ``core_config``
(``gcs simulate``) or ``core`` (``gcs run``). :func:`apply_overrides` changes it for a
what-if replay (``--set tau=0.9``).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from domain.errors import DataError
from groundstation.core.config import CoreConfig, config_from_dict, config_to_dict

__all__ = [
    "JournalError",
    "LoadedJournal",
    "apply_overrides",
    "core_config_of",
    "find_journal",
    "load_journal",
    "skipped_summary",
]


class JournalError(DataError):
    """The journal cannot be used at all; ``str()`` is a one-line message."""


@dataclass
class LoadedJournal:
    """Every readable record of a journal, with the line number each came from."""

    path: Path
    records: list[dict[str, Any]] = field(default_factory=list)
    line_numbers: list[int] = field(default_factory=list)
    damaged: list[tuple[int, str]] = field(default_factory=list)
    truncated_last_line: bool = False
    lines_total: int = 0

    @property
    def start(self) -> dict[str, Any] | None:
        """The first ``start`` record, if any."""
        for record in self.records:
            if record.get("event") == "start":
                return record
        return None

    def warnings(self, first: int | None = None) -> list[str]:
        """One line per problem found while reading (for the user); with ``first``, only
        that many (:func:`skipped_summary` says how many there are in all)."""
        out = []
        for line, problem in self.damaged[:first]:
            out.append(f"{self.path}: line {line}: {problem} (skipped)")
        return out


def skipped_summary(lines_total: int, skipped: Sequence[int], first: int = 5) -> str | None:
    """``skipped 3 of 2603 journal lines: 6, 11, 21`` (the first ``first`` line numbers,
    then ``and N more``); None when nothing was skipped."""
    if not skipped:
        return None
    shown = ", ".join(str(n) for n in sorted(skipped)[:first])
    more = f" and {len(skipped) - first} more" if len(skipped) > first else ""
    return f"skipped {len(skipped)} of {lines_total} journal lines: {shown}{more}"


def find_journal(path: Path) -> Path:
    """``RUN_DIR`` -> ``RUN_DIR/journal.jsonl``; a file is taken as the journal itself."""
    if path.is_dir():
        candidate = path / "journal.jsonl"
        if not candidate.is_file():
            raise JournalError(f"{path}: no journal.jsonl in this folder")
        return candidate
    if not path.exists():
        raise JournalError(f"{path}: no such file or folder")
    return path


def load_journal(path: Path) -> LoadedJournal:
    """Read ``path`` (a run folder or a journal file); see the module docstring."""
    journal_path = find_journal(path)
    try:
        data = journal_path.read_bytes()
    except OSError as exc:
        raise JournalError(f"{journal_path}: cannot read: {exc.strerror or exc}") from None
    if not data.strip():
        raise JournalError(f"{journal_path}: the journal is empty")
    out = LoadedJournal(journal_path)
    lines = data.split(b"\n")
    ends_with_newline = data.endswith(b"\n")
    if ends_with_newline:
        lines = lines[:-1]
    out.lines_total = len(lines)
    for number, raw in enumerate(lines, start=1):
        if not raw.strip():
            continue
        last = number == len(lines)
        try:
            record = json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            if last and not ends_with_newline:
                out.truncated_last_line = True
                out.damaged.append((number, f"truncated last line ({len(raw)} bytes)"))
            else:
                out.damaged.append((number, f"not JSON ({_short(exc)})"))
            continue
        if not isinstance(record, dict) or not isinstance(record.get("event"), str):
            out.damaged.append((number, "not a journal record (no 'event')"))
            continue
        out.records.append(record)
        out.line_numbers.append(number)
    if not out.records:
        raise JournalError(f"{journal_path}: no readable journal record")
    return out


def _short(exc: Exception) -> str:
    text = str(exc)
    return text if len(text) < 60 else text[:57] + "..."


def core_config_of(journal: LoadedJournal) -> CoreConfig:
    """The decision core's configuration from the ``start`` record."""
    start = journal.start
    if start is None:
        raise JournalError(f"{journal.path}: no 'start' record (is this a floe journal?)")
    data = start.get("core_config", start.get("core"))
    if not isinstance(data, Mapping):
        raise JournalError(
            f"{journal.path}: the 'start' record holds no core configuration"
            " ('core_config' or 'core')"
        )
    try:
        return config_from_dict(data)
    except (ValueError, TypeError) as exc:
        raise JournalError(f"{journal.path}: start record: {exc}") from None


def _parse_value(text: str) -> Any:
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text


def apply_overrides(config: CoreConfig, settings: Sequence[str]) -> CoreConfig:
    """``KEY=VALUE`` settings (``tau=0.9``, ``planner.tau=0.9``, ``policy.commit=false``,
    ``observer.q_per_s=0.2``) applied to ``config``; ValueError names a bad one."""
    data = config_to_dict(config)
    for setting in settings:
        key, sep, value_text = setting.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"--set {setting!r}: expected KEY=VALUE")
        parts = key.split(".")
        if parts[0] in ("planner", "core", "fleet"):
            parts = parts[1:]
        if not parts or len(parts) > 2:
            raise ValueError(f"--set {setting!r}: unknown key {key!r}")
        value = _parse_value(value_text.strip())
        node: dict[str, Any] = data
        if len(parts) == 2:
            inner = data.get(parts[0])
            if not isinstance(inner, dict):
                raise ValueError(f"--set {setting!r}: unknown key {key!r}")
            node = inner
        if parts[-1] not in node:
            raise ValueError(f"--set {setting!r}: unknown key {key!r}")
        old = node[parts[-1]]
        if isinstance(old, float) and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        mu_setting = parts == ["mu"]  # a rule name or a number (planner.MuRule)
        if (
            not mu_setting
            and old is not None
            and value is not None
            and type(value) is not type(old)
            and not (isinstance(old, float) and isinstance(value, float))
        ):
            raise ValueError(
                f"--set {setting!r}: {key} takes a {type(old).__name__}, got {value_text!r}"
            )
        node[parts[-1]] = value
    try:
        return config_from_dict(data)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"--set: {exc}") from None
