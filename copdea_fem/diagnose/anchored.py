"""The FE as the model of record, the ring model as its anchored surrogate (issue 13).

A diagnosis evaluates thousands of effect states per condition; the FE takes
0.5-2 s (axisymmetric engine) to ~10-30 s (3-D quadrant, square frame) per solve,
the ring model milliseconds.  So the FE fixes the numbers and the ring model
interpolates between FE solves:

    f(state) = f_ring(state) * f_FE(anchor) / f_ring(anchor)            (A1)

per mode label, where ``anchor`` is the state's *anchor state*: its effects
that the FE represents (:data:`FE_ROLES`) -- the ones the ring model cannot
(air on: the real coupled added mass, square frame) whenever they are in the
state; the ones it moves well (Maxwell and stiffness scale, disc on its
spring) once accepted, at the accepted values (:meth:`AnchoredEngine.set_anchor`,
called by the search at every accepted step: a candidate costs no FE solve
unless it needs the FE, and one that does is solved with the earlier fits'
FE parameters at the base values, so those solves are shared by every step
and every data set of the same conditions); ring-only effects (air-mass
scale, visco-elasticity, spring mass, damping) off -- also where the base
study has them on (:func:`ring_only_off`), so that they act through the ring
model's ratio and are not cancelled by the anchor.  At the anchor (A1) is the FE exactly, so the ring model's
discretisation error (a 6-ring (0,2) 4-5 % too stiff) never reads as physics
and an effect that only the FE has (the frame; the real coupled added mass
in place of the baffled estimate) acts through f_FE(anchor).

Modes the ring model lacks -- non-axisymmetric (m,n) and (0,n) past its
truncation -- take the FE's frequency times the relative change of the ring
mode nearest in frequency at the anchor (its *proxy*); ring modes the FE
lacks (P2, P3 of the spring's mass; modes past the FE's band) take the ratio
of P1, or of the highest axisymmetric mode that has one.  Non-axisymmetric
modes are *optional* (excited only by imperfections: pairable, but their
absence costs nothing).  Quality factors are the ring model's (modal damping);
the proxy's for the modes it lacks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from copdea_fem.diagnose.effects import CATALOGUE
from copdea_fem.diagnose.engine import Engine, ModelMode
from copdea_fem.diagnose.fe import BAND_MARGIN, FEModel
from copdea_fem.reduced.rings import ReducedModelError

# How the FE represents each effect: "switch" (the ring model cannot: on in the FE whenever
# on in the state; its parameters, if any, act on the ring surrogate only), "anchored" (the
# ring model moves it well: in the FE from the step that accepts it, at the accepted
# values), or absent (ring only).
FE_ROLES = {"air_loading": "switch", "frame_reflection": "switch", "baffle": "switch",
            "open_air": "switch",
            "disc_pumping": "anchored",
            "electrostatic_softening": "anchored", "uniform_stiffness": "anchored"}
# Parameter values of a switch in the anchor state (the ring side of the ratio).
SWITCH_VALUES = {"air_loading": (1.0,)}


def ring_only_off(study):
    """``study`` with the physics only the ring model has switched off (the FE's side of
    (A1)): effects without an FE role, and the air-mass scale at 1."""
    overrides = {}
    for effect_id, entry in CATALOGUE.items():
        if effect_id not in FE_ROLES and entry.is_on(study):
            overrides.update(entry.off(study))
    if study["effects"]["air_mass_scale"] != 1.0:
        overrides["effects.air_mass_scale"] = 1.0
    return study.replace(overrides) if overrides else study


class FEFailure(ReducedModelError):
    """The FE cannot be solved at an effect state (the state is not evaluable)."""


@dataclass(frozen=True)
class Anchor:
    """FE and ring modes of one condition at one anchor state, and (A1)'s ratios."""

    fe: object                    # FEResult
    ring: tuple                   # ring ModelModes at the anchor
    ratio: dict                   # label -> f_FE / f_ring at the anchor
    proxies: tuple = field(init=False, default=())   # (FE mode, its ring proxy), derived

    def __post_init__(self):
        # the proxy of every FE mode the ring model lacks: the ring mode nearest in
        # frequency at the anchor (fixed per anchor; apply() runs in the fits' hot loop)
        ring_labels = {m.label for m in self.ring}
        membrane = [m for m in self.ring if m.kind != "pumping"]
        proxies = []
        for fe_mode in self.fe.modes:
            if fe_mode.label in ring_labels or fe_mode.kind == "pumping" or not membrane:
                continue
            proxy = min(membrane, key=lambda m: abs(math.log(m.frequency_hz
                                                             / fe_mode.frequency_hz)))
            proxies.append((fe_mode, proxy))
        object.__setattr__(self, "proxies", tuple(proxies))

    def apply(self, modes) -> tuple:
        """(A1) on the ring modes of a state, plus the FE modes the ring model lacks."""
        now = {m.label: m for m in modes}
        out = []
        for mode in modes:
            ratio = self.ratio.get(mode.label)
            if ratio is None:
                ratio = self._fallback(mode)
            out.append(replace(mode, frequency_hz=mode.frequency_hz * ratio))
        for fe_mode, proxy in self.proxies:
            if fe_mode.label in now:
                continue
            current = now.get(proxy.label)
            change = current.frequency_hz / proxy.frequency_hz if current is not None else 1.0
            quality = current.quality_factor if current is not None else math.inf
            optional = fe_mode.kind == "non-axisymmetric"
            out.append(ModelMode(fe_mode.label, fe_mode.kind, fe_mode.frequency_hz * change,
                                 quality, math.nan, expected=True, optional=optional))
        return tuple(sorted(out, key=lambda m: m.frequency_hz))

    def _fallback(self, mode) -> float:
        if mode.kind == "pumping" and "P1" in self.ratio:
            return self.ratio["P1"]
        axisymmetric = [m for m in self.ring if m.label in self.ratio and m.kind != "pumping"]
        if axisymmetric:
            return self.ratio[max(axisymmetric, key=lambda m: m.frequency_hz).label]
        return 1.0


