"""Diagnose: which catalogued effect the model lacks, with evidence (issue 5, item 4).

The loop
--------
Start from the base study.  At each step, every catalogued effect that is
off, that the reduced engine can evaluate and that the data can see is a
*candidate* (an effect whose requirement is off comes with it:
``disc_pumping + spring_mass``).  For each candidate:

1. fit its 0-2 parameters on all conditions (maximum likelihood = minimum
   deviance, :mod:`copdea_fem.diagnose.compare`), within the catalogue's
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

Speed: each candidate's per-condition mode frequencies and quality factors
are tabulated exactly on a coarse parameter grid (9 points for the effects
that need a new static solve, 17 otherwise, 9 x 9 for two parameters) and
interpolated by cubic splines in the (log) parameters (error in ln f below
1e-3, a test checks it, against sigma_f = 1-2 %); fits, folds and the
prequential scores work on the interpolated modes; the in-sample deviance of
every candidate and everything reported of the accepted model are exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.interpolate
import scipy.optimize
import scipy.stats

from copdea_fem.diagnose.compare import (ConditionMatch, DevianceTerms, MeasuredPeak, gap,
                                         match_condition, residual_summary)
from copdea_fem.diagnose.effects import CATALOGUE, Parameter
from copdea_fem.diagnose.engine import Engine, ModelMode, safe_predict
from copdea_fem.diagnose.peaks import find_spectrum_peaks, peak_height

ALPHA = 0.05
ORDERINGS = 3          # cyclic orderings averaged in the prequential evidence (fixed in advance)
EXPENSIVE = ("electrostatic_softening", "uniform_stiffness")   # need a new static solve
_INVALID = math.inf


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

    def __init__(self, measured, alpha: float = ALPHA, engine: Engine | None = None,
                 progress=None):
        self.measured = measured
        self.alpha = alpha
        self.engine = engine or Engine(measured)
        self.conditions = measured.conditions
        self.peaks = {c.name: condition_peaks(c) for c in self.conditions}
        self.progress = progress or (lambda message: None)
        self._terms: dict = {}
        self.meta = {}
        for c in self.conditions:
            study = measured.study_of(c)
            self.meta[c.name] = {"voltage": study["load"]["voltage"], "z": study["load"]["z"]}

    # -- evaluation ------------------------------------------------------------------------
    def match(self, condition, modes) -> ConditionMatch:
        terms = self._terms.get(condition.name)
        if terms is None:
            terms = self._terms[condition.name] = DevianceTerms(self.measured.noise,
                                                                condition.band)
        return match_condition(condition.name, modes, self.peaks[condition.name],
                               condition.band, self.measured.noise, terms)

    def evaluate(self, state) -> tuple[dict, dict]:
        """Exact predictions and matches of every condition ({} entries None if invalid)."""
        predictions, matches = {}, {}
        for c in self.conditions:
            prediction = safe_predict(self.engine, c, state)
            predictions[c.name] = prediction
            matches[c.name] = self.match(c, prediction.modes) if prediction else None
        return predictions, matches

    @staticmethod
    def deviances(matches) -> dict:
        return {name: (m.deviance if m is not None else _INVALID) for name, m in matches.items()}

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
            if entry.engine != "reduced":
                setting = (" (the base study's geometry.frame = "
                           f"{base_study['geometry']['frame']} acts only there)"
                           if effect_id == "frame_reflection" else "")
                skipped[effect_id] = ("needs the fully-coupled air/PML FE engine, which this "
                                      f"version does not have{setting}")
                continue
            if effect_id in on:
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

    # -- fitting -----------------------------------------------------------------------------
    def score(self, state, group, current_deviance: dict, tested: int) -> CandidateScore:
        """Fit, cross-validate and test one candidate group (module notes)."""
        parameters = [p for e in group for p in CATALOGUE[e].parameters]
        table = _Tabulation(self, state, group, parameters, nuisance=True)
        names = [c.name for c in self.conditions]
        full_u = table.fit(names)
        values = table.values(full_u)
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
        return CandidateScore(effects=tuple(group), values=tuple(values), deviance=total,
                              delta_in=delta_in, fold_delta=fold_delta, delta_cv=delta_cv,
                              log_evidence=log_evidence, threshold=threshold,
                              significant=significant, held_out=held_out,
                              state=table.state_at(full_u), prequential=prequential,
                              in_sample=dict(deviance))

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
        parameters = list(CATALOGUE[effect_id].parameters)
        if not parameters:
            return state
        rest = state[:index] + state[index + 1:]
        table = _Tabulation(self, rest, (effect_id,), parameters)
        u = table.fit([c.name for c in self.conditions])
        values = tuple(table.values(u))
        return state[:index] + ((effect_id, values),) + state[index + 1:]

    # -- the loop ----------------------------------------------------------------------------
    def run(self) -> DiagnosisResult:
        base = self.measured.base_study
        state: tuple = ()
        predictions_before, matches_before = self.evaluate(state)
        if any(m is None for m in matches_before.values()):
            bad = [n for n, m in matches_before.items() if m is None]
            from copdea_fem.study import StudyError
            raise StudyError(f"conditions {', '.join(bad)} are not allowed: the base model "
                             "cannot be evaluated there (see copdea-fem spectrum on that "
                             "condition's study); allowed: operating points the reduced model "
                             "solves")
        deviance = self.deviances(matches_before)
        matches = matches_before
        steps, missing, ambiguous = [], [], []
        not_tested: dict = {}
        tested_ever: set = set()
        for index in range(1, len(CATALOGUE) + 1):
            groups, skipped = self.candidates(state, base)
            not_tested.update(skipped)
            if not groups:
                break
            self.progress(f"step {index}: testing {', '.join(g[-1] for g in groups)}")
            scores = [self.score(state, g, deviance, len(groups)) for g in groups]
            tested_ever.update(g[-1] for g in groups)
            scores.sort(key=lambda s: -s.delta_cv if math.isfinite(s.delta_cv) else math.inf)
            passing = [s for s in scores if s.significant]
            if not passing:
                steps.append(Step(index, "none", (), {}, scores[0],
                                  gap(matches.values()), gap(matches.values()),
                                  sum(deviance.values()), sum(deviance.values()), [],
                                  candidates=scores))
                break
            best = passing[0]
            rivals = [s for s in scores if s is not best and math.isfinite(s.delta_cv)
                      and s.delta_cv > 0 and self._indistinguishable(best, s)]
            new_state = best.state
            for position in range(len(state)):
                new_state = self.refit(new_state, position)
            _, new_matches = self.evaluate(new_state)
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
                   if entry.is_on(base) and entry.engine == "reduced"]
        for effect_id in CATALOGUE:
            if effect_id in missing:
                status[effect_id] = "missing: added"
            elif effect_id in ambiguous_ids:
                status[effect_id] = ("ambiguous (kept provisionally)" if effect_id in added
                                     else "ambiguous")
            elif effect_id in not_tested:
                status[effect_id] = "not tested: " + not_tested[effect_id]
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
            predictions_after=predictions_after)
        result.verdict = verdict(result)
        return result

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
        at the first condition's geometry.  A probe's separation is
        ``sqrt(sum_modes (ln(f_first / f_second) / sigma_f)^2)`` over the expected modes in
        the band (what one measurement there would add to the deviance difference); the
        mode that differs most is named.
        """
        sigma = self.measured.noise.frequency_relative
        template = self.conditions[0]
        z_values = sorted({round(m["z"], 6) for m in self.meta.values()}
                          | {0.0, 0.011, 0.016, 0.018})
        best = None
        for voltage in (0.0, 1000.0, 2000.0, 3000.0):
            for z in z_values:
                probe = _probe(template, {**template.overrides, "load.z": z,
                                          "load.voltage": voltage})
                a = safe_predict(self.engine, probe, first.state)
                b = safe_predict(self.engine, probe, second.state)
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
            return {"first": first.effects[-1], "second": second.effects[-1], "sigma": 0.0}
        return best


