"""The candidates of a step: which effects the search may add to a state, and why not the others.

At each step of the search (:mod:`copdea_fem.diagnosis.select`), every
catalogued effect that is off, that the engine can evaluate and that the
data can see is a *candidate*.  An effect whose requirement is off comes
with it as one group (``disc_pumping + spring_mass``), so a candidate is a
tuple of effects, requirements first, the tested effect last.  An effect
that is not a candidate gets the reason the report prints: it needs the FE
as the model of record, air in the model, quality factors, a bias voltage
or a preload (:meth:`~copdea_fem.diagnosis.effects.Effect.applies_to`); another
mounting or material-damping cause is in the model (one at a time:
:func:`mounting_skipped`, :func:`material_skipped`); or its requirement is not a
candidate of ``measured.yaml``.  Every rule reads the fields of the effects
(:class:`~copdea_fem.diagnosis.effects.Effect`), never their names.
"""

from __future__ import annotations

import math

from copdea_fem.diagnosis.effects import AIR_EFFECT, CATALOGUE, MOUNTINGS, base_mounting


def candidate_groups(scorer, state, base_study) -> tuple[list, dict]:
    """Candidate effect groups at this state, and reasons for the effects not tested.

    Parameters
    ----------
    scorer : Scorer
        The data and the engine (:class:`copdea_fem.diagnosis.scoring.Scorer`): which
        effects ``measured.yaml`` allows, what the engine can evaluate (``uses_fe``,
        ``direct``), what the data hold (quality factors, bias voltages, preloads).
    state : tuple
        The effects added so far, ``((effect, values), ...)``.
    base_study : Study
        The base model (the effects it has on are no candidates).

    Returns
    -------
    groups : list of tuple of str
        The candidates, each requirements first, the tested effect last.
    skipped : dict
        ``{effect: reason}`` of the effects not tested at this state.
    """
    on = {e for e, _ in state} | {e for e, entry in CATALOGUE.items()
                                  if entry.is_on(base_study)}
    has_quality = any(math.isfinite(p.quality_factor) for peaks in scorer.peaks.values()
                      for p in peaks)
    operating_points = tuple(scorer.meta.values())
    allowed = scorer.measured.candidates
    groups, skipped = [], {}
    for effect_id in allowed:
        entry = CATALOGUE[effect_id]
        if entry.split_signature is not None:       # named from split pairs, after the search
            skipped[effect_id] = entry.not_tested_note
            continue
        if entry.engine == "coupled_fe" and not scorer.uses_fe:
            skipped[effect_id] = ("needs the fully-coupled air/PML FE as the model of "
                                  "record (measured.yaml model: fe)")
            continue
        if entry.engine == "fe" and not scorer.uses_fe:
            skipped[effect_id] = ("needs the FE as the model of record (measured.yaml "
                                  "model: fe): the FE's damped eigen step evaluates it")
            continue
        if effect_id in on:
            continue
        if scorer.direct and not entry.direct:
            skipped[effect_id] = entry.not_direct or (
                "needs the ring surrogate, which cannot represent this membrane (no central "
                "disc), and the FE does not model it")
            continue
        why = (entry.why_not_applicable(base_study, operating_points)
               or mounting_skipped(effect_id, state, base_study)
               or material_skipped(effect_id, state, base_study))
        if why:
            skipped[effect_id] = why
            continue
        if entry.engine == "coupled_fe" and AIR_EFFECT.id not in on:
            skipped[effect_id] = ("needs air in the model (the frame reflects sound): "
                                  f"tested once {AIR_EFFECT.id} is on")
            continue
        if entry.needs == "quality_factors" and not has_quality:
            skipped[effect_id] = ("needs quality factors (a quality_factor column or "
                                  "spectra with resolved peaks)")
            continue
        group = tuple(r for r in entry.requires if r not in on) + (effect_id,)
        if any(g not in allowed for g in group):
            skipped[effect_id] = f"needs {', '.join(group[:-1])}, which is not a candidate"
            continue
        groups.append(group)
    return groups, skipped