class AnchoredEngine(Engine):
    """:class:`Engine` whose predictions are the FE's, interpolated by the ring model (A1).

    Parameters
    ----------
    measured : MeasuredSet
    fe : FEModel, optional
    """

    def __init__(self, measured, fe: FEModel | None = None, cache_size: int = 4096):
        super().__init__(measured, cache_size)
        self.fe = fe or FEModel()
        self.anchored: dict = {}
        self._anchors: dict = {}

    def set_anchor(self, state) -> None:
        """Solve the FE with the FE effects of ``state`` (at its values) from now on."""
        self.anchored = {e: tuple(v) for e, v in state if e in FE_ROLES}

    def anchor_state(self, state) -> tuple:
        """The anchor state of ``state`` (module notes).

        A state with a switch not yet accepted (a candidate that needs the FE) is
        anchored with the accepted "anchored" effects left at the base study's values:
        its FE solves then do not depend on earlier fits, and are reused across steps.
        """
        testing = any(FE_ROLES.get(e) == "switch" and e not in self.anchored for e, _ in state)
        out = []
        for effect_id, values in state:
            role = FE_ROLES.get(effect_id)
            if role == "switch":
                out.append((effect_id, SWITCH_VALUES.get(effect_id, tuple(values))))
            elif role == "anchored" and effect_id in self.anchored and not testing:
                out.append((effect_id, self.anchored[effect_id]))
        return tuple(out)

    def prefetch(self, pairs) -> None:
        """The FE solves of the anchors of ``(condition, state)`` pairs not yet anchored,
        side by side (:meth:`FEModel.solve_many`); :meth:`anchor` then finds them."""
        requests, seen = [], set()
        for condition, state in pairs:
            anchor_state = self.anchor_state(state)
            key = (condition.name, anchor_state)
            if key in self._anchors or key in seen:
                continue
            seen.add(key)
            try:
                study = self.study(condition, anchor_state)
            except (ReducedModelError, ValueError):    # predict() reports it (safe_predict)
                continue
            requests.append((study, BAND_MARGIN * condition.band[1]))
        self.fe.solve_many(requests)

    def anchor(self, condition, state=()) -> Anchor:
        """The FE and the ring model at the anchor of ``state`` (cached)."""
        anchor_state = self.anchor_state(state)
        key = (condition.name, anchor_state)
        hit = self._anchors.get(key)
        if hit is not None:
            return hit
        study = self.study(condition, anchor_state)
        try:
            result = self.fe.modes(study, f_max=BAND_MARGIN * condition.band[1])
        except (RuntimeError, ValueError) as error:
            raise FEFailure(f"the FE cannot be solved at {condition.name} with "
                            f"{[e for e, _ in anchor_state] or 'the base model'}: "
                            f"{error}") from error
        ring = self.ring_predict_study(ring_only_off(study), condition).modes
        fe = result.frequencies()
        ratio = {m.label: fe[m.label] / m.frequency_hz for m in ring if m.label in fe}
        hit = self._anchors[key] = Anchor(result, ring, ratio)
        return hit

    def predict(self, condition, state=(), perturbation=None):
        prediction = self.ring_predict(condition, state, perturbation)
        anchor = self.anchor(condition, state)
        return replace(prediction, modes=anchor.apply(prediction.modes))
