"""The FE as the model of record, the ring model as its anchored surrogate.

A diagnosis evaluates thousands of effect states per condition; the FE takes
seconds (axisymmetric engine) to tens of seconds (3-D quadrant, square frame) per
solve, the ring model milliseconds.  So the FE fixes the numbers and the ring model
interpolates between FE solves:

    f(state) = f_ring(state) * f_FE(anchor) / f_ring(anchor)            (A1)

per mode label, where ``anchor`` is the state's *anchor state*: its effects
that the FE represents (their ``fe_role``, :data:`~copdea_fem.diagnosis.effects.FE_ROLES`)
-- the ones the ring model cannot
(air on: the real coupled added mass, square frame) whenever they are in the
state; the ones it moves well (Maxwell and stiffness scale, disc on its
spring) once accepted, at the accepted values (:meth:`AnchoredEngine.set_anchor`,
called by the search at every accepted step: a candidate costs no FE solve
unless it needs the FE, and one that does is solved with the earlier fits'
FE parameters at the base values, so those solves are shared by every step
and every data set of the same conditions); ring-only effects (air-mass
scale, visco-elasticity, spring mass, damping) off -- also where the base
study has them on (:func:`ring_only_off`), so that they act through the ring
model's ratio and are not cancelled by the anchor.  At the anchor (A1) is the FE
exactly, so the ring model's discretisation error (a 6-ring (0,2) 4-5 % too stiff)
never reads as physics and an effect that only the FE has (the frame; the real coupled
added mass in place of the baffled estimate) acts through f_FE(anchor).

Modes the ring model lacks -- non-axisymmetric (m,n) and (0,n) past its
truncation -- take the FE's frequency times the relative change of the ring
mode nearest in frequency at the anchor (its *proxy*); ring modes the FE
lacks (P2, P3 of the spring's mass; modes past the FE's band) take the ratio
of P1, or of the highest axisymmetric mode that has one.  Non-axisymmetric
modes are *optional* (excited only by imperfections: pairable, but their
absence costs nothing).

Quality factors.  Damping adds (radiation and structural loss are
separate terms of the damped pencil, docs/damping.md), so the damping ratio
zeta = 1/(2Q) follows (A1) additively:

    zeta(state) = zeta_FE(anchor) + zeta_ring(state) - zeta_ring(anchor)        (A2)

per mode label (clipped at 0), zeta_FE the FE's complex frequency's
``|Im f| / |f|`` (radiation with air; the Prony term's loss once
``viscoelastic_membrane`` is anchored) and zeta_ring the ring model's (modal b/m
and the Prony term's loss, :mod:`copdea_fem.diagnosis.ring_predictor`).  At the anchor it
is the FE's; a ring-only damping (modal b/m) adds to it.  Modes the ring model
lacks take the change of their proxy's zeta scaled to their own modal damping: the
ring's zeta of a mode is ``(b/m) / (2 omega)`` times its membrane share (eq. 19), so a
mode L given the proxy p's share takes ``Delta zeta_p (b/m)_L omega_p / ((b/m)_p omega_L)``
(the state's ``(b/m)`` by label: a (m,1) mode gets ``reduced.damping_higher``, not the
(0,1)'s b/m that its proxy carries; nothing where the proxy has none).  Modes the FE
lacks take the ring's.

The Prony term (``viscoelastic_membrane``).  The ring model does not
model ``membrane.prony`` (:mod:`copdea_fem.diagnosis.ring_predictor`: its elastic stiffness
is not the FE's material tangent), so between FE solves a *modal* surrogate moves
it, calibrated on the FE.  A mode's stiffness splits into the material part
``s k`` (``s``: its material share of the strain energy, relaxed) and the rest
(initial stress, electrostatic), so with the branches
``k(w) = k (1 + s sum_i g_i (S_i + i L_i))``, ``S_i = x_i^2 / (1 + x_i^2)``,
``L_i = x_i / (1 + x_i^2)``, ``x_i = w tau_i`` (docs/damping.md), and a mode of
relaxed frequency ``w_e`` sits at

    w^2 = w_e^2 (1 + s sum g_i S_i(w)),    zeta = s sum g_i L_i(w) / (2 (1 + s sum g_i S_i(w))) (P1)

(light damping, the mode shape frozen).  ``s`` of every FE mode comes from ONE
probe FE solve per condition in vacuo with a small term (:data:`PROBE`: g = 0.1,
tau = 0.3 ms, the loss peak at 530 Hz, mid-band), inverting (P1):
``s = 2 zeta / (g (L - 2 zeta S))`` at the probe's frequency; it does not depend on
the air (a ratio of stiffnesses).  A state's Prony terms then move each mode from
the anchor's terms (none, the base study's, or the accepted fit: there the
prediction is the FE's exactly) by the ratio of (P1)'s frequencies and the
difference of its zeta ((A1), (A2) again).  A mode without an FE share (the ring's
P2, P3; modes past the FE's band) is left as it is.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace

from copdea_fem.diagnosis.effects import AIR_EFFECT, CATALOGUE, FE_ROLES
from copdea_fem.diagnosis.fe import BAND_MARGIN, FEModel
from copdea_fem.diagnosis.ring_predictor import ModelMode, RingPredictor, damping_per_mass
from copdea_fem.reduced.rings import ReducedModelError
from copdea_fem.study import StudyError

# How the FE represents each effect (FE_ROLES, the effects' ``fe_role``): "switch" (the ring
# model cannot: on in the FE whenever on in the state; its surrogate-only parameters, if
# any, act on the ring surrogate only and sit at their defaults in the anchor state, the
# others set the anchor's FE study: enclosure's depth, one FE solve per depth), "anchored"
# (the ring model moves it well: in the FE from the step that accepts it, at the accepted
# values), or absent (ring only).
MAX_RINGS = 48         # the largest ring count the convergence check suggests


def ring_only_off(study):
    """``study`` with the physics only the ring model has switched off (the FE's side of
    (A1)): effects without an FE role, and the air-mass scale at 1."""
    overrides = {}
    for effect_id, entry in CATALOGUE.items():
        if effect_id not in FE_ROLES and entry.is_on(study):
            overrides.update(entry.off(study))
    if study.effects.air_mass_scale != 1.0:
        overrides["effects.air_mass_scale"] = 1.0
    return study.replace(overrides) if overrides else study


def damping_ratio(quality: float) -> float:
    """zeta = 1 / (2 Q) [-] (0 for an undamped mode, Q = inf)."""
    return 0.5 / quality if math.isfinite(quality) and quality > 0 else 0.0


def quality_factor(zeta: float) -> float:
    """Q = 1 / (2 zeta) [-] (inf for zeta <= 0: undamped)."""
    return 0.5 / zeta if zeta > 0 else math.inf


#: Probe terms of the material shares (module notes): a small one (linear in g) and a
#: strong one (how the share changes as the branches stiffen the material), their loss
#: peak mid-band (x = 1 at 530 Hz), so that every mode of 0.1-3 kHz has L >= 0.17.
PROBE = {"modulus_ratio": 0.1, "relaxation_time": 3e-4}
STRONG_PROBE = {"modulus_ratio": 1.0, "relaxation_time": 3e-4}
#: A probe zeta below this (relative to g L / 2) is no material share: a flat membrane's
#: out-of-plane modes (docs/damping.md), round-off of ~1e-17 in the FE's complex frequency.
SHARE_FLOOR = 1e-9


def prony_mode(frequency_hz: float, share: "Share", terms) -> tuple:
    """(P1) of the module notes: the frequency [Hz] and damping ratio [-] of a mode of
    relaxed frequency ``frequency_hz`` and material share ``share`` under the Prony
    ``terms`` ``((g, tau [s]), ...)`` (fixed point in w: S, L vary slowly)."""
    if not terms or share.relaxed <= 0:
        return frequency_hz, 0.0
    f = frequency_hz
    for _ in range(100):        # contracts: d ln f / d ln f_previous <= s g / 4 (s << 1)
        storage = _storage_loss(f, terms)[0]
        new = frequency_hz * math.sqrt(1 + share.at(storage) * storage)
        if abs(new - f) <= 1e-13 * f:
            break
        f = new
    storage, loss = _storage_loss(f, terms)
    s = share.at(storage)
    return f, s * loss / (2 * (1 + s * storage))


def _storage_loss(frequency_hz: float, terms) -> tuple:
    """``(sum g S, sum g L)`` of the module notes at ``frequency_hz`` [Hz]."""
    storage = loss = 0.0
    for ratio, time in terms:
        x = 2 * math.pi * frequency_hz * time
        storage += ratio * x * x / (1 + x * x)
        loss += ratio * x / (1 + x * x)
    return storage, loss


def material_share(frequency_hz: float, zeta: float, probe=PROBE) -> float:
    """``s`` of (P1) from a probe's frequency [Hz] and its structural zeta [-]."""
    x = 2 * math.pi * frequency_hz * probe["relaxation_time"]
    g = probe["modulus_ratio"]
    storage, loss = x * x / (1 + x * x), x / (1 + x * x)
    if zeta <= SHARE_FLOOR * g * loss:
        return 0.0
    return max(0.0, 2 * zeta / (g * (loss - 2 * zeta * storage)))


