"""A Dask cluster for the sweeps and the diagnosis's FE solves: a running one, or a local one.

``--executor dask`` with ``--scheduler ADDRESS`` sends the work to the Dask scheduler at
``ADDRESS`` (a cluster the user runs: ``dask scheduler`` and ``dask worker`` on other
machines); without ``--scheduler`` :func:`dask_client` starts a local cluster for the run
(:class:`distributed.LocalCluster`: worker processes, one thread each, closed when the run
ends, also on an error or Ctrl-C).  Both are the same code path for the caller: a
:class:`distributed.Client` to submit tasks to.
"""

from __future__ import annotations

import contextlib
import logging
import os

from copdea_fem.study import StudyError

logger = logging.getLogger(__name__)

#: Longest wait [s] for the scheduler at ``--scheduler`` to answer before the run stops with a
#: one-line error: a scheduler on the network answers in milliseconds; Dask's own default
#: (30 s) would only lengthen the wait for a wrong address.
SCHEDULER_TIMEOUT_SECONDS = 10.0


def check_scheduler(executor: str | None, scheduler, option: str = "--scheduler") -> None:
    """:class:`StudyError` when ``scheduler`` is given with an executor other than ``dask``
    (a scheduler address means nothing to the local or pool executor); called before any
    work."""
    if scheduler is not None and executor != "dask":
        from copdea_fem.inputs import preview
        raise StudyError(f"{option} = {preview(scheduler)} is not allowed with --executor "
                         f"{executor or 'local'}; allowed: a Dask scheduler address with "
                         "--executor dask only")


def require_distributed():
    """The :mod:`distributed` module, or a one-line :class:`StudyError` saying how to install it."""
    try:
        import distributed
    except ImportError:
        raise StudyError("--executor = 'dask' is not allowed (dask.distributed is not "
                         "installed); allowed: local or pool, or install Dask: pip install "
                         "'copdea-fem[dask]'") from None
    return distributed


def connect(address: str, option: str = "--scheduler"):
    """A :class:`distributed.Client` of the scheduler at ``address``, or a one-line
    :class:`StudyError` naming ``option`` when the address is malformed or no scheduler
    answers there within :data:`SCHEDULER_TIMEOUT_SECONDS`."""
    distributed = require_distributed()
    from copdea_fem.inputs import preview
    try:
        return distributed.Client(address, timeout=SCHEDULER_TIMEOUT_SECONDS)
    except (OSError, ValueError, TypeError) as error:
        reason = " ".join(str(error).split())[:200] or type(error).__name__
        raise StudyError(f"{option} = {preview(address)} is not allowed ({reason}); allowed: "
                         "the address of a running Dask scheduler, e.g. tcp://10.0.0.5:8786, "
                         "or no --scheduler for a local cluster") from None


def local_workers(workers: int | None = None) -> int:
    """Worker processes of a local cluster: ``workers``, else one per core."""
    return workers if workers is not None else max(1, os.cpu_count() or 1)


@contextlib.contextmanager
def dask_client(scheduler=None, workers: int | None = None, option: str = "--scheduler"):
    """A :class:`distributed.Client` for the run, closed (with its local cluster) on the way out.

    Parameters
    ----------
    scheduler : str or distributed.Client, optional
        The address of a running scheduler (:func:`connect`), or a client the caller holds
        (used as it is and left open); None: a local cluster started here.
    workers : int, optional
        Worker processes of the local cluster (default :func:`local_workers`: one per core).
    option : str
        The option named in errors.

    Notes
    -----
    The local cluster's workers are spawned processes (Dask's default: NGSolve's threads do
    not survive a fork), one thread each, with one BLAS/OpenMP thread (Dask's
    ``distributed.nanny.pre-spawn-environ``) and no memory limit (as the pool's processes:
    an FE solve's memory is bounded by the size guard, not by a share of the machine); they
    end with this process (Dask's worker processes watch their parent).
    """
    distributed = require_distributed()
    if scheduler is not None and not isinstance(scheduler, str):
        yield scheduler                      # the caller's client: the caller closes it
        return
    if scheduler is not None:
        client = connect(scheduler, option)
        try:
            logger.info(f"dask: connected to {client.scheduler.address} "
                        f"({len(client.scheduler_info()['workers'])} workers)")
            yield client
        finally:
            client.close()
        return
    count = local_workers(workers)
    logger.info(f"dask: starting a local cluster of {count} worker processes, one thread each "
                "...")
    with distributed.LocalCluster(n_workers=count, threads_per_worker=1, processes=True,
                                  memory_limit=0, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        logger.info(f"dask: local cluster at {cluster.scheduler_address}")
        try:
            yield client
        finally:
            logger.info("dask: closing the local cluster")
