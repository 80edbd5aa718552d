"""A stale committed FE cache fails the tests that read it at once, with the refill command.

``tests/data/fe_cache`` is keyed by the FE code's fingerprint (``fe_battery.py``): after
a change to the FE code it holds no entry for the new keys, and a test reading it would
solve for many minutes.  Such tests (their source reads the battery or the committed
cache) fail at once instead, naming ``python tests/diagnosis/fe_battery.py --refill``;
with ``COPDEA_FEM_FE_REFILL=1`` they solve and write what they miss; with
``COPDEA_FEM_FE_STALE=skip`` they are skipped (``tools/mutation_check.py``: a mutated FE
has a fingerprint of its own, and the committed cache cannot judge it).
"""

from __future__ import annotations

import functools
import inspect
import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import fe_battery as battery  # noqa: E402

READS_COMMITTED_CACHE = ("battery.write_measured", "battery.FE_CACHE", "check_battery(",
                         "diagnose(\"", "diagnose(battery.", "diagnose(case,", '"fe_cache"')


@functools.lru_cache(maxsize=1)
def _missing() -> tuple:
    return tuple(battery.missing_entries())


@pytest.fixture(autouse=True)
def _committed_fe_cache_is_current(request):
    function = getattr(request.node, "function", None)
    if function is None or os.environ.get(battery.REFILL_VARIABLE) == "1":
        return
    source = inspect.getsource(function)
    if any(mark in source for mark in READS_COMMITTED_CACHE) and _missing():
        if os.environ.get("COPDEA_FEM_FE_STALE") == "skip":
            pytest.skip(battery.stale_message(list(_missing())))
        pytest.fail(battery.stale_message(list(_missing())), pytrace=False)
