"""floe's distribution name and its optional extras: the one place an install hint is
spelled, so every message names the package floe is published as (``floe-gcs``; ``floe``
on the package index is another project).

The field install (``pip install floe-gcs``, or ``pip install .`` from a checkout) flies
vehicles and serves the live map; it holds no plotting, Parquet or Dask. Those are extras:

* ``plot``: matplotlib, for ``gcs simulate``'s PNGs and ``gcs report``'s figures;
* ``campaign``: pyarrow and dask[distributed] (and ``plot``), for ``gcs campaign``.
"""

from __future__ import annotations

import importlib.util

__all__ = ["DISTRIBUTION", "EXTRA_OF_MODULE", "extra_hint", "missing_extra_message",
           "module_missing"]

DISTRIBUTION = "floe-gcs"

# top-level module -> the extra that installs it
EXTRA_OF_MODULE: dict[str, str] = {
    "matplotlib": "plot",
    "pyarrow": "campaign",
    "dask": "campaign",
    "distributed": "campaign",
}


def extra_hint(extra: str) -> str:
    """``pip install 'floe-gcs[EXTRA]'`` (from a checkout: ``pip install '.[EXTRA]'``)."""
    return f"pip install '{DISTRIBUTION}[{extra}]' (from a checkout: pip install '.[{extra}]')"


def module_missing(module: str) -> bool:
    """True when the top-level ``module`` cannot be imported here (not installed)."""
    try:
        return importlib.util.find_spec(module) is None
    except (ImportError, ValueError):
        return True


def missing_extra_message(exc: ModuleNotFoundError) -> str | None:
    """The one-line hint for an ImportError of a module one of floe's extras installs, or
    None when ``exc`` is about another module (a real bug: let it show)."""
    top = (exc.name or "").split(".")[0]
    extra = EXTRA_OF_MODULE.get(top)
    if extra is None:
        return None
    return f"this needs {top}, which is not installed: {extra_hint(extra)}"
