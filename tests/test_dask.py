"""``--executor dask`` without a scheduler: a local Dask cluster for the sweeps and the
diagnosis's FE solves (copdea_fem.parallel).

A sweep runs on the local executor and on a local cluster of two worker processes started
by the code under test, and the tables are compared; the cluster is closed at the end, also
on Ctrl-C; the errors (a scheduler that does not answer or a malformed address, a scheduler
without ``--executor dask``) are one line and exit 2, for sweep and diagnose.  The
diagnosis's FE solves on a cluster: ``tests/diagnosis/test_diagnose_dask.py``.  Skipped where
dask.distributed is not installed (a test dependency).
"""

from __future__ import annotations

import multiprocessing
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from copdea_fem.cli import main
from copdea_fem.study import StudyError
from copdea_fem.sweeps import load_sweep, read_table, run_sweep

ROOT = Path(__file__).resolve().parent.parent
GRID = ROOT / "studies" / "sweeps" / "coarse_reduced_grid.yaml"
UNREACHABLE = "tcp://127.0.0.1:1"          # port 1: nothing listens there


def no_children_left(before=(), seconds: float = 10.0) -> bool:
    """Whether this process's child processes, but those in ``before``, are all gone within
    ``seconds`` (a local cluster's workers end a moment after it is closed)."""
    end = time.monotonic() + seconds
    while set(multiprocessing.active_children()) - set(before) and time.monotonic() < end:
        time.sleep(0.1)
    return not set(multiprocessing.active_children()) - set(before)


@pytest.fixture
def quick_timeout(monkeypatch):
    from copdea_fem import parallel
    monkeypatch.setattr(parallel, "SCHEDULER_TIMEOUT_SECONDS", 0.5)


def test_sweep_on_a_local_cluster_gives_the_table_of_the_inline_executor(tmp_path):
    """Two worker processes, two chains: every point's record and the tracked table as the
    local executor writes them (the ring model is deterministic: equal to the last digit)."""
    before = multiprocessing.active_children()
    sweep = load_sweep(GRID)
    sweep.plots = False
    local = run_sweep(sweep, out_dir=tmp_path / "local", executor="inline")
    remote = run_sweep(sweep, out_dir=tmp_path / "dask", executor="dask", workers=2)
    assert sorted(remote.computed) == sorted(local.computed) and not remote.failed
    assert read_table(tmp_path / "dask" / "sweep.csv") == \
        read_table(tmp_path / "local" / "sweep.csv")
    assert no_children_left(before)                     # the local cluster is closed


def test_an_interrupted_dask_sweep_closes_its_cluster_and_resumes(tmp_path):
    before = multiprocessing.active_children()
    sweep = load_sweep(GRID)
    sweep.plots = False

    def interrupt(result):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_sweep(sweep, out_dir=tmp_path / "s", executor="dask", workers=2,
                  on_point_done=interrupt)
    assert no_children_left(before)
    again = run_sweep(sweep, out_dir=tmp_path / "s", executor="dask", workers=2)
    assert again.resumed and len(again.resumed) + len(again.computed) == len(sweep.points)


def test_executor_and_scheduler_are_checked_before_any_work(quick_timeout, tmp_path, capsys):
    from copdea_fem.diagnosis.fe import FEModel
    with pytest.raises(StudyError, match="--executor = 'slurm' is not allowed; allowed: one "
                                         "of inline, processes, dask"):
        FEModel(cache_dir=False, executor="slurm")
    with pytest.raises(StudyError, match="not allowed with --executor local"):
        FEModel(cache_dir=False, scheduler=UNREACHABLE)
    # diagnose: refused before the measured file is read (it does not exist)
    assert main(["diagnose", "absent.yaml", "--scheduler", UNREACHABLE]) == 2
    assert capsys.readouterr().err.strip() == (
        f"error: --scheduler = '{UNREACHABLE}' is not allowed with --executor local; allowed: "
        "a Dask scheduler address with --executor dask only")
    # sweep: before the folder is claimed
    out = tmp_path / "out"
    assert main(["sweep", str(GRID), "--scheduler", UNREACHABLE, "--out", str(out)]) == 2
    assert "not allowed with --executor local" in capsys.readouterr().err
    for arguments in (["--scheduler", UNREACHABLE], ["--scheduler", "nowhere"]):
        assert main(["sweep", str(GRID), "--executor", "dask", *arguments,
                     "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith(f"error: --scheduler = '{arguments[1]}' is not allowed (")
        assert "allowed: the address of a running Dask scheduler" in err
        assert len(err.splitlines()) == 1 and not out.exists()


def test_diagnose_with_an_unreachable_scheduler_stops_with_one_line(quick_timeout, tmp_path,
                                                                   capsys):
    measured = ROOT / "studies" / "measured_drum_example" / "measured.yaml"
    code = main(["diagnose", str(measured), "--executor", "dask", "--scheduler", UNREACHABLE,
                 "--fe-cache", str(tmp_path / "cache"), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert err == (f"error: --scheduler = '{UNREACHABLE}' is not allowed (no Dask scheduler "
                   "answered there within 0.5 s); allowed: the address of a running "
                   "Dask scheduler, e.g. tcp://10.0.0.5:8786, or no --scheduler for a local "
                   "cluster")
    assert not (tmp_path / "cache").exists() and not (tmp_path / "out").exists()


@pytest.fixture
def not_dask_peers():
    """Two addresses that accept a connection but are not Dask: an HTTP server (as a
    dashboard given by mistake: it never answers Dask's handshake) and a peer that sends
    garbage (read by Dask as a frame of exabytes)."""
    import http.server
    import socket
    import threading
    class Quiet(http.server.BaseHTTPRequestHandler):
        def log_message(self, *args):              # the server's own log: not the CLI's
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Quiet)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen()

    def garbage():
        while True:
            try:
                connection, _ = listener.accept()
            except OSError:
                return
            connection.sendall(bytes(range(256)) * 4)

    threading.Thread(target=garbage, daemon=True).start()
    yield {"http": f"tcp://127.0.0.1:{server.server_address[1]}",
           "garbage": f"tcp://127.0.0.1:{listener.getsockname()[1]}"}
    server.shutdown()
    listener.close()


@pytest.mark.parametrize("peer", ["http", "garbage"])
def test_a_scheduler_address_that_is_not_dask_is_refused_before_any_work(
        quick_timeout, not_dask_peers, peer, tmp_path, capsys):
    """sweep: before the output folder is claimed; diagnose: before the measured file is
    read (it does not exist here, so a later check would name it)."""
    address = not_dask_peers[peer]
    out = tmp_path / "out"
    start = time.monotonic()
    for argv in (["sweep", str(GRID), "--out", str(out)], ["diagnose", "absent.yaml"]):
        assert main([*argv, "--executor", "dask", "--scheduler", address]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1, err
        assert err[0].startswith(f"error: --scheduler = '{address}' is not allowed (")
        assert "allowed: the address of a running Dask scheduler" in err[0]
        assert not out.exists()
    assert time.monotonic() - start < 60          # bounded: no hang (the limit is 0.5 s)
