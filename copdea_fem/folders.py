"""Result folders: where a run may write, and how it replaces a previous result.

A result folder carries a manifest, :data:`MANIFEST`, listing every file the
run wrote (with the tool version and the command).  The rules, checked by
:func:`check_output` before any work:

- the target may be a new path, an empty folder, or a previous result of the
  same command whose folder holds nothing the manifest does not list; anything
  else (an existing file, a folder of measurements or notes, a result with
  files added by hand, the result of another command) is refused, and nothing
  is written;
- never the working folder, one of its parents, the home folder, or a folder
  holding (or above) one of the run's input files;
- a directory taken from an input file (``output.directory`` of a study or
  sweep file, data that may come from someone else) must lie inside the
  working folder;
- its parent must be a writable folder (checked by creating the lock file), and an
  existing folder must be writable too (a file created in it and removed, once it is
  locked: a read-only folder is refused, not swapped for a writable one).

Writing (:func:`result_directory`) is staged: the files go to a hidden sibling
``.NAME.staging-*``; when complete, the old result (if any) is renamed to
``.NAME.old-*``, the staging folder renamed to ``NAME``, and the old copy
deleted last (its manifest after all its other files, so that a copy whose
deletion was cut short is still recognised as ours).  SIGINT/SIGTERM that
arrive during this swap are acted on after it (:func:`_signals_deferred`: the
Python handlers are replaced for the swap, since a signal mask is per thread
and NGSolve's, BLAS's or a pool's threads would take the signal and let Python
raise it in the middle of the swap); :class:`Claim` records whether the new
result is in place and where a previous result is when it is not in ``NAME``,
so the CLI's message after an interruption says where the complete result is.
A rename that fails puts the previous result back; an old copy that cannot be
deleted is named in a one-line warning.  At every instant a complete old or a
complete new result exists.  Leftovers of a run that was killed (SIGKILL, power
loss) are cleaned by the next run into the same folder: staging folders are
removed, an old copy whose swap did not finish is renamed back, one whose new
result is in place is removed.

Concurrent runs into one folder: :func:`claim` takes an exclusive lock
(``.NAME.copdea-fem-lock`` beside the folder, :func:`exclusive_lock`) for the
whole run; a second run is refused at once, naming the holder's process id.
The CLI claims once, before any work, and hands the :class:`Claim` to the writer
(:func:`held`).

:func:`exclusive_lock` is the package's one file lock (also the FE cache's per
entry, :class:`copdea_fem.diagnosis.fe.FEModel`): ``flock`` on a lock file that
holds the holder's process id, released by the kernel when a process dies, and
the file removed by its holder when done.  Since the file is removed, a process
that opened it before the removal may lock an unlinked file: only a lock on the
file still in place counts (its inode is checked after locking, else it tries
again), so two holders never coexist.  (The filelock package keeps the file in
place for that reason and records no holder.)
"""

from __future__ import annotations

import contextlib
import datetime
import json
import logging
import os
import re
import shutil
import signal
import threading
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

try:
    import fcntl
except ImportError:          # Windows: no advisory locks; folders are not locked
    fcntl = None

logger = logging.getLogger(__name__)

MANIFEST = ".copdea-fem-result.json"
#: Test hook: seconds to sleep inside the write phase (staging written, not yet swapped).
WRITE_DELAY_VARIABLE = "COPDEA_FEM_TEST_WRITE_DELAY"
#: Test hook: a path; when set, the write-phase delay ends early once that file exists (a
#: test holds a run in its write phase exactly as long as it needs, whatever the load).
WRITE_GATE_VARIABLE = "COPDEA_FEM_TEST_WRITE_GATE"


def _test_write_delay() -> None:
    """The tests' hold inside the write phase (:data:`WRITE_DELAY_VARIABLE`,
    :data:`WRITE_GATE_VARIABLE`); nothing when neither is set."""
    delay = float(os.environ.get(WRITE_DELAY_VARIABLE, 0))
    gate = os.environ.get(WRITE_GATE_VARIABLE)
    deadline = time.monotonic() + delay
    while time.monotonic() < deadline:
        if gate and os.path.exists(gate):
            return
        time.sleep(min(0.05, max(deadline - time.monotonic(), 0.0)))