def _probe(template, overrides):
    from copdea_fem.diagnose.measured import Condition
    return Condition(name=f"probe_{overrides['load.z']:g}_{overrides['load.voltage']:g}",
                     overrides=overrides, resonances=None, spectrum=None, band=template.band)


def _extend(state, group, values) -> tuple:
    out, offset = list(state), 0
    for effect_id in group:
        count = len(CATALOGUE[effect_id].parameters)
        out.append((effect_id, tuple(float(v) for v in values[offset:offset + count])))
        offset += count
    return tuple(out)


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


class _Tabulation:
    """Per-condition modes of a candidate on a coarse parameter grid, interpolated anywhere.

    Parameters are mapped to u in [0, 1] (log or linear between the bounds).
    """

    def __init__(self, diagnoser: Diagnoser, state, group, parameters: list[Parameter],
                 nuisance: bool = False):
        self.d = diagnoser
        self.state, self.group, self.parameters = state, tuple(group), parameters
        self.k = len(parameters)
        expensive = any(e in EXPENSIVE for e in group)
        count = (9 if expensive else 17) if self.k == 1 else 9
        self.axes = [np.linspace(0, 1, count) for _ in range(self.k)]
        self.default_u = np.array([self._to_u(p, p.default) for p in parameters])
        self.cache: dict = {}
        self.splines: dict = {}
        # nuisance: the fitted parameters of the effects already in the state
        self.nuisance = [(i, j, p) for i, (e, values) in enumerate(state) if nuisance
                         for j, p in enumerate(CATALOGUE[e].parameters)]
        self.nuisance_u0 = np.array([self._to_u(p, state[i][1][j])
                                     for i, j, p in self.nuisance])
        self.jacobian: dict = {}
        if self.k:
            self._tabulate()
        if self.nuisance:
            self._linearise()

    @property
    def dimension(self) -> int:
        return self.k + len(self.nuisance)

    def state_at(self, u) -> tuple:
        """The full effect state at a point (candidate + nuisance parameters)."""
        u = np.atleast_1d(np.asarray(u, float))
        state = [list(entry) for entry in self.state]
        for (i, j, p), x in zip(self.nuisance, u[self.k:]):
            values = list(state[i][1])
            values[j] = self._from_u(p, x)
            state[i][1] = tuple(values)
        base = tuple((e, tuple(v)) for e, v in state)
        return _extend(base, self.group, self.values(u[:self.k]))

    def _linearise(self):
        """d ln f / d u_nuisance of every mode at the candidate's default, per condition."""
        u0 = np.concatenate([self.default_u, self.nuisance_u0])
        step = 0.02
        for c in self.d.conditions:
            centre = safe_predict(self.d.engine, c, self.state_at(u0))
            rows = []
            for n in range(len(self.nuisance)):
                u = u0.copy()
                u[self.k + n] += step if u[self.k + n] + step <= 1 else -step
                shifted = safe_predict(self.d.engine, c, self.state_at(u))
                if centre is None or shifted is None or [m.label for m in centre.modes] != [
                        m.label for m in shifted.modes]:
                    rows = None
                    break
                rows.append([(math.log(b.frequency_hz / a.frequency_hz)) / (u[self.k + n]
                                                                          - u0[self.k + n])
                             for a, b in zip(centre.modes, shifted.modes)])
            self.jacobian[c.name] = (
                {m.label: np.array([row[q] for row in rows]) for q, m in
                 enumerate(centre.modes)} if rows is not None else None)

    # parameter <-> u
    @staticmethod
    def _to_u(p: Parameter, value: float) -> float:
        if p.log:
            return math.log(value / p.lower) / math.log(p.upper / p.lower)
        return (value - p.lower) / (p.upper - p.lower)

    @staticmethod
    def _from_u(p: Parameter, x: float) -> float:
        x = float(np.clip(x, 0, 1))
        return p.lower * (p.upper / p.lower) ** x if p.log else p.lower + x * (p.upper - p.lower)

    def values(self, u) -> list:
        """Candidate parameter values (SI) at a point."""
        return [self._from_u(p, x) for p, x in zip(self.parameters, np.atleast_1d(u))]

    def _tabulate(self):
        grid = np.array(np.meshgrid(*self.axes, indexing="ij")).reshape(self.k, -1).T
        shape = tuple(a.size for a in self.axes)
        for c in self.d.conditions:
            predictions = [safe_predict(self.d.engine, c, _extend(self.state, self.group,
                                                                  self.values(u)))
                           for u in grid]
            valid = [p for p in predictions if p is not None]
            if not valid:
                self.splines[c.name] = None
                continue
            template = valid[len(valid) // 2].modes
            labels = [m.label for m in template]
            ok = np.array([p is not None and [m.label for m in p.modes] == labels
                           for p in predictions])
            freq = np.full((grid.shape[0], len(labels)), np.nan)
            quality = np.full_like(freq, np.nan)
            for g, p in enumerate(predictions):
                if ok[g]:
                    freq[g] = [math.log(m.frequency_hz) for m in p.modes]
                    quality[g] = [math.log(m.quality_factor) if 0 < m.quality_factor < math.inf
                                  else np.nan for m in p.modes]
            self.splines[c.name] = _ModeInterpolator(self.axes, shape, ok, freq, quality,
                                                     template)

    def modes_at(self, name, u):
        u = np.atleast_1d(np.asarray(u, float))
        if self.k:
            spline = self.splines.get(name)
            if spline is None:
                return None
            modes = spline(u[:self.k])
        else:
            modes = self._fixed_modes(name)
        if modes is None or not self.nuisance:
            return modes
        jacobian = self.jacobian.get(name)
        if jacobian is None or u.size == self.k:
            return modes
        shift = u[self.k:] - self.nuisance_u0
        out = []
        for m in modes:
            row = jacobian.get(m.label)
            factor = math.exp(float(row @ shift)) if row is not None else 1.0
            out.append(ModelMode(m.label, m.kind, m.frequency_hz * factor, m.quality_factor,
                                 m.radial_ratio, m.expected))
        return out

    def _fixed_modes(self, name):
        if not hasattr(self, "_fixed"):
            self._fixed = {}
            for c in self.d.conditions:
                p = safe_predict(self.d.engine, c, _extend(self.state, self.group, []))
                self._fixed[c.name] = list(p.modes) if p is not None else None
        return self._fixed.get(name)

    def deviance(self, names, u) -> float:
        """Deviance of the named conditions at u (candidate [+ nuisance] parameters)."""
        total = 0.0
        for c in self.d.conditions:
            if c.name not in names:
                continue
            modes = self.modes_at(c.name, u)
            if modes is None:
                return _INVALID
            total += self.d.match(c, modes).deviance
        return total

    def profile(self, names, candidate_u) -> tuple[float, np.ndarray]:
        """Deviance with the nuisance parameters profiled out, and the full u.

        ln f is linear in the nuisance parameters (:meth:`_linearise`), so for the
        pairs within the strict gate (the Gaussian branch of the deviance) their best
        shift is a least-squares solution; two Gauss-Newton passes with re-matching,
        kept only where they lower the deviance.
        """
        candidate_u = np.atleast_1d(np.asarray(candidate_u, float))[:self.k]
        best_u = np.concatenate([candidate_u, self.nuisance_u0])
        best = self.deviance(names, best_u)
        if not self.nuisance or not math.isfinite(best):
            return best, best_u
        u = best_u.copy()
        for _ in range(2):
            rows, residuals = [], []
            for c in self.d.conditions:
                if c.name not in names or self.jacobian.get(c.name) is None:
                    continue
                modes = self.modes_at(c.name, u)
                match = self.d.match(c, modes)
                limit = self.d._terms[c.name].strict_gate()
                for pair in match.pairs:
                    row = self.jacobian[c.name].get(pair.model.label)
                    if row is not None and abs(pair.log_error) <= limit:
                        rows.append(row)
                        residuals.append(pair.log_error)
            if len(rows) < len(self.nuisance):
                break
            step = np.linalg.lstsq(np.array(rows), np.array(residuals), rcond=None)[0]
            u = u.copy()
            u[self.k:] = np.clip(u[self.k:] + step, 0, 1)
            value = self.deviance(names, u)
            if value < best:
                best, best_u = value, u.copy()
            else:
                break
        return best, best_u

    def start(self) -> np.ndarray:
        """The physical defaults of the candidate, the current nuisance values (u)."""
        return np.concatenate([self.default_u, self.nuisance_u0])

    def check_interpolation(self, name) -> float:
        """Largest |ln f| error of the interpolation against exact predictions, at the
        midpoints of the coarse grid (for tests)."""
        condition = next(c for c in self.d.conditions if c.name == name)
        worst = 0.0
        if self.k != 1:
            return worst
        axis = self.axes[0]
        for x in 0.5 * (axis[1:] + axis[:-1]):
            u = np.concatenate([[x], self.nuisance_u0])
            exact = safe_predict(self.d.engine, condition, self.state_at(u))
            modes = self.modes_at(name, u)
            if exact is None or modes is None:
                continue
            for a, b in zip(exact.modes, modes):
                worst = max(worst, abs(math.log(a.frequency_hz / b.frequency_hz)))
        return worst

    def fit(self, names) -> np.ndarray:
        """u minimising the interpolated deviance of the named conditions (candidate
        parameters, then the nuisance ones)."""
        key = tuple(sorted(names))
        if key in self.cache:
            return self.cache[key]
        if not self.k:
            _, u = self.profile(names, [])
            self.cache[key] = u
            return u
        fine = 61 if self.k == 1 else 13
        axes = [np.linspace(0, 1, fine) for _ in range(self.k)]
        points = np.array(np.meshgrid(*axes, indexing="ij")).reshape(self.k, -1).T
        per_condition = self._fine_table(points)
        total = sum(per_condition[n] for n in names)
        start = points[int(np.argmin(total))]
        objective = lambda x: min(self.profile(names, np.clip(x, 0, 1))[0], 1e12)  # noqa
        step = 1.0 / (fine - 1)
        reach = 3 * step if self.nuisance else step   # the nuisance can move the optimum
        if self.k == 1:
            low, high = max(0.0, start[0] - reach), min(1.0, start[0] + reach)
            found = scipy.optimize.minimize_scalar(lambda x: objective([x]), bounds=(low, high),
                                                   method="bounded",
                                                   options={"xatol": 1e-4})
            best = np.array([found.x]) if found.fun <= objective(start) else start
        else:   # two parameters: simplex with the nuisance held, profiled at the end
            held = lambda x: min(self.deviance(names, np.clip(x, 0, 1)), 1e12)  # noqa: E731
            simplex = np.array([start, start + [step, 0], start + [0, step]])
            found = scipy.optimize.minimize(held, start, method="Nelder-Mead",
                                            options={"initial_simplex": simplex,
                                                     "xatol": 1e-3, "fatol": 1e-2,
                                                     "maxfev": 60})
            best = np.clip(found.x, 0, 1) if found.fun <= held(start) else start
        _, u = self.profile(names, best)
        self.cache[key] = u
        return u

    def _fine_table(self, points) -> dict:
        if hasattr(self, "_fine"):
            return self._fine
        table = {}
        for c in self.d.conditions:
            table[c.name] = np.array([self.deviance([c.name], u) for u in points])
        self._fine = table
        return table


class _ModeInterpolator:
    """Cubic interpolation of ln f and ln Q of every mode over the coarse grid (one spline
    object for all modes; a Q that is not finite everywhere keeps its template value)."""

    def __init__(self, axes, shape, ok, freq, quality, template):
        self.template = template
        self.k = len(axes)
        self.has_q = np.all(np.isfinite(quality[ok]), axis=0) if np.any(ok) else \
            np.zeros(freq.shape[1], bool)
        quality = np.where(self.has_q, quality, 0.0)
        values = np.concatenate([freq, quality], axis=1)
        self.low, self.high, self.spline = 1.0, 0.0, None
        if self.k == 1:
            x = axes[0][ok]
            if x.size >= 2:
                self.low, self.high = x.min(), x.max()
                self.spline = (scipy.interpolate.CubicSpline(x, values[ok], axis=0)
                               if x.size >= 4 else scipy.interpolate.interp1d(
                                   x, values[ok], axis=0))
        elif np.all(ok):
            self.low, self.high = 0.0, 1.0
            self.spline = [scipy.interpolate.RectBivariateSpline(*axes,
                                                                 values[:, j].reshape(shape))
                           for j in range(values.shape[1])]

    def __call__(self, u):
        if self.spline is None or not all(self.low - 1e-12 <= x <= self.high + 1e-12
                                          for x in u[:self.k]):
            return None
        if self.k == 1:
            values = np.asarray(self.spline(u[0]))
        else:
            values = np.array([s(u[0], u[1])[0, 0] for s in self.spline])
        count = len(self.template)
        out = []
        for j, mode in enumerate(self.template):
            ln_f, ln_q = values[j], values[count + j]
            if not math.isfinite(ln_f):
                return None
            quality = math.exp(ln_q) if self.has_q[j] else mode.quality_factor
            out.append(ModelMode(mode.label, mode.kind, math.exp(ln_f), quality,
                                 mode.radial_ratio, mode.expected))
        return out


# -- evidence, goodness of fit, verdict ---------------------------------------------------------
def describe_evidence(before, after, meta) -> list[str]:
    """Which residual patterns a step removed, largest first (sentences)."""
    b, a = residual_summary(before.values(), meta), residual_summary(after.values(), meta)
    items = []
    change = b["unexplained_pumping"] - a["unexplained_pumping"]
    if change > 0:
        items.append((10 + change, f"{change} unexplained pistonic peak(s) now explained "
                                   f"({b['unexplained_pumping']} -> {a['unexplained_pumping']})"))
    change = b["unexplained"] + b["unseen"] - a["unexplained"] - a["unseen"]
    if change > 0:
        items.append((5 + change, f"unexplained peaks + unseen modes {b['unexplained']} + "
                                  f"{b['unseen']} -> {a['unexplained']} + {a['unseen']}"))
    for label, error in b["mean_error_by_label"].items():
        new = a["mean_error_by_label"].get(label)
        if new is not None and abs(error) - abs(new) > 0.005:
            items.append((100 * (abs(error) - abs(new)),
                          f"{label}: mean frequency error {100 * error:+.1f} % -> "
                          f"{100 * new:+.1f} %"))
    for key, text in (("span_vs_log_frequency", "frequency"),
                      ("span_vs_voltage_squared", "V_b^2"), ("span_vs_z", "z")):
        old, new = -b[key], -a[key]          # model error (f_model/f_meas) across the range
        if abs(old) - abs(new) > 0.005 and abs(old) > 2 * abs(new):
            items.append((100 * (abs(old) - abs(new)),
                          f"model error changing with {text} (across the data's range): "
                          f"{100 * old:+.1f} % -> {100 * new:+.1f} %"))
    old, new = b["median_log_quality_ratio"], a["median_log_quality_ratio"]
    if math.isfinite(new) and (not math.isfinite(old) or abs(old) - abs(new) > 0.2):
        shown = "infinite" if not math.isfinite(old) else f"{math.exp(-old):.3g}"
        items.append((20, f"model/measured quality factor (median) {shown} -> "
                          f"{math.exp(-new):.3g}"))
    items.sort(key=lambda item: -item[0])
    return [text for _, text in items]


def goodness_of_fit(matches, noise) -> dict:
    """Chi-square of the paired ln-frequency residuals against the stated sigma_f.

    ``p_value`` small: the remaining scatter exceeds the noise model (a cause outside the
    catalogue, or sigma_f set too small).  Pairs beyond 4 sigma_f count as outliers.
    """
    sigma = noise.frequency_relative
    errors = np.array([p.log_error for m in matches if m is not None for p in m.pairs])
    inliers = errors[np.abs(errors) <= 4 * sigma]
    chi2 = float(np.sum((inliers / sigma) ** 2))
    count = int(inliers.size)
    p_value = float(scipy.stats.chi2.sf(chi2, count)) if count else math.nan
    rms = float(np.sqrt(np.mean(inliers ** 2))) if count else math.nan
    return {"pairs": int(errors.size), "inliers": count, "outliers": int(errors.size - count),
            "chi2": chi2, "p_value": p_value, "rms_log_error": rms, "sigma": sigma}


def verdict(result: DiagnosisResult) -> str:
    parts = []
    if result.missing_effects:
        parts.append("Missing: " + ", ".join(result.missing_effects)
                     + f" (in order of importance); gap {100 * result.gap_before:.1f} % -> "
                     f"{100 * result.gap_after:.1f} %.")
    for group in result.ambiguous:
        parts.append("The data cannot tell " + " from ".join(group) + " apart (see the "
                     "separating measurement).")
    if not result.missing_effects and not result.ambiguous:
        parts.append(f"Nothing is missing: no catalogued effect improves the model "
                     f"significantly (alpha = {result.alpha:g}); gap "
                     f"{100 * result.gap_before:.1f} %.")
    g = result.goodness
    if g["inliers"] and g["p_value"] < 0.01:
        parts.append(f"The remaining frequency scatter ({100 * g['rms_log_error']:.2f} % rms) "
                     f"exceeds the stated noise ({100 * g['sigma']:.2f} %): a cause outside the "
                     "catalogue, or noise.frequency_relative set too small.")
    if result.not_tested:
        parts.append("Not tested: " + ", ".join(result.not_tested) + ".")
    return " ".join(parts)
