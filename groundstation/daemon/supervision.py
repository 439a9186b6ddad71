"""Task supervision by error class (the flockwave way: expected faults restart, bugs stop).

Every long-running task of the daemon runs under :meth:`Supervisor.supervise`:

* it returns normally: done;
* it fails with an error the outside world can cause (:data:`domain.errors.EXPECTED_TASK_ERRORS`:
  a link that failed, a peer that broke the protocol, a socket or serial error, a timeout):
  journalled (``task_error``, ``expected: true``), logged as a warning and restarted after a
  short pause that grows with each failure, at most ``max_restarts`` times within
  ``window_s`` mission seconds; past that the task is given up (``task_gave_up``, an error on
  the console) and ``on_give_up`` is called (a vehicle session leaves the plan);
* it fails with anything else: a bug (:meth:`Supervisor.bug`, also the path of a bug in the
  decision core or a vehicle's controller, which run in callbacks rather than tasks). It
  is journalled with its traceback (``task_error``,
  ``bug: true``), logged as critical, and ``on_bug`` stops the daemon cleanly: no further
  command is sent, so the vehicles keep flying their last mission (an unlimited loiter).
"""

from __future__ import annotations

import asyncio
import logging
import traceback
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Any, Protocol

from domain.errors import EXPECTED_TASK_ERRORS

__all__ = ["RestartPolicy", "Supervisor"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RestartPolicy:
    """At most ``max_restarts`` restarts within ``window_s`` mission seconds."""

    max_restarts: int = 5
    window_s: float = 60.0
    pause_step_s: float = 0.2
    """Wall pause before restart k: min(5 s, k x pause_step_s)."""


class _Journal(Protocol):
    """``Daemon.journal``: the supervisor warns in its own words, so its lines pass
    ``logged=True`` (told once on the console)."""

    def __call__(self, event: str, *, logged: bool = False, **fields: Any) -> None: ...


class Supervisor:
    """Runs tasks under the rules of the module docstring."""

    def __init__(
        self,
        now_s: Callable[[], float],
        journal: _Journal,
        on_bug: Callable[[str, BaseException], None],
        policy: RestartPolicy | None = None,
    ) -> None:
        self._now_s = now_s
        self._journal = journal
        self._on_bug = on_bug
        self.policy = policy or RestartPolicy()
        self.stopped = False
        self.given_up: list[str] = []
        self.bugs: list[str] = []
        """Where bugs happened, each once (a callback's bug may repeat until the stop)."""

    async def supervise(
        self,
        name: str,
        factory: Callable[[], Awaitable[None]],
        on_give_up: Callable[[], None] | None = None,
    ) -> None:
        """Run ``factory()`` until it returns, restarting it on expected errors."""
        failures_s: list[float] = []
        while not self.stopped:
            try:
                await factory()
                return
            except asyncio.CancelledError:
                raise
            except EXPECTED_TASK_ERRORS as exc:
                now = self._now_s()
                failures_s = [t for t in failures_s if now - t < self.policy.window_s]
                failures_s.append(now)
                restarts = len(failures_s)
                if restarts > self.policy.max_restarts:
                    log.error(
                        "task %s failed %d times within %.0f s (last: %s): given up",
                        name, restarts, self.policy.window_s, _one_line(exc),
                    )
                    self._journal("task_gave_up", task=name, error=repr(exc), failures=restarts,
                                  logged=True)
                    self.given_up.append(name)
                    if on_give_up is not None:
                        on_give_up()
                    return
                log.warning("task %s: %s; restart %d", name, _one_line(exc), restarts)
                self._journal(
                    "task_error", task=name, error=repr(exc), restarts=restarts, expected=True,
                    logged=True,
                )
                await asyncio.sleep(min(5.0, self.policy.pause_step_s * restarts))
            except Exception as exc:
                self.bug(name, exc)
                return

    def bug(self, where: str, exc: BaseException) -> None:
        """A bug (an unexpected exception) in ``where``, a task or a callback the daemon
        runs outside a task (the decision core, a vehicle's controller): the traceback is
        journalled (``task_error``, ``bug: true``), it is logged as critical and ``on_bug``
        stops the daemon cleanly. Every bug takes this one path; the same bug repeated
        before the stop (the next frame into a broken controller) is not told again."""
        if where in self.bugs:
            return
        self.bugs.append(where)
        log.critical(
            "internal error in task %s: %s; stopping (vehicles keep their last mission)",
            where, _one_line(exc), exc_info=exc,
        )
        self._journal(
            "task_error",
            task=where,
            error=repr(exc),
            bug=True,
            traceback=traceback.format_exception(exc)[-6:],
            logged=True,
        )
        self._on_bug(where, exc)


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__