class OutputFolderError(ValueError):
    """An output folder this run may not write; the message says which and what to do.

    Raised before any work by :func:`check_output` and :func:`claim` (the working or home
    folder, a folder holding an input file, a file, a folder with another command's result
    or foreign files, one another run is writing; the CLI's exit 2), and so by every
    ``write`` of :mod:`copdea_fem.api` and by :func:`copdea_fem.api.sweep` with ``out``.

    Parameters
    ----------
    message : str
        The folder, why it may not be written, and what to do instead.
    """


#: The claims each thread holds (:func:`claim`).
_THREAD = threading.local()


class ResultWriteError(RuntimeError):
    """Writing or swapping a result failed (a full disk, a rename refused); the message
    says where the complete result is (exit 1 in the CLI)."""


@dataclass
class Claim:
    """A folder this process holds the lock of for a run."""

    target: Path
    command: str
    had_result: bool            # a previous result was there when the run started
    written: bool = False       # this run's result is in place
    old_copy: Path | None = None    # where the previous result (or what is left of it) is
                                    # when a swap could not finish; None: nowhere else

    def whereabouts(self) -> str:
        """Where the complete result is, for a message after an interruption or a failure."""
        if self.written:
            where = f"the result in {self.target} is complete"
            if self.old_copy is not None:
                where += (f"; the rest of the previous result, {self.old_copy}, is removed by "
                          "the next run into it (or delete it)")
            return where
        if self.old_copy is not None:
            return (f"previous result kept in {self.old_copy} (the next run into {self.target} "
                    "puts it back)")
        if self.had_result:
            return f"previous result kept in {self.target}"
        return "no result written"


def read_manifest(folder: Path) -> dict | None:
    """The manifest of a result folder, or None when it has none (or an unreadable one)."""
    try:
        document = json.loads((Path(folder) / MANIFEST).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(document, dict) or document.get("tool") != "copdea-fem" or \
            not isinstance(document.get("command"), str) or \
            not isinstance(document.get("files"), list) or \
            not all(isinstance(name, str) and name for name in document["files"]):
        return None
    return document


def write_manifest(folder: Path, command: str, files=None) -> None:
    """Mark ``folder`` as a result of ``command``; ``files``: its relative paths (default: all)."""
    from importlib import metadata
    folder = Path(folder)
    if files is None:
        files = sorted(str(path.relative_to(folder)) for path in folder.rglob("*")
                       if path.is_file() and path.name != MANIFEST)
    try:
        version = metadata.version("copdea-fem")
    except metadata.PackageNotFoundError:
        version = "unknown"
    document = {"tool": "copdea-fem", "version": version, "command": command,
                "written_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(
                    timespec="seconds"), "files": list(files)}
    temporary = folder / (MANIFEST + ".tmp")
    temporary.write_text(json.dumps(document, indent=1))
    temporary.replace(folder / MANIFEST)


def package_versions() -> dict[str, str]:
    """Python's and the packages' versions, the provenance every result carries beside its
    manifest (``study.resolved.yaml``, ``modes.json``, ``diagnosis.json``, a sweep's spec).

    A new dict each call; looked up once per process (the installed metadata are searched
    on ``sys.path``, which is slow).
    """
    global _VERSIONS
    if _VERSIONS is None:
        import platform
        from importlib import metadata
        versions = {"python": platform.python_version()}
        for package in ("copdea-fem", "ngsolve", "numpy", "scipy", "matplotlib", "pyvista",
                        "pint"):
            try:
                versions[package] = metadata.version(package)
            except metadata.PackageNotFoundError:
                versions[package] = "not installed"
        _VERSIONS = versions
    return dict(_VERSIONS)


_VERSIONS: dict[str, str] | None = None