def mounting_skipped(effect_id, state, base_study) -> str | None:
    """Why the mounting ``effect_id`` is not a candidate at ``state`` (None: it is).

    One mounting at a time: the base study's own (:func:`base_mounting`: open in air,
    baffled, framed or over an enclosure) is the starting point, and every other
    mounting is a candidate that *replaces* it (its overrides set ``geometry.frame`` and
    ``geometry.enclosure``: the whole mounting) -- the search adds
    effects, and this is how a base with the wrong mounting is corrected (open-air
    data from a baffled base).  Once a mounting is accepted (or held provisionally)
    no other is tested.  A framed or baffled base without air (``air.enabled: false``,
    the frame inert) keeps its stated mounting: only a base that models the air states
    a mounting to replace.  None for an effect that is not a mounting.
    """
    if CATALOGUE[effect_id].mounting is None:
        return None
    added = next((e for e, _ in state if e in MOUNTINGS and e != effect_id), None)
    if added:
        return f"another mounting ({added}) is in the model: one mounting at a time"
    stated = base_mounting(base_study)
    if (stated is not None and CATALOGUE[stated].mounting == "built"
            and not base_study.air.enabled):
        return (f"another mounting ({stated}) is in the model: one mounting at a time "
                "(the base study states it without air, air.enabled: false)")
    return None


def material_skipped(effect_id, state, base_study) -> str | None:
    """Why the effect ``effect_id`` is not a candidate at ``state`` because of an
    exclusion (:attr:`~copdea_fem.diagnosis.effects.Effect.exclusion`; None: it is).

    One material-damping cause at a time: the FE's Prony term (``viscoelastic_membrane``)
    stiffens AND damps, so it is the cause that the ring model's storage factor
    (``viscoelastic_stiffening``) and the paper's modal b/m (``modal_damping``) each
    describe a part of.  It is never tested beside either: not once one of them is in the
    model (added, or on in the base), nor either once it is.  An effect it replaces (the
    base study's modal b/m, on by default, Sect. 5.3) is no obstacle: the Prony term
    replaces it (its overrides set ``reduced.damping_*`` to 0), as a mounting replaces
    another.  At one step all three may be tested; the best is named (or the group
    reported as ambiguous) by the search's usual rule.
    """
    entry = CATALOGUE[effect_id]
    added = {e for e, _ in state}
    if entry.exclusion is not None:
        rule = entry.exclusion
        other = next((e for e in rule.effects if e in added), None)
        if other is None:
            other = next((e for e in rule.effects if not entry.replaces_effect(CATALOGUE[e])
                          and CATALOGUE[e].is_on(base_study)), None)
        if other:
            return f"{rule.rule}: {other} is in the model ({rule.why})"
    for holder in CATALOGUE.values():
        if (holder.exclusion is not None and effect_id in holder.exclusion.effects
                and (holder.id in added or (holder.is_on(base_study)
                                            and not entry.replaces_effect(holder)))):
            return (f"{holder.exclusion.rule}: {holder.id} ({holder.exclusion.what}) is in "
                    "the model")
    return None


def prefetch_defaults(scorer, state, groups) -> None:
    """The FE solves every candidate of a step needs at its defaults, side by side.

    :meth:`FEModel.solve_many` solves the cold diagnosis's switches (air, mountings)
    at every condition at once; on the direct engine only the candidates without a
    fitted parameter are prefetched (the others are solved on their grids, a batch
    each).
    """
    pairs = []
    for group in groups:
        free = [p for e in group for p in CATALOGUE[e].parameters
                if p.key not in scorer.pinned]
        if scorer.direct and free:
            continue
        candidate = state + tuple((e, CATALOGUE[e].defaults) for e in group)
        pairs.extend((c, candidate) for c in scorer.conditions)
    scorer.engine.prefetch(pairs)
