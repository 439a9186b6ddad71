"""The ``gcs`` command: parses the subcommand and hands the rest to its module.

Composition only: each subcommand lives in ``groundstation/commands/<name>.py`` and exposes
``run(argv: list[str]) -> int``. Modules are imported lazily, so ``gcs plan`` does not pay
for matplotlib and ``gcs --help`` is instant.
"""

from __future__ import annotations

import importlib
import os
import sys
from collections.abc import Sequence

from domain.errors import FloeError, UsageError
from domain.extras import DISTRIBUTION, missing_extra_message

__all__ = ["main"]

COMMANDS: dict[str, str] = {
    "run": "the ground-station daemon: fly vehicles over MAVLink to keep targets tracked",
    "simulate": "run a scenario in virtual time against the world model (metrics, plots)",
    "campaign": "run a grid of simulations (local pool or Dask) into Parquet; resumable",
    "plan": "solve one target-visitation problem (JSON file) and print the plan as JSON",
    "sitl": "start built-in ArduPlane-like MAVLink vehicles, or real ArduPilot SITL",
    "replay": "replay a recorded run through today's decision core, or serve its vehicles",
    "report": "write a self-contained HTML report of a run (simulate, run folder or tlog)",
    "target": "add, move, remove or list the targets of the running daemon",
    "vehicle": "launch, resume, release or list the vehicles of the running daemon",
    "scenarios": "list the bundled scenarios",
}


def _usage() -> str:
    lines = ["usage: gcs COMMAND [options]", "", "floe ground station. Commands:"]
    lines += [f"  {name:<10} {text}" for name, text in COMMANDS.items()]
    lines += ["", "Run 'gcs COMMAND --help' for a command's options."]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``gcs`` console script; returns the exit status."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ("-h", "--help", "help"):
        print(_usage())
        return 0 if args else 2
    if args[0] == "--version":
        from importlib.metadata import version

        print(f"floe {version(DISTRIBUTION)}")
        return 0
    name, rest = args[0], args[1:]
    if name not in COMMANDS:
        print(f"gcs: error: unknown command {name!r}\n\n{_usage()}", file=sys.stderr)
        return 2
    # Before numpy loads: OpenBLAS would start a thread per core at import, 30-60 ms of CPU
    # per process; floe's matrices are 4x4 to ~100x100, one thread is enough. A value the
    # user set wins. (docs/architecture.md, "Start-up and simulation speed")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    module = importlib.import_module(f"groundstation.commands.{name}")
    try:
        status: int = module.run(rest)
    except KeyboardInterrupt:
        print(f"gcs {name}: interrupted", file=sys.stderr)
        return 130
    except UsageError as exc:  # a mistake a subcommand did not turn into its own message
        print(f"gcs {name}: error: {exc}", file=sys.stderr)
        return 2
    except FloeError as exc:
        print(f"gcs {name}: error: {exc}", file=sys.stderr)
        return 1
    except ModuleNotFoundError as exc:  # an optional extra (domain/extras.py) not installed
        hint = missing_extra_message(exc)
        if hint is None:
            raise
        print(f"gcs {name}: error: {hint}", file=sys.stderr)
        return 2
    return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
