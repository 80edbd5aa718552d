"""Vibrometer scans as the diagnosis's measured peaks: identified, and labelled by shape.

A condition with a ``scan:`` and no ``resonances:`` gets its resonance list from the scan:

1. its modes are identified (:func:`copdea_fem.vibrometer.identification.identify`, in the
   condition's band; nothing from the FE): frequency, damping ratio zeta, shape;
2. they are paired by shape with the base model's FE modes at that condition
   (:func:`copdea_fem.vibrometer.model_shapes.fe_shapes`, the FE the diagnosis runs:
   :func:`copdea_fem.diagnosis.fe.fe_study`; one-to-one, largest total MAC within the
   ``pairing:`` window, :mod:`copdea_fem.vibrometer.pairing`);
3. each test mode becomes a resonance: its frequency, ``Q = 1 / (2 zeta)`` (the half-power
   quality factor of a lightly damped mode), and the *label of the FE mode its shape
   matches* (with the kind that label implies).  A labelled peak pairs only with the model
   mode of that label (:mod:`copdea_fem.diagnosis.compare`, rule 2), so wherever a shape
   was measured the pairing between measurement and model is by shape, whatever an effect
   does to the frequencies: an effect that would bring frequencies closer by pairing a
   peak with a mode of another shape cannot, since the pair is fixed by the shape.
   Test modes paired with in-plane FE modes are seen and explained but left out (the
   diagnosis's model holds the out-of-plane family only: :mod:`copdea_fem.diagnosis.fe`);
   the two members of a pair the diagnosis's FE merges (split below
   :data:`copdea_fem.diagnosis.fe.PAIR_MERGE`) are one peak at their mean frequency;
   unpaired test modes are unlabelled peaks of unknown kind.

The correlations are kept (:class:`ScanPairing`) for the report (the MAC of each pair).
"""

from __future__ import annotations

import dataclasses
import logging
import math

from copdea_fem.measured import MeasuredSet, Resonance, normalise_label

logger = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True)
class ScanPairing:
    """One scanned condition's identification and shape pairing (for the report and the
    shape check of each step, :class:`ShapeCheck`)."""

    condition: str
    correlation: object            # copdea_fem.vibrometer.pairing.Correlation
    resonances: tuple
    modes: tuple = ()              # the identified modes (IdentifiedMode)
    scan: object = None            # the condition's ScanData
    f_max: float = math.nan        # top of the FE band [Hz]


def _resonance(pair) -> Resonance | None:
    """A test mode as a resonance (module notes, step 3); None: an in-plane mode."""
    quality = (1 / (2 * pair.test_damping_ratio)
               if math.isfinite(pair.test_damping_ratio) and pair.test_damping_ratio > 0
               else math.nan)
    if pair.label.startswith("ip"):
        return None
    label, kind = normalise_label(pair.label, "scan label") if pair.label else ("", "")
    return Resonance(pair.test_freq_hz, label, kind, quality)


def _merge_unresolved(resonances: list, correlation) -> list:
    """Two test modes on the members of a pair the diagnosis's FE merges: one peak."""
    from copdea_fem.diagnosis.fe import PAIR_MERGE

    fe_freq = dict(zip(correlation.fe_labels, correlation.fe_freq_hz))
    out, used = [], set()
    for index, resonance in enumerate(resonances):
        if index in used:
            continue
        label = resonance.label
        partner_label = (label[:-1] + ("b" if label.endswith("a") else "a")
                         if label[-1:] in ("a", "b") else "")
        partner = next((j for j, other in enumerate(resonances)
                        if j != index and j not in used and other.label == partner_label),
                       None)
        split = (abs(fe_freq[partner_label] / fe_freq[label] - 1)
                 if partner is not None and label in fe_freq and partner_label in fe_freq
                 else math.inf)
        if partner is None or split >= PAIR_MERGE:
            out.append(resonance)
            continue
        other = resonances[partner]
        used.add(partner)
        qualities = [q for q in (resonance.quality_factor, other.quality_factor)
                     if math.isfinite(q)]
        out.append(Resonance(0.5 * (resonance.frequency_hz + other.frequency_hz), label[:-1],
                             resonance.kind,
                             sum(qualities) / len(qualities) if qualities else math.nan))
    return out


