"""The ring-model predictor: model modes and spectra of a condition under an effect state.

The reduced model (Sect. 3.2, Annex I) predicts: milliseconds per
condition.  An *effect state* is a tuple of ``(effect id, parameter values)``
switched on, in order, on top of the base study and the condition's
overrides (:meth:`RingPredictor.study`).  The result is an ordinary study that
:func:`copdea_fem.reduced.build_reduced` honours.

Speed.  Only the static solve and the dry modes are expensive; they
depend on the geometry, material, z, V_b, ``effects.stiffness_scale`` and
``effects.maxwell_scale`` and are cached in :mod:`copdea_fem.reduced.model`.
Everything else is applied here to a cached *reference* build (air-mass
factor 1, elastic, massless spring, b/m = 1) in closed form, exactly as
``build_reduced`` does it (a test checks the two agree):

- added mass of (0,n) times ``effects.air_mass_scale`` (eq. 19);
- visco-elastic stiffness ``k_j(w) = k_j + (g(w) - 1) k_el,j``;
- the membrane's Prony series ``membrane.prony`` is NOT modelled by the ring model: its
  ``k_el`` (all but the electrostatic term) is not the FE's material tangent, whose share
  of an out-of-plane mode's stiffness is small on the cone and zero on the flat membrane
  (docs/damping.md; G1, z = 16 mm, 2 kV, g = 2, tau = 0.3 ms: the FE raises (0,1) by
  1.2 %, the ring's k_el would by 56 %).  It is a cheap key only so that it never
  triggers a rebuild; the FE anchor applies it (:mod:`copdea_fem.diagnosis.anchored`);
- pumping modes: the P1 modal equation with the biasing spring's dynamic
  stiffness ``D(w) = k_d theta cot(theta)``, ``theta = w sqrt(M_s/k_d)``
  (Annex I, eq. 21) in place of k_d:

      R(w) = k_P1(w) - w^2 (m + m_ad) + a^2 (D(w) - k_d) = 0,           (E1)

  a = disc displacement per modal coordinate.  R falls strictly on each
  interval (j pi, (j+1) pi) of theta, so root j is P_{j+1}: P1 is the root
  ``build_reduced`` puts P1 at (``pumping_added_mass``), P2, P3 follow from
  the same equation (eq. 22 with the membrane's own mass).  The paper
  identified P1-P3 (Fig. 10); higher P_k sit next to the spring's
  fixed-fixed resonances where the disc hardly moves, and are not predicted;
- quality factors from the half-power width of a root of R(w) + i w b:
  ``Q = |dR/dw| / (2 b)`` (= w M / b for a mass-spring mode).

A mode is *expected* in a measurement when the chirp excites it: pumping
modes need z > 0 (dC/dz = 0 on the flat membrane); the membrane modes are
seen at every z (at z = 0 through inhomogeneities, Sect. 4.3).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
import scipy.optimize

from copdea_fem.diagnosis.effects import AIR_EFFECT, CATALOGUE
from copdea_fem.reduced.chirp_response import Chirp, SpectrumResult
from copdea_fem.reduced.model import build_reduced, damping_key, operating_point, ring_model_of
from copdea_fem.reduced.rings import ReducedModelError

# Keys applied in closed form on the cached reference build (module notes).
CHEAP_KEYS = ("effects.air_mass_scale", "effects.viscoelastic_strength",
              "effects.viscoelastic_time", "spring.mass", "reduced.damping_p1",
              "reduced.damping_01", "reduced.damping_02", "reduced.damping_higher",
              "reduced.modes", "reduced.pumping_added_mass", "membrane.prony")
REFERENCE_VALUES = {"effects.air_mass_scale": 1.0, "effects.viscoelastic_strength": 0.0,
                    "membrane.prony": [],
                    "spring.mass": 0.0, "reduced.damping_p1": 1.0, "reduced.damping_01": 1.0,
                    "reduced.damping_02": 1.0, "reduced.damping_higher": 1.0,
                    "reduced.pumping_added_mass": "spring"}
PUMPING_MODES = 3          # P1-P3, as identified in the paper (Fig. 10)


@dataclass(frozen=True)
class ModelMode:
    """One mode the model predicts for a condition.

    Attributes
    ----------
    label : str
        ``P1, P2, P3`` or ``(0,n)``.
    kind : str
        ``"pumping"`` or ``"axisymmetric"``.
    frequency_hz : float
        Undamped natural frequency in air [Hz] (eq. 19, E1).
    quality_factor : float
        Q [-]; inf for an undamped mode.
    radial_ratio : float
        Mean |u_r| over mean |u_z| at the scan points [-] (shape evidence
        for matching against an average spectrum's peak).
    expected : bool
        Whether the chirp excites it (module notes).
    optional : bool
        Excited only through imperfections (the FE's non-axisymmetric modes): it may
        explain a peak, its absence costs nothing.
    """

    label: str
    kind: str
    frequency_hz: float
    quality_factor: float
    radial_ratio: float
    expected: bool
    optional: bool = False


@dataclass
class _Reference:
    """Cached reference build of one condition (module notes)."""

    labels: tuple
    modal_mass: np.ndarray
    added_mass: np.ndarray        # at air_mass_scale 1 (P1: from coupled_freq_p1 or 0)
    stiffness: np.ndarray
    elastic_stiffness: np.ndarray
    force: np.ndarray             # modal force per volt [N/V]
    scan_axial: np.ndarray
    scan_radial: np.ndarray
    point_axial: np.ndarray
    point_radial: np.ndarray
    radial_ratio: np.ndarray
    disc_amplitude: float         # a of (E1), per unit modal coordinate [-]
    pumping_index: int | None
    z: float
    chirp: Chirp
    setup: object


@dataclass(frozen=True)
class Prediction:
    """Modes (and, on demand, spectra) of one condition under one effect state.

    ``structural_study`` is validated; the effect overrides of the cheap keys
    (:data:`CHEAP_KEYS`) are in ``overrides`` and :attr:`study` applies them.
    """

    modes: tuple
    structural_study: object
    reference: _Reference
    cheap: dict
    overrides: dict
    perturbation: dict | None = None

    @property
    def study(self):
        """The full, validated study of this prediction."""
        cheap = {k: v for k, v in self.overrides.items() if k in CHEAP_KEYS}
        return self.structural_study.replace(cheap) if cheap else self.structural_study

    def mode(self, label):
        return next((m for m in self.modes if m.label == label), None)

    def spectra(self, frequency_hz=None, voltage_lines=None) -> SpectrumResult:
        """Velocity spectra |FFT|/N [m/s] under the study's chirp (or given lines)."""
        if frequency_hz is None:
            frequency_hz, voltage_lines = self.reference.chirp.lines()
        return _spectra(self.reference, self.cheap, np.asarray(frequency_hz, float),
                        np.asarray(voltage_lines), self.perturbation)


def state_overrides(study, state) -> dict:
    """Overrides of an effect state ``((id, values), ...)`` on top of ``study``."""
    overrides = {}
    for effect_id, values in state:
        overrides.update(CATALOGUE[effect_id].on(study, values))
    return overrides


class RingPredictor:
    """Predictions for the conditions of a :class:`~copdea_fem.measured.MeasuredSet` by the
    ring model (the FE-anchored and direct-FE predictors of the diagnosis derive from it;
    not an FE engine, :class:`copdea_fem.fe.engines.Engine`).

    Parameters
    ----------
    measured : MeasuredSet
    cache_size : int
        Reference builds kept (one per condition and expensive-key combination).
    """

    def __init__(self, measured, cache_size: int = 4096):
        self.measured = measured
        self._cache: OrderedDict = OrderedDict()
        self._cache_size = cache_size
        self._conditions: dict = {}
        self.builds = 0

    def condition_study(self, condition):
        """Base study + the condition's overrides, resolved once (unit strings parsed once)."""
        key = (condition.name, tuple(sorted(map(str, condition.overrides.items()))))
        study = self._conditions.get(key)
        if study is None:
            study = self._conditions[key] = self.measured.study_of(condition)
        return study

    def study(self, condition, state=()):
        """Base study + condition overrides + the state's effect overrides (validated)."""
        base = self.condition_study(condition)
        return base.replace(state_overrides(base, state)) if state else base

    def _structural(self, condition, structural: dict):
        key = (condition.name, tuple(sorted(map(str, condition.overrides.items()))),
               tuple(sorted(structural.items(), key=lambda item: item[0])))
        study = self._conditions.get(key)
        if study is None:
            base = self.condition_study(condition)
            study = self._conditions[key] = base.replace(structural) if structural else base
            if len(self._conditions) > self._cache_size:
                self._conditions.pop(next(iter(self._conditions)))
        return study

    def predict(self, condition, state=(), perturbation=None) -> Prediction:
        """Model modes of a condition under an effect state.

        ``perturbation`` (synthetic data only): ``{label: factor}`` on the
        natural frequency of P1 and (0,n) (applied to their stiffness), and
        ``"spring"``: factor on the spring's wave speed (moves P2, P3),
        ``"force:<label>"``: factor on a mode's modal force (spectra only).

        Raises
        ------
        ReducedModelError, StudyError
            The state is outside what the model can do (e.g. loss of tension).
        """
        base = self.condition_study(condition)
        overrides = state_overrides(base, state)
        structural = {k: v for k, v in overrides.items() if k not in CHEAP_KEYS}
        study = self._structural(condition, structural)
        cheap = _cheap_values(study, {k: v for k, v in overrides.items() if k in CHEAP_KEYS})
        return self._predict(study, condition, cheap, overrides, perturbation)

    def prefetch(self, pairs) -> None:
        """Solve ahead, side by side, what :meth:`predict` of the ``(condition, state)``
        pairs will need (the FE engines); nothing for the ring model alone."""

    def ring_predict(self, condition, state=(), perturbation=None) -> Prediction:
        """The ring model alone (the same as :meth:`predict` here)."""
        return RingPredictor.predict(self, condition, state, perturbation)

    def ring_predict_study(self, study, condition, perturbation=None) -> Prediction:
        """The ring model alone for a full study."""
        return RingPredictor.predict_study(self, study, condition, perturbation)

    def predict_study(self, study, condition, perturbation=None) -> Prediction:
        """Prediction for a full study (already holding any effect keys)."""
        return self._predict(study, condition, _cheap_values(study), {}, perturbation)

    def _predict(self, study, condition, cheap, overrides, perturbation):
        reference = self._reference(study, condition)
        modes = _modes(reference, cheap, condition.band, perturbation)
        return Prediction(modes=modes, structural_study=study, reference=reference, cheap=cheap,
                          overrides=overrides, perturbation=perturbation)

    # -- reference builds --------------------------------------------------------------------
    def _reference(self, study, condition) -> _Reference:
        air_on = AIR_EFFECT.is_on(study)
        fe = condition.fe_frequencies if (air_on and condition.fe_frequencies) else None
        key = (condition.name, _frozen(study, exclude=CHEAP_KEYS), condition.band,
               tuple(sorted((fe or {}).items())))
        hit = self._cache.get(key)
        if hit is not None:
            self._cache.move_to_end(key)
            return hit
        reference = self._build(study, condition, fe)
        self._cache[key] = reference
        if len(self._cache) > self._cache_size:
            self._cache.popitem(last=False)
        return reference

    def _build(self, study, condition, fe) -> _Reference:
        self.builds += 1
        if (study.air.enabled and study.effects.air_added_mass == "none"
                and not fe and not study.reduced.modes_json):
            # a base written with air: the ring model carries the air's estimate (eq. 19)
            study = study.replace({"effects.air_added_mass": "incompressible"})
        ring_model = ring_model_of(study)
        load = study.load
        _, basis, elastic = operating_point(ring_model, load.z, load.voltage,
                                            study.effects.maxwell_scale)
        limit = 2.0 * condition.band[1]
        membrane = [m.label for m in basis.modes if m.kind == "out-of-plane"]
        kept = [label for label in membrane if basis[label].frequency_hz <= limit]
        kept = membrane[:max(2, len(kept))][:study.reduced.rings - 1]
        labels = (["P1"] if study.disc.motion == "spring" else []) + kept
        reference = study.replace({**REFERENCE_VALUES, "reduced.modes": ", ".join(labels)})
        setup = build_reduced(reference, fe)
        reduced = setup.reduced
        modes = setup.basis.truncate(reduced.labels)
        shapes = np.stack([m.shape / m.largest_displacement for m in modes], axis=1)
        pumping = reduced.labels.index("P1") if "P1" in reduced.labels else None
        disc = (modes[pumping].axial[-1] / modes[pumping].largest_displacement
                if pumping is not None else 0.0)
        axial_mean = np.mean(np.abs(reduced.scan_axial), axis=0)
        radial_mean = np.mean(np.abs(reduced.scan_radial), axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(axial_mean > 0, radial_mean / axial_mean, np.nan)
        return _Reference(
            labels=reduced.labels, modal_mass=reduced.modal_mass.copy(),
            added_mass=reduced.added_mass.copy(), stiffness=reduced.modal_stiffness.copy(),
            elastic_stiffness=np.einsum("ij,ik,kj->j", shapes, elastic, shapes),
            force=reduced.modal_force_per_volt.copy(), scan_axial=reduced.scan_axial,
            scan_radial=reduced.scan_radial, point_axial=reduced.point_axial,
            point_radial=reduced.point_radial, radial_ratio=ratio,
            disc_amplitude=float(disc), pumping_index=pumping, z=load.z,
            chirp=setup.chirp, setup=setup)


def _frozen(study, exclude=()) -> tuple:
    items = []
    for section, keys in study.values.items():
        for key, value in keys.items():
            if f"{section}.{key}" not in exclude:
                # a list value (membrane.prony: list of mappings) as hashable text
                items.append((section, key, repr(value) if isinstance(value, list) else value))
    return tuple(items)


def _cheap_values(study, overrides=None) -> dict:
    """The closed-form keys of a study, ``overrides`` (SI values, within the schema's
    bounds: they come from the catalogue's fit bounds) taking precedence."""
    overrides = overrides or {}
    get = lambda key: float(overrides[key]) if key in overrides else study.get(key)  # noqa
    return {"air_mass_scale": get("effects.air_mass_scale"),
            "viscoelastic_strength": get("effects.viscoelastic_strength"),
            "viscoelastic_time": get("effects.viscoelastic_time"),
            "spring_own_mass": get("spring.mass"),
            "spring_stiffness": study.spring.stiffness,
            "spring_length": study.spring.length,
            "damping": {label: get(damping_key(label))
                        for label in ("P1", "(0,1)", "(0,2)", "(0,3)")}}


def damping_per_mass(cheap, label) -> float:
    """The modal b/m [1/s] of a mode label (eq. 19) among a state's cheap values: P1's,
    (0,1)'s, (0,2)'s, ``reduced.damping_higher`` for every other mode."""
    return cheap["damping"]["P1" if label == "P1" else
                            label if label in ("(0,1)", "(0,2)") else "(0,3)"]


class _ModeEquation:
    """R(w) of one mode (E1 for P1, k(w) - w^2 M otherwise) with the cheap parameters."""

    def __init__(self, reference: _Reference, cheap: dict, index: int, perturbation=None):
        label = reference.labels[index]
        factor = (perturbation or {}).get(label, 1.0) ** 2
        self.label = label
        self.stiffness = float(factor * reference.stiffness[index])
        self.elastic = float(factor * reference.elastic_stiffness[index])
        added = reference.added_mass[index]
        if label != "P1":
            added = added * cheap["air_mass_scale"]
        self.mass = float(reference.modal_mass[index] + added)
        self.strength = cheap["viscoelastic_strength"]
        self.time = cheap["viscoelastic_time"]
        self.damping = float(damping_per_mass(cheap, label) * reference.modal_mass[index])
        self.spring = None
        if label == "P1" and cheap["spring_own_mass"] > 0 and cheap["spring_stiffness"] > 0:
            speed = (perturbation or {}).get("spring", 1.0)
            self.spring = (cheap["spring_stiffness"],
                           math.sqrt(cheap["spring_own_mass"] / cheap["spring_stiffness"])
                           / speed,
                           float(reference.disc_amplitude ** 2))

    def stiffness_at(self, omega):
        if self.strength == 0:
            return self.stiffness + 0 * omega
        x2 = (omega * self.time) ** 2
        return self.stiffness + self.strength * x2 / (1 + x2) * self.elastic

    def residual(self, omega):
        """R(w) of (E1) [N/m]; w a float (fast path for root finding) or an array."""
        if isinstance(omega, float):
            value = self.stiffness_at(omega) - omega * omega * self.mass
            if self.spring is not None:
                k_d, slowness, a2 = self.spring
                theta = omega * slowness
                cot = theta / math.tan(theta) if theta != 0 else 1.0
                value += a2 * k_d * (cot - 1)
            return value
        omega = np.asarray(omega, float)
        value = self.stiffness_at(omega) - omega ** 2 * self.mass
        if self.spring is not None:
            k_d, slowness, a2 = self.spring
            theta = omega * slowness
            with np.errstate(divide="ignore", invalid="ignore"):
                cot = np.where(theta == 0, 1.0, theta / np.tan(np.where(theta == 0, 1, theta)))
            value = value + a2 * k_d * (cot - 1)
        return value

    def pole(self, j) -> float:
        """w where theta = j pi (a pole of D(w)) [rad/s]."""
        return j * math.pi / self.spring[1]

    def roots(self, count: int) -> list:
        """The first ``count`` roots of R [rad/s] (one for a mode without spring waves)."""
        glassy = self.stiffness + max(self.strength, 0) * max(self.elastic, 0)
        upper = math.sqrt(max(glassy, self.stiffness) / self.mass) * 1.0001 + 1e-9
        if self.spring is None:
            lower = math.sqrt(min(glassy, self.stiffness) / self.mass) * 0.9999
            if self.strength == 0:
                return [math.sqrt(self.stiffness / self.mass)]
            return [scipy.optimize.brentq(self.residual, lower, upper, xtol=1e-12, rtol=1e-13)]
        out = []
        for j in range(count):
            low = self.pole(j) * (1 + 1e-12) if j else 0.0
            high = self.pole(j + 1) * (1 - 1e-12)
            if j == 0:
                high = min(high, upper)
            if self.residual(high) > 0:       # no sign change: a disc that does not move
                break
            out.append(scipy.optimize.brentq(self.residual, low, high, xtol=1e-12, rtol=1e-13))
        return out

    def quality(self, omega) -> float:
        """Q = |dR/dw| / (2 b) at a root (half-power width of R + i w b)."""
        if self.damping <= 0:
            return math.inf
        step = 1e-6 * omega
        slope = (self.residual(omega + step) - self.residual(omega - step)) / (2 * step)
        return float(abs(slope) / (2 * self.damping))


def _modes(reference: _Reference, cheap: dict, band, perturbation=None) -> tuple:
    modes = []
    for index, label in enumerate(reference.labels):
        equation = _ModeEquation(reference, cheap, index, perturbation)
        if label == "P1":
            count = PUMPING_MODES if equation.spring is not None else 1
            roots = equation.roots(count)
            for j, omega in enumerate(roots):
                modes.append(ModelMode(f"P{j + 1}", "pumping", omega / (2 * math.pi),
                                       equation.quality(omega),
                                       float(reference.radial_ratio[index]),
                                       expected=reference.z > 0))
        else:
            omega = equation.roots(1)[0]
            modes.append(ModelMode(label, "axisymmetric", omega / (2 * math.pi),
                                   equation.quality(omega),
                                   float(reference.radial_ratio[index]), expected=True))
    return tuple(sorted(modes, key=lambda m: m.frequency_hz))


def _spectra(reference: _Reference, cheap: dict, frequency_hz, lines, perturbation=None):
    """Spectra of the predicted modes, each a damped oscillator (eq. 19).

    A membrane mode j: ``a_j = f_j V / (k_j(w) - w^2 M_j + i w b_j)``.  The
    pumping modes P_k are the roots w_k of (E1); near each, (E1) + i w b
    behaves as an oscillator of mass ``m_k = -R'(w_k) / (2 w_k)`` and
    stiffness ``w_k^2 m_k`` with P1's force, damping and membrane shape, so
    the spectrum shows exactly the modes :func:`_modes` predicts (P1-P3; the
    lossless spring's higher waves are left out, as in the paper).
    """
    omega = 2 * math.pi * frequency_hz
    columns, shapes = [], []
    for index, label in enumerate(reference.labels):
        equation = _ModeEquation(reference, cheap, index, perturbation)
        force = reference.force[index] * (perturbation or {}).get(f"force:{label}", 1.0)
        if label == "P1" and equation.spring is not None:
            for root in equation.roots(PUMPING_MODES):
                step = 1e-6 * root
                slope = (equation.residual(root + step) - equation.residual(root - step)) / \
                    (2 * step)
                mass = -slope / (2 * root)
                response = force * lines / (mass * (root ** 2 - omega ** 2)
                                            + 1j * omega * equation.damping)
                columns.append(1j * omega * response)
                shapes.append(index)
        else:
            response = force * lines / (equation.residual(omega) + 1j * omega * equation.damping)
            columns.append(1j * omega * response)
            shapes.append(index)
    velocity = np.stack(columns, axis=1)
    pick = lambda matrix: matrix[:, shapes]  # noqa: E731
    return SpectrumResult(
        frequency_hz=frequency_hz,
        average_axial=np.abs(velocity @ pick(reference.scan_axial).T).mean(axis=1),
        average_radial=np.abs(velocity @ pick(reference.scan_radial).T).mean(axis=1),
        point_axial=np.abs(velocity @ pick(reference.point_axial).T),
        point_radial=np.abs(velocity @ pick(reference.point_radial).T))


def safe_predict(engine: RingPredictor, condition, state, perturbation=None, ring_only=False):
    """:meth:`RingPredictor.predict` (``ring_only``: the ring model even where the engine is
    anchored to the FE), or None where the model cannot be evaluated there."""
    from copdea_fem.study import StudyError
    predict = engine.ring_predict if ring_only else engine.predict
    try:
        return predict(condition, state, perturbation)
    except (ReducedModelError, StudyError):
        return None
