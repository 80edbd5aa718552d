"""Microphones inside the Kirchhoff sphere (copdea_fem.forced_response.microphone_places):
the FE's own pressure there, checked against what it did not make.

- **Continuity with the integral.**  Just inside the sphere the FE's field, just outside
  it the Kirchhoff-Helmholtz integral over the sphere: two codes sharing nothing but the
  pressure vectors must give nearly the same pressure at points 2 % of the radius apart.
- **A sealed cavity far below its own modes** holds a uniform pressure
  (``p = -rho c^2 dV / V``): the field at the centre and near the wall agree.
- Where no air is (an enclosure's wall, the membrane plane) a microphone is refused by
  name before any work.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from copdea_fem.fe import engine_for
from copdea_fem.fe.forced.radiation import KIRCHHOFF_FRACTION
from copdea_fem.forced_response.microphone_places import FAR, FIELD, microphone_places
from copdea_fem.forced_response.run import forced_response, parse_microphones, \
    prepare_order_zero
from copdea_fem.study import StudyError, load_study

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "studies" / "g1_z16_v2_quick.yaml"
CYLINDER = ROOT / "studies" / "g1_enclosure_cylinder.yaml"


def _pressures(path, overrides, lines):
    study = load_study(path, overrides)
    problem = prepare_order_zero(study, engine=engine_for(study))
    result = forced_response(problem, np.asarray(lines, float), np.ones(len(lines)))
    return study, result


def test_the_field_inside_the_sphere_meets_the_integral_outside_it():
    # an air mesh fine enough for the field itself (the quick study's 35.5 mm, order 1:
    # 10-14 %; 15 mm, order 2: 0.7-0.9 %; 10 mm, order 3: 0.5-0.9 %)
    fine = {"geometry.frame": "none", "mesh.air_size": "15 mm", "mesh.pressure_order": "2",
            "response.method": "direct"}
    radius = KIRCHHOFF_FRACTION * load_study(QUICK, fine).air.domain_radius
    text = (f"near = 0 m, {0.6 * 0.99 * radius} m, {0.8 * 0.99 * radius} m; "
            f"far = 0 m, {0.6 * 1.01 * radius} m, {0.8 * 1.01 * radius} m")
    study, result = _pressures(QUICK, {**fine, "response.microphones": text}, [150.0, 300.0])
    assert microphone_places(study, parse_microphones(study)) == [FAR, FIELD, FAR]
    near, far = result.pressure[:, 1], result.pressure[:, 2]
    assert np.all(np.abs(near - far) / np.abs(far) < 0.03), np.abs(near - far) / np.abs(far)


def test_a_sealed_cavity_far_below_its_modes_holds_one_pressure():
    text = "centre = 0 m, 0 m, -10 mm; side = 25 mm, 0 m, -5 mm"
    _, result = _pressures(CYLINDER, {"geometry.frame": "none", "response.microphones": text},
                           [100.0, 200.0])
    centre, side = result.pressure[:, 1], result.pressure[:, 2]
    assert np.all(np.abs(centre) > 1e-3), centre        # driven: ~0.01-0.1 Pa per volt
    assert np.all(np.abs(centre - side) / np.abs(centre) < 0.01)
    # the outside microphone (1 m on the axis) is far quieter than the trapped air
    assert np.all(np.abs(result.pressure[:, 0]) < 0.1 * np.abs(centre))


@pytest.mark.parametrize("position, fragment", [
    ("0 m, 0 m, -20 mm", "lies on the enclosure's rigid wall"),
    ("35.5 mm, 0 m, -10 mm", "lies on the enclosure's rigid wall"),
    ("10 mm, 0 m, 0 m", "lies on the plane z = 0 of the membrane, disc or frame"),
])
def test_a_microphone_where_no_air_is_is_refused_by_name(position, fragment):
    study = load_study(CYLINDER, {"geometry.frame": "none",
                                  "response.microphones": f"bad = {position}"})
    with pytest.raises(StudyError, match="response.microphones: microphone 'bad'") as error:
        microphone_places(study, parse_microphones(study))
    assert fragment in str(error.value)


def test_each_vectors_pressure_at_each_frequency_is_what_observe_gives_a_line():
    """Microphones.column_pressure (the modal model's kernels, modal_inputs eq. 3) against
    observe (response's lines): one line per (frequency, vector) pair, weight 1 on it."""
    from copdea_fem.forced_response.observers import LineResponse
    from copdea_fem.forced_response.run import microphone_observer

    text = "near = 0 m, 0 m, 30 mm; side = 0.3 m, 0 m, 0.5 m"
    study, result = _pressures(QUICK, {"geometry.frame": "none", "response.method": "modal",
                                       "response.microphones": text}, [150.0])
    microphones = parse_microphones(study)
    assert microphone_places(study, microphones) == [FAR, FIELD, FAR]
    forced, vectors = result.problem.forced, result.vectors[:, :4]
    observer = microphone_observer(study, result.problem.sector.sphere, forced.coupled,
                                   microphones)
    lines = np.array([120.0, 480.0, 910.0])
    columns = observer.column_pressure(LineResponse(forced, vectors, np.eye(1)), lines)
    pairs = [(f, k) for f in range(lines.size) for k in range(vectors.shape[1])]
    weights = np.zeros((len(pairs), vectors.shape[1]))
    weights[np.arange(len(pairs)), [k for _, k in pairs]] = 1.0
    each = observer.observe(LineResponse(forced, vectors, weights), lines[[f for f, _ in pairs]])
    expected = np.stack([each[i] for i in range(len(pairs))]).reshape(
        lines.size, vectors.shape[1], -1).transpose(0, 2, 1)
    assert np.abs(columns - expected).max() <= 1e-12 * np.abs(expected).max()
    assert np.abs(columns[:, 1] - columns[0, 1]).max() <= 1e-14 * np.abs(columns[:, 1]).max()
