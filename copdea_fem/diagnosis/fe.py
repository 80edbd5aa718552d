"""The FE model of record of the diagnosis: study -> structural modes, cached.

The diagnosis compares the measurement with the finite-element model as the
base study is written: in vacuo where ``air.enabled`` is false, fully coupled
with the air (and its frame) where it is true.  :func:`fe_study` maps a
diagnosis study to the study the FE runs; :class:`FEModel` solves it with the
engine the geometry allows (the axisymmetric-harmonic engine for dry modes and
for frames none/baffle/circle, seconds a solve; the 3-D quadrant for the square frame)
and keeps the structural modes (out-of-plane and pumping) in memory and,
optionally, on disk, keyed by a hash of the FE study.

What the FE honours (:data:`FE_EFFECT_KEYS`): everything of the geometry,
material and load, ``air.enabled``, ``geometry.frame``, ``disc.motion`` and
the spring's stiffness, and the two effect keys ``effects.stiffness_scale``
and ``effects.maxwell_scale`` (:meth:`copdea_fem.fe.materials.Membrane.with_effects`).
What it does not: the ring model's own keys (``reduced.*``), the air-mass
estimate and its scale, visco-elasticity, the spring's mass, modal damping --
those act through the anchored ring surrogate (:mod:`copdea_fem.diagnosis.anchored`).

Side by side.  A cold diagnosis needs tens of independent FE solves (every
condition at every switch state, the grid of a fitted parameter on the direct engine):
the search hands each batch to :meth:`FEModel.solve_many` first, which solves what the
cache lacks in spawned worker processes (``executor="processes"``, the default, ``workers``
of them: ``--workers``), or on a Dask cluster (``executor="dask"``, ``--executor dask``: the
cluster at ``--scheduler``, else a local one of ``workers`` processes started for the run;
:mod:`copdea_fem.parallel`), each worker writing its entry under the per-entry lock, so runs
and workers share one cache folder safely; ``executor="inline"`` solves them here, one at a
time.

Modes.  Frequencies are the real parts of the (coupled) eigenfrequencies [Hz].
A split pair ``(m,n)a``/``(m,n)b`` that a vibrometer cannot resolve (relative
split below :data:`PAIR_MERGE`) is one mode ``(m,n)`` at the mean frequency;
in-plane modes (hardly seen by an out-of-plane vibrometer) and air modes are
left out.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import math
import os
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

from copdea_fem.fingerprint import fe_fingerprint
from copdea_fem.folders import LockHeld, exclusive_lock
from copdea_fem.parallel import (
    DIAGNOSIS_SPELLINGS,
    check_executor,
    check_workers,
    dask_client,
    one_thread_per_worker,
    process_pool,
)
from copdea_fem.study import Study, StudyError
from copdea_fem.study.imperfections import is_imperfect

logger = logging.getLogger(__name__)

FE_CACHE_VERSION = 1           # bump when structural_modes changes (the FE code: fe_fingerprint)
PAIR_MERGE = 2e-3              # split pairs closer than this (relative) are one peak: a
                               # fifth of a 1 % identification scatter, not resolvable

#: Suffix of the cache key of an entry with every pair's members kept (FEModel.modes).
PAIRS_SUFFIX = "-pairs"

FE_EFFECT_KEYS = ("effects.stiffness_scale", "effects.maxwell_scale")
# The FE's band reaches past the data's, so a mode just above the band edge is still
# paired: 25 % is past the 4 sigma_f strict gate of unknown-kind peaks and near the 50 %
# gate of known ones (copdea_fem.diagnosis.compare), at the cost of more FE modes.
BAND_MARGIN = 1.25


@dataclass(frozen=True)
class FEMode:
    """One structural mode of the FE: label ``P1``, ``(0,n)``, ``(m,n)`` (or ``(m,n)a/b``),
    kind ``pumping``/``axisymmetric``/``non-axisymmetric``, frequency [Hz], damping ratio
    Im f / |f| [-] (0 in vacuo)."""

    label: str
    kind: str
    frequency_hz: float
    damping_ratio: float = 0.0


@dataclass(frozen=True)
class FEResult:
    """The structural modes of one FE study, and how they were obtained."""

    modes: tuple
    engine: str                  # "axisymmetric" or "3d"
    coupled: bool
    seconds: float
    key: str

    def frequencies(self) -> dict:
        return {m.label: m.frequency_hz for m in self.modes}


def fe_study(study: Study, f_max: float | None = None) -> Study:
    """The study the FE solves for a diagnosis study.

    In vacuo the frame and the enclosure play no part (they act through the air), so dry
    modes run on the axisymmetric engine (an imperfect device,
    :func:`copdea_fem.study.imperfections.is_imperfect`: ``mesh.engine: auto``, its
    perturbation path within its range, else the 3-D engine) with ``frame: none``, ``enclosure: none`` (and
    ``air.outside: true``, which only an enclosure may turn off); coupled ones keep the
    frame and the enclosure and let ``mesh.engine: auto`` choose.  ``f_max`` [Hz]
    (default: the study's) is the top of the FE band (``eigen.f_min`` raised where a
    ``membrane.prony`` relaxation spectrum would reach that band:
    :func:`~copdea_fem.diagnosis.effects.prony_band_floor`); no result files are written.
    """
    overrides = {"output.plots": False, "output.paraview": False}
    if f_max is not None:
        overrides["eigen.f_max"] = float(f_max)
        from copdea_fem.diagnosis.effects import prony_band_floor
        floor = prony_band_floor(study.membrane.prony, study.eigen, float(f_max))
        if floor is not None:        # a Prony relaxation spectrum the wider band would reach
            overrides["eigen.f_min"] = floor
    if not study.air.enabled:
        # an imperfect device: auto picks the perturbation path within its range, else 3-D
        engine = "auto" if is_imperfect(study.membrane, study.imperfections) else "axisymmetric"
        overrides.update({"geometry.frame": "none", "geometry.enclosure": "none",
                          "air.outside": True, "mesh.engine": engine})
    return study.replace(overrides)


def fe_key(study: Study) -> str:
    """Hash of what the FE reads from a study (:func:`fe_study` applied), of the FE code
    (:func:`copdea_fem.fingerprint.fe_fingerprint`: a physics change gives new keys) and
    :data:`FE_CACHE_VERSION` (this module's own post-processing): the cache key of
    :class:`FEModel`.  Sections of the
    physics and the mesh, whole; of the others only the keys that change the modes."""
    whole = ("geometry", "membrane", "disc", "load", "air", "mesh", "imperfections")
    picked = ("spring.stiffness", "eigen.f_min", "eigen.f_max", "eigen.max_damping_ratio",
              "air.min_membrane_energy") + FE_EFFECT_KEYS
    values = study.values
    items = {f"{s}.{k}": v for s in whole for k, v in values.get(s, {}).items()}
    items.update({key: study.get(key) for key in picked})
    text = json.dumps({"version": FE_CACHE_VERSION, "code": fe_fingerprint(), "study": items},
                      sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def structural_modes(modes, merge_pairs: bool = True) -> tuple:
    """:class:`FEMode` list from the pipeline's modes (module notes: pairs merged; with
    ``merge_pairs`` False every member kept, however close: the splits the imperfection
    stage measures, :mod:`copdea_fem.diagnosis.imperfections`)."""
    kept = []
    for mode in modes:
        if mode.kind not in ("out-of-plane", "pumping") or not mode.label:
            continue
        magnitude = math.hypot(mode.freq_hz, getattr(mode, "freq_im_hz", 0.0))
        zeta = abs(getattr(mode, "freq_im_hz", 0.0)) / magnitude if magnitude else 0.0
        kind = ("pumping" if mode.kind == "pumping" else
                "axisymmetric" if mode.m == 0 else "non-axisymmetric")
        kept.append(FEMode(mode.label, kind, float(mode.freq_hz), float(zeta)))
    by_label = {m.label: m for m in kept}
    out = []
    for mode in kept:
        if mode.label.endswith("b") and mode.label[:-1] + "a" in by_label:
            continue
        if mode.label.endswith("a") and mode.label[:-1] + "b" in by_label:
            other = by_label[mode.label[:-1] + "b"]
            if merge_pairs and abs(other.frequency_hz / mode.frequency_hz - 1) < PAIR_MERGE:
                out.append(FEMode(mode.label[:-1], mode.kind,
                                  0.5 * (mode.frequency_hz + other.frequency_hz),
                                  0.5 * (mode.damping_ratio + other.damping_ratio)))
                continue
            out.append(other)
        out.append(mode)
    return tuple(sorted(out, key=lambda m: m.frequency_hz))


CACHE_VARIABLE = "COPDEA_FEM_FE_CACHE"
#: Longest wait [s] for an entry another run is computing (its lock file held) before this
#: run solves it itself: past the longest single FE solve of a diagnosis (the 3-D square
#: frame coupled on the default mesh, minutes on a fine mesh), so only a hung run is overtaken.
LOCK_WAIT_SECONDS = 600.0

ENTRY_ENGINES = ("axisymmetric", "3d")
ENTRY_KINDS = ("pumping", "axisymmetric", "non-axisymmetric")


def fe_cache_dir() -> Path:
    """``$COPDEA_FEM_FE_CACHE`` when set, else the user cache folder (``platformdirs``:
    ``~/.cache/copdea-fem/fe-modes`` on Linux)."""
    if os.environ.get(CACHE_VARIABLE):
        return Path(os.environ[CACHE_VARIABLE]).expanduser()
    import platformdirs
    return Path(platformdirs.user_cache_dir("copdea-fem")) / "fe-modes"


def cache_dir_problem(path) -> str | None:
    """Why ``path`` cannot be an FE cache folder (it, or a folder above it, is an existing
    file), or None: a folder, or a path that can be created."""
    path = Path(path).expanduser()
    for item in (path, *path.parents):
        if item.exists() or item.is_symlink():
            if item.is_dir():
                return None
            return ("an existing file, not a folder" if item == path else
                    f"{item} is an existing file")
    return None


def check_cache_dir(path, option: str = "--fe-cache") -> Path:
    """``path`` as an FE cache folder, or :class:`StudyError` naming ``option`` and the path
    (called before any work: the CLI's ``--fe-cache`` exits 2 on a file)."""
    problem = cache_dir_problem(path)
    if problem:
        from copdea_fem.inputs import PATH_CHARACTERS, preview
        shown = preview(Path(path), PATH_CHARACTERS)
        raise StudyError(f"{option} = {shown} is not allowed ({problem}); allowed: a folder "
                         "(created when missing)")
    return Path(path).expanduser()


def entry_problem(document) -> str | None:
    """Why a decoded cache entry does not follow the schema of :meth:`FEModel._write`, or None.

    Schema: ``{"modes": [{"label": non-empty str, "kind": one of ENTRY_KINDS,
    "frequency_hz": finite number > 0, "damping_ratio": finite number in [0, 1]}, ...],
    "engine": one of ENTRY_ENGINES, "coupled": bool, "seconds": finite number >= 0}``
    (numbers: int or float, not bool; every key present).
    """
    def number(value, low, high=math.inf, open_low=False):
        return (isinstance(value, (int, float)) and not isinstance(value, bool)
                and math.isfinite(value) and (value > low if open_low else value >= low)
                and value <= high)

    if not isinstance(document, dict):
        return f"a JSON {type(document).__name__}, not an object"
    missing = [key for key in ("modes", "engine", "coupled", "seconds") if key not in document]
    if missing:
        return "no " + ", ".join(repr(key) for key in missing)
    if document["engine"] not in ENTRY_ENGINES:
        return f"engine = {document['engine']!r}, not one of {', '.join(ENTRY_ENGINES)}"
    if not isinstance(document["coupled"], bool):
        return f"coupled = {document['coupled']!r}, not true or false"
    if not number(document["seconds"], 0.0):
        return f"seconds = {document['seconds']!r}, not a finite number >= 0"
    if not isinstance(document["modes"], list):
        return "modes is not a list"
    fields = {"label", "kind", "frequency_hz", "damping_ratio"}
    for index, mode in enumerate(document["modes"]):
        where = f"modes[{index}]"
        if not isinstance(mode, dict) or set(mode) != fields:
            return f"{where} is not an object with keys {', '.join(sorted(fields))}"
        if not isinstance(mode["label"], str) or not mode["label"]:
            return f"{where}.label = {mode['label']!r}, not a label"
        if mode["kind"] not in ENTRY_KINDS:
            return f"{where}.kind = {mode['kind']!r}, not one of {', '.join(ENTRY_KINDS)}"
        if not number(mode["frequency_hz"], 0.0, open_low=True):
            return f"{where}.frequency_hz = {mode['frequency_hz']!r}, not a finite number > 0"
        if not number(mode["damping_ratio"], 0.0, 1.0):
            return f"{where}.damping_ratio = {mode['damping_ratio']!r}, not a finite number " \
                   "in [0, 1]"
    return None


class FEModel:
    """FE structural modes of diagnosis studies, solved once per FE study.

    Parameters
    ----------
    cache_dir : path, optional
        Folder of ``<key>.json`` files kept between runs (default
        :func:`fe_cache_dir`); ``False``: memory only.  A path that is an existing
        file is ignored with a warning (memory only): the cache only saves time.
    lock_wait : float, optional
        Longest wait [s] for an entry another run is computing (default
        :data:`LOCK_WAIT_SECONDS`).
    workers : int, optional
        Processes that solve a batch of FE studies side by side (:meth:`solve_many`);
        default :func:`default_workers`; 1: every solve in this process, one at a time.
        With ``executor="dask"`` and no ``scheduler``: the local cluster's workers.
    executor : {"processes", "inline", "dask"}, optional
        Where :meth:`solve_many` solves (:mod:`copdea_fem.parallel`): ``"processes"``
        (default), spawned processes of this machine; ``"inline"``, here, one at a time;
        ``"dask"``, a Dask cluster (:func:`copdea_fem.parallel.dask_client`), started at the
        first batch and closed by :meth:`close`.  The old ``"local"`` is ``"processes"``
        (with a deprecation warning).
    scheduler : str or distributed.Client, optional
        With ``executor="dask"``: the address of a running scheduler (connected here, so a
        wrong address fails at once with a :class:`StudyError`) or a client the caller
        holds; None: a local cluster.  Refused with another executor.

    The cache never fails a diagnosis.  An entry is read only when it follows the
    schema of :func:`entry_problem`; a damaged one (not JSON, a wrong type, a
    non-finite number, a missing key) is solved again and replaced, with a one-line
    warning naming the file.  Runs sharing the folder coordinate per entry: the
    one that solves holds ``<key>.lock`` (``flock``, released by the system if
    the process dies); another that needs the entry waits for it and reads it,
    at most ``lock_wait`` seconds, then solves it itself.  Warnings go through
    :mod:`logging` (the CLI prints them on stderr, also with ``--quiet``).
    """

    def __init__(self, cache_dir=None, lock_wait: float = LOCK_WAIT_SECONDS,
                 workers: int | None = None, executor: str | None = None, scheduler=None):
        executor = check_executor(executor, scheduler, DIAGNOSIS_SPELLINGS, "processes")
        if cache_dir is None:
            cache_dir = fe_cache_dir()
        self.cache_dir = Path(cache_dir).expanduser() if cache_dir else None
        if self.cache_dir is not None:
            problem = cache_dir_problem(self.cache_dir)
            if problem:
                logger.warning(f"FE cache {self.cache_dir} ignored ({problem}); FE solves "
                               "are kept in memory only")
                self.cache_dir = None
        self.progress = logger.info      # progress lines, at INFO
        self.lock_wait = lock_wait
        self.workers = default_workers() if workers is None else check_workers(workers)
        self._memory: dict = {}
        self._pool = None
        self.executor = executor
        self._cluster = contextlib.ExitStack()    # the Dask client (and local cluster), if any
        self._client = None
        if executor == "dask" and scheduler is not None:
            self._client = self._cluster.enter_context(dask_client(scheduler))
        self.solves = 0
        self.seconds = 0.0

    def modes(self, study: Study, f_max: float | None = None,
              merge_pairs: bool = True) -> FEResult:
        """Structural modes of ``study`` (a diagnosis study: :func:`fe_study` applied);
        ``merge_pairs`` False: every pair's members kept (:func:`structural_modes`; an entry
        of its own, key :func:`fe_key` + ``-pairs``)."""
        run = fe_study(study, f_max)
        key = fe_key(run) + ("" if merge_pairs else PAIRS_SUFFIX)
        hit = self._memory.get(key) or self._read(key, quiet=True)
        if hit is None:
            with self._entry_lock(key):
                hit = self._read(key)          # written by another run while we waited?
                if hit is None:
                    hit = self._solve(run, key, merge_pairs)
                    self._write(hit)
        self._memory[key] = hit
        return hit

    def solve_many(self, requests) -> int:
        """Solve the FE studies of ``requests`` (``(study, f_max)`` pairs, as :meth:`modes`
        takes them) that neither memory nor the cache folder holds, side by side in
        :attr:`workers` spawned processes (NGSolve's threads do not survive a fork; one
        BLAS thread each: the axisymmetric solves are single-threaded anyway); the
        results land in memory, and in the cache folder as :meth:`modes` writes them.

        Safe with the cache shared: each worker is an :class:`FEModel` on the same
        folder, so an entry is solved under its ``<key>.lock`` (class notes) -- two
        workers, or two runs, never solve the same entry at once, and a worker that
        finds an entry another run wrote reads it.  A study a worker cannot solve is
        left out (the caller's :meth:`modes` solves it again and raises its error).
        Returns the number of studies solved here (0 inline, with one worker process or
        with < 2 to solve).

        With ``executor="dask"`` the batch goes to the Dask cluster instead, as the same
        tasks (one :class:`FEModel` per task on the cache folder); an entry a remote worker
        solved that this machine's folder lacks is written there too.
        """
        if self.executor == "inline" or (self.executor == "processes" and self.workers < 2):
            return 0
        todo = {}
        for request in requests:
            study, f_max = request[:2]
            merge_pairs = request[2] if len(request) > 2 else True
            run = fe_study(study, f_max)
            key = fe_key(run) + ("" if merge_pairs else PAIRS_SUFFIX)
            if key in self._memory or key in todo:
                continue
            hit = self._read(key, quiet=True)
            if hit is not None:
                self._memory[key] = hit
                continue
            todo[key] = (study, f_max, merge_pairs)
        if len(todo) < 2:
            return 0
        import concurrent.futures
        where = ("the Dask cluster" if self.executor == "dask" else
                 f"{self.workers} processes side by side")
        self.progress(f"FE: {len(todo)} solves on {where} ...")
        folder = str(self.cache_dir) if self.cache_dir is not None else None
        solved, broken = 0, None
        start = time.perf_counter()
        futures = {}
        try:
            if self.executor == "dask":
                from distributed import as_completed
                client = self._dask_client()
                batch = uuid.uuid4().hex[:8]
                futures = {client.submit(_solve_in_worker, study, f_max, folder,
                                         self.lock_wait, merge, key=f"copdea-fe-{key}-{batch}",
                                         pure=False): key
                           for key, (study, f_max, merge) in todo.items()}
                completed = as_completed(list(futures))
            else:
                with one_thread_per_worker():     # read by the workers as they start
                    pool = self._worker_pool()
                    futures = {pool.submit(_solve_in_worker, study, f_max, folder,
                                           self.lock_wait, merge): key
                               for key, (study, f_max, merge) in todo.items()}
                completed = concurrent.futures.as_completed(futures)
            for future in completed:
                try:
                    result, solves = future.result()
                except (RuntimeError, ValueError) as error:   # the FE's own error:
                    if isinstance(error, concurrent.futures.process.BrokenProcessPool):
                        broken = broken or error
                    logger.debug(f"FE worker failed on {futures[future]}: {error!r}")
                    continue                                  # modes() raises it here
                except Exception as error:  # noqa: BLE001 -- the workers, not the FE
                    broken = broken or error
                    continue
                self._memory[futures[future]] = result
                path = self._path(result.key)
                if self.executor == "dask" and path is not None and not path.is_file():
                    self._write(result)          # solved on another machine's folder
                if solves:
                    solved += 1
                    self.solves += 1
                    self.seconds += result.seconds
        except BaseException:            # an error or Ctrl-C: nothing left running
            for future in futures:
                future.cancel()
            raise
        if broken is not None:             # do not try again: one at a time from now on
            self.close()
            self.workers, self.executor = 1, "inline"
            logger.warning(f"FE worker processes failed ({broken!r}); the remaining FE "
                           "studies are solved here, one at a time")
        self.progress(f"FE: {solved} solves in {time.perf_counter() - start:.1f} s "
                      f"(side by side)")
        return solved

    def _worker_pool(self):
        """The spawned worker processes of :meth:`solve_many`, started at its first batch
        and kept for the next ones (a worker's start -- Python, NGSolve -- costs seconds);
        ended by :meth:`close`, or when this model is collected or the process exits."""
        if self._pool is None:
            import weakref
            self._pool = process_pool(self.workers)
            self._finalizer = weakref.finalize(self, self._pool.shutdown, wait=True,
                                               cancel_futures=True)
        return self._pool

    def _dask_client(self):
        """The Dask client of :meth:`solve_many`: the one connected at construction, else a
        local cluster of :attr:`workers` processes started at the first batch and kept for
        the next ones; closed by :meth:`close`."""
        if self._client is None:
            self._client = self._cluster.enter_context(dask_client(None, self.workers))
        return self._client

    def close(self, error: BaseException | None = None) -> None:
        """End the worker processes of :meth:`solve_many` (if any were started), and close
        the Dask client and its local cluster (if any).  ``error``: the exception that ends
        the run, handed to the client's context (:func:`copdea_fem.parallel.dask_client`),
        so that an interrupt closes the local cluster in silence and the CLI's one line is
        all that follows it."""
        if self._pool is not None:
            self._finalizer()
            self._pool = None
        self._client = None
        if error is None:
            self._cluster.close()
        else:
            self._cluster.__exit__(type(error), error, error.__traceback__)

    def _solve(self, run: Study, key: str, merge_pairs: bool = True) -> FEResult:
        from copdea_fem.fe import coupled_modes, dry_modes, engine_for
        from copdea_fem.progress import quiet_progress
        engine = engine_for(run)
        coupled = bool(run.air.enabled)
        load = run.load
        self.progress(f"FE ({engine.name}, {'coupled' if coupled else 'in vacuo'}) at "
                      f"z = {1e3 * load.z:g} mm, V_b = {1e-3 * load.voltage:g} kV ...")
        start = time.perf_counter()
        with quiet_progress():             # one line per FE study, not its steps
            if coupled:
                modes = coupled_modes(run, engine=engine).modes
            else:
                _, modes, _ = dry_modes(run, engine=engine)
        seconds = time.perf_counter() - start
        self.solves += 1
        self.seconds += seconds
        return FEResult(structural_modes(modes, merge_pairs), engine.name, coupled, seconds,
                        key)

    # -- disk cache ------------------------------------------------------------------------
    def _path(self, key: str):
        return self.cache_dir / f"{key}.json" if self.cache_dir else None

    def _read(self, key: str, quiet: bool = False):
        """The entry of ``key``, or None: absent, or damaged (then, unless ``quiet``, a
        warning naming the file; the caller solves it again and replaces it)."""
        path = self._path(key)
        if path is None or not path.is_file():
            return None
        try:
            document = json.loads(path.read_text(), parse_constant=_refuse_constant)
        except (OSError, ValueError) as error:
            problem = f"not readable JSON: {error}"[:200]
        else:
            problem = entry_problem(document)
        if problem:
            if not quiet:
                logger.warning(f"FE cache entry {path} is damaged ({problem}); solving it "
                               "again and replacing it")
            return None
        modes = tuple(FEMode(m["label"], m["kind"], float(m["frequency_hz"]),
                             float(m["damping_ratio"])) for m in document["modes"])
        return FEResult(modes, document["engine"], document["coupled"],
                        float(document["seconds"]), key)

    @contextlib.contextmanager
    def _entry_lock(self, key: str):
        """Hold ``<key>.lock`` in the cache folder while solving ``key`` (class notes:
        :func:`copdea_fem.folders.exclusive_lock`, waiting up to :attr:`lock_wait` for
        another run); without a cache folder, where it cannot be locked, or after the
        wait, no lock."""
        if self.cache_dir is None:
            yield
            return
        path = self.cache_dir / f"{key}.lock"

        def waiting(holder):
            logger.info(f"waiting for FE cache entry {path.stem}, being computed by another "
                        f"run (process {holder}) ...")

        with contextlib.ExitStack() as lock:
            try:
                self.cache_dir.mkdir(parents=True, exist_ok=True)
                lock.enter_context(exclusive_lock(path, self.lock_wait, waiting))
            except LockHeld as held:
                logger.warning(f"FE cache entry {path.with_suffix('.json')} is still being "
                               f"computed by process {held.holder} after {self.lock_wait:g} s; "
                               "solving it here too")
            except OSError as error:           # a read-only folder: solve without the lock
                logger.warning(f"FE cache {self.cache_dir} cannot be locked "
                               f"({error.strerror or error}); solving without coordination")
            yield

    def _write(self, result: FEResult) -> None:
        path = self._path(result.key)
        if path is None:
            return
        document = {"modes": [m.__dict__ for m in result.modes], "engine": result.engine,
                    "coupled": result.coupled, "seconds": result.seconds}
        staging = path.with_suffix(f".tmp{os.getpid()}-{uuid.uuid4().hex[:8]}")
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            staging.write_text(json.dumps(document, indent=1, allow_nan=False))
            os.replace(staging, path)          # only <key>.json: the names this class makes
        except (OSError, ValueError) as error:  # the cache only saves time: never fail on it
            logger.warning(f"FE cache {self.cache_dir} not written "
                           f"({getattr(error, 'strerror', None) or error})")
            with contextlib.suppress(OSError):
                staging.unlink(missing_ok=True)


WORKERS_VARIABLE = "COPDEA_FEM_FE_WORKERS"
MAX_DEFAULT_WORKERS = 4


def default_workers() -> int:
    """``$COPDEA_FEM_FE_WORKERS`` when set, else the machine's cores up to
    :data:`MAX_DEFAULT_WORKERS` (a cold diagnosis has tens of independent solves)."""
    if os.environ.get(WORKERS_VARIABLE):
        return check_workers(os.environ[WORKERS_VARIABLE], WORKERS_VARIABLE)
    return max(1, min(MAX_DEFAULT_WORKERS, os.cpu_count() or 1))


def _solve_in_worker(study, f_max, folder, lock_wait, merge_pairs=True):
    """Worker process of :meth:`FEModel.solve_many`: one study through an :class:`FEModel`
    on the shared folder (its per-entry lock); the result and whether it was solved here."""
    model = FEModel(cache_dir=folder if folder is not None else False, lock_wait=lock_wait,
                    workers=1)
    result = model.modes(study, f_max, merge_pairs)
    return result, model.solves


def _refuse_constant(name: str):
    """``json.loads`` hook: NaN and Infinity are not numbers of an entry."""
    raise ValueError(f"{name} is not a finite number")