def check_output(target, command: str, inputs=(), from_file=None) -> Path:
    """Refuse an output folder ``command`` may not write (module doc); return its absolute path.

    ``inputs``: the run's input files; ``from_file``: the input file the folder
    name came from (then it must stay inside the working folder).
    """
    target = Path(os.path.abspath(Path(target).expanduser()))
    resolved = target.resolve()
    here = Path.cwd().resolve()
    shown = str(target)
    if from_file is not None and not resolved.is_relative_to(here):
        raise OutputFolderError(
            f"output folder {shown} (from {from_file}) is outside the working folder {here}; "
            "a directory named in an input file must stay inside it: change output.directory "
            "or pass --out")
    if resolved == here or resolved in here.parents:
        raise OutputFolderError(f"output folder {shown} is the working folder or a parent of "
                                "it; choose a new subfolder, e.g. --out results/NAME")
    if resolved == Path.home().resolve():
        raise OutputFolderError(f"output folder {shown} is the home folder; choose a new "
                                "subfolder")
    for item in inputs:
        if item is None:
            continue
        source = Path(item).resolve()
        if resolved == source.parent or resolved in source.parents:
            raise OutputFolderError(f"output folder {shown} holds the input file {item}; "
                                    "choose another folder for the results")
    existing = next(path for path in (target, *target.parents) if path.exists())
    if existing != target and not existing.is_dir():
        raise OutputFolderError(f"output folder {shown} cannot be created: {existing} is a "
                                "file; choose another path")
    if target.exists() and not target.is_dir():
        raise OutputFolderError(f"output folder {shown} is an existing file, not a folder; "
                                "choose another path")
    if target.is_dir():
        _check_replaceable(target, command)
    return target


def _check_writable(target: Path) -> None:
    """Refuse a folder this process cannot write: a file is created in it and removed (the
    permission bits alone do not say it: root may write a read-only folder, unless run
    without that capability)."""
    try:
        probe = target / f".copdea-fem-probe-{uuid.uuid4().hex[:8]}"
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        os.unlink(probe)
    except OSError as error:
        raise OutputFolderError(f"output folder {target} cannot be written "
                                f"({error.strerror or error}); nothing was written: make it "
                                "writable or choose another folder") from None


def _check_replaceable(target: Path, command: str) -> None:
    try:
        entries = sorted(entry.name for entry in target.iterdir())
    except OSError as error:
        raise OutputFolderError(f"output folder {target} cannot be read: "
                                f"{error.strerror or error}") from None
    if not entries:
        return
    manifest = read_manifest(target)
    if manifest is None:
        listed = ", ".join(entries[:3]) + (", ..." if len(entries) > 3 else "")
        raise OutputFolderError(
            f"output folder {target} is not empty and not a copdea-fem result (it holds "
            f"{listed}); nothing was written: choose a new or empty folder")
    if manifest["command"] != command:
        raise OutputFolderError(
            f"output folder {target} holds a {manifest['command']} result, which a {command} "
            "run would replace; nothing was written: choose another folder (--out)")
    owned = {Path(name).parts[0] for name in manifest["files"]} | {MANIFEST}
    foreign = [name for name in entries if name not in owned]
    if foreign:
        listed = ", ".join(foreign[:3]) + (", ..." if len(foreign) > 3 else "")
        raise OutputFolderError(
            f"output folder {target} holds files its copdea-fem result did not write "
            f"({listed}); nothing was written: move them out or choose another folder")


@contextlib.contextmanager
def claim(target, command: str, inputs=(), from_file=None):
    """Check ``target`` (:func:`check_output`), lock it for the block and clean leftovers.

    Yields a :class:`Claim`.  Re-entrant within one thread only (a writer below the
    command's claim, :func:`result_directory`): a claim of a held folder from another
    thread or process is refused.  Writers take the held :class:`Claim` itself where they
    can (:func:`held`).
    """
    target = check_output(target, command, inputs, from_file)
    held_here = _THREAD.__dict__.setdefault("claims", {})
    if target in held_here:
        yield held_here[target]
        return
    with contextlib.ExitStack() as lock:
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            lock.enter_context(exclusive_lock(_lock_path(target)))
        except LockHeld as held_by:
            raise OutputFolderError(
                f"output folder {target} is being written by another copdea-fem run (process "
                f"{held_by.holder}); wait for it to finish or choose another folder") from None
        except OSError as error:
            raise OutputFolderError(f"output folder {target} cannot be written: "
                                    f"{error.strerror or error}") from None
        try:
            _clean_leftovers(target)
            check_output(target, command, inputs, from_file)   # again, now that it is ours
            if target.is_dir():             # probed only while held: no other run swaps it
                _check_writable(target)
            record = Claim(target, command, had_result=read_manifest(target) is not None)
            held_here[target] = record
            yield record
        finally:
            held_here.pop(target, None)


