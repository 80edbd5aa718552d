"""Diagnose: which catalogued effect the model lacks, with evidence (issue 5, item 4).

The loop
--------
Start from the base study.  At each step, every catalogued effect that is
off, that the reduced engine can evaluate and that the data can see is a
*candidate* (an effect whose requirement is off comes with it:
``disc_pumping + spring_mass``).  For each candidate:

1. fit its 0-2 parameters on all conditions (maximum likelihood = minimum
   deviance, :mod:`copdea_fem.diagnosis.compare`), within the catalogue's
   bounds;
2. cross-validate by condition: for every condition f, fit on the others
   and evaluate the deviance of f, ``Delta_f = D_current(f) - D_candidate(f)``
   (the held-out improvement);
3. rank by the cross-validated improvement ``Delta_cv = sum_f Delta_f``
   (leave-one-out CV charges every fitted parameter what it costs in
   prediction -- asymptotically 2 per parameter, Stone 1977 -- so no
   separate penalty is added);
4. test by the prequential likelihood ratio (Dawid 1984): take the
   conditions in an order c_1, c_2, ...; score c_j with the parameters fitted
   on c_1 .. c_(j-1) only (c_1 with the catalogue's physical defaults), and
   multiply ``exp(Delta_j / 2)``.  Averaged over three cyclic orderings
   (starting at conditions 1, 1 + K/3, 1 + 2K/3 of the K, fixed before
   looking at the data) this is the evidence U.

Significance (derived, not tuned).  Every factor of the product compares
likelihoods on a condition its parameters have not seen, so under "the
candidate is not better than the current model" the product is a test
martingale: E[U] <= 1 (also for the average over orderings) and Ville's /
Markov's inequality gives P(U >= 1/alpha) <= alpha -- for any model, any
number of parameters, any number of conditions, no asymptotics (the
e-value logic of universal inference, Wasserman, Ramdas & Balakrishnan,
PNAS 117, 2020).  With N candidates tested at a step (Bonferroni) the best
one is accepted when

    ln U >= ln(N / alpha)  and  Delta_cv > 0,        alpha = 0.05,

so a step raises a false alarm with probability at most 5 %.  Unlike an
average of held-out ratios, the product accumulates evidence spread over
many conditions.  With a single condition there is nothing to hold out:
the in-sample likelihood ratio is used with Wilks' threshold
``chi2_k^-1(1 - alpha/N)`` (k >= 1) or ``2 ln(N/alpha)`` (k = 0, simple
hypotheses, Markov again), and the report says so.

Ambiguity.  Another candidate B that improves the held-out deviance
(Delta_cv > 0; significant or not) is indistinguishable from the best A when
the same test, run between them, cannot tell A better:
``ln U_AB < ln(1/alpha)`` with U_AB the prequential likelihood of A over
B's *maximum* likelihood on all conditions.  B's denominator must be its
full-data fit: L_B(theta_hat) >= L_B(theta_true) keeps E[U_AB] <= 1 when B
is the truth (with B fitted on the past only, the ratio could be inflated
and a wrong A named with confidence).  Then the group is
reported, no member is named missing, the best is kept *provisionally* so
that the search can go on, and the report proposes the measurement that
separates them: the operating point (V_b, z of the data's geometry) where
the two fitted models differ most in units of sigma_f.

The parameters of the effects added before are nuisance parameters of every
candidate's fit: they are re-fitted with it (jointly, in every fold), using
modes linearised in them about their current values (one finite difference
per parameter and condition), so an effect added earlier cannot keep a
share of the discrepancy that belongs to the new one.  After each accepted
step they are re-fitted exactly one effect at a time (a coordinate pass).
The loop stops when no candidate passes.  (Approximation: the earlier
effects' parameters are not re-fitted inside each fold; this makes the
current model look slightly better than it would out of sample, i.e. the
test slightly conservative.)

The surrogate's tabulation is :mod:`copdea_fem.diagnosis.tabulation`; the sentences of
the report (evidence, goodness of fit, verdict) are :mod:`copdea_fem.diagnosis.evidence`.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np
import scipy.stats

from copdea_fem.diagnosis.anchored import ring_only_off
from copdea_fem.diagnosis.compare import (
    ConditionMatch,
    DevianceTerms,
    MeasuredPeak,
    gap,
    match_condition,
)
from copdea_fem.diagnosis.direct import (
    DIRECT_EFFECTS,
    DIRECT_GRID,
    PINNED_KEYS,
    DirectFEEngine,
    ring_can_represent,
)
from copdea_fem.diagnosis.effects import CATALOGUE, MATERIAL_DAMPING, MOUNTINGS, base_mounting
from copdea_fem.diagnosis.engine import Engine, safe_predict
from copdea_fem.diagnosis.evidence import describe_evidence, goodness_of_fit, remaining_off, verdict
from copdea_fem.diagnosis.fe import BAND_MARGIN
from copdea_fem.diagnosis.peaks import find_spectrum_peaks, peak_height
from copdea_fem.diagnosis.tabulation import INVALID, Tabulation
from copdea_fem.reduced.rings import ReducedModelError
from copdea_fem.study import StudyError

ALPHA = 0.05
ORDERINGS = 3          # cyclic orderings averaged in the prequential evidence (fixed in advance)
MAX_RINGS = 48         # the largest ring count the convergence check suggests
BOUND_MARGIN = 1e-3    # a fitted u this close to 0 or 1 is at a bound of the fit range


logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class CandidateScore:
    """One candidate at one step.

    Attributes
    ----------
    effects : tuple of str
        The effect (and any requirement switched on with it).
    values : tuple of float
        Parameters fitted on all conditions (SI, in the order of the effects').
    deviance : float
        In-sample deviance at ``values``.
    delta_in : float
        In-sample improvement over the current model.
    fold_delta : dict
        Held-out improvement per condition.
    delta_cv : float
        sum of ``fold_delta``: the ranking score.
    log_evidence : float
        ln U, the prequential evidence (module notes); with one condition, Delta_in / 2.
    threshold : float
        The ln U (or Delta_in / 2) it must reach.
    significant : bool
    held_out : dict
        Held-out deviance per condition.
    at_bound : tuple of str
        Parameters fitted at a bound of their fit range (``effect.parameter``): such a
        fit is reported, never accepted (the effect's range cannot explain the data).
    """

    effects: tuple
    values: tuple
    deviance: float
    delta_in: float
    fold_delta: dict
    delta_cv: float
    log_evidence: float
    threshold: float
    significant: bool
    held_out: dict
    state: tuple = ()
    prequential: tuple = ()       # per ordering: {condition: deviance with past-fitted params}
    in_sample: dict = field(default_factory=dict)   # {condition: deviance at the full fit}
    at_bound: tuple = ()

    @property
    def parameters(self) -> list:
        return [p for e in self.effects for p in CATALOGUE[e].parameters]

    def described(self) -> str:
        parts = []
        offset = 0
        for effect_id in self.effects:
            entry = CATALOGUE[effect_id]
            values = self.values[offset:offset + len(entry.parameters)]
            offset += len(entry.parameters)
            parts.append(effect_id + (f" ({entry.describe_values(values)})" if values else ""))
        return " + ".join(parts)


@dataclass
class Step:
    """One step of the loop: what was added, why, and what it changed."""

    index: int
    action: str                   # "added" or "ambiguous"
    effects: tuple
    values: dict                  # {effect: {parameter: SI value}}
    score: CandidateScore
    gap_before: float
    gap_after: float
    deviance_before: float
    deviance_after: float
    evidence: list
    ambiguous_with: tuple = ()
    separation: list = field(default_factory=list)
    candidates: list = field(default_factory=list)


@dataclass
class DiagnosisResult:
    """Everything the report and ``diagnosis.json`` need."""

    measured: object
    steps: list
    final_state: tuple
    missing_effects: list
    ambiguous: list
    gap_before: float
    gap_after: float
    matches_before: dict
    matches_after: dict
    deviance_before: float
    deviance_after: float
    status: dict                  # effect -> status text
    not_tested: dict              # effect -> reason
    base_on: list
    goodness: dict
    verdict: str
    cross_validated: bool
    alpha: float
    predictions_before: dict = field(default_factory=dict)
    predictions_after: dict = field(default_factory=dict)
    rejected: list = field(default_factory=list)   # significant fits the acceptance refused
    ring_convergence: dict | None = None           # the surrogate against the FE at the base
    model: str = "reduced"                         # the model of record: "fe" or "reduced"
    fe_solves: int = 0
    fe_seconds: float = 0.0
    remaining_off: list = field(default_factory=list)   # modes off beyond the noise (final)
    engines: dict = field(default_factory=dict)          # what evaluated what (report)


def condition_peaks(condition) -> list[MeasuredPeak]:
    """The measured peaks of a condition: its resonance list (heights and radial ratios
    read from its spectrum, if any), else the peaks found in its spectrum."""
    spectrum = condition.spectrum
    if condition.resonances is None:
        return find_spectrum_peaks(spectrum.frequency_hz, spectrum.axial, spectrum.radial,
                                   condition.band)
    peaks = []
    for r in condition.resonances:
        height = ratio = math.nan
        if spectrum is not None:
            axial = peak_height(spectrum.frequency_hz, spectrum.axial, r.frequency_hz, 0.01)
            radial = peak_height(spectrum.frequency_hz, spectrum.radial, r.frequency_hz, 0.01)
            height = axial + radial
            ratio = radial / axial if axial > 0 else math.nan
        peaks.append(MeasuredPeak(r.frequency_hz, r.label, r.kind, r.quality_factor, height,
                                  ratio, "resonances"))
    return peaks


class Diagnoser:
    """Runs the loop of the module notes on a :class:`MeasuredSet`."""

    def __init__(self, measured, alpha: float = ALPHA, engine: Engine | None = None):
        self.measured = measured
        self.alpha = alpha
        self.progress = logger.info      # progress lines, at INFO
        if engine is None and measured.model == "fe":
            from copdea_fem.diagnosis.anchored import AnchoredEngine
            from copdea_fem.diagnosis.fe import FEModel
            fe = FEModel()
            engine = (AnchoredEngine(measured, fe) if ring_can_represent(measured.base_study)
                      else DirectFEEngine(measured, fe))
        if engine is None and not ring_can_represent(measured.base_study):
            raise StudyError(f"model = {measured.model!r} is not allowed for a membrane without "
                             "a disc (geometry.inner_radius = 0: the ring model of Sect. 3.2.1 "
                             "needs the central disc); allowed: fe (the FE evaluated directly)")
        self.engine = engine or Engine(measured)
        self.uses_fe = hasattr(self.engine, "anchor")
        self.direct = bool(getattr(self.engine, "direct", False))
        self.pinned = PINNED_KEYS if self.direct else ()
        self.conditions = measured.conditions
        self.peaks = {c.name: condition_peaks(c) for c in self.conditions}
        self._terms: dict = {}
        self.meta = {}
        for c in self.conditions:
            study = measured.study_of(c)
            self.meta[c.name] = {"voltage": study["load"]["voltage"], "z": study["load"]["z"]}

    # -- evaluation ------------------------------------------------------------------------
    def terms(self, name) -> DevianceTerms:
        """The deviance constants of condition ``name``."""
        terms = self._terms.get(name)
        if terms is None:
            condition = next(c for c in self.conditions if c.name == name)
            terms = self._terms[name] = DevianceTerms(self.measured.noise, condition.band)
        return terms

    def match(self, condition, modes) -> ConditionMatch:
        return match_condition(condition.name, modes, self.peaks[condition.name],
                               condition.band, self.measured.noise, self.terms(condition.name))

    def evaluate(self, state) -> tuple[dict, dict]:
        """Exact predictions and matches of every condition ({} entries None if invalid)."""
        predictions, matches = {}, {}
        self.engine.prefetch([(c, state) for c in self.conditions])
        for c in self.conditions:
            prediction = safe_predict(self.engine, c, state)
            predictions[c.name] = prediction
            matches[c.name] = self.match(c, prediction.modes) if prediction else None
        return predictions, matches

    @staticmethod
    def deviances(matches) -> dict:
        return {name: (m.deviance if m is not None else INVALID) for name, m in matches.items()}

    # -- candidates --------------------------------------------------------------------------
    def candidates(self, state, base_study) -> tuple[list, dict]:
        """Candidate effect groups at this state, and reasons for the effects not tested."""
        on = {e for e, _ in state} | {e for e, entry in CATALOGUE.items()
                                      if entry.is_on(base_study)}
        has_quality = any(math.isfinite(p.quality_factor) for peaks in self.peaks.values()
                          for p in peaks)
        any_voltage = any(m["voltage"] > 0 for m in self.meta.values())
        any_z = any(m["z"] > 0 for m in self.meta.values())
        groups, skipped = [], {}
        for effect_id in self.measured.candidates:
            entry = CATALOGUE[effect_id]
            if entry.engine == "coupled_fe" and not self.uses_fe:
                skipped[effect_id] = ("needs the fully-coupled air/PML FE as the model of "
                                      "record (measured.yaml model: fe)")
                continue
            if entry.engine == "fe" and not self.uses_fe:
                skipped[effect_id] = ("needs the FE as the model of record (measured.yaml "
                                      "model: fe): the FE's damped eigen step evaluates it")
                continue
            if effect_id in on:
                continue
            if self.direct and effect_id == "viscoelastic_membrane":
                skipped[effect_id] = ("needs the ring surrogate to fit its two parameters "
                                      "(the direct FE engine would tabulate them on a grid "
                                      "of damped FE solves per condition), which cannot "
                                      "represent this membrane (no central disc)")
                continue
            if self.direct and effect_id not in DIRECT_EFFECTS:
                skipped[effect_id] = ("needs the ring surrogate, which cannot represent this "
                                      "membrane (no central disc), and the FE does not model "
                                      "it")
                continue
            if effect_id == "disc_pumping" and base_study["geometry"]["inner_radius"] == 0:
                skipped[effect_id] = "a membrane without a disc has no disc to pump"
                continue
            if effect_id in MOUNTINGS:
                why = self._mounting_skipped(effect_id, state, base_study)
                if why:
                    skipped[effect_id] = why
                    continue
            if effect_id in MATERIAL_DAMPING:
                why = self._material_skipped(effect_id, state, base_study)
                if why:
                    skipped[effect_id] = why
                    continue
            if entry.engine == "coupled_fe" and "air_loading" not in on:
                skipped[effect_id] = ("needs air in the model (the frame reflects sound): "
                                      "tested once air_loading is on")
                continue
            if entry.needs == "quality_factors" and not has_quality:
                skipped[effect_id] = ("needs quality factors (a quality_factor column or "
                                      "spectra with resolved peaks)")
                continue
            if effect_id == "electrostatic_softening" and not any_voltage:
                skipped[effect_id] = "every condition has V_b = 0: nothing to soften"
                continue
            if effect_id in ("disc_pumping", "spring_mass") and not any_z:
                skipped[effect_id] = "every condition has z = 0: the pumping modes are not driven"
                continue
            group = tuple(r for r in entry.requires if r not in on) + (effect_id,)
            if any(g not in self.measured.candidates for g in group):
                skipped[effect_id] = f"needs {', '.join(group[:-1])}, which is not a candidate"
                continue
            groups.append(group)
        return groups, skipped

    @staticmethod
    def _mounting_skipped(effect_id, state, base_study) -> str | None:
        """Why the mounting ``effect_id`` is not a candidate at ``state`` (None: it is).

        One mounting at a time: the base study's own (:func:`base_mounting`: open in air,
        baffled or framed) is the starting point, and every other mounting is a candidate
        that *replaces* it (its overrides set ``geometry.frame``) -- the search adds
        effects, and this is how a base with the wrong mounting is corrected (issue 24:
        open-air data from a baffled base).  Once a mounting is accepted (or held
        provisionally) no other is tested.  A framed or baffled base without air
        (``air.enabled: false``, the frame inert) keeps its stated mounting: only a base
        that models the air states a mounting to replace.
        """
        added = next((e for e, _ in state if e in MOUNTINGS and e != effect_id), None)
        if added:
            return f"another mounting ({added}) is in the model: one mounting at a time"
        stated = base_mounting(base_study)
        if stated not in (None, "open_air") and not base_study["air"]["enabled"]:
            return (f"another mounting ({stated}) is in the model: one mounting at a time "
                    "(the base study states it without air, air.enabled: false)")
        return None

    @staticmethod
    def _material_skipped(effect_id, state, base_study) -> str | None:
        """Why the material-damping effect ``effect_id`` is not a candidate at ``state``
        (None: it is).

        One material cause at a time (:data:`~copdea_fem.diagnosis.effects.MATERIAL_DAMPING`):
        the FE's Prony term (``viscoelastic_membrane``) stiffens AND damps, so it is the
        cause that the ring model's storage factor (``viscoelastic_stiffening``) and the
        paper's modal b/m (``modal_damping``) each describe a part of.  It is never tested
        beside either: not once one of them is in the model (added, or
        ``viscoelastic_stiffening`` on in the base), nor either once it is.  The base
        study's modal b/m (on by default, Sect. 5.3) is no obstacle: the Prony term replaces
        it (its overrides set ``reduced.damping_*`` to 0), as a mounting replaces another.
        At one step all three may be tested; the best is named (or the group reported as
        ambiguous) by the search's usual rule.
        """
        added = {e for e, _ in state}
        if effect_id == "viscoelastic_membrane":
            other = next((e for e in ("viscoelastic_stiffening", "modal_damping")
                          if e in added), None)
            if other is None and CATALOGUE["viscoelastic_stiffening"].is_on(base_study):
                other = "viscoelastic_stiffening"
            if other:
                return (f"one material-damping cause at a time: {other} is in the model "
                        "(the Prony term would explain the same stiffening or widths)")
            return None
        if "viscoelastic_membrane" in added or CATALOGUE["viscoelastic_membrane"].is_on(
                base_study):
            return ("one material-damping cause at a time: viscoelastic_membrane (the FE's "
                    "Prony term, which stiffens and damps) is in the model")
        return None

    def _prefetch_switches(self, state, groups) -> None:
        """The FE solves every candidate of a step needs at its defaults, side by side
        (:meth:`FEModel.solve_many`: the cold diagnosis's switches -- air, mountings --
        at every condition at once); on the direct engine only the candidates without a
        fitted parameter (the others are solved on their grids, a batch each)."""
        pairs = []
        for group in groups:
            free = [p for e in group for p in CATALOGUE[e].parameters
                    if p.key not in self.pinned]
            if self.direct and free:
                continue
            candidate = state + tuple((e, CATALOGUE[e].defaults) for e in group)
            pairs.extend((c, candidate) for c in self.conditions)
        self.engine.prefetch(pairs)

    # -- fitting -----------------------------------------------------------------------------
    def score(self, state, group, current_deviance: dict, tested: int) -> CandidateScore:
        """Fit, cross-validate and test one candidate group (module notes)."""
        parameters = [p for e in group for p in CATALOGUE[e].parameters
                      if p.key not in self.pinned]
        table = Tabulation(self, state, group, parameters, nuisance=True, pinned=self.pinned,
                           grid=DIRECT_GRID if self.direct else None)
        names = [c.name for c in self.conditions]
        full_u = table.fit(names)
        values = table.values(full_u)
        if self.direct:      # the FE's own tabulation (exact at the grid; no seed-dependent
            matches = {}     # solve per candidate -- an accepted model is solved exactly)
            for c in self.conditions:
                modes = table.modes_at(c.name, full_u)
                matches[c.name] = self.match(c, modes) if modes is not None else None
        else:
            _, matches = self.evaluate(table.state_at(full_u))
        deviance = self.deviances(matches)
        total = sum(deviance.values())
        current_total = sum(current_deviance.values())
        delta_in = current_total - total
        k = len(parameters)
        prequential = ()
        if len(names) >= 2:
            held_out, fold_delta = {}, {}
            for name in names:
                train = [n for n in names if n != name]
                held = self._held_out(table, name, table.fit(train))
                held_out[name] = held
                fold_delta[name] = current_deviance[name] - held
            delta_cv = sum(fold_delta.values())
            shifts = sorted({round(i * len(names) / ORDERINGS) for i in range(ORDERINGS)})
            prequential = tuple(self._prequential(table, names[i:] + names[:i])
                                for i in shifts if i < len(names))
            log_evidence = _log_mean_exp([
                sum(current_deviance[n] - d for n, d in order.items()) / 2
                for order in prequential])
            threshold = math.log(tested / self.alpha)
            significant = log_evidence >= threshold and delta_cv > 0
        else:
            held_out, fold_delta = dict(deviance), {names[0]: delta_in}
            delta_cv = delta_in - 2 * k
            log_evidence = delta_in / 2
            threshold = 0.5 * (scipy.stats.chi2.ppf(1 - self.alpha / tested, k) if k
                               else 2 * math.log(tested / self.alpha))
            significant = log_evidence >= threshold
        if not math.isfinite(delta_cv):
            significant = False
        at_bound = tuple(f"{effect}.{p.name}" for (effect, p), x in zip(
            ((e, p) for e in group for p in CATALOGUE[e].parameters
             if p.key not in self.pinned), full_u[:k])
            if x <= BOUND_MARGIN or x >= 1 - BOUND_MARGIN)
        if at_bound:
            significant = False
        return CandidateScore(effects=tuple(group), values=tuple(values), deviance=total,
                              delta_in=delta_in, fold_delta=fold_delta, delta_cv=delta_cv,
                              log_evidence=log_evidence, threshold=threshold,
                              significant=significant, held_out=held_out,
                              state=table.state_at(full_u), prequential=prequential,
                              in_sample=dict(deviance), at_bound=at_bound)

    def _held_out(self, table, name, u) -> float:
        """Deviance of one condition at u, on the interpolated modes (error << sigma_f)."""
        return table.deviance([name], u)

    def _prequential(self, table, order) -> dict:
        """Deviance of each condition of ``order`` with parameters fitted on those before it."""
        out = {}
        for j, name in enumerate(order):
            u = table.fit(order[:j]) if j else table.start()
            out[name] = self._held_out(table, name, u)
        return out

    def refit(self, state, index) -> tuple:
        """Re-fit the parameters of state entry ``index`` with the others fixed."""
        effect_id, _ = state[index]
        parameters = [p for p in CATALOGUE[effect_id].parameters if p.key not in self.pinned]
        if not parameters:
            return state
        rest = state[:index] + state[index + 1:]
        table = Tabulation(self, rest, (effect_id,), parameters, pinned=self.pinned,
                           grid=DIRECT_GRID if self.direct else None)
        u = table.fit([c.name for c in self.conditions])
        values = tuple(table.values(u))
        return state[:index] + ((effect_id, values),) + state[index + 1:]

    # -- the loop ----------------------------------------------------------------------------
    def run(self) -> DiagnosisResult:
        base = self.measured.base_study
        state: tuple = ()
        self._anchor(state)
        predictions_before, matches_before = self.evaluate(state)
        if any(m is None for m in matches_before.values()):
            bad = [n for n, m in matches_before.items() if m is None]
            why = ""
            try:
                self.engine.predict(next(c for c in self.conditions if c.name == bad[0]))
            except (ReducedModelError, StudyError) as error:   # what safe_predict hid
                why = f" ({error})"
            raise StudyError(f"conditions {', '.join(bad)} are not allowed: the base model "
                             f"cannot be evaluated there{why}; allowed: operating points the "
                             "model solves")
        convergence = self.ring_convergence() if self.uses_fe and not self.direct else None
        deviance = self.deviances(matches_before)
        matches = matches_before
        steps, missing, ambiguous, rejected = [], [], [], []
        not_tested: dict = {}
        tested_ever: set = set()
        for index in range(1, len(CATALOGUE) + 1):
            groups, skipped = self.candidates(state, base)
            not_tested.update({e: r for e, r in skipped.items() if e not in tested_ever})
            if not groups:
                break
            for group in groups:
                not_tested.pop(group[-1], None)
            self.progress(f"step {index}: testing {', '.join(g[-1] for g in groups)}")
            self._prefetch_switches(state, groups)
            scores = [self.score(state, g, deviance, len(groups)) for g in groups]
            tested_ever.update(g[-1] for g in groups)
            scores.sort(key=lambda s: -s.delta_cv if math.isfinite(s.delta_cv) else math.inf)
            accepted = None
            for best in (s for s in scores if s.significant):
                new_state = best.state
                for position in range(len(state)):
                    new_state = self.refit(new_state, position)
                previous = self._anchor(new_state)
                _, new_matches = self.evaluate(new_state)
                reason = self._refusal(matches, new_matches, best.effects)
                if reason is None:
                    accepted = best
                    break
                rejected.append({"step": index, "effect": best.effects[-1],
                                 "values": _values_dict(new_state, best.effects),
                                 "reason": reason})
                self.progress(f"step {index}: {best.described()} refused: {reason}")
                self._restore_anchor(previous)
            if accepted is None:
                steps.append(Step(index, "none", (), {}, scores[0],
                                  gap(matches.values()), gap(matches.values()),
                                  sum(deviance.values()), sum(deviance.values()), [],
                                  candidates=scores))
                break
            best = accepted
            rivals = [s for s in scores if s is not best and math.isfinite(s.delta_cv)
                      and s.delta_cv > 0 and self._indistinguishable(best, s)]
            new_deviance = self.deviances(new_matches)
            evidence = describe_evidence(matches, new_matches, self.meta)
            action = "ambiguous" if rivals else "added"
            step = Step(index, action, best.effects, _values_dict(new_state, best.effects),
                        best, gap(matches.values()), gap(new_matches.values()),
                        sum(deviance.values()), sum(new_deviance.values()), evidence,
                        ambiguous_with=tuple(r.effects[-1] for r in rivals), candidates=scores)
            if rivals:
                group = [best.effects[-1]] + [r.effects[-1] for r in rivals]
                ambiguous.append(group)
                step.separation = [self.separation(state, best, r) for r in rivals]
            else:
                missing.extend(e for e in best.effects if e not in missing)
            steps.append(step)
            self.progress(f"step {index}: {action} {best.described()}, ln U = "
                          f"{best.log_evidence:.1f} >= {best.threshold:.1f}")
            state, matches, deviance = new_state, new_matches, new_deviance
        predictions_after, matches_after = self.evaluate(state)
        status = {}
        added = {e for e, _ in state}
        ambiguous_ids = {e for group in ambiguous for e in group}
        base_on = [e for e, entry in CATALOGUE.items()
                   if entry.is_on(base) and (entry.engine == "reduced" or self.uses_fe)]
        replaced_by = next((e for e in added if e in MOUNTINGS), None)
        for effect_id in CATALOGUE:
            if effect_id in missing:
                status[effect_id] = "missing: added"
            elif effect_id in ambiguous_ids:
                status[effect_id] = ("ambiguous (kept provisionally)" if effect_id in added
                                     else "ambiguous")
            elif effect_id in not_tested:
                status[effect_id] = "not tested: " + not_tested[effect_id]
            elif effect_id in base_on and effect_id in MOUNTINGS and replaced_by:
                status[effect_id] = f"on in the base model: replaced by {replaced_by}"
            elif (effect_id == "modal_damping" and effect_id in base_on
                  and "viscoelastic_membrane" in added):
                status[effect_id] = "on in the base model: replaced by viscoelastic_membrane"
            elif effect_id in base_on:
                status[effect_id] = "on in the base model"
            elif effect_id not in self.measured.candidates:
                status[effect_id] = "not a candidate (measured.yaml candidates)"
            elif effect_id in tested_ever:
                status[effect_id] = "tested: not needed"
            else:
                status[effect_id] = "not tested"
        goodness = goodness_of_fit(matches_after.values(), self.measured.noise)
        result = DiagnosisResult(
            measured=self.measured, steps=steps, final_state=state, missing_effects=missing,
            ambiguous=ambiguous, gap_before=gap(matches_before.values()),
            gap_after=gap(matches_after.values()), matches_before=matches_before,
            matches_after=matches_after, deviance_before=sum(self.deviances(
                matches_before).values()), deviance_after=sum(self.deviances(
                    matches_after).values()),
            status=status, not_tested={e: r for e, r in not_tested.items()
                                       if e not in added}, base_on=base_on,
            goodness=goodness, verdict="", cross_validated=len(self.conditions) >= 2,
            alpha=self.alpha, predictions_before=predictions_before,
            predictions_after=predictions_after, rejected=rejected,
            ring_convergence=convergence, model="fe" if self.uses_fe else "reduced",
            fe_solves=self.engine.fe.solves if self.uses_fe else 0,
            fe_seconds=self.engine.fe.seconds if self.uses_fe else 0.0)
        result.remaining_off = remaining_off(matches_after.values(), self.measured.noise)
        result.engines = self.engines_used()
        result.verdict = verdict(result)
        return result

    def engines_used(self) -> dict:
        """Which engine evaluated what (the report's "model of record" section)."""
        if not self.uses_fe:
            return {"predictions": "ring model (model: reduced)"}
        if self.direct:
            used = getattr(self.engine, "engines", {})
            return {"predictions": "FE directly (no ring surrogate: the device has no "
                                   "central disc)",
                    "states": {" + ".join(k) or "base": sorted(v) for k, v in used.items()},
                    "fitted_grid": f"{DIRECT_GRID} FE solves per condition and parameter"}
        return {"predictions": "ring surrogate anchored to the FE (A1)",
                "fe_switches": "air_loading, baffle, frame_reflection, open_air: FE solves "
                               "(axisymmetric engine for frames none/baffle/circle, 3-D for "
                               "the square frame)",
                "fe_damping": "viscoelastic_membrane: fitted on the ring surrogate's Prony "
                              "term, then the FE's damped eigen step at the accepted values "
                              "(frequencies and quality factors Q = 1/(2 zeta))"}

    # -- acceptance --------------------------------------------------------------------------
    def _anchor(self, state):
        """Solve the FE at ``state``'s FE parameters from now on; the previous anchor."""
        if not self.uses_fe:
            return None
        previous = dict(self.engine.anchored)
        self.engine.set_anchor(state)
        return previous

    def _restore_anchor(self, previous) -> None:
        if self.uses_fe:
            self.engine.anchored = previous

    @staticmethod
    def _refusal(matches, new_matches, effects) -> str | None:
        """Why an effect that passed the test is not accepted (None: accepted).

        Exact evaluation (the FE re-solved at the fitted FE parameters): accepted only
        when the model can be evaluated everywhere and both the headline gap and the
        in-sample deviance fall -- an accepted step never makes the model worse.  (An
        effect on the quality factors alone, modal_damping, cannot move the gap -- a
        frequency error -- so there the gap must only not rise.)
        """
        if any(m is None for m in new_matches.values()):
            bad = [n for n, m in new_matches.items() if m is None]
            return f"the fitted model cannot be evaluated at {', '.join(bad)}"
        before, after = gap(matches.values()), gap(new_matches.values())
        widths_only = all(CATALOGUE[e].needs == "quality_factors" for e in effects)
        if after > before or (after == before and not widths_only):
            return f"the gap does not fall ({100 * before:.2f} % -> {100 * after:.2f} %)"
        old = sum(m.deviance for m in matches.values())
        new = sum(m.deviance for m in new_matches.values())
        if not new < old:
            return f"the deviance does not fall ({old:.1f} -> {new:.1f})"
        return None

    def ring_convergence(self) -> dict:
        """The ring surrogate against the FE at the base point (FE model of record only).

        The anchor (A1 of :mod:`copdea_fem.diagnosis.anchored`) removes the ring model's
        discretisation error at the anchor, but a surrogate far from the FE also moves
        its modes differently with the parameters; it is flagged when its largest error
        on an axisymmetric mode in a band exceeds the data's scatter sigma_f, with the
        ring count (doubling, up to :data:`MAX_RINGS`) that brings it below sigma_f / 2.
        """
        sigma = self.measured.noise.frequency_relative
        rings = self.measured.base_study["reduced"]["rings"]

        def worst(ring_count):
            out = (0.0, "", "")
            for c in self.conditions:
                study = self.engine.condition_study(c)
                study = ring_only_off(study.replace(CATALOGUE["air_loading"].off(study)))
                fe = self.engine.fe.modes(study, f_max=BAND_MARGIN * c.band[1]).frequencies()
                if ring_count != rings:
                    study = study.replace({"reduced.rings": ring_count})
                try:
                    modes = self.engine.ring_predict_study(study, c).modes
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

    def _indistinguishable(self, best: CandidateScore, other: CandidateScore) -> bool:
        if len(self.conditions) >= 2:
            terms = [sum(other.in_sample[n] - d for n, d in order.items()) / 2
                     for order in best.prequential]
            return _log_mean_exp(terms) < math.log(1 / self.alpha)
        return (other.deviance - best.deviance) / 2 < 0.5 * scipy.stats.chi2.ppf(
            1 - self.alpha, 1)

    # -- what would separate two explanations -----------------------------------------------
    def separation(self, state, first: CandidateScore, second: CandidateScore) -> dict:
        """The probe operating point where the two fitted models differ most.

        Probes: V_b in {0, 1, 2, 3} kV x z in the data's z values and {0, 11, 16, 18} mm,
        at the first condition's geometry, on the ring model (no FE solve per probe).  A probe's separation is
        ``sqrt(sum_modes (ln(f_first / f_second) / sigma_f)^2)`` over the expected modes in
        the band (what one measurement there would add to the deviance difference); the
        mode that differs most is named.
        """
        if self.direct:
            return self._mode_separation(first, second)
        sigma = self.measured.noise.frequency_relative
        template = self.conditions[0]
        z_values = sorted({round(m["z"], 6) for m in self.meta.values()}
                          | {0.0, 0.011, 0.016, 0.018})
        best = None
        for voltage in (0.0, 1000.0, 2000.0, 3000.0):
            for z in z_values:
                probe = _probe(template, {**template.overrides, "load.z": z,
                                          "load.voltage": voltage})
                a = safe_predict(self.engine, probe, first.state, ring_only=True)
                b = safe_predict(self.engine, probe, second.state, ring_only=True)
                if a is None or b is None:
                    continue
                distances = []
                for mode in a.modes:
                    other = b.mode(mode.label)
                    if other is None or not (mode.expected and template.band[0]
                                             <= mode.frequency_hz <= template.band[1]):
                        continue
                    distances.append((abs(math.log(mode.frequency_hz / other.frequency_hz))
                                      / sigma, mode, other))
                if not distances:
                    continue
                combined = math.sqrt(sum(d * d for d, _, _ in distances))
                if best is None or combined > best["sigma"]:
                    _, mode, other = max(distances, key=lambda item: item[0])
                    best = {"voltage": voltage, "z": z, "label": mode.label,
                            "first": first.effects[-1], "second": second.effects[-1],
                            "first_hz": mode.frequency_hz, "second_hz": other.frequency_hz,
                            "sigma": combined}
        if best is None:
            best = {"first": first.effects[-1], "second": second.effects[-1], "sigma": 0.0}
        best["in_vacuo"] = _in_vacuo_separates(first, second)
        return best

    def _mode_separation(self, first: CandidateScore, second: CandidateScore) -> dict:
        """The mode where the two fitted models differ most at the data's conditions, both
        evaluated by the FE (the direct engine: no operating point to vary on a device
        without a disc and voltage); a mode seen in few conditions, or one the data lack,
        measured more carefully separates them."""
        sigma = self.measured.noise.frequency_relative
        best = {"first": first.effects[-1], "second": second.effects[-1], "sigma": 0.0}
        for c in self.conditions:
            a = safe_predict(self.engine, c, first.state)
            b = safe_predict(self.engine, c, second.state)
            if a is None or b is None:
                continue
            for mode in a.modes:
                other = b.mode(mode.label)
                if other is None or not c.band[0] <= mode.frequency_hz <= c.band[1]:
                    continue
                distance = abs(math.log(mode.frequency_hz / other.frequency_hz)) / sigma
                if distance > best["sigma"]:
                    best.update({"label": mode.label, "condition": c.name, "sigma": distance,
                                 "first_hz": mode.frequency_hz,
                                 "second_hz": other.frequency_hz})
        best["in_vacuo"] = _in_vacuo_separates(first, second)
        return best


def _in_vacuo_separates(first, second) -> bool:
    """Whether a measurement in vacuo separates the two: one is an effect of the air (the
    air loading or a mounting, which act through the air only), the other not."""
    airy = {"air_loading", *MOUNTINGS}
    return (first.effects[-1] in airy) != (second.effects[-1] in airy)


def _probe(template, overrides):
    from copdea_fem.diagnosis.measured import Condition
    return Condition(name=f"probe_{overrides['load.z']:g}_{overrides['load.voltage']:g}",
                     overrides=overrides, resonances=None, spectrum=None, band=template.band)


def _values_dict(state, effects) -> dict:
    out = {}
    for effect_id, values in state:
        if effect_id in effects:
            out[effect_id] = {p.name: float(v) for p, v in
                              zip(CATALOGUE[effect_id].parameters, values)}
    return out


def _log_mean_exp(values) -> float:
    values = np.asarray(values, float)
    if values.size == 0 or np.any(np.isnan(values)):
        return -math.inf
    top = np.max(values)
    if not math.isfinite(top):
        return float(top)
    return float(top + math.log(np.mean(np.exp(values - top))))
