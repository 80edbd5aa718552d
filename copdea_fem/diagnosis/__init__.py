"""Diagnose model-measurement disagreement: which physical effect is missing.

Pipeline (data flows one way; each module pure except ``report`` and the
entry points below):

``effects``   the catalogue: effects, parameters, signatures, study overrides; what
              ``measured.yaml`` may say of them (the set itself: :mod:`copdea_fem.measured`)
``engine``    ring-model modes and spectra of a condition under an effect state
``fe``        the FE model of record: study -> structural modes, cached
``anchored``  the ring model anchored to the FE: the surrogate the fits run on
``direct``    the FE evaluated directly, for a membrane the ring model cannot represent
``peaks``     resonance peaks of measured spectra; the measured peaks of a condition
``compare``   one-to-one matching, deviance (-2 ln L), the headline gap
``candidates`` the effects a step may add to the model, and why not the others
``tabulation`` a candidate's modes over its parameters, interpolated
``scoring``   deviance of a state; fit, cross-validate, test, accept; ambiguity
``separation`` the measurement that separates two indistinguishable candidates
``select``    the search: the loop of steps, each effect's status, the result
``evidence``  the sentences: evidence of a step, goodness of fit, verdict
``report``    report.md, diagnosis.json, PNG figures, final_study.yaml
``synth``     synthetic measurements from the ring model with chosen effects on
``imperfections`` after the search: an imperfection (anisotropy, uneven film, point mass)
              named from split (m,n) pairs and their orientations, trial 3-D FE solves

The wall time of an FE diagnosis is benchmarked by ``python -m benchmarks.diagnose``
(``benchmarks/diagnose.py``, outside the package).

Entry points of ``copdea-fem diagnose`` and ``copdea-fem synth`` (nothing written: the
results of :mod:`copdea_fem.api` write their files):

- :func:`load_measured` (MEASURED.yaml -> :class:`MeasuredSet`, checked with the
  catalogue's effects)
- :func:`diagnose_measured` (MEASURED.yaml or a MeasuredSet -> DiagnosisResult; the report
  is written by :meth:`copdea_fem.api.Diagnosis.write`)
- :func:`synthesise_set` (STUDY + effects + conditions -> a synthetic measured data set
  from the ring model) and :func:`check_scan_truth` with
  :func:`copdea_fem.diagnosis.synth_scan.synthesise_scan_set` (vibrometer exports made by
  the FE); written by :meth:`copdea_fem.api.SyntheticData.write`
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING

from copdea_fem.diagnosis.effects import (
    CATALOGUE,
    EFFECT_IDS,
    MANIFEST_RULES,
    Effect,
    Parameter,
    catalogue_table,
)
from copdea_fem.measured import MeasuredDataError, MeasuredSet, manifest

if TYPE_CHECKING:
    from copdea_fem.diagnosis.select import Diagnoser, DiagnosisResult


def __getattr__(name):
    """``Diagnoser`` and ``DiagnosisResult`` imported when first used: the search's modules
    (scipy.stats among them, 0.6 s) are not needed to read a measured.yaml
    (:func:`load_measured`: ``copdea-fem identify``)."""
    if name in ("Diagnoser", "DiagnosisResult"):
        from copdea_fem.diagnosis import select
        return getattr(select, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def load_measured(measured) -> MeasuredSet:
    """A ``measured.yaml`` read and checked with the catalogue's effects
    (:func:`copdea_fem.measured.load_measured` with
    :data:`~copdea_fem.diagnosis.effects.MANIFEST_RULES`); a :class:`MeasuredSet` given is
    returned as it is (each file is read once).

    Raises
    ------
    MeasuredDataError
        A bad manifest or measured file (a :class:`~copdea_fem.study.StudyError`; an unknown
        effect in ``candidates:`` too).
    """
    if isinstance(measured, MeasuredSet):
        return measured
    return manifest.load_measured(measured, effects=MANIFEST_RULES)


def diagnose_out_dir(measured: MeasuredSet) -> Path:
    """Default report folder of ``copdea-fem diagnose``: ``results/diagnose_<name>``."""
    return Path("results") / f"diagnose_{measured.name}"


def synth_out_dir(study, seed: int) -> Path:
    """Default folder of ``copdea-fem synth``: ``results/synth_<study name>_seed<N>``."""
    return Path("results") / f"synth_{study.name}_seed{seed}"


def check_options(alpha: float = 0.05, fe_cache=None, fe_workers=None, executor=None,
                  scheduler=None, workers_option: str = "--fe-workers") -> tuple:
    """The options of :func:`diagnose_measured` checked before any work (its parameters;
    ``workers_option``: the name of ``fe_workers`` in messages); ``(fe_workers, executor)``
    as it uses them (the worker count capped at the cores, the executor's name;
    :mod:`copdea_fem.parallel`).

    Raises
    ------
    StudyError
        A bad option, naming it.
    """
    import numbers

    from copdea_fem.parallel import DIAGNOSIS_SPELLINGS, check_executor, check_workers
    from copdea_fem.study import StudyError
    if isinstance(alpha, bool) or not isinstance(alpha, numbers.Real) or not 0 < alpha < 1:
        raise StudyError(f"--alpha = {alpha!r} is not allowed; allowed: a number in (0, 1)")
    if fe_cache:
        from copdea_fem.diagnosis.fe import check_cache_dir
        check_cache_dir(fe_cache, "--fe-cache")
    executor = check_executor(executor, scheduler, DIAGNOSIS_SPELLINGS, "processes",
                              workers=fe_workers)
    if fe_workers is not None:
        fe_workers = check_workers(fe_workers, workers_option)
    return fe_workers, executor


def diagnose_measured(measured, alpha: float = 0.05, model: str | None = None,
                      fe_cache=None, fe_workers=None, executor=None,
                      scheduler=None) -> DiagnosisResult:
    """Diagnose a measured data set (nothing written: :func:`copdea_fem.api.diagnose` and its
    :meth:`~copdea_fem.api.Diagnosis.write`).

    Parameters
    ----------
    measured : path or MeasuredSet
        ``measured.yaml`` (:mod:`copdea_fem.measured.manifest`), or the set
        :func:`load_measured` read from it.
    alpha : float
        False-alarm probability per step (:mod:`copdea_fem.diagnosis.scoring`), in (0, 1).
    model : str, optional
        ``"fe"`` or ``"reduced"``: overrides the manifest's ``model``.
    fe_cache : path, optional
        Folder of cached FE solves (:class:`copdea_fem.diagnosis.fe.FEModel`).
    fe_workers : int, optional
        Processes solving FE studies side by side (default
        :func:`copdea_fem.diagnosis.fe.default_workers`); with ``executor="dask"`` and
        no ``scheduler``, the local cluster's workers.
    executor : {"processes", "inline", "dask"}, optional
        Where the FE studies are solved (:class:`copdea_fem.diagnosis.fe.FEModel`):
        ``"processes"`` (default), side by side in processes of this machine; ``"inline"``,
        in this process, one at a time; ``"dask"``, a Dask cluster.
    scheduler : str or distributed.Client, optional
        With ``executor="dask"``: a running scheduler's address (or a client); without it a
        local cluster is started for the run and closed at its end.

    Returns
    -------
    DiagnosisResult

    Raises
    ------
    StudyError
        A bad option or input file (checked before any solve).
    ReducedModelError
        The ring model failed at a condition.
    """
    fe_workers, executor = check_options(alpha, fe_cache, fe_workers, executor, scheduler)
    measured = load_measured(measured)
    if model is not None:
        measured = dataclasses.replace(measured, model=model)
    pairings = ()
    if any(c.shapes_measured and c.resonances is None for c in measured.conditions):
        from copdea_fem.diagnosis.scanned import resonances_from_scans
        measured, pairings = resonances_from_scans(measured)
    engine = None
    if measured.model == "fe":
        from copdea_fem.diagnosis.anchored import AnchoredEngine
        from copdea_fem.diagnosis.direct import DirectFEEngine, ring_can_represent
        from copdea_fem.diagnosis.fe import FEModel
        fe = FEModel(cache_dir=fe_cache, workers=fe_workers, executor=executor,
                     scheduler=scheduler)         # a wrong scheduler address stops here
        engine = (AnchoredEngine(measured, fe) if ring_can_represent(measured.base_study)
                  else DirectFEEngine(measured, fe))     # no disc: the FE directly
    try:
        shape_check = None
        if pairings:
            from copdea_fem.diagnosis.scanned import ShapeCheck
            shape_check = ShapeCheck(measured, pairings)
        from copdea_fem.diagnosis.select import Diagnoser
        result = Diagnoser(measured, alpha=alpha, engine=engine, shape_check=shape_check).run()
        if pairings:
            result = dataclasses.replace(result, scan_pairings=pairings)
        from copdea_fem.diagnosis import imperfections
        if engine is not None and imperfections.tested_imperfections(measured):
            from copdea_fem.diagnosis.ring_predictor import state_overrides
            base = measured.base_study
            final = base.replace(state_overrides(base, result.final_state))
            square = any(s.geometry.frame == "square" for s in (base, final))
            verdict = imperfections.name_imperfections(measured, engine.fe, pairings, alpha,
                                                       square_frame=square)
            result = dataclasses.replace(result, imperfections=verdict,
                                         fe_solves=result.fe_solves + verdict.fe_solves)
        elif imperfections.tested_imperfections(measured):   # model: reduced
            result = dataclasses.replace(result, imperfections=imperfections.untested_verdict(
                measured, pairings, "they need model: fe (trial 3-D FE solves)"))
    except BaseException as error:       # an interrupt: the Dask cluster closes in silence
        if engine is not None:
            engine.fe.close(error)
        raise
    if engine is not None:
        engine.fe.close()                                # the FE worker processes, if any
    return result


def summary_lines(result: DiagnosisResult, out: Path) -> list[str]:
    """What ``copdea-fem diagnose`` prints: the verdict, the gap, the files written."""
    fe = (f"; model of record: FE ({result.fe_solves} solves, {result.fe_seconds:.0f} s)"
          if result.model == "fe" else "; model of record: ring model")
    return [result.verdict + fe,
            f"gap {100 * result.gap_before:.2f} % -> {100 * result.gap_after:.2f} %; "
            f"missing: {', '.join(result.missing_effects) or 'none'}; ambiguous: "
            f"{'; '.join('/'.join(g) for g in result.ambiguous) or 'none'}",
            *([f"imperfections: {result.imperfections.verdict}"]
              if result.imperfections is not None else []),
            f"wrote the report to {out} (report.md, diagnosis.json)"]


def synthesise_set(study, effects_text, conditions_text=None, parameters=None,
                   options=None) -> tuple[dict, list]:
    """Synthetic measurement set (``copdea-fem synth``), see :mod:`copdea_fem.diagnosis.synth`;
    nothing written (:func:`copdea_fem.diagnosis.synth.write_synthetic`).

    Parameters
    ----------
    study : Study
        The base study (written as the set's ``base_study.yaml``).
    effects_text : str
        Comma-separated effect identifiers switched on in the truth ("" for none).
    conditions_text : str, optional
        ``"load.z=11 mm, load.voltage=2 kV; load.z=16 mm"`` (default: five of the paper's
        operating points of G1).
    parameters : list of str, optional
        ``["air_loading.scale=1.2", ...]``.
    options : SynthOptions, optional

    Returns
    -------
    (dict, list of SynthCondition)
        ``{effect id: parameter values}`` switched on in the truth, and each condition's data.
    """
    from copdea_fem.diagnosis.effects import parse_effect_list
    from copdea_fem.diagnosis.synth import (
        SynthOptions,
        parse_conditions,
        parse_parameters,
        synthesise,
    )
    from copdea_fem.study import StudyError
    options = options or SynthOptions()
    options.check()
    names = parse_effect_list(effects_text or "")
    given = parse_parameters(parameters)
    for effect_id in given:
        if effect_id not in names:
            raise StudyError(f"--param {effect_id}.* is not allowed; allowed: parameters of "
                             f"the effects in --effects ({', '.join(names) or 'none'})")
    effects = {}
    for effect_id in names:
        entry = CATALOGUE[effect_id]
        values = given.get(effect_id, {})
        effects[effect_id] = tuple(values.get(p.name, p.default) for p in entry.parameters)
    conditions = parse_conditions(conditions_text)
    return effects, synthesise(study, effects, conditions, options)


def describe_truth(effects: dict) -> str:
    """The effects of a synthetic set's truth, with their parameters (``synth``'s summary)."""
    return ", ".join(f"{e} ({CATALOGUE[e].describe_values(v)})" if v else e
                     for e, v in effects.items()) or "no effect added"


def check_scan_truth(study, effects_text, conditions_text=None,
                     parameters=None) -> tuple[dict, list]:
    """The effects and conditions of a synthetic set of vibrometer exports (``copdea-fem
    synth --format uff``, :mod:`copdea_fem.diagnosis.synth_scan`), checked before any
    solve.  Parameters as :func:`synthesise_set`'s.

    Returns
    -------
    (dict, list of (str, dict))
        ``{effect id: parameter values}`` switched on in the truth, and each condition's
        name and study overrides.
    """
    from copdea_fem.diagnosis.effects import SCAN_EFFECTS, parse_effect_list
    from copdea_fem.diagnosis.synth import condition_name, parse_conditions, parse_parameters
    from copdea_fem.study import StudyError
    names = parse_effect_list(effects_text or "")
    for effect_id in names:
        if effect_id not in SCAN_EFFECTS:
            raise StudyError(f"--effects {effect_id} is not allowed with --format uff (the FE "
                             "makes the export and does not hold it); allowed: "
                             + ", ".join(SCAN_EFFECTS))
    given = parse_parameters(parameters)
    for effect_id in given:
        if effect_id not in names:
            raise StudyError(f"--param {effect_id}.* is not allowed; allowed: parameters of "
                             f"the effects in --effects ({', '.join(names) or 'none'})")
    effects = {effect_id: tuple(given.get(effect_id, {}).get(p.name, p.default)
                                for p in CATALOGUE[effect_id].parameters)
               for effect_id in names}
    conditions, taken = [], set()
    for index, overrides in enumerate(parse_conditions(conditions_text)):
        try:
            condition_study = study.replace(overrides)
        except StudyError as error:
            raise StudyError(f"--conditions #{index + 1}: {error}") from None
        conditions.append((condition_name(condition_study, overrides, index, taken),
                           overrides))
    return effects, conditions


__all__ = ["CATALOGUE", "EFFECT_IDS", "Effect", "Parameter", "catalogue_table",
           "MeasuredDataError", "MeasuredSet", "load_measured", "Diagnoser", "DiagnosisResult",
           "diagnose_measured", "synthesise_set", "check_scan_truth", "describe_truth",
           "summary_lines", "diagnose_out_dir", "synth_out_dir"]
