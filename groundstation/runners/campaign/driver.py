"""The driver of a campaign: open its folder, find what is left, run it, store each run.

:func:`open_campaign` validates the campaign file, checks it against the folder's copy
(``DIR/campaign.yaml``; a different grid needs ``extend``), prepares the results folders
and reads which runs are stored. :func:`run_campaign` hands the missing runs to an
executor (the local pool or Dask), stores each result the moment it arrives, and merges
the parts at the end. Running the same campaign again therefore computes only what is
missing: the runs a crash, a Ctrl-C or a lost worker did not finish.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from domain.errors import ConfigError
from domain.yaml_fields import FieldError, load_yaml_file
from groundstation.runners.campaign.grid import (
    CampaignError,
    CampaignSpec,
    RunTask,
    canonical_form,
    grid_difference,
    load_campaign,
    parse_campaign_shape,
)
from groundstation.runners.campaign.pool import RunSink
from groundstation.runners.campaign.run import RunOutcome
from groundstation.runners.campaign.schema import plans_schema, runs_schema
from groundstation.runners.campaign.store import COPY_NAME, RUNS_DIR, CampaignStore, StoreError
from groundstation.storage import StorageError, atomic_write_bytes

__all__ = ["CampaignPlan", "CampaignResult", "Executor", "open_campaign", "run_campaign"]

Progress = Callable[[int, int], None]
"""``progress(finished, failed)``: called after each run ends, in the driver's thread."""


class Executor(Protocol):
    """What runs tasks: :class:`.pool.LocalPool`, :class:`.dask.DaskExecutor`."""

    def describe(self) -> str: ...

    def run(self, tasks: Iterable[RunTask], sink: RunSink) -> None: ...


@dataclass
class CampaignPlan:
    """A campaign and its folder, ready to run."""

    spec: CampaignSpec
    out_dir: Path
    store: CampaignStore
    total: int
    done: set[str]
    stale: int
    """Runs stored in the folder that the (extended) grid no longer holds: kept."""

    @property
    def todo(self) -> int:
        return self.total - len(self.done)


@dataclass
class CampaignResult:
    """What a call of :func:`run_campaign` did."""

    finished: int = 0
    failures: list[tuple[RunTask, str]] = field(default_factory=list)


def open_campaign(campaign_file: Path, out_dir: Path, *, extend: bool = False) -> CampaignPlan:
    """Validate ``campaign_file`` and prepare ``out_dir`` (module docstring). Raises
    :class:`CampaignError` (a bad file, another campaign in the folder) or
    :class:`StoreError` (the folder cannot be read or written)."""
    spec = load_campaign(campaign_file)
    copy = out_dir / COPY_NAME
    if copy.exists():
        difference = grid_difference(_stored_form(copy), spec.canonical())
        if difference is not None and not extend:
            raise CampaignError(
                f"{out_dir} holds another campaign ({difference}); use --extend to "
                "extend it, or another --out folder"
            )
    elif (out_dir / RUNS_DIR).exists():
        raise CampaignError(f"{out_dir} holds results but no {COPY_NAME}; use another --out")
    else:
        difference = "new"
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        if difference is not None:
            atomic_write_bytes(copy, campaign_file.read_bytes())
    except (OSError, StorageError) as exc:
        raise StoreError(f"cannot write {copy}: {exc}") from None
    store = CampaignStore(out_dir, runs_schema(spec),
                          plans_schema(spec) if spec.per_plan else None)
    store.prepare()
    grid_ids = set(spec.run_ids())
    stored = store.done_run_ids(need_plans=False)
    done = store.done_run_ids(need_plans=True) if spec.per_plan else stored
    return CampaignPlan(spec, out_dir, store, len(grid_ids), done & grid_ids,
                        len(stored - grid_ids))


def _stored_form(copy: Path) -> dict[str, Any]:
    try:
        data = load_yaml_file(copy, str(copy))
        return canonical_form(*parse_campaign_shape(data, default_name=copy.stem))
    except (ConfigError, FieldError) as exc:
        raise CampaignError(f"{copy} (the folder's copy) cannot be read: {exc}") from None


class _StoringSink:
    def __init__(self, store: CampaignStore, result: CampaignResult,
                 progress: Progress | None) -> None:
        self.store, self.result, self.progress = store, result, progress

    def done(self, outcome: RunOutcome) -> None:
        self.store.write(outcome)
        self.result.finished += 1
        self._report()

    def failed(self, task: RunTask, reason: str) -> None:
        self.result.failures.append((task, reason))
        self._report()

    def _report(self) -> None:
        if self.progress is not None:
            self.progress(self.result.finished, len(self.result.failures))


def run_campaign(
    plan: CampaignPlan, executor: Executor, progress: Progress | None = None
) -> CampaignResult:
    """Run the missing runs of ``plan`` on ``executor``, storing each as it ends, then merge
    the stored parts. KeyboardInterrupt propagates (what is stored stays stored)."""
    result = CampaignResult()
    sink = _StoringSink(plan.store, result, progress)
    executor.run(plan.spec.tasks(skip=plan.done), sink)
    plan.store.compact(final=True)
    return result
