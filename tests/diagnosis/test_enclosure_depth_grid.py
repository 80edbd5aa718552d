"""The enclosure effect's depth is searched on a logarithmic grid: its fit range spans a
factor 40 (0.05 .. 2 r_o), and the air spring goes as 1 / V, so equal steps in ln L put as
many grid points in the shallow, strongly stiffening decade as in the deep one (on a linear
grid most points would lie in the deep half).  Checked on the depths the tabulation asks
the engine for, not on the parameter's flag."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np


class RecordingEngine:
    """Records the depth ratio of every state it is asked for; predicts nothing."""

    def __init__(self):
        self.ratios = []

    def prefetch(self, items):
        for _, state in items:
            self.ratios.append(dict(state)["enclosure"][0])

    def predict(self, condition, state=(), perturbation=None):
        return None


def test_the_enclosure_depth_is_searched_on_a_logarithmic_grid():
    from copdea_fem.diagnosis.effects import CATALOGUE, ENCLOSURE_DEPTH_RATIO
    from copdea_fem.diagnosis.tabulation import Tabulation

    engine = RecordingEngine()
    scorer = SimpleNamespace(engine=engine, conditions=[SimpleNamespace(name="c")])
    Tabulation(scorer, (), ("enclosure",), list(CATALOGUE["enclosure"].parameters))
    ratios = np.array(engine.ratios)
    lower, upper = ENCLOSURE_DEPTH_RATIO
    assert ratios.size >= 5
    assert np.isclose(ratios[0], lower) and np.isclose(ratios[-1], upper)
    steps = ratios[1:] / ratios[:-1]
    # a geometric grid: one ratio (40 ** (1 / (n - 1))) between neighbours
    assert np.allclose(steps, (upper / lower) ** (1 / (ratios.size - 1))), steps
    # the geometric middle of the range is a grid point (a linear grid has 1.025 there)
    assert np.isclose(ratios[ratios.size // 2], np.sqrt(lower * upper))
