"""Shared fixtures: coarse studies and cached meshes."""

import pytest

from copdea_fem.study import parse_study

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
