"""Running the chains of a sweep: in this process, in worker processes, or on Dask
(:mod:`copdea_fem.parallel`)."""

from __future__ import annotations

import itertools
import logging
import os
import threading
import time
from pathlib import Path
from typing import Callable

from copdea_fem.folders import Claim, held, write_manifest
from copdea_fem.parallel import (
    SWEEP_SPELLINGS,
    check_executor,
    check_workers,
    dask_client,
    one_thread_per_worker,
    process_pool,
)
from copdea_fem.sweeps.gather import SweepOutcome, finish_sweep, write_summary
from copdea_fem.sweeps.grid import content_hash
from copdea_fem.sweeps.models import MODEL_CLASSES, ChainState, PointResult, solve_point
from copdea_fem.sweeps.spec import (
    SWEEP_FILES,
    ReuseSettings,
    Sweep,
    SweepError,
    SweepPoint,
    check_chain_length,
)
from copdea_fem.sweeps.store import PointStore

logger = logging.getLogger(__name__)


def _needs_sampling(sweep: Sweep) -> bool:
    return len({p.space_key for p in sweep.points}) > 1


def _describe(sweep: Sweep, point: SweepPoint) -> str:
    return ", ".join(f"{axis.key} = {axis.format(point.overrides[axis.key])}"
                     for axis in sweep.axes)


def _summary_line(sweep: Sweep, record: dict) -> str:
    point = sweep.point(record["point"])
    head = f"{record['point']} ({_describe(sweep, point)})"
    if record["status"] != "ok":
        return f"{head}: FAILED -- {record['error']}"
    seconds = record.get("timings_s", {})
    reuse = record.get("reuse", {})
    parts = [f"{len(record['modes'])} modes in {seconds.get('total', 0):.2f} s"]
    if "prestress" in seconds:
        source = f" from {reuse['prestress_from']}" if reuse.get("prestress_from") else ""
        parts.append(f"prestress {seconds['prestress']:.2f} s{source}")
    if "eigen" in seconds:
        parts.append(f"eigen {seconds['eigen']:.2f} s"
                     + (" (neighbour's shifts)" if reuse.get("initial_shifts") else ""))
    return f"{head}: " + ", ".join(parts)


def _run_chain(sweep: Sweep, chain_ids: list[str], reuse: ReuseSettings, sink: Callable,
               chain: ChainState | None = None) -> None:
    """Solve the points of one chain in order, continuing from each to the next."""
    chain = chain or ChainState()
    needs_sampling = _needs_sampling(sweep)
    for point_id in chain_ids:
        result = solve_point(sweep.model, sweep.point(point_id), chain, reuse, needs_sampling)
        sink(result)


def _pool_chain_task(sweep: Sweep, chain_ids: list[str], reuse: ReuseSettings,
                     directory: str, threads: int) -> list[str]:
    """Worker process: run one chain, writing each point to the store as it finishes."""
    try:
        import ngsolve
        ngsolve.SetNumThreads(max(1, threads))
    except Exception:   # noqa: BLE001 -- the thread count is a hint only
        pass
    store = PointStore(directory)
    _run_chain(sweep, chain_ids, reuse, store.write)
    return chain_ids


_WORKER_CHAINS: dict = {}          # dask worker-local chain states, by chain key
_WORKER_CHAINS_LOCK = threading.Lock()


def _dask_point_task(sweep: Sweep, point_id: str, chain_key: str, previous_id: str | None,
                     last_in_chain: bool, reuse: ReuseSettings, needs_sampling: bool,
                     _after=None) -> PointResult:
    """Dask task: one point, continuing the chain's solver if this worker holds it.

    ``_after`` is the predecessor's future (ordering only).
    """
    with _WORKER_CHAINS_LOCK:
        chain = _WORKER_CHAINS.get(chain_key)
        if chain is None or chain.last_point != previous_id:
            chain = ChainState()      # no (or a stale) predecessor here: start afresh
        _WORKER_CHAINS[chain_key] = chain
    try:
        return solve_point(sweep.model, sweep.point(point_id), chain, reuse, needs_sampling)
    finally:
        if last_in_chain:
            with _WORKER_CHAINS_LOCK:
                _WORKER_CHAINS.pop(chain_key, None)


