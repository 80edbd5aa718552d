"""Shared fixtures: coarse studies and cached meshes."""

import os

# One BLAS thread: ARPACK's many small dense operations run far slower with
# threads competing on a 2-core machine (measured: up to 100x on small calls).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import pytest  # noqa: E402

from copdea_fem.study import parse_study  # noqa: E402

# A coarse mesh keeps the suite fast; the verification tests that need the
# default mesh say so explicitly.
COARSE = {"mesh": {"membrane_size": "6 mm", "order": 2}}


def coarse_study(**sections):
    raw = {key: dict(value) for key, value in COARSE.items()}
    for section, values in sections.items():
        raw.setdefault(section, {}).update(values)
    return parse_study(raw, name="test")


@pytest.fixture
def make_study():
    return coarse_study
