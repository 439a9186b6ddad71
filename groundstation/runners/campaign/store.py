"""A campaign's folder: the copy of its file and its results, written as runs finish.

::

    DIR/campaign.yaml            the campaign file, copied (a changed grid needs --extend)
    DIR/runs.parquet/            a Parquet dataset folder: one row per run
    DIR/plans.parquet/           one row per adopted plan (only with per_plan: true)

Each finished run becomes one part in each folder, ``run-<run_id>.parquet``, written to a
dot-prefixed temporary name (pyarrow skips names starting with ``.`` or ``_``), flushed to
disk and renamed into place, plans before the run. So at every moment
``pyarrow.parquet.read_table(DIR / "runs.parquet")`` reads whole parts only, a run whose row
exists has its plans, and a killed driver loses only the runs in flight. Parts are merged
(:meth:`CampaignStore.compact`) into ``chunk-<uuid>.parquet`` files as they pile up and into
one at the end: the merged file is written first, then the parts it holds are removed, so a
crash in between leaves a run twice, never zero times; :func:`read_results` (and every
compaction) keeps one row per run (per run and plan for plans), the newest.
"""

from __future__ import annotations

import contextlib
import os
import uuid
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from domain.errors import FloeError

if TYPE_CHECKING:
    import pyarrow as pa

    from groundstation.runners.campaign.run import RunOutcome

__all__ = [
    "COPY_NAME",
    "PLANS_DIR",
    "RUNS_DIR",
    "CampaignStore",
    "StoreError",
    "read_results",
]

RUNS_DIR = "runs.parquet"
PLANS_DIR = "plans.parquet"
COPY_NAME = "campaign.yaml"
RUN_PART = "run-"
CHUNK_PART = "chunk-"
COMPACT_EVERY_PARTS = 500


class StoreError(FloeError):
    """The results folder cannot be read or written (one line, names the path)."""


def _keys(kind: str) -> tuple[str, ...]:
    return ("run_id",) if kind == RUNS_DIR else ("run_id", "plan_index")


def _parts(folder: Path) -> list[Path]:
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir()
                  if p.suffix == ".parquet" and not p.name.startswith((".", "_")))


def _dedupe(table: pa.Table, keys: Sequence[str]) -> pa.Table:
    """One row per key, the last one read (parts are read chunks first, then per-run
    parts, which are newer: a run recomputed with its plans replaces one without)."""
    columns = [table.column(k).to_pylist() for k in keys]
    last: dict[tuple[Any, ...], int] = {}
    for index, key in enumerate(zip(*columns, strict=True)):
        last[key] = index
    if len(last) == table.num_rows:
        return table
    return table.take(sorted(last.values()))


