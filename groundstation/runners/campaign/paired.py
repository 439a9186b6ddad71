"""Paired comparison of a campaign's variants, seed by seed, against a base variant.

Every run of a seed sees the same icebergs whatever its objective or tau, so variants are
best compared on the same seed (as ``benchmarks/paper_study.py`` does). The grid's varying
keys split in two:

* *variant* keys: every varying key except the fleet size (``uavs``) and the duration
  (``duration_s``), e.g. ``objective``, ``tau``, ``observer.r_m2``;
* *block* keys: ``uavs`` and ``duration_s`` when they vary; variants are compared within a
  block.

The base variant is the paper's (``objective`` sequence with ``tau`` 0.5) when the grid has
it, else the first variant in the cells' order (the campaign file's). For each other
variant of a block, over the seeds both have: the mean of
``100 (run's mean_uncertainty / base run's - 1)`` in %, its 95 % Student t interval, and
wins/losses (seeds where the variant is lower/higher).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyarrow as pa

from groundstation.runners.campaign.data import SEED_KEY, column_codes, float_column
from groundstation.runners.campaign.stats import Cells, grouped_mean_ci

__all__ = ["BLOCK_KEYS", "PairedRow", "paired_with_base"]

BLOCK_KEYS = ("uavs", "duration_s")
"""Varying grid keys that form blocks rather than variants."""
PAPER_VARIANT = {"objective": "sequence", "tau": 0.5}


@dataclass(frozen=True)
class PairedRow:
    """One variant of one block against the block's base variant."""

    block: dict[str, Any]
    variant: dict[str, Any]
    base: dict[str, Any]
    pairs: int
    mean_pct: float | None
    ci_low_pct: float | None
    ci_high_pct: float | None
    wins: int
    losses: int


def _base_variant(cells: Cells, variant_keys: list[str]) -> dict[str, Any]:
    variants = [{k: v[k] for k in variant_keys} for v in cells.values]
    paper = {k: PAPER_VARIANT[k] for k in variant_keys if k in PAPER_VARIANT}
    if len(paper) == len(variant_keys) and paper in variants:
        return paper
    return variants[0]


def paired_with_base(runs: pa.Table, cells: Cells) -> list[PairedRow] | None:
    """The paired rows (module docstring), blocks then variants in cell order; None when
    no key other than the blocks' varies or the runs have no seed column."""
    variant_keys = [k for k in cells.varying if k not in BLOCK_KEYS]
    if not variant_keys or SEED_KEY not in runs.column_names:
        return None
    block_keys = [k for k in cells.varying if k in BLOCK_KEYS]
    base = _base_variant(cells, variant_keys)
    # per cell: its block number and whether it is the base variant
    block_of: dict[tuple[str, ...], int] = {}
    cell_block = np.empty(cells.count, dtype=np.int64)
    cell_is_base = np.zeros(cells.count, dtype=bool)
    for c, values in enumerate(cells.values):
        key = tuple(repr(values[k]) for k in block_keys)
        cell_block[c] = block_of.setdefault(key, len(block_of))
        cell_is_base[c] = all(values[k] == v for k, v in base.items())
    seed, seeds = column_codes(runs.column(SEED_KEY))
    value = float_column(runs, "mean_uncertainty")
    slot = cell_block[cells.index] * len(seeds) + seed  # (block, seed) of each run
    base_value = np.full(len(block_of) * len(seeds), math.nan)
    is_base_run = cell_is_base[cells.index]
    base_value[slot[is_base_run]] = value[is_base_run]
    paired_base = base_value[slot]
    ok = ~is_base_run & np.isfinite(value) & np.isfinite(paired_base) & (paired_base > 0)
    diff = np.full(runs.num_rows, math.nan)
    diff[ok] = 100.0 * (value[ok] / paired_base[ok] - 1.0)
    n, mean, half = grouped_mean_ci(diff, cells.index, cells.count)
    wins = np.bincount(cells.index[ok], weights=value[ok] < paired_base[ok], minlength=cells.count)
    losses = np.bincount(
        cells.index[ok], weights=value[ok] > paired_base[ok], minlength=cells.count
    )
    out: list[PairedRow] = []
    for c, values in enumerate(cells.values):
        if cell_is_base[c]:
            continue
        has = n[c] >= 1
        has_ci = n[c] >= 2
        out.append(
            PairedRow(
                block={k: values[k] for k in block_keys},
                variant={k: values[k] for k in variant_keys},
                base=dict(base),
                pairs=int(n[c]),
                mean_pct=float(mean[c]) if has else None,
                ci_low_pct=float(mean[c] - half[c]) if has_ci else None,
                ci_high_pct=float(mean[c] + half[c]) if has_ci else None,
                wins=int(wins[c]),
                losses=int(losses[c]),
            )
        )
    return out
