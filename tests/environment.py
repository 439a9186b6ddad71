"""What a test needs from the machine, said once.

A test that needs something only some machines have (``/dev/full``, root to mount a
tmpfs, pymavlink's tools, a browser) calls :func:`need`. On a developer's machine a missing
piece skips the test with the reason; where ``CI`` is set (``.ci/run`` sets it, and CI
machines have every piece), the same gap fails the test, so a check can never be skipped
silently in CI.
"""

from __future__ import annotations

import os

import pytest


def need(available: bool, reason: str) -> None:
    """Skip (developer machine) or fail (``CI`` set) unless ``available``."""
    if available:
        return
    if os.environ.get("CI"):
        pytest.fail(f"this test cannot run here: {reason} (CI must provide it)")
    pytest.skip(reason)
