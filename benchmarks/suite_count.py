"""The test suite's size: tests collected and checks written, to show a change lost none.

    python benchmarks/suite_count.py [--tests-dir tests] [--no-collect] [--json FILE]

Two figures, each a floor that a faster suite must not go under (issue 30, item 6):

- **tests**: the test items pytest collects (``python -m pytest --collect-only -q``, the
  lines naming a ``file::test``); parametrized cases count one each.
- **checks**: the checks written in the test files (every ``*.py`` under the tests folder,
  helpers included), counted on their syntax tree: ``assert`` statements, and calls of
  ``pytest.raises``, ``pytest.warns``, ``pytest.fail`` and ``pytest.deprecated_call``.
  The rule is static: an ``assert`` in a loop counts once, as it is written.

The counts are printed per kind and in total; ``--json`` also writes them to a file.
"""

from __future__ import annotations

import argparse
import ast
import json
import subprocess
import sys
from pathlib import Path

CHECK_CALLS = ("raises", "warns", "fail", "deprecated_call")


def count_checks(tests_dir: Path) -> dict[str, int]:
    """Per kind, the checks written in every ``*.py`` file under ``tests_dir``."""
    counts = {"assert": 0, **{f"pytest.{name}": 0 for name in CHECK_CALLS}}
    for path in sorted(tests_dir.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Assert):
                counts["assert"] += 1
            elif (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Attribute)
                and node.func.attr in CHECK_CALLS
                and isinstance(node.func.value, ast.Name)
                and node.func.value.id == "pytest"
            ):
                counts[f"pytest.{node.func.attr}"] += 1
    return counts


def count_tests(tests_dir: Path) -> int:
    """The test items ``pytest --collect-only -q`` lists for ``tests_dir``."""
    out = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider",
         str(tests_dir)],
        capture_output=True, text=True, check=False,
    )
    if out.returncode != 0:
        raise SystemExit(f"pytest could not collect {tests_dir}:\n{out.stdout[-2000:]}")
    return sum(1 for line in out.stdout.splitlines() if "::" in line)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tests-dir", default="tests", type=Path)
    parser.add_argument("--no-collect", action="store_true",
                        help="count the checks only (no pytest collection)")
    parser.add_argument("--json", type=Path, help="also write the counts here")
    args = parser.parse_args(argv)
    checks = count_checks(args.tests_dir)
    figures: dict[str, int] = {}
    if not args.no_collect:
        figures["tests"] = count_tests(args.tests_dir)
    figures.update(checks)
    figures["checks"] = sum(checks.values())
    files = len(list(args.tests_dir.glob("test_*.py")))
    print(f"test files {files}")
    for name, value in figures.items():
        print(f"{name:24} {value}")
    if args.json is not None:
        args.json.write_text(json.dumps({"test_files": files, **figures}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
