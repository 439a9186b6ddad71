"""`gcs plan PROBLEM.json`: solve one planning problem, print the result as JSON.

    gcs plan PROBLEM.json [--workers N] [--seed S] [--deterministic]

PROBLEM.json may be `-` for standard input. Output: one JSON object on stdout (see
planner.result_to_dict). Malformed input: one line `gcs plan: error: <field>: <what>` on
stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any, NoReturn

from domain.errors import UsageError
from planner import ProblemError, problem_from_dict, result_to_dict, solve_plan


class _UsageError(UsageError):
    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")


class _PlanParser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise _UsageError("arguments", message)


def _parser() -> argparse.ArgumentParser:
    parser = _PlanParser(allow_abbrev=False, prog="gcs plan",
                         description="Solve one target-visitation problem.")
    parser.add_argument("problem", help="problem JSON file, or - for standard input")
    parser.add_argument("--workers", type=int, default=1, help="CP-SAT workers (default 1)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument(
        "--deterministic",
        action="store_true",
        help="repeatable result: one worker, deterministic time limit",
    )
    return parser


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not valid JSON")


def _load(path: str) -> Any:
    try:
        if path == "-":
            text = sys.stdin.read()
        else:
            with open(path, encoding="utf-8") as fh:
                text = fh.read()
    except OSError as exc:
        raise _UsageError("problem", f"cannot read {path}: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise _UsageError("problem", f"{path} is not UTF-8 text") from exc
    try:
        return json.loads(text, parse_constant=_reject_constant)
    except (ValueError, RecursionError) as exc:  # JSONDecodeError is a ValueError
        raise _UsageError("problem", f"invalid JSON: {exc}") from exc


def run(argv: list[str]) -> int:
    """Entry point used by groundstation.cli; returns the exit status."""
    try:
        try:
            args = _parser().parse_args(argv)
        except SystemExit as exc:  # --help
            return int(exc.code or 0)
        if args.workers < 1:
            raise _UsageError("--workers", "must be >= 1")
        problem = problem_from_dict(_load(args.problem))
    except (_UsageError, ProblemError) as exc:
        print(f"gcs plan: error: {exc}", file=sys.stderr)
        return 2
    result = solve_plan(
        problem,
        num_workers=args.workers,
        random_seed=args.seed,
        deterministic=args.deterministic,
    )
    out = result_to_dict(result)
    for key in ("objective", "f1", "f2", "mu", "bound", "gap"):
        if out[key] is not None and not math.isfinite(out[key]):
            out[key] = None
    print(json.dumps(out))
    return 0
