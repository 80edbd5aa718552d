"""The diagnosis's FE solves on a local Dask cluster (``diagnose --executor dask``): the same
modes and the same diagnosis as the local executor, the cache shared by the workers.

Skipped where dask.distributed is not installed (a test dependency).
"""

from __future__ import annotations

import json
import multiprocessing
import shutil
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")

sys.path.insert(0, str(Path(__file__).resolve().parent))

import fe_battery as battery

from copdea_fem.diagnosis.fe import FEModel
from copdea_fem.study import parse_study


def no_children_left(before=(), seconds: float = 10.0) -> bool:
    """Whether this process's child processes, but those in ``before``, are all gone within
    ``seconds`` (a local cluster's workers end a moment after it is closed)."""
    end = time.monotonic() + seconds
    while set(multiprocessing.active_children()) - set(before) and time.monotonic() < end:
        time.sleep(0.1)
    return not set(multiprocessing.active_children()) - set(before)


def test_a_batch_of_fe_solves_on_a_local_cluster_gives_the_local_modes(tmp_path):
    """FEModel.solve_many on a local cluster of two processes: the modes of one solve at a
    time in this process, each cache entry written once by the workers (the per-entry
    lock), the cluster closed by close()."""
    before = multiprocessing.active_children()

    study = parse_study(battery.DRY, name="flat").replace(
        {"load.z": 0.0, "load.voltage": 0.0, "eigen.f_max": 600.0, "mesh.membrane_size": 0.004})
    studies = [study.replace({"effects.stiffness_scale": s}) for s in (0.9, 1.1)]
    requests = [(s, None) for s in studies] * 2                      # duplicates solved once
    cluster = FEModel(cache_dir=tmp_path, workers=2, executor="dask")
    try:
        assert cluster.solve_many(requests) == 2 and cluster.solves == 2
    finally:
        cluster.close()
    assert no_children_left(before)
    assert len(list(tmp_path.glob("*.json"))) == 2 and not list(tmp_path.glob("*.lock"))
    serial = FEModel(cache_dir=False, workers=1)
    for s in studies:
        assert cluster.modes(s).modes == serial.modes(s).modes
    assert cluster.solves == 2                                       # memory hits
    again = FEModel(cache_dir=tmp_path, workers=2, executor="dask")
    assert again.solve_many(requests) == 0 and again._client is None  # no cluster started


def to_last_bits(tree, rel=1e-9):
    """``tree`` with every float compared to ``rel``: a solve on another CPU (its BLAS
    kernels) or in another process order may differ in the last bits, nothing more."""
    if isinstance(tree, dict):
        return {key: to_last_bits(value, rel) for key, value in tree.items()}
    if isinstance(tree, (list, tuple)):
        return type(tree)(to_last_bits(value, rel) for value in tree)
    if isinstance(tree, float):
        return pytest.approx(tree, rel=rel, abs=1e-300)
    return tree


def test_a_cold_diagnosis_on_a_local_cluster_is_the_local_one(tmp_path, monkeypatch, caplog):
    """The whole diagnosis (battery case ``air_hidden``, seed 1) with the committed cache
    read by the local executor, then again with the in-vacuo entries it read removed from a
    copy of that cache, so that a local cluster of two processes solves them: the same
    document (verdict, steps, gaps, every FE frequency), and the removed entries written
    back with the same modes."""
    before = multiprocessing.active_children()
    import copdea_fem as cf
    measured = battery.write_measured("air_hidden", 1, tmp_path / "measured")
    read: set = set()
    original_read = FEModel._read

    def recording(self, key, quiet=False):
        hit = original_read(self, key, quiet)
        if hit is not None:
            read.add(key)
        return hit

    monkeypatch.setattr(FEModel, "_read", recording)
    local = cf.diagnose(measured, fe_cache=battery.FE_CACHE, workers=1)
    monkeypatch.setattr(FEModel, "_read", original_read)
    cache = tmp_path / "cache"
    shutil.copytree(battery.FE_CACHE, cache)
    dry = sorted(key for key in read if '"coupled": false' in (cache / f"{key}.json").read_text())
    removed = {key: (cache / f"{key}.json").read_text() for key in dry[:2]}
    assert len(removed) == 2                    # a batch the cluster solves side by side
    for key in removed:
        (cache / f"{key}.json").unlink()
    with caplog.at_level("INFO", logger="copdea_fem"):
        remote = cf.diagnose(measured, fe_cache=cache, executor="dask", workers=2)
    assert no_children_left(before)
    assert remote.result.fe_solves == len(removed)
    assert f"FE: {len(removed)} solves on the Dask cluster ..." in caplog.messages
    for key, text in removed.items():      # same modes; the last bits follow the CPU's BLAS
        written, committed = (json.loads(t)["modes"] for t in
                              ((cache / f"{key}.json").read_text(), text))
        assert written == to_last_bits(committed)
    document, expected = remote.document, local.document
    document.pop("fe"), expected.pop("fe")     # how many solved here, in how long
    assert document == to_last_bits(expected)