@contextlib.contextmanager
def held(folder, command: str, inputs=()):
    """The :class:`Claim` of ``folder`` for a writer: ``folder`` itself when it is a claim
    already held (the CLI claims once, before any work), else a new :func:`claim` of it."""
    if isinstance(folder, Claim):
        if folder.command != command:
            raise ValueError(f"a claim for {folder.command} cannot hold a {command} result")
        yield folder
        return
    with claim(folder, command, inputs=inputs) as record:
        yield record


def _lock_path(target: Path) -> Path:
    return target.parent / f".{target.name}.copdea-fem-lock"


#: Seconds between two tries of a lock another process holds (:func:`exclusive_lock`).
LOCK_POLL_SECONDS = 0.2


class LockHeld(Exception):
    """The lock file ``path`` is held by another process; ``holder``: its process id as
    the holder wrote it in the file (``"unknown"`` when it is not there yet)."""

    def __init__(self, path: Path, holder: str):
        super().__init__(f"{path} is held by process {holder}")
        self.path, self.holder = path, holder


@contextlib.contextmanager
def exclusive_lock(path, wait: float = 0.0, waiting=None):
    """Hold an exclusive ``flock`` of the lock file ``path`` for the block (module notes).

    Parameters
    ----------
    path : path
        The lock file: created, the holder's process id written in it, removed after the
        block.
    wait : float
        Longest wait [s] for another holder, trying every :data:`LOCK_POLL_SECONDS`; 0:
        refused at once.
    waiting : callable, optional
        Called once with the holder's process id when the lock is busy and this call
        waits for it.

    Raises
    ------
    LockHeld
        Another process still holds the lock after ``wait`` seconds.
    OSError
        The lock file cannot be created (a read-only or missing folder).

    Where ``fcntl`` is missing (Windows) the block runs without a lock.
    """
    if fcntl is None:
        yield
        return
    path = Path(path)
    fd = _acquire(path, wait, waiting)
    try:
        yield
    finally:
        with contextlib.suppress(OSError):
            if os.stat(path).st_ino == os.fstat(fd).st_ino:
                os.unlink(path)
        os.close(fd)


def _acquire(path: Path, wait: float, waiting) -> int:
    """The descriptor of the locked file still in place at ``path`` (:func:`exclusive_lock`)."""
    deadline = time.monotonic() + wait
    told = False
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.read(fd, 64).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            if time.monotonic() >= deadline:
                raise LockHeld(path, holder) from None
            if waiting is not None and not told:
                waiting(holder)
                told = True
            time.sleep(LOCK_POLL_SECONDS)
            continue
        # the previous holder removes the file when done: lock only the file still in place
        with contextlib.suppress(FileNotFoundError):
            if os.stat(path).st_ino == os.fstat(fd).st_ino:
                os.ftruncate(fd, 0)
                os.write(fd, f"{os.getpid()}\n".encode())
                return fd
        os.close(fd)


def _clean_leftovers(target: Path) -> None:
    """Staging folders and old copies a killed run left beside ``target`` (module doc)."""
    say = logger.info

    def ours(kind):
        """Folders named exactly as result_directory names them (8 hex digits); an old copy
        must also carry its manifest: a user's look-alike folder is never touched."""
        pattern = re.compile(rf"\.{re.escape(target.name)}\.{kind}-[0-9a-f]{{8}}")
        return [path for path in sorted(target.parent.glob(f".{target.name}.{kind}-*"))
                if path.is_dir() and pattern.fullmatch(path.name)
                and (kind == "staging" or read_manifest(path) is not None)]

    for path in ours("old"):
        if target.exists():
            try:
                _remove_result(path)
            except OSError as error:
                logger.warning(f"{path} (a replaced result an earlier run left) could not be "
                               f"removed ({error.strerror or error}); delete it by hand")
            else:
                say(f"removed {path.name}, a replaced result an interrupted run left")
        else:
            path.rename(target)
            say(f"restored the previous result {target} (an interrupted run had moved it)")
    for path in ours("staging"):
        shutil.rmtree(path, ignore_errors=True)
        if path.exists():
            logger.warning(f"{path} (an unfinished result an earlier run left) could not be "
                           "removed; delete it by hand")
        else:
            say(f"removed {path.name}, an unfinished result an interrupted run left")


