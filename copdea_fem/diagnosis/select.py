"""The search for the missing effects: from the base study, one effect at a time.

The loop
--------
Start from the base study (the effects it has on stay on).  At each step:

1. the candidates (:mod:`copdea_fem.diagnosis.candidates`): every catalogued
   effect that is off, that the engine can evaluate and that the data can
   see, with any requirement of it that is off;
2. each is fitted, cross-validated and tested against the current model,
   and ranked by its cross-validated improvement ``Delta_cv``
   (:mod:`copdea_fem.diagnosis.scoring`, whose notes derive the threshold:
   a step raises a false alarm with probability at most alpha);
3. the best significant candidate is taken with the parameters of the
   effects added before re-fitted exactly, one effect at a time (a
   coordinate pass), evaluated exactly (the FE re-anchored at its FE
   parameters) and accepted unless the acceptance refuses it
   (:func:`~copdea_fem.diagnosis.scoring.refusal`: the model must be
   evaluable everywhere and both the gap and the deviance must fall); a
   refused one is recorded and the next significant one tried;
4. the other candidates that improve the held-out deviance and that the
   test cannot tell from the accepted one
   (:meth:`~copdea_fem.diagnosis.scoring.Scorer.indistinguishable`) make the
   step *ambiguous*: the group is reported, no member is named missing, the
   best is kept *provisionally* so that the search can go on, and the
   report proposes the measurement that separates them
   (:mod:`copdea_fem.diagnosis.separation`).

The loop stops when no candidate passes.  Then every catalogued effect gets
its status (missing, ambiguous, on in the base model or replaced, not
tested and why, tested and not needed).  With the FE as the model of record
the ring surrogate is first checked against the FE at the base point
(:meth:`~copdea_fem.diagnosis.anchored.AnchoredEngine.ring_convergence`).

The sentences of the report (evidence, goodness of fit, verdict) are
:mod:`copdea_fem.diagnosis.evidence`.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

from copdea_fem.diagnosis.candidates import candidate_groups, prefetch_defaults
from copdea_fem.diagnosis.compare import gap
from copdea_fem.diagnosis.direct import (
    DIRECT_GRID,
    DIRECT_GRID_OF,
    DirectFEEngine,
    ring_can_represent,
)
from copdea_fem.diagnosis.effects import CATALOGUE
from copdea_fem.diagnosis.evidence import describe_evidence, goodness_of_fit, remaining_off, verdict
from copdea_fem.diagnosis.ring_predictor import RingPredictor
from copdea_fem.diagnosis.scoring import ALPHA, CandidateScore, Scorer, refusal
from copdea_fem.diagnosis.separation import separation
from copdea_fem.reduced.rings import ReducedModelError
from copdea_fem.study import StudyError

logger = logging.getLogger(__name__)


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
    shape_macs: dict = field(default_factory=dict)   # scans: {condition: {test mode: (label,
                                                     # MAC)}} of the model after the step


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
    scan_pairings: tuple = ()     # scanned conditions' shape pairing (diagnosis.scanned)
    imperfections: object = None  # the split pairs' verdict (diagnosis.imperfections)


class Diagnoser:
    """Runs the loop of the module notes on a :class:`MeasuredSet`.

    Parameters
    ----------
    measured : MeasuredSet
        The data and the base study.
    alpha : float
        False-alarm probability per step.
    engine : RingPredictor, optional
        What evaluates the model.  Default: with ``model: fe`` the ring model anchored
        to the FE, or the FE directly for a membrane without a disc (which the ring
        model cannot represent); else the ring model.
    """

    def __init__(self, measured, alpha: float = ALPHA, engine: RingPredictor | None = None,
                 shape_check=None):
        self.measured = measured
        self.alpha = alpha
        self.shape_check = shape_check   # diagnosis.scanned.ShapeCheck of scanned conditions
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
        self.engine = engine or RingPredictor(measured)
        self.scorer = Scorer(measured, self.engine, alpha)

    def run(self) -> DiagnosisResult:
        """The loop of the module notes, from the base study until no candidate passes."""
        scorer = self.scorer
        base = self.measured.base_study
        state: tuple = ()
        self._anchor(state)
        predictions_before, matches_before = scorer.evaluate(state)
        if any(m is None for m in matches_before.values()):
            bad = [n for n, m in matches_before.items() if m is None]
            why = ""
            try:
                self.engine.predict(next(c for c in scorer.conditions if c.name == bad[0]))
            except (ReducedModelError, StudyError) as error:   # what safe_predict hid
                why = f" ({error})"
            raise StudyError(f"conditions {', '.join(bad)} are not allowed: the base model "
                             f"cannot be evaluated there{why}; allowed: operating points the "
                             "model solves")
        convergence = (self.engine.ring_convergence() if scorer.uses_fe and not scorer.direct
                       else None)
        deviance = scorer.deviances(matches_before)
        matches = matches_before
        steps, missing, ambiguous, rejected = [], [], [], []
        not_tested: dict = {}
        tested_ever: set = set()
        for index in range(1, len(CATALOGUE) + 1):
            groups, skipped = candidate_groups(scorer, state, base)
            not_tested.update({e: r for e, r in skipped.items() if e not in tested_ever})
            if not groups:
                break
            for group in groups:
                not_tested.pop(group[-1], None)
            self.progress(f"step {index}: testing {', '.join(g[-1] for g in groups)}")
            prefetch_defaults(scorer, state, groups)
            scores = [scorer.score(state, g, deviance, len(groups)) for g in groups]
            tested_ever.update(g[-1] for g in groups)
            scores.sort(key=lambda s: -s.delta_cv if math.isfinite(s.delta_cv) else math.inf)
            accepted = None
            for best in (s for s in scores if s.significant):
                new_state = best.state
                for position in range(len(state)):
                    new_state = scorer.refit(new_state, position)
                previous = self._anchor(new_state)
                _, new_matches = scorer.evaluate(new_state)
                reason = refusal(matches, new_matches, best.effects)
                if reason is None and self.shape_check is not None:
                    reason = self.shape_check.refusal(new_state)
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
                      and s.delta_cv > 0 and scorer.indistinguishable(best, s)]
            new_deviance = scorer.deviances(new_matches)
            evidence = describe_evidence(matches, new_matches, scorer.meta)
            action = "ambiguous" if rivals else "added"
            step = Step(index, action, best.effects, _values_dict(new_state, best.effects),
                        best, gap(matches.values()), gap(new_matches.values()),
                        sum(deviance.values()), sum(new_deviance.values()), evidence,
                        ambiguous_with=tuple(r.effects[-1] for r in rivals), candidates=scores)
            if self.shape_check is not None:
                step.shape_macs = self.shape_check.macs(new_state)
            if rivals:
                group = [best.effects[-1]] + [r.effects[-1] for r in rivals]
                ambiguous.append(group)
                step.separation = [separation(scorer, best, r) for r in rivals]
            else:
                missing.extend(e for e in best.effects if e not in missing)
            steps.append(step)
            self.progress(f"step {index}: {action} {best.described()}, ln U = "
                          f"{best.log_evidence:.1f} >= {best.threshold:.1f}")
            state, matches, deviance = new_state, new_matches, new_deviance
        predictions_after, matches_after = scorer.evaluate(state)
        added = {e for e, _ in state}
        base_on = [e for e, entry in CATALOGUE.items()
                   if entry.is_on(base) and (entry.engine == "reduced" or scorer.uses_fe)]
        status = _effect_status(added, missing, ambiguous, not_tested, base_on,
                                self.measured.candidates, tested_ever)
        goodness = goodness_of_fit(matches_after.values(), self.measured.noise)
        result = DiagnosisResult(
            measured=self.measured, steps=steps, final_state=state, missing_effects=missing,
            ambiguous=ambiguous, gap_before=gap(matches_before.values()),
            gap_after=gap(matches_after.values()), matches_before=matches_before,
            matches_after=matches_after, deviance_before=sum(scorer.deviances(
                matches_before).values()), deviance_after=sum(scorer.deviances(
                    matches_after).values()),
            status=status, not_tested={e: r for e, r in not_tested.items()
                                       if e not in added}, base_on=base_on,
            goodness=goodness, verdict="", cross_validated=len(scorer.conditions) >= 2,
            alpha=self.alpha, predictions_before=predictions_before,
            predictions_after=predictions_after, rejected=rejected,
            ring_convergence=convergence, model="fe" if scorer.uses_fe else "reduced",
            fe_solves=self.engine.fe.solves if scorer.uses_fe else 0,
            fe_seconds=self.engine.fe.seconds if scorer.uses_fe else 0.0)
        result.remaining_off = remaining_off(matches_after.values(), self.measured.noise)
        result.engines = self.engines_used()
        result.verdict = verdict(result)
        return result

    def engines_used(self) -> dict:
        """Which engine evaluated what (the report's "model of record" section)."""
        if not self.scorer.uses_fe:
            return {"predictions": "ring model (model: reduced)"}
        if self.scorer.direct:
            used = getattr(self.engine, "engines", {})
            return {"predictions": "FE directly (no ring surrogate: the device has no "
                                   "central disc)",
                    "states": {" + ".join(k) or "base": sorted(v) for k, v in used.items()},
                    "fitted_grid": f"{DIRECT_GRID} FE solves per condition and parameter "
                                   f"({DIRECT_GRID_OF['geometry.enclosure_depth']} for "
                                   "enclosure's depth)"}
        return {"predictions": "ring surrogate anchored to the FE (A1)",
                "fe_switches": "air_loading, baffle, frame_reflection, open_air: FE solves "
                               "(axisymmetric engine for frames none/baffle/circle, 3-D for "
                               "the square frame)",
                "fe_damping": "viscoelastic_membrane: fitted on the ring surrogate's Prony "
                              "term, then the FE's damped eigen step at the accepted values "
                              "(frequencies and quality factors Q = 1/(2 zeta))"}

    def _anchor(self, state):
        """Solve the FE at ``state``'s FE parameters from now on; the previous anchor."""
        if not self.scorer.uses_fe:
            return None
        previous = dict(self.engine.anchored)
        self.engine.set_anchor(state)
        return previous

    def _restore_anchor(self, previous) -> None:
        if self.scorer.uses_fe:
            self.engine.anchored = previous


def _effect_status(added, missing, ambiguous, not_tested, base_on, candidates,
                   tested_ever) -> dict:
    """The status text of every catalogued effect at the end of the search."""
    status = {}
    ambiguous_ids = {e for group in ambiguous for e in group}
    for effect_id, entry in CATALOGUE.items():
        replaced_by = next((e for e in added if CATALOGUE[e].replaces_effect(entry)), None)
        if effect_id in missing:
            status[effect_id] = "missing: added"
        elif effect_id in ambiguous_ids:
            status[effect_id] = ("ambiguous (kept provisionally)" if effect_id in added
                                 else "ambiguous")
        elif effect_id in not_tested:
            status[effect_id] = "not tested: " + not_tested[effect_id]
        elif effect_id in base_on and replaced_by:
            status[effect_id] = f"on in the base model: replaced by {replaced_by}"
        elif effect_id in base_on:
            status[effect_id] = "on in the base model"
        elif effect_id not in candidates:
            status[effect_id] = "not a candidate (measured.yaml candidates)"
        elif effect_id in tested_ever:
            status[effect_id] = "tested: not needed"
        else:
            status[effect_id] = "not tested"
    return status


def _values_dict(state, effects) -> dict:
    """``{effect: {parameter: SI value}}`` of ``effects`` in ``state``."""
    out = {}
    for effect_id, values in state:
        if effect_id in effects:
            out[effect_id] = {p.name: float(v) for p, v in
                              zip(CATALOGUE[effect_id].parameters, values)}
    return out