def run_sweep(sweep: Sweep, out_dir: str | Path | Claim | None = None, executor: str | None = None,
              workers: int | None = None, scheduler=None, chain_length=None,
              reuse: ReuseSettings | None = None,
              on_point_done: Callable | None = None) -> SweepOutcome:
    """Run (or resume) a sweep and write its table, plots and summary.

    Parameters
    ----------
    sweep : Sweep
    out_dir : path or Claim, optional
        Result directory (default ``output.directory`` of the sweep file), or the
        :class:`copdea_fem.folders.Claim` of it the caller holds.
    executor : {"inline", "processes", "dask"}, optional
        Default ``execution.executor``, else inline (:mod:`copdea_fem.parallel`; the old
        ``"local"`` and ``"pool"`` with a deprecation warning).
    workers : int, optional
        Processes of the ``processes`` executor (default ``execution.workers``), or of the
        local Dask cluster.
    scheduler : str or distributed.Client, optional
        Dask scheduler address (or a connected client) for ``executor="dask"`` (default
        ``execution.scheduler``); without one, a local cluster of ``workers`` processes
        (when given, else one per core) runs the sweep and is closed at its end
        (:func:`copdea_fem.parallel.dask_client`).  Refused with another executor.
    chain_length : "auto" or int, optional
        Points per continuation chain (default ``execution.chain_length``).
    reuse : ReuseSettings, optional
        Default ``execution.reuse``.
    on_point_done : callable(PointResult), optional
        Called in this process after each computed point is stored.

    Returns
    -------
    SweepOutcome
    """
    start = time.perf_counter()
    progress = logger.info     # one line per point (and a few more), at INFO
    given = executor or sweep.execution.executor
    executor = check_executor(given, scheduler, SWEEP_SPELLINGS, error=SweepError,
                              workers=workers)
    explicit_workers = workers is not None
    workers = sweep.execution.workers if workers is None else workers
    workers = check_workers(workers, "--workers", "processes solving the sweep's chains side "
                            "by side")
    chain_length = check_chain_length(sweep.execution.chain_length if chain_length is None
                                      else chain_length)
    if executor == "dask" and scheduler is None:
        scheduler = sweep.execution.scheduler      # None: a local cluster for the run
    if executor == "dask":
        if isinstance(scheduler, str):             # a wrong address stops before any folder
            with dask_client(scheduler) as client:
                return run_sweep(sweep, out_dir, executor, workers if explicit_workers else None,
                                 client, chain_length, reuse, on_point_done)
    reuse = reuse or sweep.execution.reuse
    MODEL_CLASSES[sweep.model]().check_available(sweep)
    with held(out_dir or sweep.output_directory, "sweep") as record:
        directory = record.target
        directory.mkdir(parents=True, exist_ok=True)
        write_manifest(directory, "sweep", SWEEP_FILES)
        store = PointStore(directory)
        resumed = [pid for pid in sweep.path if store.finished(sweep.point(pid))]
        todo = [pid for pid in sweep.path if pid not in set(resumed)]
        progress(f"sweep {sweep.name}: {len(sweep.points)} points, model {sweep.model}, "
                 f"{len(resumed)} already done, {len(todo)} to compute ({executor})")
        computed: list[str] = []
        counter = itertools.count(len(resumed) + 1)

        def sink(result: PointResult, write: bool = True):
            if write:
                store.write(result)
            computed.append(result.point_id)
            progress(f"[{next(counter)}/{len(sweep.points)}] "
                     + _summary_line(sweep, result.record))
            if on_point_done is not None:
                on_point_done(result)

        todo_set = set(todo)

        def chains_for(parallel: int) -> list[list[str]]:
            chains = [[pid for pid in chain if pid in todo_set]
                      for chain in sweep.chains(chain_length, parallel)]
            return [chain for chain in chains if chain]

        if executor == "inline":
            for chain in chains_for(1):
                _run_chain(sweep, chain, reuse, sink)
        elif executor == "processes":
            _run_pool(sweep, chains_for(workers), reuse, directory, workers, store, sink)
        elif todo:
            with dask_client(scheduler, workers if explicit_workers else None) as client:
                _run_dask(sweep, chains_for, reuse, client, sink)
        outcome = finish_sweep(sweep, directory)
        outcome.computed, outcome.resumed = computed, resumed
        outcome.wall_seconds = time.perf_counter() - start
        write_summary(sweep, directory, outcome)
        return outcome


