"""Progress through :mod:`logging` and the threads that run a solve.

Every module logs to its ``copdea_fem.*`` logger; :func:`progress_to` forwards the records
of one run (this thread and the threads it hands its context to, :func:`carried`) to a
sink: the CLI's stderr or an API caller's ``progress`` callable.  :func:`tagging` prefixes a
sector's or an order's lines, :func:`quiet_progress` hides the steps of a sweep point or a
diagnosis solve.  :func:`single_threaded_blas` is the eigen stage's BLAS setting.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from dataclasses import dataclass, field


@dataclass
class Timings:
    """Wall time per stage of a solve [s] (mesh, prestress, eigen, ...)."""

    seconds: dict[str, float] = field(default_factory=dict)

    @contextlib.contextmanager
    def stage(self, name: str):
        start = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - start


def quiet(message: str) -> None:
    """The progress callback that says nothing."""


# -- progress through logging: the ``copdea_fem`` logger at INFO ----------------------------
_THREAD = threading.local()


@contextlib.contextmanager
def tagging(prefix: str):
    """Progress lines of this thread start with ``prefix`` while inside (``"m = 2: "``,
    a sector's name): see :func:`tagged`."""
    saved = getattr(_THREAD, "prefix", "")
    _THREAD.prefix = saved + prefix
    try:
        yield
    finally:
        _THREAD.prefix = saved


def tagged(message: str) -> str:
    """``message`` with the prefix of the enclosing :func:`tagging` blocks of this thread."""
    return getattr(_THREAD, "prefix", "") + message


@contextlib.contextmanager
def quiet_progress():
    """The INFO records of this thread are not shown by the handlers of :func:`progress_to`
    while inside (a sweep point, an FE solve of the diagnosis: their steps are not
    reported, only their summary line); warnings still are."""
    saved = getattr(_THREAD, "quiet", False)
    _THREAD.quiet = True
    try:
        yield
    finally:
        _THREAD.quiet = saved


def _context() -> tuple:
    return (getattr(_THREAD, "prefix", ""), getattr(_THREAD, "quiet", False),
            getattr(_THREAD, "owners", frozenset()))


def _restore(context: tuple) -> None:
    _THREAD.prefix, _THREAD.quiet, _THREAD.owners = context


def carried():
    """The progress context of this thread (:func:`tagging`, :func:`quiet_progress`, the
    :func:`progress_to` blocks it runs in), as a context manager that applies it in
    another thread (the sector threads)."""
    context = _context()

    @contextlib.contextmanager
    def applied():
        saved = _context()
        _restore(context)
        try:
            yield
        finally:
            _restore(saved)
    return applied


class _Forward(logging.Handler):
    """Each record's message to ``sink(message)``, except INFO records inside
    :func:`quiet_progress` and records of threads outside this handler's
    :func:`progress_to` block (another caller's run in the same process)."""

    def __init__(self, sink, level: int, only_info: bool):
        super().__init__(level)
        self.sink, self.only_info = sink, only_info

    def filter(self, record) -> bool:
        # runs in the thread that logs: its owners say which progress_to blocks it is in
        if self not in getattr(_THREAD, "owners", frozenset()):
            return False
        if record.levelno <= logging.INFO and getattr(_THREAD, "quiet", False):
            return False
        if self.only_info and record.levelno != logging.INFO:
            return False
        return super().filter(record)

    def emit(self, record) -> None:
        try:
            self.sink(record.getMessage())
        except Exception:  # noqa: BLE001 -- logging's rule: a handler never raises
            self.handleError(record)


@contextlib.contextmanager
def progress_to(sink, level: int = logging.INFO, only_info: bool = False):
    """While inside, the records of the ``copdea_fem`` loggers at ``level`` and above go
    to ``sink(message)`` (with ``only_info``: the INFO ones, the progress lines); the
    logger's level is lowered to INFO for the time if it was above.  Only the records
    of this thread, and of the threads it hands its context to (:func:`carried`), reach
    ``sink``: two runs in two threads of one process (two API calls) each see their own."""
    logger = logging.getLogger("copdea_fem")
    handler = _Forward(sink, level, only_info)
    owners = getattr(_THREAD, "owners", frozenset())
    _THREAD.owners = owners | {handler}
    with _LEVEL_LOCK:
        if _OPEN["blocks"] == 0:           # the first block in keeps the level it found
            _OPEN["level"] = logger.level
            if logger.getEffectiveLevel() > logging.INFO:
                logger.setLevel(logging.INFO)
        _OPEN["blocks"] += 1
    logger.addHandler(handler)
    try:
        yield handler
    finally:
        logger.removeHandler(handler)
        _THREAD.owners = owners
        with _LEVEL_LOCK:
            _OPEN["blocks"] -= 1
            if _OPEN["blocks"] == 0:       # the last block out restores the level found
                logger.setLevel(_OPEN["level"])


# the progress_to blocks open now (any thread) and the logger level the first one found
_LEVEL_LOCK = threading.Lock()
_OPEN = {"blocks": 0, "level": logging.NOTSET}


def single_threaded_blas():
    """BLAS on one thread for the eigen stage: SuperLU's triangular solves call BLAS
    on small supernode blocks, where a second thread costs more than it brings
    (coupled sectors of G1, default mesh: about a third less time on one BLAS thread than
    on two)."""
    from threadpoolctl import threadpool_limits
    return threadpool_limits(limits=1, user_api="blas")
