"""CP-SAT off the event loop: one worker thread, a deadline, a fallback, stale plans dropped.

``submit(request)`` starts :class:`planner.PlanSolver` in a worker thread (``num_workers``
CP-SAT workers, 1 by default: all cores would starve the event loop on a 2-core machine).
The solver honours the problem's ``time_limit_s`` itself; if it has not answered after
``1.5 x time_limit_s + 0.5`` wall seconds it is stopped (``PlanSolver.stop``) and returns its
best plan so far (status ``fallback`` when CP-SAT found none). If solving raises, the
heuristic alone is tried; if that fails too, the request gets no answer and the next
trigger asks again. ``cancel(id)`` stops an overtaken solve at once; whether an answer still
counts is the core's rule (``DecisionCore.wants_answer``: only the newest request), which the
daemon applies before it journals the answer.

The runner is a service of the daemon's task tree: :meth:`SolverRunner.run` (supervised in
the root task group) owns a child ``asyncio.TaskGroup`` in which every solve runs, so a
stopped daemon cancels them all and no solve outlives it. ``submit`` only queues.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
from collections.abc import Callable, Mapping, Sequence

from groundstation.core.commands import SolveRequest
from planner import PlanResult, PlanSolver
from planner.solve import libraries_loaded, needs_libraries, warm_up

__all__ = ["SolverRunner"]

log = logging.getLogger(__name__)


class SolverRunner:
    """Runs solve requests in a worker thread and answers with ``on_solved``."""

    def __init__(
        self,
        on_solved: Callable[[SolveRequest, PlanResult], None],
        *,
        num_workers: int = 1,
        seed: int = 0,
        on_error: Callable[[SolveRequest, str], None] | None = None,
    ) -> None:
        self.on_solved = on_solved
        self.on_error = on_error
        self.num_workers = num_workers
        self.seed = seed
        self._executor = concurrent.futures.ThreadPoolExecutor(
            max_workers=2, thread_name_prefix="floe-solver"
        )
        self._solvers: dict[int, PlanSolver] = {}
        self._queue: asyncio.Queue[tuple[SolveRequest, PlanSolver]] = asyncio.Queue()
        self.cancelled = 0
        self.deadline_stops = 0
        self.solved = 0
        self._warmed = False  # warm_up asked for (once per runner)

    def submit(self, request: SolveRequest) -> None:
        solver = PlanSolver(
            request.problem,
            _hint(request.hint),
            num_workers=self.num_workers,
            random_seed=self.seed,
        )
        self._solvers[request.request_id] = solver
        self._queue.put_nowait((request, solver))

    async def run(self) -> None:
        """Serve submitted requests until cancelled (each solve a child task)."""
        async with asyncio.TaskGroup() as solves:
            while True:
                request, solver = await self._queue.get()
                if request.request_id in self._solvers:  # not cancelled while queued
                    solves.create_task(self._solve(request, solver), name="solve")

    def cancel(self, request_id: int) -> None:
        solver = self._solvers.pop(request_id, None)
        if solver is not None:
            solver.stop()
            self.cancelled += 1

    @property
    def busy(self) -> bool:
        return bool(self._solvers)

    async def _solve(self, request: SolveRequest, solver: PlanSolver) -> None:
        loop = asyncio.get_running_loop()
        future = loop.run_in_executor(self._executor, solver.solve)
        deadline_s = 1.5 * request.problem.time_limit_s + 0.5
        result: PlanResult | None = None
        try:
            result = await asyncio.wait_for(asyncio.shield(future), deadline_s)
        except TimeoutError:
            self.deadline_stops += 1
            solver.stop()
            try:
                result = await future
            except Exception as exc:
                log.warning("solver failed after stop: %s", exc)
        except asyncio.CancelledError:
            solver.stop()
            raise
        except Exception as exc:
            log.warning("solver failed (%s): trying the heuristic", exc)
            fallback = PlanSolver(
                request.problem, _hint(request.hint), method="heuristic", random_seed=self.seed
            )
            try:
                result = await loop.run_in_executor(self._executor, fallback.solve)
            except Exception as exc2:
                if self.on_error is not None:
                    self.on_error(request, repr(exc2))
        self._solvers.pop(request.request_id, None)
        if result is not None:
            self.solved += 1
            self.on_solved(request, result)
        await self._warm_up_for(request)

    async def _warm_up_for(self, request: SolveRequest) -> None:
        """Load CP-SAT (ortools.sat and pandas) and scipy's LP, ~1 CPU-s of imports, in the
        worker thread after the answer to the first problem beyond the DP
        (``needs_libraries``): that solve imported what its budget could pay for, the next
        ones find both loaded, and a run whose problems stay in the DP's range (paper-boat's
        3 x 10) never imports them. A solve started meanwhile runs in the second thread."""
        problem = request.problem
        if self._warmed or not needs_libraries(
            len(problem.uavs), len(problem.targets), problem.time_limit_s
        ):
            return
        self._warmed = True
        if libraries_loaded():
            return
        log.info("planner: loading CP-SAT and the LP (%d UAVs, %d targets)",
                 len(problem.uavs), len(problem.targets))
        try:
            await asyncio.get_running_loop().run_in_executor(self._executor, warm_up)
        except Exception as exc:  # a broken install: each solve then pays (or fails) itself
            log.warning("planner warm-up failed: %s", exc)

    def close(self) -> None:
        for solver in self._solvers.values():
            solver.stop()
        self._solvers.clear()
        self._executor.shutdown(wait=False, cancel_futures=True)


def _hint(hint: Mapping[str, Sequence[str]]) -> dict[str, list[str]]:
    return {k: list(v) for k, v in hint.items()}