SWAP_SIGNALS = ("SIGINT", "SIGTERM")


@contextlib.contextmanager
def _signals_deferred():
    """SIGINT and SIGTERM that arrive in the block are acted on after it (the swap).

    In the main thread the Python handlers are replaced by ones that note the
    signal; the first noted one is handed to the previous handler after the block
    (Ctrl-C's KeyboardInterrupt, the CLI's SIGTERM handler).  A signal mask alone
    would not do: it is per thread, the kernel hands a process signal to a thread
    that does not block it, and Python then runs the handler in the main thread
    at its next instruction, inside the swap.  Python runs handlers in the main
    thread only, so a swap in another thread is never interrupted by them.
    """
    import threading
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    numbers = [getattr(signal, name) for name in SWAP_SIGNALS if hasattr(signal, name)
               and signal.getsignal(getattr(signal, name)) is not None]   # None: set in C
    noted = []
    previous = {number: signal.signal(number, lambda signum, frame: noted.append(signum))
                for number in numbers}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
        if noted:
            handler = previous[noted[0]]
            if callable(handler):
                handler(noted[0], None)
            elif handler == signal.SIG_DFL:
                signal.raise_signal(noted[0])


def _remove_result(folder: Path) -> None:
    """Delete a result folder, its manifest last (module doc)."""
    for entry in sorted(folder.iterdir(), key=lambda path: path.name == MANIFEST):
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry)
        else:
            os.unlink(entry)
    os.rmdir(folder)


def _swap(staging: Path, target: Path, record: Claim) -> None:
    """Move the complete result ``staging`` to ``target``, the previous one aside and away
    (module doc); signals are deferred by the caller."""
    if not target.exists():
        os.rename(staging, target)
        record.written = True
        return
    old = target.parent / f".{target.name}.old-{uuid.uuid4().hex[:8]}"
    os.rename(target, old)
    try:
        os.rename(staging, target)
    except BaseException:
        try:
            os.rename(old, target)             # the previous result back in place
        except BaseException:
            record.old_copy = old              # the next run into target puts it back
        raise
    record.written = True
    try:
        _remove_result(old)
    except BaseException as error:        # the message after an interrupt names it
        record.old_copy = old if old.exists() else None
        if not isinstance(error, OSError):
            raise
        if record.old_copy is not None:
            logger.warning(f"the previous result {old} was not removed "
                           f"({error.strerror or error}); the next run into {target} tries "
                           "again (or delete it)")


@contextlib.contextmanager
def result_directory(target, command: str):
    """Yield an empty staging folder; on success it replaces ``target`` atomically.

    ``target``: a path, checked and locked (:func:`claim`), or a held :class:`Claim`; on any
    exception, KeyboardInterrupt included, the staging folder is removed and ``target``
    holds the previous result (or nothing, or the new result when the exception
    came after the swap; :meth:`Claim.whereabouts` says which).  An OSError while
    writing or swapping becomes :class:`ResultWriteError`, saying where the result is.
    """
    with held(target, command) as record:
        target = record.target
        staging = target.parent / f".{target.name}.staging-{uuid.uuid4().hex[:8]}"
        staging.mkdir()
        try:
            yield staging
            write_manifest(staging, command)
            _test_write_delay()
            with _signals_deferred():
                _swap(staging, target, record)
        except OSError as error:
            shutil.rmtree(staging, ignore_errors=True)
            raise ResultWriteError(f"output folder {target}: the result could not be written "
                                   f"({error.strerror or error}); "
                                   f"{record.whereabouts()}") from None
        except BaseException:
            shutil.rmtree(staging, ignore_errors=True)
            raise
