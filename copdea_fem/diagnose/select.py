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
3. score: the cross-validated improvement ``Delta_cv = sum_f Delta_f``
   (ranks the candidates; leave-one-out CV charges every fitted parameter
   what it costs in prediction -- asymptotically 2 per parameter, Stone
   1977 -- so no separate penalty is added), and the evidence
   ``U = mean_f exp(Delta_f / 2)``.

Significance (derived, not tuned).  U is the cross-fit split likelihood ratio
of universal inference (Wasserman, Ramdas & Balakrishnan, PNAS 117, 2020):
every factor compares likelihoods on data its parameters were not fitted
on, so under "the candidate is not better" E[U] <= 1 and Markov's inequality
gives P(U >= 1/alpha) <= alpha, for any model, any number of parameters,
with no asymptotics.  With N candidates tested at a step (Bonferroni) the
best one is accepted when

    ln U >= ln(N / alpha)  and  Delta_cv > 0,        alpha = 0.05,

so a step raises a false alarm with probability at most 5 %.  With a
single condition there is nothing to hold out: the in-sample likelihood
ratio is used with Wilks' threshold ``chi2_k^-1(1 - alpha/N)`` (k >= 1) or
``2 ln(N/alpha)`` (k = 0, simple hypotheses, Markov again), and the report
says so.