def resonances_from_scans(measured: MeasuredSet) -> tuple[MeasuredSet, tuple]:
    """``measured`` with a resonance list for every condition that has a scan and none of
    its own (module notes), and the :class:`ScanPairing` of each such condition.

    Conditions without a scan, or with their own ``resonances:``, are kept as they are.
    """
    from copdea_fem.diagnosis.fe import fe_study
    from copdea_fem.vibrometer.identification import condition_band, identify
    from copdea_fem.vibrometer.model_shapes import correlate_identified, fe_shapes

    settings = measured.pairing
    window = settings.window if settings is not None else 0.5
    mac_min = settings.mac_min if settings is not None else 0.5
    conditions, pairings = [], []
    for condition in measured.conditions:
        if condition.scan is None or condition.resonances is not None:
            conditions.append(condition)
            continue
        low, high = condition.band
        f_min, f_max = condition_band(condition)
        modes = identify(condition.scan, f_min=f_min, f_max=f_max)
        study = fe_study(measured.study_of(condition), f_max=high * (1 + window))
        correlation = correlate_identified(condition.name, modes,
                                           fe_shapes(study, condition.scan),
                                           window=window, mac_min=mac_min)
        resonances = [r for r in map(_resonance, correlation.pairs) if r is not None]
        resonances = tuple(sorted(_merge_unresolved(resonances, correlation),
                                  key=lambda r: r.frequency_hz))
        logger.info("%s: %d modes identified in the scan, %d paired by shape, %d resonances",
                    condition.name, len(modes),
                    sum(1 for pair in correlation.pairs if pair.label), len(resonances))
        pairings.append(ScanPairing(condition.name, correlation, resonances, tuple(modes),
                                    condition.scan, high * (1 + window)))
        conditions.append(dataclasses.replace(condition, resonances=resonances or None))
        if not resonances and condition.spectrum is None:
            from copdea_fem.measured import MeasuredDataError
            raise MeasuredDataError(f"{condition.name}: scan {condition.files.get('scan')}: "
                                    "no mode identified in the band "
                                    f"[{low:g} Hz, {high:g} Hz]; allowed: a scan with at "
                                    "least one resonance in the condition's band")
    return dataclasses.replace(measured, conditions=tuple(conditions)), tuple(pairings)


