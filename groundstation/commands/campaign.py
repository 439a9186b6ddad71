"""``gcs campaign``: many simulations from one grid file, stored as Parquet as they finish.

    gcs campaign CAMPAIGN.yaml --out DIR               # local process pool
    gcs campaign CAMPAIGN.yaml --out DIR --dask local:2
    gcs campaign CAMPAIGN.yaml --out DIR --dask tcp://scheduler:8786
    gcs campaign report DIR [--out FILE]               # the HTML report

Running the same command again resumes: only the missing runs are computed. Exit status:
0 every run stored, 1 some runs failed (named) or the executor failed, 2 a bad campaign
file or folder (one line), 130 interrupted (the line says how to resume). File format,
executors and storage: docs/campaigns.md.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from domain.errors import FloeError

if TYPE_CHECKING:
    from groundstation.runners.campaign.dask_executor import DaskExecutor
    from groundstation.runners.campaign.driver import CampaignPlan, CampaignResult
    from groundstation.runners.campaign.pool import LocalPool

__all__ = ["run"]

_PROG = "gcs campaign"


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        allow_abbrev=False,
        prog=_PROG,
        description="Run every combination of a campaign file's grid (scenarios x fleet "
        "sizes x objectives x tau x seeds x scenario overrides) and store one row per run "
        "(and per plan) in DIR/runs.parquet (DIR/plans.parquet) as runs finish. Run it "
        "again to resume. 'gcs campaign report DIR' writes the HTML report.",
    )
    parser.add_argument("campaign", type=Path, metavar="CAMPAIGN.yaml", help="campaign file")
    parser.add_argument("--out", type=Path, required=True, metavar="DIR",
                        help="results folder (created; resumed when it holds this campaign)")
    parser.add_argument("--extend", action="store_true",
                        help="accept a grid that differs from DIR's copy: keep the stored "
                        "runs the new grid holds, compute the rest")
    parser.add_argument("--workers", type=int, default=None, metavar="N",
                        help="local pool size (default: the number of CPUs)")
    parser.add_argument("--dask", metavar="ADDRESS", default=None,
                        help="run on Dask: local:N (a LocalCluster on 127.0.0.1 that floe "
                        "starts and stops) or a scheduler address (tcp://HOST:PORT)")
    parser.add_argument("--quiet", action="store_true",
                        help="no start line and no progress (the summary is still printed)")
    return parser


def _report(argv: list[str]) -> int:
    from groundstation.commands.campaign_report import run as report

    return report(argv)


def _error(message: str, status: int = 2) -> int:
    print(f"{_PROG}: error: {message}", file=sys.stderr)
    return status


def run(argv: list[str]) -> int:
    if argv and argv[0] == "report":
        return _report(argv[1:])
    args = _parser().parse_args(argv)
    if args.workers is not None and args.workers < 1:
        return _error(f"--workers must be >= 1, got {args.workers}")
    if args.workers is not None and args.dask is not None:
        return _error("--workers sizes the local pool; with --dask the cluster decides")
    from groundstation.runners.campaign.driver import open_campaign
    from groundstation.runners.campaign.grid import CampaignError
    from groundstation.runners.campaign.store import StoreError

    try:
        executor = _executor(args)
    except ValueError as exc:
        return _error(str(exc))
    try:
        plan = open_campaign(args.campaign, args.out, extend=args.extend)
    except CampaignError as exc:
        return _error(str(exc))
    except StoreError as exc:
        return _error(str(exc))
    if plan.todo == 0:  # nothing to run: no pool, no cluster
        from groundstation.runners.campaign.driver import CampaignResult

        plan.store.compact(final=True)
        _print_end(args, plan, CampaignResult())
        return 0
    return _run_plan(args, plan, executor)


def _executor(args: argparse.Namespace) -> LocalPool | DaskExecutor:
    if args.dask is not None:
        from groundstation.runners.campaign.dask_executor import DaskExecutor

        return DaskExecutor(args.dask)
    from groundstation.runners.campaign.pool import LocalPool

    return LocalPool(args.workers or os.cpu_count() or 1)


def _resume_command(args: argparse.Namespace) -> str:
    words = ["gcs", "campaign", str(args.campaign), "--out", str(args.out)]
    if args.dask is not None:
        words += ["--dask", args.dask]
    elif args.workers is not None:
        words += ["--workers", str(args.workers)]
    return shlex.join(words)


def _run_plan(
    args: argparse.Namespace, plan: CampaignPlan, executor: LocalPool | DaskExecutor
) -> int:
    from groundstation.commands.campaign_progress import CampaignProgress
    from groundstation.runners.campaign.driver import run_campaign

    spec = plan.spec
    try:
        with executor as engine:
            if not args.quiet:
                stale = f"; {plan.stale} stored runs are not in this grid (kept)" \
                    if plan.stale else ""
                print(f"{_PROG}: {spec.name}: {plan.total} runs, {len(plan.done)} done, "
                      f"{plan.todo} to do, on the {engine.describe()}{stale}",
                      file=sys.stderr, flush=True)
            with CampaignProgress(plan.todo, quiet=args.quiet) as progress:
                result = run_campaign(plan, engine, progress.update)
    except KeyboardInterrupt:
        stored = len(plan.store.done_run_ids(spec.per_plan) & set(spec.run_ids()))
        print(f"{_PROG}: interrupted: {stored} of {plan.total} runs stored in {args.out}; "
              f"resume with: {_resume_command(args)}", file=sys.stderr)
        return 130
    except FloeError as exc:  # Dask unreachable, the folder unwritable
        return _error(str(exc), 1)
    _print_end(args, plan, result)
    return 1 if result.failures else 0


def _print_end(args: argparse.Namespace, plan: CampaignPlan, result: CampaignResult) -> None:
    from groundstation.commands.campaign_progress import print_summary
    from groundstation.runners.campaign.store import read_results
    from groundstation.runners.campaign.summary import SUMMARY_FIGURES, summarise

    for task, reason in result.failures:
        where = ", ".join(f"{k}={v}" for k, v in task.coords.items())
        print(f"{_PROG}: run {task.run_id} failed ({where}): {reason}", file=sys.stderr)
    rows: list[dict[str, object]] = []
    if plan.done or result.finished:
        grid = set(plan.spec.run_ids())  # not the stored runs an --extend left out
        columns = [*plan.spec.grid_keys, *SUMMARY_FIGURES, "bounded_trend"]
        table = read_results(args.out, columns=columns)
        rows = [r for r in table.to_pylist() if r["run_id"] in grid]
    keys, cells = summarise(rows, plan.spec.grid)
    if cells:
        print_summary(keys, cells)
    failed = f", {len(result.failures)} failed" if result.failures else ""
    print(f"{_PROG}: {result.finished} runs computed, {len(plan.done)} reused{failed}; "
          f"results in {args.out / 'runs.parquet'}"
          + (f" and {args.out / 'plans.parquet'}" if plan.spec.per_plan else ""),
          file=sys.stderr)
