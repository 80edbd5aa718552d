"""What would separate two explanations the data cannot tell apart.

When the search finds two candidates indistinguishable
(:meth:`copdea_fem.diagnosis.scoring.Scorer.indistinguishable`), the report
names no member missing and proposes the measurement that separates them:
the operating point (V_b, z at the data's geometry) where the two fitted
models differ most in units of sigma_f (:func:`separation`, on the ring
model), or, on a device the ring model cannot represent, the mode where
the FE-evaluated models differ most at the data's own conditions; and
whether a measurement in vacuo would separate them
(:func:`in_vacuo_separates`).
"""

from __future__ import annotations

import math

from copdea_fem.diagnosis.effects import CATALOGUE
from copdea_fem.diagnosis.ring_predictor import safe_predict
from copdea_fem.diagnosis.scoring import CandidateScore
from copdea_fem.measured import Condition

PROBE_VOLTAGES = (0.0, 1000.0, 2000.0, 3000.0)     # V_b of the probes [V]
PROBE_Z = (0.0, 0.011, 0.016, 0.018)                # z of the probes besides the data's [m]


def separation(scorer, first: CandidateScore, second: CandidateScore) -> dict:
    """The probe operating point where the two fitted models differ most.

    Probes: V_b in {0, 1, 2, 3} kV x z in the data's z values and {0, 11, 16, 18} mm,
    at the first condition's geometry, on the ring model (no FE solve per probe).  A
    probe's separation is ``sqrt(sum_modes (ln(f_first / f_second) / sigma_f)^2)`` over
    the expected modes in the band (what one measurement there would add to the
    deviance difference); the mode that differs most is named.  On the direct FE engine
    (no ring model) the mode that differs most at the data's conditions
    (:func:`mode_separation`).

    Parameters
    ----------
    scorer : Scorer
        The data and the engine (:class:`copdea_fem.diagnosis.scoring.Scorer`).
    first, second : CandidateScore
        The two fitted candidates (their ``state`` is evaluated).

    Returns
    -------
    dict
        ``first``, ``second`` (the effects), ``sigma`` (the separation), and where it
        is largest: ``voltage`` [V], ``z`` [m], ``label``, ``first_hz``, ``second_hz``;
        ``in_vacuo``.
    """
    if scorer.direct:
        return mode_separation(scorer, first, second)
    sigma = scorer.measured.noise.frequency_relative
    template = scorer.conditions[0]
    z_values = sorted({round(m["z"], 6) for m in scorer.meta.values()} | set(PROBE_Z))
    best = None
    for voltage in PROBE_VOLTAGES:
        for z in z_values:
            probe = _probe(template, {**template.overrides, "load.z": z,
                                      "load.voltage": voltage})
            a = safe_predict(scorer.engine, probe, first.state, ring_only=True)
            b = safe_predict(scorer.engine, probe, second.state, ring_only=True)
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
    best["in_vacuo"] = in_vacuo_separates(first, second)
    return best


def mode_separation(scorer, first: CandidateScore, second: CandidateScore) -> dict:
    """The mode where the two fitted models differ most at the data's conditions.

    Both are evaluated by the FE (the direct engine: no operating point to vary on a
    device without a disc and voltage); a mode seen in few conditions, or one the data
    lack, measured more carefully separates them.
    """
    sigma = scorer.measured.noise.frequency_relative
    best = {"first": first.effects[-1], "second": second.effects[-1], "sigma": 0.0}
    for c in scorer.conditions:
        a = safe_predict(scorer.engine, c, first.state)
        b = safe_predict(scorer.engine, c, second.state)
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
    best["in_vacuo"] = in_vacuo_separates(first, second)
    return best


def in_vacuo_separates(first: CandidateScore, second: CandidateScore) -> bool:
    """Whether a measurement in vacuo separates the two: one is an effect of the air (the
    air loading or a mounting, which act through the air only), the other not."""
    return (CATALOGUE[first.effects[-1]].acts_through_air
            != CATALOGUE[second.effects[-1]].acts_through_air)


def _probe(template, overrides):
    """A condition at ``overrides`` with ``template``'s band and no data."""
    return Condition(name=f"probe_{overrides['load.z']:g}_{overrides['load.voltage']:g}",
                     overrides=overrides, resonances=None, spectrum=None, band=template.band)
