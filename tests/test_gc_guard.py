"""groundstation.daemon.gc_guard: the heap that exists when the daemon starts is kept out
of its garbage collections (a full collection over a test process's heap stalled the
event loop ~0.4 s during the flood test), and given back when the last user leaves."""

from __future__ import annotations

import gc
from collections.abc import Iterator

import pytest

from groundstation.daemon.gc_guard import frozen_heap


@pytest.fixture(autouse=True)
def _nothing_frozen() -> Iterator[None]:
    gc.unfreeze()
    yield
    gc.unfreeze()


def test_objects_alive_at_entry_are_frozen_and_returned_on_exit() -> None:
    before = [[i] for i in range(10_000)]  # tracked containers
    with frozen_heap():
        frozen = gc.get_freeze_count()
        assert frozen >= len(before)
        after = [[i] for i in range(1_000)]
        assert gc.get_freeze_count() == frozen  # what the run allocates stays collectable
        gc.collect()
        assert gc.get_freeze_count() == frozen
    assert gc.get_freeze_count() == 0
    assert gc.is_tracked(before[0]) and gc.is_tracked(after[0])


def test_nested_users_share_one_freeze() -> None:
    with frozen_heap():
        with frozen_heap():
            assert gc.get_freeze_count() > 0
        assert gc.get_freeze_count() > 0  # the outer user still runs
    assert gc.get_freeze_count() == 0


def test_a_freeze_made_by_the_process_itself_is_left_alone() -> None:
    gc.freeze()
    mine = gc.get_freeze_count()
    assert mine > 0
    with frozen_heap():
        pass
    assert gc.get_freeze_count() >= mine


def test_an_error_in_the_body_still_unfreezes() -> None:
    with pytest.raises(RuntimeError), frozen_heap():
        raise RuntimeError("boom")
    assert gc.get_freeze_count() == 0