def _read_parts(
    parts: Sequence[Path], schema: pa.Schema | None, columns: Sequence[str] | None = None,
    known: Mapping[Path, pa.Table] | None = None,
) -> pa.Table:
    """Read whole parts (or their ``columns``), cast to ``schema`` when given (columns it
    lacks are null). A part found in ``known`` (the table this process wrote there, in
    ``schema``) is taken from it instead of being read back."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    tables = []
    for part in parts:
        if known is not None and part in known:
            tables.append(known[part])
            continue
        try:
            table = pq.read_table(part, columns=None if columns is None else list(columns))
        except (OSError, pa.ArrowException) as exc:
            raise StoreError(f"cannot read {part}: {exc}") from None
        if schema is not None:
            table = _conform(table, schema, part)
        tables.append(table)
    if not tables:
        if schema is None:
            raise StoreError("no parts to read")
        return schema.empty_table()
    if schema is None:
        return pa.concat_tables(tables, promote_options="permissive")
    return pa.concat_tables(tables)


def _conform(table: pa.Table, schema: pa.Schema, where: Path) -> pa.Table:
    import pyarrow as pa

    arrays = []
    for field in schema:
        if field.name in table.column_names:
            column = table.column(field.name)
            try:
                arrays.append(column.cast(field.type))
            except (pa.ArrowInvalid, pa.ArrowNotImplementedError) as exc:
                raise StoreError(
                    f"{where}: column {field.name} ({column.type}) cannot become "
                    f"{field.type}: {exc}; use a new --out folder"
                ) from None
        else:
            arrays.append(pa.nulls(table.num_rows, field.type))
    return pa.Table.from_arrays(arrays, schema=schema)


def read_results(
    out_dir: Path, kind: str = RUNS_DIR, columns: Sequence[str] | None = None
) -> pa.Table:
    """The rows of ``DIR/runs.parquet`` (or ``plans.parquet``), one per run (per run and
    plan), optionally only ``columns`` (the keys are always read): what readers should use
    instead of a bare ``read_table``, which may see a run twice for a moment during a
    compaction."""
    folder = Path(out_dir) / kind
    parts = _parts(folder)
    if not parts:
        raise StoreError(f"{folder}: no results")
    wanted = None if columns is None else list(dict.fromkeys([*_keys(kind), *columns]))
    return _dedupe(_read_parts(parts, None, wanted), _keys(kind))


class CampaignStore:
    """The results folders of one campaign, written by one process (module docstring)."""

    def __init__(self, out_dir: Path, runs_schema: pa.Schema, plans_schema: pa.Schema | None):
        self.out_dir = Path(out_dir)
        self.schemas: dict[str, pa.Schema] = {RUNS_DIR: runs_schema}
        if plans_schema is not None:
            self.schemas[PLANS_DIR] = plans_schema
        self._new_parts = 0
        #: the per-run parts this store wrote and has not merged yet, by path: a merge takes
        #: them from here instead of reading them back (a read and a cast of every column
        #: cost ~16 ms a part, two thirds of the driver's CPU in a 1 000-run campaign)
        self._written: dict[Path, pa.Table] = {}

    def folder(self, kind: str) -> Path:
        return self.out_dir / kind

    def prepare(self) -> None:
        """Create the folders; rewrite stored parts whose schema is not this campaign's
        (a grid extended with a new key, another floe's metrics) into one conforming part,
        so every part of a folder has one schema."""
        for kind, schema in self.schemas.items():
            folder = self.folder(kind)
            try:
                folder.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise StoreError(f"cannot create {folder}: {exc.strerror or exc}") from None
            self._clean_temporaries(folder)
            parts = _parts(folder)
            if parts and any(_schema_of(p) != schema.remove_metadata() for p in parts):
                self._merge(kind, parts)

    def done_run_ids(self, need_plans: bool) -> set[str]:
        """Runs already stored (with their plans, when ``need_plans``)."""
        parts = _parts(self.folder(RUNS_DIR))
        if not parts:
            return set()
        import pyarrow.parquet as pq

        done: set[str] = set()
        for part in parts:
            try:
                table = pq.read_table(part, columns=["run_id", "per_plan"])
            except Exception as exc:
                raise StoreError(f"cannot read {part}: {exc}") from None
            for run, planned in zip(table.column("run_id").to_pylist(),
                                    table.column("per_plan").to_pylist(), strict=True):
                if planned or not need_plans:
                    done.add(run)
        return done

    def write(self, outcome: RunOutcome) -> None:
        """Store one finished run: its plans' part, then its run part (module docstring)."""
        if PLANS_DIR in self.schemas and outcome.plan_rows:
            self._write_run_part(PLANS_DIR, outcome.run_id, outcome.plan_rows)
        self._write_run_part(RUNS_DIR, outcome.run_id, [outcome.run_row])
        self._new_parts += 1
        if self._new_parts >= COMPACT_EVERY_PARTS:
            self.compact(final=False)

    def compact(self, *, final: bool) -> None:
        """Merge the per-run parts into one chunk (``final``: every part into one file)."""
        for kind in self.schemas:
            parts = _parts(self.folder(kind))
            if not final:
                parts = [p for p in parts if p.name.startswith(RUN_PART)]
            if len(parts) > 1:
                self._merge(kind, parts)
        self._new_parts = 0

    def _write_run_part(self, kind: str, run_id: str, rows: list[dict[str, Any]]) -> None:
        """One run's rows of ``kind`` as its own part, the table kept for the next merge."""
        from groundstation.runners.campaign.schema import rows_to_table

        table = rows_to_table(rows, self.schemas[kind])
        path = self.folder(kind) / f"{RUN_PART}{run_id}.parquet"
        self._write_part(path, table)
        self._written[path] = table

    def _merge(self, kind: str, parts: Sequence[Path]) -> None:
        schema = self.schemas[kind]
        table = _dedupe(_read_parts(parts, schema, known=self._written), _keys(kind))
        target = self.folder(kind) / f"{CHUNK_PART}{uuid.uuid4().hex}.parquet"
        self._write_part(target, table)
        for part in parts:
            self._written.pop(part, None)
            try:
                part.unlink()
            except FileNotFoundError:
                pass
            except OSError as exc:
                raise StoreError(f"cannot remove {part}: {exc.strerror or exc}") from None

    def _write_part(self, path: Path, table: pa.Table) -> None:
        import pyarrow.parquet as pq

        temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        try:
            pq.write_table(table, temporary)
            with open(temporary, "rb+") as handle:
                os.fsync(handle.fileno())
            os.replace(temporary, path)
        except OSError as exc:
            _remove_quietly(temporary)
            raise StoreError(f"cannot write {path}: {exc.strerror or exc}") from None

    @staticmethod
    def _clean_temporaries(folder: Path) -> None:
        """Temporaries of a killed writer (they are never read; removed to save space)."""
        for path in folder.iterdir():
            if path.name.startswith(".") and path.name.endswith(".tmp"):
                _remove_quietly(path)


def _schema_of(part: Path) -> pa.Schema:
    import pyarrow.parquet as pq

    try:
        return pq.read_schema(part).remove_metadata()
    except Exception as exc:
        raise StoreError(f"cannot read {part}: {exc}") from None


def _remove_quietly(path: Path) -> None:
    with contextlib.suppress(OSError):
        path.unlink()