@dataclass(frozen=True)
class Share:
    """A mode's material share as the branches stiffen the material (module notes):
    ``s(G) = relaxed / (1 + slope G)``, ``G = sum g_i S_i`` [-], from the two probes."""

    relaxed: float
    slope: float = 0.0

    def at(self, storage: float) -> float:
        # at most doubled: past the strong probe the law is an extrapolation, and a mode
        # that mixes with the in-plane family (the (0,2) of G1's cone) has no smooth share
        return self.relaxed / max(1 + self.slope * storage, 0.5)

    @classmethod
    def from_probes(cls, weak: tuple, strong: tuple | None) -> "Share":
        """From ``(frequency_hz, zeta)`` of the mode under :data:`PROBE` and
        :data:`STRONG_PROBE` (None: the mode is not in the strong probe's band)."""
        s1 = material_share(*weak, probe=PROBE)
        if s1 <= 0 or strong is None:
            return cls(s1)
        s2 = material_share(*strong, probe=STRONG_PROBE)
        g1 = _storage_loss(weak[0], ((PROBE["modulus_ratio"], PROBE["relaxation_time"]),))[0]
        g2 = _storage_loss(strong[0], ((STRONG_PROBE["modulus_ratio"],
                                        STRONG_PROBE["relaxation_time"]),))[0]
        denominator = s2 * g2 - s1 * g1
        if s2 <= 0 or abs(denominator) < 1e-12:
            return cls(s1)
        slope = (s1 - s2) / denominator
        return cls(s1 * (1 + slope * g1), slope)