class ShapeCheck:
    """The shape pairing of a model state: an accepted step must keep it (module notes).

    For a state of the diagnosis (effects and values), every scanned condition's FE is solved
    with the state's effects on (:func:`copdea_fem.diagnosis.ring_predictor.state_overrides`), its
    modes sampled at the scan points and paired with the identified modes again.  The step
    is refused when a test mode that the base model paired by shape with one mode (unit)
    now pairs with a mode of another shape, or with none: an effect that brings frequencies
    closer by breaking the shape pairing.  :meth:`macs` keeps each pair's MAC per state
    for the report.
    """

    def __init__(self, measured: MeasuredSet, pairings):
        self.measured = measured
        self.pairings = {pairing.condition: pairing for pairing in pairings}
        settings = measured.pairing
        self.window = settings.window if settings is not None else 0.5
        self.mac_min = settings.mac_min if settings is not None else 0.5
        self._cache: dict = {}

    def correlations(self, state) -> dict:
        """``{condition: Correlation}`` of the model ``state`` (FE solved once per state)."""
        from copdea_fem.diagnosis.ring_predictor import state_overrides
        from copdea_fem.diagnosis.fe import fe_study
        from copdea_fem.vibrometer.model_shapes import correlate_identified, fe_shapes

        key = repr(state)
        if key not in self._cache:
            out = {}
            for condition in self.measured.conditions:
                pairing = self.pairings.get(condition.name)
                if pairing is None:
                    continue
                study = self.measured.study_of(condition)
                if state:
                    study = study.replace(state_overrides(study, state))
                out[condition.name] = correlate_identified(
                    condition.name, pairing.modes, fe_shapes(fe_study(study, pairing.f_max),
                                                             pairing.scan),
                    window=self.window, mac_min=self.mac_min)
            self._cache[key] = out
        return self._cache[key]

    def refusal(self, state) -> str | None:
        """Why ``state`` breaks the base model's shape pairing (None: it keeps it)."""
        from copdea_fem.vibrometer.pairing import unit_key

        broken = []
        for name, correlation in self.correlations(state).items():
            base = self.pairings[name].correlation
            for before, after in zip(base.pairs, correlation.pairs):
                if before.label and unit_key(after.label) != unit_key(before.label):
                    broken.append(f"{name} test mode {before.test_mode} "
                                  f"({before.test_freq_hz:.1f} Hz): {before.label} -> "
                                  f"{after.label or 'unpaired'}")
        if broken:
            return "it breaks the shape pairing (" + "; ".join(broken) + ")"
        return None

    def macs(self, state) -> dict:
        """``{condition: {test_mode: (label, MAC)}}`` of the model ``state``."""
        return {name: {pair.test_mode: (pair.label, pair.mac) for pair in correlation.pairs}
                for name, correlation in self.correlations(state).items()}


def base_shape_macs(pairings) -> dict:
    """``{condition: {test_mode: (label, MAC)}}`` of the base model (:meth:`ShapeCheck.macs`'s
    form)."""
    return {pairing.condition: {pair.test_mode: (pair.label, pair.mac)
                                for pair in pairing.correlation.pairs}
            for pairing in pairings}


def step_mac_lines(before: dict, after: dict) -> list[str]:
    """report.md's table of a step: each shape pair's label and MAC before -> after."""
    lines = ["Shape pairing of the scans, before -> after this step (label, MAC):", "",
             "| condition | test mode | before | after |", "|---|---|---|---|"]
    for name, pairs in after.items():
        for test_mode, (label, mac) in pairs.items():
            old_label, old_mac = before.get(name, {}).get(test_mode, ("", math.nan))
            shown = [f"{lab or 'unpaired'}" + (f" {value:.3f}" if lab else "")
                     for lab, value in ((old_label, old_mac), (label, mac))]
            lines.append(f"| {name} | {test_mode} | {shown[0]} | {shown[1]} |")
    return lines + [""]


def pairing_report_lines(pairings) -> list[str]:
    """report.md's section on the scans: each pair's MAC against the base model."""
    if not pairings:
        return []
    lines = ["## Shape pairing (vibrometer scans)", "",
             ("Peaks identified in the scans (no FE input) and labelled by the FE mode of the "
              "base model whose shape they match (largest total MAC, one-to-one; a split "
              "pair compared as a subspace); a labelled peak pairs only with that mode."), ""]
    for pairing in pairings:
        correlation = pairing.correlation
        lines += [f"### {pairing.condition}", "",
                  "| test mode | f [Hz] | Q | label (by shape) | base FE [Hz] | MAC |",
                  "|---|---|---|---|---|---|"]
        for pair in correlation.pairs:
            quality = (1 / (2 * pair.test_damping_ratio) if pair.test_damping_ratio > 0
                       else math.nan)
            lines.append(f"| {pair.test_mode} | {pair.test_freq_hz:.2f} | {quality:.3g} | "
                         f"{pair.label or 'unpaired'} | "
                         + (f"{pair.fe_freq_hz:.2f} | {pair.mac:.3f} |" if pair.label
                            else "- | - |"))
        lines.append("")
    return lines


__all__ = ["ScanPairing", "ShapeCheck", "base_shape_macs", "pairing_report_lines",
           "resonances_from_scans", "step_mac_lines"]
