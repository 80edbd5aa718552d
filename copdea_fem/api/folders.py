"""The result folders of the API's ``write``: a folder claimed for a command, and the folder
a sweep runs in (the one asked for, or a private temporary one that ``write`` copies).
"""

from __future__ import annotations

import contextlib
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from copdea_fem.folders import Claim


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
