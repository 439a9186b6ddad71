"""``tests/conftest.py``'s order of the collection for xdist's worksteal shares."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any, cast

import pytest
from conftest import DURATIONS, LONG_MODULE_S, deal


@dataclass
class _Item:
    nodeid: str


def _items(spec: dict[str, int]) -> list[Any]:
    return [_Item(f"tests/{m}.py::t{k}") for m, n in spec.items() for k in range(n)]


def test_long_modules_lead_the_shares_and_every_test_stays_once() -> None:
    items = _items({"a": 50, "flood": 3, "b": 40, "watch": 2, "c": 30, "first_leg": 2,
                    "d": 60})
    wall = {"tests/flood.py::t0": 47.0, "tests/watch.py::t0": 30.0, "tests/watch.py::t1": 5.0,
            "tests/first_leg.py::t0": 23.0, "tests/first_leg.py::t1": 22.0,
            "tests/a.py::t3": 2.0}
    out = deal(cast(list[pytest.Item], items), 3, wall)
    assert sorted(i.nodeid for i in out) == sorted(i.nodeid for i in items)  # a permutation
    ids = [i.nodeid for i in out]
    # the shares xdist cuts (n // 3 first, then the rest alike: 62, 62, 63)
    shares = [ids[:62], ids[62:124], ids[124:]]
    firsts = {share[0].split("::")[0] for share in shares}
    assert firsts == {"tests/flood.py", "tests/first_leg.py", "tests/watch.py"}
    for module in ("flood", "watch", "first_leg"):  # a long module's tests stay together
        at = [k for k, i in enumerate(ids) if i.startswith(f"tests/{module}.py")]
        assert at == list(range(at[0], at[0] + len(at)))
    # the short modules keep their order, cut only where a share ends
    rest = [i for i in ids if not i.startswith(("tests/flood", "tests/watch",
                                                "tests/first_leg"))]
    assert rest == [i.nodeid for i in items if i.nodeid in set(rest)]


def test_without_long_modules_the_order_is_unchanged() -> None:
    items = _items({"a": 10, "b": 7})
    assert deal(cast(list[pytest.Item], items), 4, {"tests/a.py::t1": LONG_MODULE_S - 1}) == items


def test_the_durations_file_names_collected_tests() -> None:
    """``benchmarks/suite_cpu.py durations`` wrote it: node ids of this suite, wall s."""
    wall = json.loads(DURATIONS.read_text())
    assert len(wall) > 50 and all(isinstance(v, float) and v > 0 for v in wall.values())
    files = {k.split("::")[0] for k in wall}
    assert all((DURATIONS.parent.parent / f).is_file() for f in files), files
