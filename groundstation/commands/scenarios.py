"""``gcs scenarios``: list the bundled scenarios with their one-line descriptions."""

from __future__ import annotations

import argparse

from world.scenario import bundled_scenarios, load_scenario


def run(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(allow_abbrev=False, prog="gcs scenarios", description=__doc__)
    parser.parse_args(argv)
    names = bundled_scenarios()
    width = max([16, *(len(name) for name in names)])
    for name in names:
        scenario = load_scenario(name)
        print(f"{name:<{width}} {scenario.description}")
    return 0
