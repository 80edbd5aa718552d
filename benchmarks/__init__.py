"""Benchmarks you can rerun: ``python -m benchmarks.<name>``; the targets and figures are in
docs/benchmarks.md."""

from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def run_cli(arguments: list[str], overrides: list[str] = ()) -> tuple[str, float, float]:
    """One fresh ``python -m copdea_fem.cli ARGUMENTS --set OVERRIDE ...`` from the checkout:
    ``(stdout + stderr, wall seconds, CPU seconds (user + system) of the child)``."""
    argv = [sys.executable, "-m", "copdea_fem.cli", *arguments]
    for item in overrides:
        argv += ["--set", item]
    environment = dict(os.environ, PYTHONPATH=str(ROOT))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    done = subprocess.run(argv, cwd=ROOT, env=environment, check=True, capture_output=True,
                          text=True)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return done.stdout + done.stderr, wall, cpu


def spread(values) -> dict:
    """``{"median", "min", "max"}`` of ``values``."""
    values = list(values)
    return {"median": statistics.median(values), "min": min(values), "max": max(values)}