def probe_study(study):
    """The in-vacuo FE study of ``study`` (a condition's) whose Prony probes give the
    material shares (module notes): no air (the shares are ratios of stiffnesses), no
    Rayleigh damping, the weak probe term; the strong probe and the reference replace
    ``membrane.prony``."""
    return study.replace({"air.enabled": False, "membrane.rayleigh_alpha": 0.0,
                          "membrane.rayleigh_beta": 0.0, "membrane.prony": [PROBE]})


def prony_terms(terms) -> tuple:
    """``membrane.prony`` (:class:`~copdea_fem.study.PronyTerm`, SI) as ``((g, tau [s]), ...)``."""
    return tuple((float(t.modulus_ratio), float(t.relaxation_time)) for t in terms or ())


class FEFailure(ReducedModelError):
    """The FE cannot be solved at an effect state (the state is not evaluable)."""


@dataclass(frozen=True)
class Anchor:
    """FE and ring modes of one condition at one anchor state, and (A1)'s ratios."""

    fe: object                    # FEResult
    ring: tuple                   # ring ModelModes at the anchor
    ratio: dict                   # label -> f_FE / f_ring at the anchor
    proxies: tuple = field(init=False, default=())   # (FE mode, its ring proxy), derived
    fe_zeta: dict = field(init=False, default_factory=dict)     # label -> FE zeta (A2)
    ring_zeta: dict = field(init=False, default_factory=dict)   # label -> ring zeta, anchor

    def __post_init__(self):
        object.__setattr__(self, "fe_zeta", {m.label: m.damping_ratio for m in self.fe.modes})
        object.__setattr__(self, "ring_zeta", {m.label: damping_ratio(m.quality_factor)
                                               for m in self.ring})
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

    def apply(self, modes, damping_per_mass=None) -> tuple:
        """(A1) on the ring modes of a state, plus the FE modes the ring model lacks;
        ``damping_per_mass``: the state's ``label -> (b/m)`` [1/s] (module notes; None: the
        proxies' zeta changes as they are)."""
        now = {m.label: m for m in modes}
        out = []
        for mode in modes:
            ratio = self.ratio.get(mode.label)
            if ratio is None:
                ratio = self._fallback(mode)
            quality = mode.quality_factor
            if mode.label in self.fe_zeta and mode.label in self.ring_zeta:     # (A2)
                quality = quality_factor(self.fe_zeta[mode.label] + damping_ratio(quality)
                                         - self.ring_zeta[mode.label])
            out.append(replace(mode, frequency_hz=mode.frequency_hz * ratio,
                               quality_factor=quality))
        for fe_mode, proxy in self.proxies:
            if fe_mode.label in now:
                continue
            current = now.get(proxy.label)
            change = current.frequency_hz / proxy.frequency_hz if current is not None else 1.0
            scale = 1.0
            if damping_per_mass is not None:
                theirs = damping_per_mass(proxy.label)
                scale = (damping_per_mass(fe_mode.label) * proxy.frequency_hz
                         / (theirs * fe_mode.frequency_hz)) if theirs > 0 else 0.0
            quality = quality_factor(fe_mode.damping_ratio + scale * (
                damping_ratio(current.quality_factor) - self.ring_zeta[proxy.label]
                if current is not None else 0.0))
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


