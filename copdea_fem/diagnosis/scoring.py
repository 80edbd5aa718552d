"""Scoring a candidate: fit, cross-validate, test, accept, and tell two candidates apart.

A candidate (:mod:`copdea_fem.diagnosis.candidates`) is scored against the
current model of the search (:mod:`copdea_fem.diagnosis.select`):

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
hypotheses, Markov again), and the report says so.  A fit at a bound of its
range is reported, never significant: the effect's range cannot explain the
data.

Acceptance.  A significant candidate is accepted only when the model,
evaluated exactly at its fit, can be evaluated at every condition and both
the headline gap and the in-sample deviance fall (:func:`refusal`).

Ambiguity.  Another candidate B that improves the held-out deviance
(Delta_cv > 0; significant or not) is indistinguishable from the best A when
the same test, run between them, cannot tell A better:
``ln U_AB < ln(1/alpha)`` with U_AB the prequential likelihood of A over
B's *maximum* likelihood on all conditions.  B's denominator must be its
full-data fit: L_B(theta_hat) >= L_B(theta_true) keeps E[U_AB] <= 1 when B
is the truth (with B fitted on the past only, the ratio could be inflated
and a wrong A named with confidence).  What would separate them is
:mod:`copdea_fem.diagnosis.separation`.

The parameters of the effects added before are nuisance parameters of every
candidate's fit: they are re-fitted with it (jointly, in every fold), using
modes linearised in them about their current values (one finite difference
per parameter and condition), so an effect added earlier cannot keep a
share of the discrepancy that belongs to the new one; :meth:`Scorer.refit`
re-fits one of them exactly with the others fixed.  (Approximation: the
earlier effects' parameters are not re-fitted inside each fold; this makes
the current model look slightly better than it would out of sample, i.e.
the test slightly conservative.)

The fits run on the candidate's tabulated modes
(:mod:`copdea_fem.diagnosis.tabulation`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.stats

from copdea_fem.diagnosis.compare import ConditionMatch, DevianceTerms, gap, match_condition
from copdea_fem.diagnosis.direct import direct_grid
from copdea_fem.diagnosis.effects import CATALOGUE, SURROGATE_ONLY_KEYS
from copdea_fem.diagnosis.peaks import condition_peaks
from copdea_fem.diagnosis.ring_predictor import RingPredictor, safe_predict
from copdea_fem.diagnosis.tabulation import INVALID, Tabulation

ALPHA = 0.05
ORDERINGS = 3          # cyclic orderings averaged in the prequential evidence (fixed in advance)
BOUND_MARGIN = 1e-3    # a fitted u this close to 0 or 1 is at a bound of the fit range


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


class Scorer:
    """A measured set and the engine that evaluates it: the deviance of an effect state,
    and the fit, cross-validation and test of a candidate (module notes).

    Parameters
    ----------
    measured : MeasuredSet
        The data: conditions, their peaks, the noise model.
    engine : RingPredictor
        What predicts the modes of a condition under an effect state: the ring model,
        the ring model anchored to the FE (it has ``anchor``: :attr:`uses_fe`), or the
        FE directly (``direct``: parameters tabulated on a grid of FE solves, the keys
        the FE does not read :attr:`pinned` at their defaults).
    alpha : float
        False-alarm probability per step.
    """

    def __init__(self, measured, engine: RingPredictor, alpha: float = ALPHA):
        self.measured = measured
        self.engine = engine
        self.alpha = alpha
        self.uses_fe = hasattr(engine, "anchor")
        self.direct = bool(getattr(engine, "direct", False))
        self.pinned = SURROGATE_ONLY_KEYS if self.direct else ()
        self.conditions = measured.conditions
        self.peaks = {c.name: condition_peaks(c) for c in self.conditions}
        self._terms: dict = {}
        self.meta = {}
        for c in self.conditions:
            study = measured.study_of(c)
            self.meta[c.name] = {"voltage": study.load.voltage, "z": study.load.z}

    # evaluation of a state against the data
    def terms(self, name) -> DevianceTerms:
        """The deviance constants of condition ``name``."""
        terms = self._terms.get(name)
        if terms is None:
            condition = next(c for c in self.conditions if c.name == name)
            terms = self._terms[name] = DevianceTerms(self.measured.noise, condition.band)
        return terms

    def match(self, condition, modes) -> ConditionMatch:
        """The model's ``modes`` matched to the measured peaks of ``condition``."""
        return match_condition(condition.name, modes, self.peaks[condition.name],
                               condition.band, self.measured.noise, self.terms(condition.name),
                               observed=self.measured.observed)

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
        """The deviance of every condition (:data:`INVALID` where the model cannot be
        evaluated)."""
        return {name: (m.deviance if m is not None else INVALID) for name, m in matches.items()}

    # fit, cross-validation, test
    def score(self, state, group, current_deviance: dict, tested: int) -> CandidateScore:
        """Fit, cross-validate and test one candidate group (module notes).

        Parameters
        ----------
        state : tuple
            The current model's effect state.
        group : tuple of str
            The candidate's effects (requirements first).
        current_deviance : dict
            The current model's deviance per condition.
        tested : int
            Candidates tested at this step (the Bonferroni factor N).
        """
        parameters = [p for e in group for p in CATALOGUE[e].parameters
                      if p.key not in self.pinned]
        table = Tabulation(self, state, group, parameters, nuisance=True, pinned=self.pinned,
                           grid=direct_grid(parameters) if self.direct else None)
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
            log_evidence = log_mean_exp([
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
                           grid=direct_grid(parameters) if self.direct else None)
        u = table.fit([c.name for c in self.conditions])
        values = tuple(table.values(u))
        return state[:index] + ((effect_id, values),) + state[index + 1:]

    # ambiguity
    def indistinguishable(self, best: CandidateScore, other: CandidateScore) -> bool:
        """Whether the test cannot tell ``best`` better than ``other`` (module notes:
        ``ln U_AB < ln(1/alpha)``; with one condition, the in-sample likelihood ratio
        against Wilks' threshold for one degree of freedom)."""
        if len(self.conditions) >= 2:
            terms = [sum(other.in_sample[n] - d for n, d in order.items()) / 2
                     for order in best.prequential]
            return log_mean_exp(terms) < math.log(1 / self.alpha)
        return (other.deviance - best.deviance) / 2 < 0.5 * scipy.stats.chi2.ppf(
            1 - self.alpha, 1)


def refusal(matches, new_matches, effects) -> str | None:
    """Why an effect that passed the test is not accepted (None: accepted).

    Exact evaluation (the FE re-solved at the fitted FE parameters): accepted only
    when the model can be evaluated everywhere and both the headline gap and the
    in-sample deviance fall -- an accepted step never makes the model worse.  (An
    effect on the quality factors alone, modal_damping, cannot move the gap -- a
    frequency error -- so there the gap must only not rise.)

    Parameters
    ----------
    matches, new_matches : dict
        ``{condition: ConditionMatch}`` of the current model and of the model with the
        candidate at its fit (None where it cannot be evaluated).
    effects : tuple of str
        The candidate's effects.
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


def log_mean_exp(values) -> float:
    """``ln(mean(exp(values)))`` without overflow; -inf for no values or a NaN among them."""
    values = np.asarray(values, float)
    if values.size == 0 or np.any(np.isnan(values)):
        return -math.inf
    top = np.max(values)
    if not math.isfinite(top):
        return float(top)
    return float(top + math.log(np.mean(np.exp(values - top))))
