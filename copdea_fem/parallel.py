"""Where independent work runs: in this process, in worker processes of this machine, or on a
Dask cluster -- one vocabulary and one implementation for the sweeps and the diagnosis's FE
solves.

``--executor`` (and a sweep file's ``execution.executor``) names one of :data:`EXECUTORS`:

``inline``
    In this process, one task after the other.
``processes``
    ``--workers N`` spawned worker processes of this machine (:func:`process_pool`; NGSolve's
    threads do not survive a fork), each with one BLAS/OpenMP thread
    (:func:`one_thread_per_worker`) and tied to the process that started it
    (:func:`tie_to_parent`: killed with it, so no worker goes on writing into a folder
    whose lock is gone).
``dask``
    A Dask cluster (:func:`dask_client`): the running one at ``--scheduler ADDRESS`` (a
    cluster the user runs: ``dask scheduler`` and ``dask worker`` on other machines), else a
    local cluster of ``--workers`` processes started for the run
    (:class:`distributed.LocalCluster`: one thread each, closed when the run ends, also on
    an error or Ctrl-C).  Both are the same code path for the caller: a
    :class:`distributed.Client` to submit tasks to.

The old spellings work for one more release, each with a one-line
:class:`FutureWarning` naming the new one (:func:`deprecated`): the sweeps' ``local``
(:data:`SWEEP_SPELLINGS`: it ran in this process) and ``pool``, and the diagnosis's
``local`` (:data:`DIAGNOSIS_SPELLINGS`: it ran the FE solves in worker processes).

Every check here runs before any work and raises :class:`~copdea_fem.study.StudyError`
naming the option, the value and what is allowed.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import threading
import time
import warnings
from typing import TYPE_CHECKING

from copdea_fem.inputs import preview
from copdea_fem.study import StudyError

if TYPE_CHECKING:
    import concurrent.futures

logger = logging.getLogger(__name__)

EXECUTORS = ("inline", "processes", "dask")
#: The sweeps' old executor names -> the new ones (``local`` ran the chains in this process).
SWEEP_SPELLINGS = {"local": "inline", "pool": "processes"}
#: The diagnosis's old executor name -> the new one (``local`` ran the FE solves side by side
#: in worker processes).
DIAGNOSIS_SPELLINGS = {"local": "processes"}

#: Longest wait [s] for the scheduler at ``--scheduler`` to answer before the run stops with a
#: one-line error: a scheduler on the network answers in milliseconds; Dask's own default
#: (30 s) would only lengthen the wait for a wrong address.
SCHEDULER_TIMEOUT_SECONDS = 10.0
#: Thread counts of the BLAS and OpenMP libraries, set to 1 for the worker processes (one
#: task per core, no oversubscription).
THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
#: How often a worker process checks that the process that started it is still there [s].
PARENT_POLL_SECONDS = 0.25
_PR_SET_PDEATHSIG = 1              # <linux/prctl.h>


def deprecated(old: str, new: str) -> None:
    """One :class:`FutureWarning` (shown to the users of an application, one line on the
    command line): ``old`` still works for one release, ``new`` is its name from now on."""
    warnings.warn(f"{old} is deprecated and will be removed in the next release; use {new}",
                  FutureWarning, stacklevel=3)


def executor_name(value: str | None, old_spellings: dict[str, str] | None = None,
                  option: str = "--executor", error: type[StudyError] = StudyError) -> str | None:
    """``value`` as one of :data:`EXECUTORS` (None stays None: the caller's default).

    Parameters
    ----------
    value : str or None
        An executor name, or one of ``old_spellings`` (then a :func:`deprecated` warning).
    old_spellings : dict, optional
        The command's old names (:data:`SWEEP_SPELLINGS`, :data:`DIAGNOSIS_SPELLINGS`).
    option : str
        The option or key named in messages.
    error : type
        The :class:`StudyError` subclass raised.

    Raises
    ------
    StudyError
        Neither an executor nor an old spelling.
    """
    if value is None:
        return None
    if old_spellings and isinstance(value, str) and value in old_spellings:
        deprecated(f"{option} {value}", f"{option} {old_spellings[value]}")
        return old_spellings[value]
    if value not in EXECUTORS:
        raise error(f"{option} = {preview(value)} is not allowed; allowed: one of "
                    + ", ".join(EXECUTORS))
    return value


def check_executor(executor: str | None, scheduler=None, old_spellings=None,
                   default: str = "inline", error: type[StudyError] = StudyError,
                   workers=None) -> str:
    """The executor of a run checked before any work: its name (:func:`executor_name`;
    ``default`` when None), a ``scheduler`` only with ``dask`` (:func:`check_scheduler`,
    naming the executor as given), ``workers`` (a count the user gave) not with ``inline``
    (one process: the count would be ignored) and, for ``dask``, :mod:`distributed`
    installed."""
    name = executor_name(executor, old_spellings, error=error) or default
    check_scheduler(executor, scheduler)
    if name == "dask" and isinstance(scheduler, str):
        check_scheduler_answers(scheduler)
    if workers is not None and name == "inline":
        raise error(f"--workers = {preview(workers)} is not allowed with --executor inline "
                    "(it runs in this process alone); allowed: --workers with --executor "
                    "processes or dask")
    if name == "dask":
        require_distributed()
    return name


def check_scheduler(executor: str | None, scheduler, option: str = "--scheduler") -> None:
    """:class:`StudyError` when ``scheduler`` is given with an executor other than ``dask``
    (a scheduler address means nothing to the others); called before any work with the
    executor as given (None: none given)."""
    if scheduler is not None and executor != "dask":
        raise StudyError(f"{option} = {preview(scheduler)} is not allowed with --executor "
                         f"{executor or 'local'}; allowed: a Dask scheduler address with "
                         "--executor dask only")


def check_scheduler_answers(address: str, option: str = "--scheduler",
                            timeout: float | None = None) -> None:
    """A one-line :class:`StudyError` naming ``option`` unless a Dask scheduler answers at
    ``address`` within ``timeout`` [s] (default :data:`SCHEDULER_TIMEOUT_SECONDS`), checked
    before any work (before an output folder is claimed or a measured file read).

    The check asks the peer for its identity in Dask's protocol (``{"op": "identity"}``) in a
    thread of its own, bounded in time as a whole: a peer that accepts the connection but is
    not Dask (an HTTP server such as a dashboard, which never answers the handshake; or one
    that sends bytes Dask reads as a frame of exabytes) is refused like a closed port, and the
    answer must come from a scheduler (``type: Scheduler``).
    """
    import asyncio
    distributed = require_distributed()
    seconds = SCHEDULER_TIMEOUT_SECONDS if timeout is None else timeout
    outcome: dict = {}

    async def identity():
        comm = await distributed.comm.connect(address, timeout=seconds)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    def ask():
        try:
            outcome["answer"] = asyncio.run(asyncio.wait_for(identity(), seconds))
        except BaseException as problem:     # noqa: BLE001 -- any failure is a refusal
            outcome["problem"] = problem

    thread = threading.Thread(target=ask, name="copdea-scheduler-check", daemon=True)
    thread.start()
    thread.join(seconds + 1.0)
    answer = outcome.get("answer")
    if isinstance(answer, dict) and answer.get("type") == "Scheduler":
        return
    problem = outcome.get("problem")
    if "answer" in outcome:
        reason = "it answered, but not as a Dask scheduler"
    elif (problem is None or isinstance(problem, (TimeoutError, asyncio.TimeoutError))
          or "timed out" in str(problem).lower()):      # Dask's own connect timeout
        reason = f"no Dask scheduler answered there within {seconds:g} s"
    elif isinstance(problem, OSError) or (isinstance(problem, (ValueError, TypeError))
                                          and "address" in str(problem)):
        reason = " ".join(str(problem).split())[:200] or type(problem).__name__
    else:
        reason = "it answered, but not in Dask's protocol"
    raise StudyError(f"{option} = {preview(address)} is not allowed ({reason}); allowed: the "
                     "address of a running Dask scheduler, e.g. tcp://10.0.0.5:8786, or no "
                     "--scheduler for a local cluster")


def check_workers(value, option: str = "--workers",
                  purpose: str = "processes solving FE studies side by side") -> int:
    """``value`` as a worker count (an integer >= 1, or its text), or :class:`StudyError`
    naming ``option`` (called before any work).  A count above the machine's cores is capped
    at them with a warning: each worker is one NGSolve process, and more than one a core
    only share the cores (and multiply the memory)."""
    try:
        count = int(value)
    except (TypeError, ValueError):
        count = None
    if count is None or isinstance(value, bool) or count < 1 or str(count) != str(value).strip():
        raise StudyError(f"{option} = {value!r} is not allowed; allowed: an integer >= 1 "
                         f"({purpose})")
    cores = os.cpu_count() or 1
    if count > cores:
        logger.warning(f"{option} = {count} is more than the {cores} cores of this machine: "
                       f"{cores} worker(s) used")
        count = cores
    return count


def require_distributed():
    """The :mod:`distributed` module, or a one-line :class:`StudyError` saying how to install it."""
    try:
        import distributed
    except ImportError:
        raise StudyError("--executor = 'dask' is not allowed (dask.distributed is not "
                         "installed); allowed: inline or processes, or install Dask: pip "
                         "install 'copdea-fem[dask]'") from None
    return distributed


# -- worker processes of this machine ----------------------------------------------------------
@contextlib.contextmanager
def one_thread_per_worker():
    """While inside, the environment that worker processes inherit as they start sets one
    BLAS/OpenMP thread (:data:`THREAD_VARIABLES`); restored after."""
    saved = {name: os.environ.get(name) for name in THREAD_VARIABLES}
    for name in saved:
        os.environ[name] = "1"
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def process_pool(workers: int) -> concurrent.futures.ProcessPoolExecutor:
    """``workers`` spawned worker processes (NGSolve's threads do not survive a fork), each
    tied to this process (:func:`tie_to_parent`); the caller shuts the pool down."""
    import concurrent.futures
    import multiprocessing
    return concurrent.futures.ProcessPoolExecutor(
        max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
        initializer=tie_to_parent, initargs=(os.getpid(),))


def tie_to_parent(parent_pid: int) -> None:
    """Worker initializer: the worker dies with the process that started it.

    A worker outliving its parent (killed with SIGKILL, or crashed) would go on
    writing point folders into a sweep folder whose lock is gone.  On Linux the
    kernel sends the worker SIGKILL when its parent dies (``prctl(PR_SET_PDEATHSIG)``);
    everywhere a daemon thread checks every :data:`PARENT_POLL_SECONDS` that the
    parent is still the one that started it (``os.getppid``: a dead parent's
    children are handed to another process) and ends the worker at once if not.
    A point being written when the worker stops is a staging folder, which the
    next run into the sweep folder removes (:mod:`copdea_fem.folders`).
    """
    if sys.platform.startswith("linux"):
        try:
            import ctypes
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):    # no prctl: the watchdog below still acts
            pass
    if os.getppid() != parent_pid:          # the parent died before prctl took effect
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent_pid,), name="copdea-parent-watch",
                     daemon=True).start()


def _watch_parent(parent_pid: int) -> None:
    while os.getppid() == parent_pid:
        time.sleep(PARENT_POLL_SECONDS)
    os._exit(1)


# -- a Dask cluster -----------------------------------------------------------------------------
def connect(address: str, option: str = "--scheduler"):
    """A :class:`distributed.Client` of the scheduler at ``address``, or a one-line
    :class:`StudyError` naming ``option`` when the address is malformed or no scheduler
    answers there within :data:`SCHEDULER_TIMEOUT_SECONDS`."""
    distributed = require_distributed()
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


#: What a local cluster's worker processes inherit as they start (:func:`quiet_workers`): Dask
#: reads ``DASK_*`` variables into its config when it is imported, before it sets up its
#: logging, so their Dask loggers print only what ends a worker (not the warnings of tasks
#: cancelled when a run is interrupted, nor "event loop unresponsive" during a long FE
#: solve, nor the errors with tracebacks of a worker whose scheduler closed first, a race of
#: every interrupted run).  A task's own error reaches this process through its future and
#: is reported there.
WORKER_ENVIRONMENT = {"DASK_LOGGING__DISTRIBUTED": "critical"}


@contextlib.contextmanager
def quiet_workers():
    """While inside, the worker processes a local cluster starts ignore SIGINT and SIGTERM and
    log only Dask's critical records (:data:`WORKER_ENVIRONMENT`).

    A terminal's Ctrl-C (or a SIGTERM to the process group) reaches every process of its
    group; a worker that took it would end with a KeyboardInterrupt traceback, or die and be
    restarted by its nanny with a warning, while this process closes the cluster anyway.  An
    ignored signal stays ignored across the exec of a spawned process (POSIX), so both are
    ignored here while the cluster starts its workers, then handled again; the main thread
    only (elsewhere signals cannot be set, and the workers keep the default).  The workers
    still end with this process (they watch their parent)."""
    main_thread = threading.current_thread() is threading.main_thread()
    saved_environment = {name: os.environ.get(name) for name in WORKER_ENVIRONMENT}
    os.environ.update(WORKER_ENVIRONMENT)
    signals = (signal.SIGINT, signal.SIGTERM)
    previous = [signal.signal(sign, signal.SIG_IGN) for sign in signals] if main_thread else []
    try:
        yield
    finally:
        for sign, handler in zip(signals, previous):
            signal.signal(sign, handler)
        for name, value in saved_environment.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


@contextlib.contextmanager
def quiet_distributed_logs():
    """Yields ``quiet()``: once called, this process's Dask loggers (``distributed`` and those
    below it that set a level of their own) drop every record until the block ends, when their
    levels are restored."""
    saved: dict[logging.Logger, int] = {}

    def quiet():
        names = ["distributed", *(name for name in logging.root.manager.loggerDict
                                  if name.startswith("distributed."))]
        for name in names:
            dask_logger = logging.getLogger(name)
            if name == "distributed" or dask_logger.level != logging.NOTSET:
                saved.setdefault(dask_logger, dask_logger.level)
                dask_logger.setLevel(logging.CRITICAL + 1)

    try:
        yield quiet
    finally:
        for dask_logger, level in saved.items():
            dask_logger.setLevel(level)


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
    ``distributed.nanny.pre-spawn-environ``) and no memory limit (as the worker processes of
    ``processes``: an FE solve's memory is bounded by the size guard, not by a share of the
    machine); they end with this process (Dask's worker processes watch their parent).

    An interrupt (Ctrl-C, which a terminal sends to the whole process group, or the CLI's
    SIGTERM) ends the run with the CLI's one line: the workers ignore SIGINT and log only
    critical records (:func:`quiet_workers`), and this process's Dask loggers fall silent while the
    cluster closes (:func:`quiet_distributed_logs`) -- else 3-4 tracebacks and the
    cancelled tasks' warnings of every worker would follow it.
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
    with quiet_distributed_logs() as quiet:
        with quiet_workers():
            cluster = distributed.LocalCluster(n_workers=count, threads_per_worker=1,
                                               processes=True, memory_limit=0,
                                               dashboard_address=None)
        with cluster, distributed.Client(cluster) as client:
            logger.info(f"dask: local cluster at {cluster.scheduler_address}")
            try:
                yield client
            except KeyboardInterrupt:
                quiet()                 # the cluster closes in silence: one line says it all
                raise
            logger.info("dask: closing the local cluster")
