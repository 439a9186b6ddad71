"""Run a command's asyncio main so that Ctrl-C always ends it cleanly.

``asyncio.run`` has a window, while it builds the event loop, in which a SIGINT raises
KeyboardInterrupt inside the loop's constructor; the half-built loop then prints
"Exception ignored in BaseEventLoop.__del__" with a traceback. Here the loop is built with
SIGINT deferred: a Ctrl-C in that window is remembered and raised as KeyboardInterrupt
once the loop is safely built (and closed), before the coroutine is even created.
"""

from __future__ import annotations

import asyncio
import signal
import threading
from collections.abc import Callable, Coroutine
from types import FrameType
from typing import Any, TypeVar

__all__ = ["run_async"]

T = TypeVar("T")


def run_async(main: Callable[[], Coroutine[Any, Any, T]]) -> T:
    """Like ``asyncio.run(main())``; KeyboardInterrupt propagates as usual."""
    deferred: list[int] = []
    in_main_thread = threading.current_thread() is threading.main_thread()
    previous: Any = None
    if in_main_thread:
        previous = signal.getsignal(signal.SIGINT)

        def remember(signum: int, frame: FrameType | None) -> None:
            deferred.append(signum)

        signal.signal(signal.SIGINT, remember)
    try:
        loop = asyncio.new_event_loop()
    finally:
        if in_main_thread:
            signal.signal(signal.SIGINT, previous)
    if deferred:
        loop.close()
        raise KeyboardInterrupt
    with asyncio.Runner(loop_factory=lambda: loop) as runner:
        return runner.run(main())
