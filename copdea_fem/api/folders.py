"""The result folders of the API's ``write``: a folder claimed for a command, the folder a
function that is given ``out`` claims before its work (:class:`Output`, :func:`claiming`),
and the folder a sweep runs in (the one asked for, or a private temporary one that ``write``
copies).
"""

from __future__ import annotations

import contextlib
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from copdea_fem.folders import Claim


class Output:
    """Where a function's result goes when the function writes it itself (its ``out``), as
    the command line asks for it: ``folder`` (``--out``), or None for the command's default
    folder (the study's ``output.directory``, ``results/<command>_<name>``), named in an input
    file and so kept inside the working folder (:func:`copdea_fem.folders.check_output`).

    The function claims the folder after its inputs are checked and before any work, and
    keeps what it claimed here: :attr:`path`, the folder as named (for messages), and
    :attr:`claim`, the held :class:`~copdea_fem.folders.Claim` (after an interruption it
    says where the result is).

    Parameters
    ----------
    folder : str or Path, optional
        The folder asked for; None: the command's default.
    """

    def __init__(self, folder: str | Path | None = None) -> None:
        self.folder = None if folder is None else Path(folder)
        self.path: Path | None = None
        self.claim: Claim | None = None


@contextlib.contextmanager
def claiming(out: str | Path | Claim | Output | None, command: str, inputs, default=None):
    """The held :class:`Claim` of ``out`` for ``command`` while inside; None (nothing claimed)
    when ``out`` is None.

    Parameters
    ----------
    out : str, Path, Claim, Output or None
        A folder (claimed here), a :class:`Claim` the caller holds (as it is), an
        :class:`Output` (its folder, else ``default`` kept inside the working folder, claimed
        here and recorded on it), or None.
    command : str
        The command whose result the folder receives.
    inputs : list
        The run's input files (a folder holding one is refused); None entries are skipped.
        The first names the default folder of an :class:`Output`.
    default : str or Path, optional
        The command's default folder (an :class:`Output` without a folder).
    """
    if out is None:
        yield None
        return
    inputs = [item for item in inputs if item]
    if not isinstance(out, Output):
        from copdea_fem.folders import held
        with held(out, command, inputs=inputs) as record:
            yield record
        return
    from copdea_fem.folders import claim
    folder = out.folder if out.folder is not None else Path(default)
    from_file = None if out.folder is not None or not inputs else inputs[0]
    with claim(folder, command, inputs=inputs, from_file=from_file) as record:
        out.path, out.claim = folder, record
        yield record


@contextlib.contextmanager
def claimed(folder: str | Path | Claim, command: str, inputs) -> Path:
    """The target of ``folder``, claimed for ``command`` (a held :class:`Claim`: as it is)."""
    from copdea_fem.folders import held
    with held(folder, command, inputs=inputs) as record:
        yield record.target


@dataclass
class RunFolder:
    """A command's result folder: the one asked for, or a private temporary one."""

    path: Path
    temporary: Any = None

    def copy_to(self, folder, command: str, inputs) -> Path:
        """The result copied into ``folder`` claimed for ``command`` (nothing to copy when it
        is the folder the command ran in)."""
        from copdea_fem.folders import result_directory
        with claimed(folder, command, inputs) as target:
            if target.resolve() == self.path.resolve():
                return target
            with result_directory(target, command) as staging:
                for item in self.path.iterdir():
                    if item.name.startswith(".copdea-fem"):
                        continue
                    if item.is_dir():
                        shutil.copytree(item, staging / item.name)
                    else:
                        shutil.copy2(item, staging / item.name)
        return target


def run_folder(command: str, out) -> RunFolder:
    """Where ``command`` runs: ``out`` (a path, or the target of a held :class:`Claim`) or,
    without it, a private temporary folder removed with the :class:`RunFolder`."""
    if isinstance(out, Claim):
        return RunFolder(out.target)
    if out is not None:
        return RunFolder(Path(out))
    temporary = tempfile.TemporaryDirectory(prefix=f"copdea-fem-{command}-")
    return RunFolder(Path(temporary.name) / "result", temporary)