Ambiguity.  Another significant candidate B is indistinguishable from the
best A when the same test cannot tell them apart:
``ln mean_f exp((D_B(f) - D_A(f)) / 2) < ln(1/alpha)``.  Then the group is
reported, no member is named missing, the best is kept *provisionally* so
that the search can go on, and the report proposes the measurement that
separates them: the operating point (V_b, z of the data's geometry) where
the two fitted models differ most in units of sigma_f.

After each accepted step the parameters of the effects added before are
re-fitted one effect at a time with the others fixed (one coordinate pass).
The loop stops when no candidate passes.  (Approximation: the earlier
effects' parameters are not re-fitted inside each fold; this makes the
current model look slightly better than it would out of sample, i.e. the
test slightly conservative.)

Speed: each candidate's per-condition mode frequencies and quality factors
are tabulated exactly on a coarse parameter grid (9 points for the effects
that need a new static solve, 17 otherwise, 9 x 9 for two parameters) and
interpolated by cubic splines in the (log) parameters; fits and folds work
on the interpolated modes, and every reported deviance is recomputed
exactly at the fitted values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.interpolate
import scipy.optimize
import scipy.stats

from copdea_fem.diagnose.compare import (ConditionMatch, MeasuredPeak, gap, match_condition,
                                         residual_summary)
from copdea_fem.diagnose.effects import CATALOGUE, Parameter
from copdea_fem.diagnose.engine import Engine, ModelMode, safe_predict
from copdea_fem.diagnose.peaks import find_spectrum_peaks, peak_height

ALPHA = 0.05
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
        ln U (module notes); with one condition, Delta_in / 2.
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
        self.meta = {}
        for c in self.conditions:
            study = measured.study_of(c)
            self.meta[c.name] = {"voltage": study["load"]["voltage"], "z": study["load"]["z"]}

    # -- evaluation ------------------------------------------------------------------------
    def match(self, condition, modes) -> ConditionMatch:
        return match_condition(condition.name, modes, self.peaks[condition.name],
                               condition.band, self.measured.noise)

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
            if effect_id in on:
                continue
            if entry.engine != "reduced":
                skipped[effect_id] = ("needs the fully-coupled air/PML FE engine, which this "
                                      "version does not have: not tested")
                continue
            if entry.needs == "quality_factors" and not has_quality:
                skipped[effect_id] = ("needs quality factors (a quality_factor column or "
                                      "spectra with resolved peaks): not tested")
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
        table = _Tabulation(self, state, group, parameters)
        names = [c.name for c in self.conditions]
        full_u = table.fit(names)
        values = table.values(full_u)
        _, matches = self.evaluate(_extend(state, group, values))
        deviance = self.deviances(matches)
        total = sum(deviance.values())
        current_total = sum(current_deviance.values())
        delta_in = current_total - total
        k = len(parameters)
        if len(names) >= 2:
            held_out, fold_delta = {}, {}
            for name in names:
                train = [n for n in names if n != name]
                u = table.fit(train) if k else full_u
                condition = next(c for c in self.conditions if c.name == name)
                prediction = safe_predict(self.engine, condition,
                                          _extend(state, group, table.values(u)))
                held = (self.match(condition, prediction.modes).deviance
                        if prediction else _INVALID)
                held_out[name] = held
                fold_delta[name] = current_deviance[name] - held
            delta_cv = sum(fold_delta.values())
            log_evidence = _log_mean_exp([d / 2 for d in fold_delta.values()])
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
                              significant=significant, held_out=held_out)

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
            rivals = [s for s in passing[1:] if self._indistinguishable(best, s)]
            new_state = _extend(state, best.effects, best.values)
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
        base_on = [e for e, entry in CATALOGUE.items() if entry.is_on(base)]
        for effect_id in CATALOGUE:
            if effect_id in missing:
                status[effect_id] = "missing: added"
            elif effect_id in ambiguous_ids:
                status[effect_id] = ("ambiguous (kept provisionally)" if effect_id in added
                                     else "ambiguous")
            elif effect_id in base_on:
                status[effect_id] = "on in the base model"
            elif effect_id in not_tested:
                status[effect_id] = "not tested: " + not_tested[effect_id]
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
            terms = [(other.held_out[n] - best.held_out[n]) / 2 for n in best.held_out]
            return _log_mean_exp(terms) < math.log(1 / self.alpha)
        return (other.deviance - best.deviance) / 2 < 0.5 * scipy.stats.chi2.ppf(
            1 - self.alpha, 1)

    # -- what would separate two explanations -----------------------------------------------
    def separation(self, state, first: CandidateScore, second: CandidateScore) -> dict:
        """The probe operating point where the two fitted models differ most (in sigma_f).

        Probes: V_b in {0, 1, 2, 3} kV x z in the data's z values and {0, 11, 16, 18} mm,
        at the first condition's geometry, every mode the models share.
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
                a = safe_predict(self.engine, probe, _extend(state, first.effects, first.values))
                b = safe_predict(self.engine, probe,
                                 _extend(state, second.effects, second.values))
                if a is None or b is None:
                    continue
                for mode in a.modes:
                    other = b.mode(mode.label)
                    if other is None or not (mode.expected and template.band[0]
                                             <= mode.frequency_hz <= template.band[1]):
                        continue
                    distance = abs(math.log(mode.frequency_hz / other.frequency_hz)) / sigma
                    if best is None or distance > best["sigma"]:
                        best = {"voltage": voltage, "z": z, "label": mode.label,
                                "first": first.effects[-1], "second": second.effects[-1],
                                "first_hz": mode.frequency_hz, "second_hz": other.frequency_hz,
                                "sigma": distance}
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

    def __init__(self, diagnoser: Diagnoser, state, group, parameters: list[Parameter]):
        self.d = diagnoser
        self.state, self.group, self.parameters = state, tuple(group), parameters
        self.k = len(parameters)
        expensive = any(e in EXPENSIVE for e in group)
        count = (9 if expensive else 17) if self.k == 1 else 9
        self.axes = [np.linspace(0, 1, count) for _ in range(self.k)]
        self.default_u = np.array([self._to_u(p, p.default) for p in parameters])
        self.cache: dict = {}
        self.splines: dict = {}
        if self.k:
            self._tabulate()

    # parameter <-> u
    @staticmethod
    def _to_u(p: Parameter, value: float) -> float:
        if p.log:
            return math.log(value / p.lower) / math.log(p.upper / p.lower)
        return (value - p.lower) / (p.upper - p.lower)

    def values(self, u) -> list:
        out = []
        for p, x in zip(self.parameters, np.atleast_1d(u)):
            x = float(np.clip(x, 0, 1))
            out.append(p.lower * (p.upper / p.lower) ** x if p.log
                       else p.lower + x * (p.upper - p.lower))
        return out

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
        spline = self.splines.get(name)
        if spline is None:
            return None
        return spline(np.atleast_1d(u))

    def deviance(self, names, u) -> float:
        total = 0.0
        for c in self.d.conditions:
            if c.name not in names:
                continue
            modes = self.modes_at(c.name, u)
            if modes is None:
                return _INVALID
            total += self.d.match(c, modes).deviance
        return total

    def fit(self, names) -> np.ndarray:
        """u minimising the interpolated deviance of the named conditions."""
        if not self.k:
            return np.zeros(0)
        key = tuple(sorted(names))
        if key in self.cache:
            return self.cache[key]
        fine = 121 if self.k == 1 else 25
        axes = [np.linspace(0, 1, fine) for _ in range(self.k)]
        points = np.array(np.meshgrid(*axes, indexing="ij")).reshape(self.k, -1).T
        per_condition = self._fine_table(points)
        total = sum(per_condition[n] for n in names)
        start = points[int(np.argmin(total))]
        objective = lambda u: self.deviance(names, np.clip(u, 0, 1))  # noqa: E731
        step = 1.0 / (fine - 1)
        if self.k == 1:
            low, high = max(0.0, start[0] - step), min(1.0, start[0] + step)
            found = scipy.optimize.minimize_scalar(lambda x: objective([x]), bounds=(low, high),
                                                   method="bounded",
                                                   options={"xatol": 1e-4})
            u = np.array([found.x]) if found.fun <= objective(start) else start
        else:
            simplex = np.array([start, start + [step, 0], start + [0, step]])
            found = scipy.optimize.minimize(objective, start, method="Nelder-Mead",
                                            options={"initial_simplex": simplex,
                                                     "xatol": 1e-4, "fatol": 1e-6,
                                                     "maxfev": 120})
            u = np.clip(found.x, 0, 1) if found.fun <= objective(start) else start
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
    """Cubic interpolation of ln f and ln Q of every mode over the coarse grid."""

    def __init__(self, axes, shape, ok, freq, quality, template):
        self.template = template
        self.axes = axes
        self.k = len(axes)
        if self.k == 1:
            x = axes[0][ok]
            self.low, self.high = (x.min(), x.max()) if x.size else (1.0, 0.0)
            self.f = [_spline1(x, freq[ok, j]) for j in range(freq.shape[1])]
            self.q = [_spline1(x, quality[ok, j]) for j in range(freq.shape[1])]
        else:
            self.complete = bool(np.all(ok))
            self.f = [scipy.interpolate.RectBivariateSpline(*axes, freq[:, j].reshape(shape))
                      if self.complete else None for j in range(freq.shape[1])]
            finite_q = np.all(np.isfinite(quality), axis=0)
            self.q = [scipy.interpolate.RectBivariateSpline(*axes, quality[:, j].reshape(shape))
                      if self.complete and finite_q[j] else None for j in range(freq.shape[1])]

    def __call__(self, u):
        if self.k == 1:
            if not self.low - 1e-12 <= u[0] <= self.high + 1e-12:
                return None
            f = [float(s(u[0])) if s else math.nan for s in self.f]
            q = [float(s(u[0])) if s else math.nan for s in self.q]
        else:
            if not self.complete:
                return None
            f = [float(s(u[0], u[1])[0, 0]) for s in self.f]
            q = [float(s(u[0], u[1])[0, 0]) if s else math.nan for s in self.q]
        out = []
        for mode, ln_f, ln_q in zip(self.template, f, q):
            if not math.isfinite(ln_f):
                return None
            quality = math.exp(ln_q) if math.isfinite(ln_q) else mode.quality_factor
            out.append(ModelMode(mode.label, mode.kind, math.exp(ln_f), quality,
                                 mode.radial_ratio, mode.expected))
        return out


def _spline1(x, y):
    finite = np.isfinite(y)
    if finite.sum() < 2:
        return None
    x, y = x[finite], y[finite]
    if x.size >= 4:
        return scipy.interpolate.CubicSpline(x, y)
    return lambda t: np.interp(t, x, y)


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
    for key, text, unit, scale in (
            ("slope_vs_log_frequency", "error growing with frequency (d ln(f_meas/f_model) / "
             "d ln f)", "", 1.0),
            ("slope_vs_voltage_squared", "error growing with V_b^2", " per kV^2", 1e6),
            ("slope_vs_z", "error growing with z", " per mm", 1e-3)):
        old, new = b[key] * scale, a[key] * scale
        if abs(old) - abs(new) > 0.004 and abs(old) > 2 * abs(new):
            items.append((100 * (abs(old) - abs(new)),
                          f"{text}: slope {old:+.4f}{unit} -> {new:+.4f}{unit}"))
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
