"""An accepted step must keep the shape pairing of the scans (diagnosis.scanned.ShapeCheck).

The correlations are made without the FE (the analytic membrane of
tests/analytic_membrane.py): the base model pairs every measured mode with its own
shape; a "model state" whose modes carry other shapes at the measured frequencies (labels
moved round) must be refused, naming the test modes whose pairing it breaks, and one that
keeps the shapes accepted.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

from copdea_fem.diagnosis.scanned import ScanPairing, ShapeCheck, step_mac_lines
from copdea_fem.vibrometer.pairing import FEShapes, correlate_shapes

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
import analytic_membrane as membrane


class _Measured:
    pairing = None
    conditions = ()


def _check(states: dict):
    positions = membrane.psv_grid()
    point, direction = membrane.channels(positions)
    model = membrane.model_modes(positions, point, direction)
    _, freq, shapes = membrane.measured_modes(np.random.default_rng(2), positions, point,
                                              direction)
    base = correlate_shapes(freq, shapes, model, condition="c")
    check = ShapeCheck(_Measured(), [ScanPairing("c", base, ())])
    correlations = {}
    for name, fe in states(model).items():
        correlations[name] = {"c": correlate_shapes(freq, shapes, fe, condition="c")}
    check.correlations = lambda state: correlations[state]
    return check, base


def _relabelled(model: FEShapes) -> FEShapes:
    """The (0,1) and (0,2) shapes swapped under their labels and frequencies."""
    labels = list(model.labels)
    shapes = model.shapes.copy()
    first, second = labels.index("(0,1)"), labels.index("(0,2)")
    shapes[:, [first, second]] = shapes[:, [second, first]]
    return dataclasses.replace(model, shapes=shapes)


def test_a_state_that_breaks_the_shape_pairing_is_refused():
    check, base = _check(lambda model: {"same": model, "moved": _relabelled(model)})
    assert check.refusal("same") is None
    reason = check.refusal("moved")
    assert reason is not None and reason.startswith("it breaks the shape pairing")
    first = next(p for p in base.pairs if p.label == "(0,1)")
    assert f"test mode {first.test_mode}" in reason and "(0,1) -> " in reason
    lines = step_mac_lines({"c": {p.test_mode: (p.label, p.mac) for p in base.pairs}},
                           check.macs("moved"))
    assert lines[0].startswith("Shape pairing of the scans") and len(lines) == 5 + len(
        base.pairs)