class AnchoredEngine(RingPredictor):
    """:class:`RingPredictor` whose predictions are the FE's, interpolated by the ring model (A1).

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
        self._shares: dict = {}

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
                out.append((effect_id, CATALOGUE[effect_id].anchor_values(values)))
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
        modes = anchor.apply(prediction.modes, functools.partial(damping_per_mass,
                                                                 prediction.cheap))
        now, then = self.prony_of(condition, state), self.prony_of(
            condition, self.anchor_state(state))
        if now != then:
            modes = self._move_prony(condition, modes, then, now)
        return replace(prediction, modes=modes)

    def prony_of(self, condition, state) -> tuple:
        """The Prony terms of a state: the values of its Prony-term effect
        (``viscoelastic_membrane``) where it is in the state, else the base study's
        ``membrane.prony``."""
        for effect_id, values in state:
            if CATALOGUE[effect_id].prony_term:
                return ((float(values[0]), float(values[1])),)
        return prony_terms(self.condition_study(condition).membrane.prony)


    def shares(self, condition) -> dict:
        """:class:`Share` of (P1) per FE mode label of ``condition`` (cached; three FE
        solves in vacuo: the two probes and the same study without a term)."""
        hit = self._shares.get(condition.name)
        if hit is None:
            probe = probe_study(self.condition_study(condition))
            f_max = BAND_MARGIN * condition.band[1]
            try:
                self.fe.solve_many([(probe, f_max),
                                    (probe.replace({"membrane.prony": [STRONG_PROBE]}), f_max),
                                    (probe.replace({"membrane.prony": []}), f_max)])
                weak = self.fe.modes(probe, f_max=f_max)
                strong = self.fe.modes(probe.replace({"membrane.prony": [STRONG_PROBE]}),
                                       f_max=f_max)
                elastic = self.fe.modes(probe.replace({"membrane.prony": []}), f_max=f_max)
            except (RuntimeError, ValueError) as error:
                raise FEFailure(f"the FE Prony probe cannot be solved at {condition.name}: "
                                f"{error}") from error
            reference = {m.label: m.damping_ratio for m in elastic.modes}
            strong_modes = {m.label: (m.frequency_hz, m.damping_ratio
                                      - reference.get(m.label, 0.0)) for m in strong.modes}
            hit = self._shares[condition.name] = {
                m.label: Share.from_probes(
                    (m.frequency_hz, m.damping_ratio - reference.get(m.label, 0.0)),
                    strong_modes.get(m.label))
                for m in weak.modes}
        return hit

    def ring_convergence(self) -> dict:
        """The ring surrogate against the FE at the base point.

        The anchor (A1) removes the ring model's discretisation error at the anchor, but
        a surrogate far from the FE also moves its modes differently with the
        parameters; it is flagged when its largest error on an axisymmetric mode in a
        band exceeds the data's scatter sigma_f, with the ring count (doubling, up to
        :data:`MAX_RINGS`) that brings it below sigma_f / 2.

        Returns
        -------
        dict
            ``rings``, ``sigma``, ``largest_error`` (relative), its ``label`` and
            ``condition``, ``converged``, ``suggested_rings`` (None when converged or
            none found) and ``suggested_error``.
        """
        sigma = self.measured.noise.frequency_relative
        rings = self.measured.base_study.reduced.rings

        def worst(ring_count):
            out = (0.0, "", "")
            for c in self.measured.conditions:
                study = self.condition_study(c)
                study = ring_only_off(study.replace(AIR_EFFECT.off(study)))
                fe = self.fe.modes(study, f_max=BAND_MARGIN * c.band[1]).frequencies()
                if ring_count != rings:
                    study = study.replace({"reduced.rings": ring_count})
                try:
                    modes = self.ring_predict_study(study, c).modes
                except (ReducedModelError, StudyError):    # a ring count it cannot take
                    return None
                for m in modes:
                    if (m.kind == "axisymmetric" and m.label in fe
                            and c.band[0] <= fe[m.label] <= c.band[1]):
                        error = m.frequency_hz / fe[m.label] - 1
                        if abs(error) > abs(out[0]):
                            out = (error, m.label, c.name)
            return out

        error, label, where = worst(rings)
        report = {"rings": rings, "sigma": sigma, "largest_error": error, "label": label,
                  "condition": where, "converged": abs(error) <= sigma, "suggested_rings": None}
        if not report["converged"]:
            count = rings
            while count < MAX_RINGS:
                count = min(2 * count, MAX_RINGS)
                found = worst(count)
                if found is not None and abs(found[0]) <= sigma / 2:
                    report["suggested_rings"] = count
                    report["suggested_error"] = found[0]
                    break
        return report

    def _move_prony(self, condition, modes, then, now) -> tuple:
        """Modes under the anchor's Prony terms ``then`` moved to ``now`` by (P1)."""
        shares = self.shares(condition)
        out = []
        for mode in modes:
            share = shares.get(mode.label)
            if share is None or share.relaxed <= 0:
                out.append(mode)
                continue
            # (P1) under ``then`` holds at the mode's own frequency: its relaxed one follows
            storage, loss = _storage_loss(mode.frequency_hz, then)
            s = share.at(storage)
            relaxed = mode.frequency_hz / math.sqrt(1 + s * storage)
            zeta_then = s * loss / (2 * (1 + s * storage))
            f_now, zeta_now = prony_mode(relaxed, share, now)
            zeta = damping_ratio(mode.quality_factor) + zeta_now - zeta_then
            out.append(replace(mode, frequency_hz=f_now, quality_factor=quality_factor(zeta)))
        return tuple(sorted(out, key=lambda m: m.frequency_hz))
