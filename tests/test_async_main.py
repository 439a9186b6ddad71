"""Ctrl-C while the event loop is being built ends the command cleanly."""

from __future__ import annotations

import asyncio
import os
import signal

import pytest

from groundstation.commands import async_main
from groundstation.commands.async_main import run_async


def test_returns_the_coroutine_result() -> None:
    async def main() -> int:
        await asyncio.sleep(0)
        return 42

    assert run_async(main) == 42


def test_sigint_while_building_the_loop_is_deferred(monkeypatch: pytest.MonkeyPatch) -> None:
    # the handler before: Python's default_int_handler, or SIG_IGN when the suite runs as a
    # background job of a non-interactive shell (POSIX: such jobs inherit SIGINT ignored)
    before = signal.getsignal(signal.SIGINT)
    real_new_loop = asyncio.new_event_loop
    created: list[asyncio.AbstractEventLoop] = []

    def interrupted_constructor() -> asyncio.AbstractEventLoop:
        os.kill(os.getpid(), signal.SIGINT)  # arrives in the middle of building the loop
        loop = real_new_loop()
        created.append(loop)
        return loop

    monkeypatch.setattr(async_main.asyncio, "new_event_loop", interrupted_constructor)
    started: list[bool] = []

    async def main() -> None:
        started.append(True)

    with pytest.raises(KeyboardInterrupt):
        run_async(main)
    assert started == []  # the coroutine was never created, so never "not awaited"
    assert created and created[0].is_closed()
    assert signal.getsignal(signal.SIGINT) is before  # restored, whatever it was
