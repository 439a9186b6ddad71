"""The daemon's services and the task set that runs them (the flockwave way).

A service is a named object with ``async run()``, built by constructor with its
collaborators and started by the daemon in its one root ``asyncio.TaskGroup``, each under
the :class:`~groundstation.daemon.supervision.Supervisor`. A service that needs children
opens a task group of its own inside ``run`` (as ``SolverRunner.run`` and ``Router.serve``
do). Stopping the daemon cancels every service's task; what a service must release after
that goes on the composition root's ``AsyncExitStack``
(:func:`groundstation.daemon.startup.run_daemon`).
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable, Sequence
from typing import Protocol

from groundstation.daemon.supervision import Supervisor

__all__ = ["FnService", "Service", "TaskSet"]


class Service(Protocol):
    """A named long-running part of the daemon."""

    @property
    def name(self) -> str: ...

    async def run(self) -> None: ...


class FnService:
    """A service made of a name and a coroutine function."""

    def __init__(self, name: str, fn: Callable[[], Awaitable[None]]) -> None:
        self.name = name
        self._fn = fn

    async def run(self) -> None:
        await self._fn()


class TaskSet:
    """The tasks of the services and of the vehicle sessions, in the root task group
    (:attr:`group`, set by its owner while the group is open)."""

    def __init__(self, supervisor: Supervisor) -> None:
        self.supervisor = supervisor
        self.group: asyncio.TaskGroup | None = None
        self.tasks: list[asyncio.Task[None]] = []

    def spawn(
        self,
        name: str,
        factory: Callable[[], Awaitable[None]],
        on_give_up: Callable[[], None] | None = None,
    ) -> None:
        """Run ``factory`` supervised in the root group (which must be open)."""
        assert self.group is not None
        coro = self.supervisor.supervise(name, factory, on_give_up)
        self.tasks.append(self.group.create_task(coro, name=name))

    def start(self, services: Sequence[Service]) -> None:
        """One supervised task per service, named after it."""
        for service in services:
            self.spawn(service.name, service.run)

    def cancel(self) -> None:
        """No restart from now on; every task is cancelled."""
        self.supervisor.stopped = True
        for task in self.tasks:
            task.cancel()