def _run_pool(sweep, chains, reuse, directory, workers, store, sink) -> None:
    """Chains in spawned worker processes (:func:`copdea_fem.parallel.process_pool`); points
    are reported as they land in the store."""
    import concurrent.futures
    # one BLAS thread per process and a share of the cores for NGSolve: no oversubscription
    threads = max(1, (os.cpu_count() or 1) // workers)
    reported: set[str] = set()

    def report_new(chain_ids):
        for point_id in chain_ids:
            record = None if point_id in reported else store.record(point_id)
            if record:
                if record.get("study_hash") == sweep.point(point_id).study_hash:
                    reported.add(point_id)
                    sink(PointResult(point_id, record["status"], record), write=False)

    with one_thread_per_worker(), process_pool(min(workers, len(chains) or 1)) as pool:
        futures = {pool.submit(_pool_chain_task, sweep, chain, reuse, str(directory),
                               threads): chain for chain in chains}
        pending = set(futures)
        try:
            while pending:
                done, pending = concurrent.futures.wait(
                    pending, timeout=1.0, return_when=concurrent.futures.FIRST_COMPLETED)
                for future in pending:
                    report_new(futures[future])
                for future in done:
                    report_new(futures[future])
                    error = future.exception()
                    for point_id in futures[future]:
                        if error is not None and point_id not in reported:
                            # a crashed worker process: its unfinished points fail
                            record = {"point": point_id, "status": "failed",
                                      "study_hash": sweep.point(point_id).study_hash,
                                      "error": f"worker process failed: {error!r}",
                                      "parameters": sweep.point(point_id).overrides}
                            reported.add(point_id)
                            sink(PointResult(point_id, "failed", record))
        except BaseException:
            for future in futures:
                future.cancel()
            raise


def _run_dask(sweep, chains_for, reuse, client, sink) -> None:
    """Chains as task chains on the Dask cluster of ``client`` (:func:`dask_client`), one
    chain's points on one worker where it can, reported as they finish."""
    from distributed import as_completed
    futures = {}
    try:
        addresses = sorted(client.scheduler_info()["workers"])
        chains = chains_for(max(1, len(addresses)))
        logger.info(f"dask: {len(chains)} chains on {len(addresses)} workers at "
                    f"{client.scheduler.address}")
        needs_sampling = _needs_sampling(sweep)
        token = content_hash([sweep.name, sweep.path, time.time_ns()])
        shared_sweep = client.scatter(sweep, broadcast=True)   # shipped once, not per task
        for number, chain in enumerate(chains):
            worker = [addresses[number % len(addresses)]] if addresses else None
            previous_future, previous_id = None, None
            for position, point_id in enumerate(chain):
                future = client.submit(
                    _dask_point_task, shared_sweep, point_id, f"{token}:{number}", previous_id,
                    position == len(chain) - 1, reuse, needs_sampling, previous_future,
                    key=f"copdea-sweep-{token}-{point_id}", workers=worker,
                    allow_other_workers=True, pure=False)
                futures[future] = point_id
                previous_future, previous_id = future, point_id
        for future in as_completed(list(futures)):
            point_id = futures[future]
            try:
                result = future.result()
            except Exception as error:   # a lost worker: report the point, go on
                record = {"point": point_id, "status": "failed",
                          "study_hash": sweep.point(point_id).study_hash,
                          "error": f"dask task failed: {error!r}",
                          "parameters": sweep.point(point_id).overrides}
                result = PointResult(point_id, "failed", record)
            sink(result)
            future.release()
    except BaseException:       # an error or Ctrl-C here: nothing left running on the cluster
        client.cancel(list(futures))
        raise
