"""The FE evaluated directly, for devices the ring surrogate cannot represent.

The ring model of Sect. 3.2.1 needs the central disc (the membrane is an annulus
between r_i > 0 and r_o).  A membrane without one -- a drum head, a loudspeaker
membrane (``geometry.inner_radius: 0``) -- is still an ordinary FE study, and the
FE is the diagnosis's model of record anyway (:mod:`copdea_fem.diagnosis.fe`).  So
for such a base the prediction of an effect state is the FE's, solved at that
state (no anchor, no ratio (A1)): seconds a solve on the axisymmetric engine (dry
modes, frames none/baffle/circle), tens of seconds to minutes on the 3-D quadrant
(square frame).

What it can evaluate: the effects the FE represents (their ``direct`` field,
:data:`~copdea_fem.diagnosis.effects.DIRECT_EFFECTS`) --
the switches ``air_loading``, ``baffle``, ``frame_reflection``, ``open_air`` (geometry and
air keys), ``enclosure`` (its depth fitted on the grid below) and the parameters
``effects.stiffness_scale`` (uniform_stiffness: the membrane's tension) and
``effects.maxwell_scale`` (electrostatic_softening), and ``disc_pumping`` where
there is a disc.  The parameters the FE does not read
(``effects.air_mass_scale`` of air_loading: the FE has the real coupled air) are
held at their defaults (the catalogue's surrogate-only parameters,
:data:`~copdea_fem.diagnosis.effects.SURROGATE_ONLY_KEYS`), not fitted.  The effects only the
ring model has (visco-elasticity, the spring's mass, modal damping) are not
tested, and the report says why.

Cost.  A parameter is tabulated on :data:`DIRECT_GRID` FE solves per condition
(5 instead of the ring surrogate's 9: ln f is smooth in ln s, f ~ sqrt(s) for a
membrane under tension; enclosure's depth on 9, :data:`DIRECT_GRID_OF`), then
interpolated as with the ring surrogate (:mod:`copdea_fem.diagnosis.tabulation`);
every number reported of a fitted model is an FE solve at the fitted values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from copdea_fem.diagnosis.anchored import FEFailure, quality_factor
from copdea_fem.diagnosis.effects import DIRECT_EFFECTS
from copdea_fem.diagnosis.fe import BAND_MARGIN, FEModel
from copdea_fem.diagnosis.ring_predictor import ModelMode, RingPredictor
from copdea_fem.reduced.rings import ReducedModelError

DIRECT_GRID = 5            # FE solves per condition tabulating one parameter
# Parameters that need a finer grid: enclosure's depth spans a factor 40 (log), over which
# the (0,n) frequencies follow a sigmoid in ln L (the air spring B ~ 1/L switching on and
# saturating); on 5 points (a factor 2.5 apart) the spline put a drum head's fitted depth
# 20 % off the truth, on 9 (a factor 1.6) the interpolation error falls ~16-fold (h^4).
DIRECT_GRID_OF = {"geometry.enclosure_depth": 9}


def direct_grid(parameters) -> int:
    """FE solves per condition and parameter axis of a tabulation on the direct engine:
    :data:`DIRECT_GRID`, or the finer grid a parameter needs (:data:`DIRECT_GRID_OF`)."""
    return max([DIRECT_GRID_OF.get(p.key, DIRECT_GRID) for p in parameters] or [DIRECT_GRID])


def ring_can_represent(study) -> bool:
    """Whether the ring surrogate (Sect. 3.2.1) can model the base study's device."""
    return study.geometry.inner_radius > 0


@dataclass(frozen=True)
class DirectPrediction:
    """Modes of one condition under one effect state, straight from an FE solve."""

    modes: tuple
    study: object
    engine: str                   # the FE engine that solved it: "axisymmetric" or "3d"

    def mode(self, label):
        return next((m for m in self.modes if m.label == label), None)

    def spectra(self, frequency_hz=None, voltage_lines=None):
        """No spectrum: the FE's eigen step gives modes (None: the report leaves it out)."""
        return None


class DirectFEEngine(RingPredictor):
    """:class:`RingPredictor` whose every prediction is an FE solve (module notes).

    Parameters
    ----------
    measured : MeasuredSet
    fe : FEModel, optional
    """

    direct = True

    def __init__(self, measured, fe: FEModel | None = None, cache_size: int = 4096):
        super().__init__(measured, cache_size)
        self.fe = fe or FEModel()
        self.anchored: dict = {}
        self.engines: dict = {}      # effect state (ids) -> FE engines used, for the report

    def set_anchor(self, state) -> None:
        """Nothing to anchor: every prediction is the FE's (kept for the search's calls)."""
        self.anchored = {e: tuple(v) for e, v in state}

    def anchor(self, condition, state=()):   # marks an FE model of record (Scorer.uses_fe)
        return None

    def prefetch(self, pairs) -> None:
        """The FE solves of ``(condition, state)`` pairs, side by side
        (:meth:`FEModel.solve_many`); :meth:`predict` then finds them."""
        requests = []
        for condition, state in pairs:
            if any(e not in DIRECT_EFFECTS for e, _ in state):
                continue
            try:
                study = self.study(condition, state)
            except (ReducedModelError, ValueError):     # predict() reports it (safe_predict)
                continue
            requests.append((study, BAND_MARGIN * condition.band[1]))
        self.fe.solve_many(requests)

    def predict(self, condition, state=(), perturbation=None) -> DirectPrediction:
        if perturbation:
            raise FEFailure("perturbations (synthetic data) need the ring model")
        outside = [e for e, _ in state if e not in DIRECT_EFFECTS]
        if outside:
            raise FEFailure(f"{', '.join(outside)} cannot be evaluated without the ring "
                            "surrogate (the FE does not model it)")
        study = self.study(condition, state)
        try:
            result = self.fe.modes(study, f_max=BAND_MARGIN * condition.band[1])
        except (RuntimeError, ValueError) as error:
            raise FEFailure(f"the FE cannot be solved at {condition.name} with "
                            f"{[e for e, _ in state] or 'the base model'}: {error}") from error
        self.engines.setdefault(tuple(e for e, _ in state), set()).add(result.engine)
        modes = tuple(ModelMode(m.label, m.kind, m.frequency_hz,
                                quality_factor(m.damping_ratio), math.nan,
                                expected=m.kind != "pumping" or study.load.z > 0,
                                optional=m.kind == "non-axisymmetric")
                      for m in result.modes)
        return DirectPrediction(modes, study, result.engine)

    def ring_predict(self, condition, state=(), perturbation=None):
        """The direct engine has no ring model: the FE (the separation probes use it)."""
        return self.predict(condition, state, perturbation)
