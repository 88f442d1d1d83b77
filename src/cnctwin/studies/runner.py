"""Running a dexel study's runs in parallel local processes.

Each run builds its own block and cuts it in one process (the cut is serial, numba-compiled);
``workers`` processes share the runs, the most expensive first (largest
``rho^2 / (t_cycle vf)``: steps times the cost of a step) so that no long run starts last.
Every worker loads the compiled kernels with a tiny run before it takes work, so no run's
runtime includes loading them. Processes start with ``spawn`` (no
inherited threads or locks): a script that calls :func:`run_study` with more than one worker
must guard its entry point with ``if __name__ == "__main__":``.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait

from cnctwin.errors import ConfigError
from cnctwin.studies.dexel_study import DexelStudy, RunResult, RunSpec, SideMillingCut, run_one

__all__ = ["default_workers", "estimate_wall_s", "run_study"]

log = logging.getLogger(__name__)

_WARM_UP = (SideMillingCut(block_length_mm=14.0), RunSpec(5.0, 0.05, 960.0))


def default_workers() -> int:
    """The number of CPUs this process may use."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _cost(spec: RunSpec) -> float:
    """Relative cost of a run: its steps (~ 1 / (t_cycle vf)) times the rays a step cuts
    (~ rho^2)."""
    return spec.density_per_mm**2 / spec.cycle_s / spec.feed_mm_min


def estimate_wall_s(
    study: DexelStudy, first: RunSpec, first_run_s: float, workers: int
) -> tuple[float, float]:
    """Wall time the study's runs will take, from the first finished run ``first`` (which
    took ``first_run_s``), s: ``(scaled, bound)``.

    ``scaled`` scales the first run's time by the relative cost of every run
    (``rho^2 / (t_cycle vf)``, the order :func:`run_study` starts them in); ``bound`` is
    ``runs x first_run_s``, an upper bound because the first run is among the most expensive.
    Both are divided by ``min(workers, runs)``. The cost model over-rates dense, short-cycle runs
    (the runtime grows about as ``(rho^2 / t_cycle)^0.7``, docs/validation.md), so ``scaled``
    tends to be low: Heide 2025's 240 runs took 370 s on one loaded process where it said 223 s
    and the bound 4,398 s.
    """
    specs = study.runs()
    share = max(1, min(workers, len(specs)))
    scaled = first_run_s * sum(_cost(spec) for spec in specs) / _cost(first) / share
    return scaled, len(specs) * first_run_s / share


def _warm_up() -> None:
    """Load the compiled kernels (from numba's cache) before timing anything."""
    run_one(*_WARM_UP)


def run_study(
    study: DexelStudy,
    *,
    workers: int | None = None,
    on_result: Callable[[RunResult], None] | None = None,
) -> list[RunResult]:
    """Run every setting of a study.

    Parameters
    ----------
    study
        The study.
    workers
        Processes to use, >= 1; ``None`` for :func:`default_workers`. With 1 the runs go one
        after the other in this process.
    on_result
        Called in this process with each result as it arrives (e.g. to advance a progress bar).

    Returns
    -------
    list of RunResult
        In the order of :meth:`DexelStudy.runs`.

    Raises
    ------
    ConfigError
        On ``workers < 1``, or from a run (see :func:`run_one`).
    """
    n = default_workers() if workers is None else workers
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ConfigError(f"workers={workers!r}; give a number of processes >= 1")
    specs = study.runs()
    order = sorted(range(len(specs)), key=lambda i: -_cost(specs[i]))
    results: dict[int, RunResult] = {}
    log.info("dexel study: %d runs on %d process(es)", len(specs), n)
    if n == 1:
        _warm_up()
        for i in order:
            results[i] = run_one(study.cut, specs[i])
            if on_result is not None:
                on_result(results[i])
        return [results[i] for i in range(len(specs))]
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=n, mp_context=context, initializer=_warm_up) as pool:
        pending: dict[Future[RunResult], int] = {
            pool.submit(run_one, study.cut, specs[i]): i for i in order
        }
        try:
            while pending:
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                for future in done:
                    i = pending.pop(future)
                    results[i] = future.result()
                    if on_result is not None:
                        on_result(results[i])
        except BaseException:
            for future in pending:
                future.cancel()
            raise
    return [results[i] for i in range(len(specs))]
