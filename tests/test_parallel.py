"""One execution layer for the sweeps and the diagnosis's FE solves (copdea_fem.parallel):
the executors ``inline|processes|dask``, the old spellings that still work with a
deprecation warning (one line on the command line), the checks before any work."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from copdea_fem.parallel import (
    DIAGNOSIS_SPELLINGS,
    EXECUTORS,
    SWEEP_SPELLINGS,
    check_executor,
    executor_name,
)
from copdea_fem.study import StudyError

ROOT = Path(__file__).resolve().parent.parent
GRID = ROOT / "studies" / "sweeps" / "coarse_reduced_grid.yaml"


def test_the_executors_and_their_old_spellings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")                  # the new names warn of nothing
        assert [executor_name(name, SWEEP_SPELLINGS) for name in EXECUTORS] == list(EXECUTORS)
        assert executor_name(None, SWEEP_SPELLINGS) is None
        assert check_executor(None) == "inline"
        assert check_executor(None, default="processes") == "processes"
    with pytest.warns(FutureWarning, match="^--executor local is deprecated and will be "
                                           "removed in the next release; use --executor inline$"):
        assert executor_name("local", SWEEP_SPELLINGS) == "inline"
    with pytest.warns(FutureWarning, match="; use --executor processes$"):
        assert executor_name("pool", SWEEP_SPELLINGS) == "processes"
    with pytest.warns(FutureWarning, match="^--executor local is deprecated.*processes$"):
        assert executor_name("local", DIAGNOSIS_SPELLINGS) == "processes"   # it ran in workers
    with pytest.raises(StudyError, match="^--executor = 'pool' is not allowed; allowed: one of "
                                         "inline, processes, dask$"):
        executor_name("pool", DIAGNOSIS_SPELLINGS)
    with pytest.raises(StudyError, match="^--scheduler = 'tcp://h:1' is not allowed with "
                                         "--executor processes; allowed: a Dask scheduler"):
        check_executor("processes", "tcp://h:1")


def test_a_sweep_file_names_its_executor_old_or_new(tmp_path):
    from copdea_fem.sweeps import load_sweep
    text = GRID.read_text().replace("study: ../", f"study: {GRID.parent.parent}/")
    (tmp_path / "default.yaml").write_text(text)
    (tmp_path / "pool.yaml").write_text(text + "execution: {executor: pool, workers: 3}\n")
    default = load_sweep(tmp_path / "default.yaml")
    assert default.execution.executor is None                         # inline
    assert default.resolved()["execution"]["executor"] == "inline"
    with pytest.warns(FutureWarning, match="^execution.executor pool is deprecated.*"
                                           "use execution.executor processes$"):
        pool = load_sweep(tmp_path / "pool.yaml")
    assert pool.execution.executor == "processes" and pool.execution.workers == 3


def test_the_diagnosis_solves_inline_in_this_process():
    """``--executor inline``: no worker process; the batch is left to :meth:`FEModel.modes`,
    one solve at a time here."""
    from copdea_fem.diagnosis.fe import FEModel
    from copdea_fem.study import parse_study
    studies = [parse_study({"effects": {"stiffness_scale": s}}) for s in (0.9, 1.1)]
    model = FEModel(cache_dir=False, workers=2, executor="inline")
    assert model.executor == "inline"
    assert model.solve_many([(s, None) for s in studies]) == 0 and model.solves == 0
    with pytest.warns(FutureWarning, match="use --executor processes"):
        assert FEModel(cache_dir=False, executor="local").executor == "processes"


def test_a_sweep_runs_inline_through_the_cli(tmp_path, capsys):
    from copdea_fem.cli import main
    with warnings.catch_warnings():
        warnings.simplefilter("error", FutureWarning)
        assert main(["sweep", str(GRID), "--executor", "inline", "--quiet",
                     "--out", str(tmp_path / "s")]) == 0
    assert (tmp_path / "s" / "sweep.csv").is_file()


def test_a_deprecated_spelling_is_one_line_on_stderr(tmp_path):
    """The command line prints each deprecation as one line (its message), then goes on:
    here to the measured file, which does not exist (exit 2)."""
    run = subprocess.run([sys.executable, "-m", "copdea_fem.cli", "diagnose", "absent.yaml",
                          "--fe-workers", "1", "--executor", "local"], cwd=tmp_path,
                         env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 2, run.stderr
    lines = run.stderr.splitlines()
    assert lines[:2] == [
        "--fe-workers is deprecated and will be removed in the next release; use --workers",
        "--executor local is deprecated and will be removed in the next release; use "
        "--executor processes"]
    assert len(lines) == 3 and lines[2].startswith("error: ") and "absent.yaml" in lines[2]
    assert not list(tmp_path.iterdir())


def test_the_default_local_cluster_has_one_worker_per_core(monkeypatch):
    """``dask_client()`` without a count starts one worker process per core (the documented
    rule of :func:`copdea_fem.parallel.local_workers`), not one: the cluster class is
    replaced by one that records its arguments (no process started)."""
    pytest.importorskip("distributed")
    import distributed

    from copdea_fem import parallel
    started = {}

    class Recorded(Exception):
        pass

    def cluster(**settings):
        started.update(settings)
        raise Recorded

    monkeypatch.setattr(distributed, "LocalCluster", cluster)
    monkeypatch.setattr(os, "cpu_count", lambda: 4)
    with pytest.raises(Recorded), parallel.dask_client():
        pass
    assert started["n_workers"] == 4 and started["threads_per_worker"] == 1
    with pytest.raises(Recorded), parallel.dask_client(workers=2):
        pass
    assert started["n_workers"] == 2
