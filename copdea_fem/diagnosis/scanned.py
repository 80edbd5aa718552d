"""Vibrometer scans and mode sets as the diagnosis's measured peaks: identified, and
labelled by shape.

A condition with a ``scan:`` (or a ``modes:`` mode set) and no ``resonances:`` gets its
resonance list from it:

1. its modes are identified (:func:`copdea_fem.vibrometer.identification.identify`, in the
   condition's band; nothing from the FE): frequency, damping ratio zeta, shape; a mode
   set's modes are the file's, within the band
   (:func:`copdea_fem.vibrometer.given_modes.modes_of_set`);
2. they are paired by shape with the base model's FE modes at that condition
   (:func:`copdea_fem.vibrometer.model_shapes.fe_shapes`, the FE the diagnosis runs:
   :func:`scan_fe_study`; one-to-one, largest total MAC within the ``pairing:`` window,
   :mod:`copdea_fem.vibrometer.pairing`);
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
Steps 1 and 2 are :func:`pair_condition`, which ``copdea-fem correlate`` calls as well: one
FE study (:func:`scan_fe_study`) and one pairing, so that pairs.csv and the diagnosis's
report give the same labels and the same FE frequencies.
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np

from copdea_fem.measured import MeasuredSet, Resonance, normalise_label

logger = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True)
class ScanPairing:
    """One scanned condition's identification and shape pairing (for the report and the
    shape check of each step, :class:`ShapeCheck`)."""

    condition: str
    correlation: object            # copdea_fem.vibrometer.pairing.Correlation
    resonances: tuple
    modes: tuple = ()              # the test modes (IdentifiedMode): identified, or a mode set's
    scan: object = None            # their channels: the scan, or the mode set's (ScanData)
    f_max: float = math.nan        # top of the FE band [Hz]


def pairing_settings(measured: MeasuredSet) -> tuple[float, float]:
    """The pairing's relative frequency window and smallest MAC: measured.yaml's
    ``pairing:``, else :mod:`copdea_fem.vibrometer.pairing`'s defaults."""
    from copdea_fem.vibrometer.pairing import DEFAULT_MAC_MIN, DEFAULT_WINDOW

    settings = measured.pairing
    if settings is None:
        return DEFAULT_WINDOW, DEFAULT_MAC_MIN
    return settings.window, settings.mac_min


def scan_fe_study(measured: MeasuredSet, condition, state=None):
    """The FE study the measured shapes of ``condition`` are paired with: the base study at
    the condition (with the diagnosis ``state``'s effects on, when given) as the diagnosis's
    FE solves it (:func:`copdea_fem.diagnosis.fe.fe_study`: in vacuo on the axisymmetric
    engine, the frame and the enclosure acting only through the air), its band reaching
    the pairing window past the condition's, ``f_max = f_high (1 + window)`` [Hz]."""
    from copdea_fem.diagnosis.fe import fe_study

    study = measured.study_of(condition)
    if state:
        from copdea_fem.diagnosis.ring_predictor import state_overrides
        study = study.replace(state_overrides(study, state))
    window, _ = pairing_settings(measured)
    return fe_study(study, f_max=condition.band[1] * (1 + window))


def condition_test_modes(condition, resolve_pairs: bool = False) -> tuple:
    """The test modes of a condition and the channels they lie on: a scan's modes
    identified in the band (nothing from the FE; ``resolve_pairs``: the measured.yaml's
    ``identification.resolve_pairs``), or a mode set's modes in the band.

    Returns
    -------
    (tuple of IdentifiedMode, ScanData)
    """
    low, high = condition.band
    if condition.mode_set is not None:
        from copdea_fem.vibrometer.given_modes import modes_of_set
        return modes_of_set(condition.mode_set, low, high), condition.mode_set.channels
    from copdea_fem.vibrometer.identification import condition_band, identify
    low, high = condition_band(condition)
    return (identify(condition.scan, f_min=low, f_max=high, resolve_pairs=resolve_pairs),
            condition.scan)


def pair_condition(measured: MeasuredSet, condition, *, solve=None) -> ScanPairing:
    """One condition's test modes (:func:`condition_test_modes`) paired by shape with the FE's
    (:func:`scan_fe_study`, :func:`copdea_fem.vibrometer.model_shapes.fe_shapes`): the
    pairing of both ``correlate`` and ``diagnose``.

    Parameters
    ----------
    measured : MeasuredSet
    condition : Condition
        A condition with a scan or a mode set.
    solve : callable, optional
        ``solve(study) -> SolveResult`` (default: the study's engine,
        :func:`copdea_fem.vibrometer.model_shapes.fe_shapes`).

    Returns
    -------
    ScanPairing
        ``resonances`` empty (:func:`resonances_from_scans` fills them).
    """
    from copdea_fem.vibrometer.model_shapes import correlate_identified, fe_shapes

    window, mac_min = pairing_settings(measured)
    modes, channels = condition_test_modes(
        condition, resolve_pairs=measured.identification.get("resolve_pairs", False))
    study = scan_fe_study(measured, condition)
    logger.info("%s: %d test modes (%s); FE modes at the %d measured points", condition.name,
                len(modes), "mode set" if condition.mode_set is not None else "identified",
                channels.n_points)
    correlation = correlate_identified(condition.name, modes,
                                       fe_shapes(study, channels, solve=solve),
                                       window=window, mac_min=mac_min)
    return ScanPairing(condition.name, correlation, (), tuple(modes), channels,
                       float(study.eigen.f_max))


def _resonance(pair) -> Resonance | None:
    """A test mode as a resonance (module notes, step 3); None: an in-plane mode."""
    quality = (1 / (2 * pair.test_damping_ratio)
               if math.isfinite(pair.test_damping_ratio) and pair.test_damping_ratio > 0
               else math.nan)
    if pair.label.startswith("ip"):
        return None
    label, kind = normalise_label(pair.label, "scan label") if pair.label else ("", "")
    return Resonance(pair.test_freq_hz, label, kind, quality)


def _merge_unresolved(resonances: list, correlation, energies: list) -> list:
    """Two test modes on the members of a pair the diagnosis's FE merges: one peak, at the
    members' mean frequency, with their quality factors weighted by ``energies`` (each
    test mode's residue energy sum |A|^2): the stronger member makes the peak's width, and
    a member a tenth of a half-power width from its partner has an ill-determined damping
    (the example scan's (6,1): 0.8 Hz apart at 6.25 Hz lines, MPC 0.55, Q 71 against the
    true 86.5; its partner 17 times stronger, Q 84)."""
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
        members = [(q, w) for q, w in ((resonance.quality_factor, energies[index]),
                                       (other.quality_factor, energies[partner]))
                   if math.isfinite(q)]
        if sum(w for _, w in members) <= 0:              # no residues: the plain mean
            members = [(q, 1.0) for q, _ in members]
        quality = (sum(q * w for q, w in members) / sum(w for _, w in members)
                   if members else math.nan)
        out.append(Resonance(0.5 * (resonance.frequency_hz + other.frequency_hz), label[:-1],
                             resonance.kind, quality))
    return out


def resonances_from_scans(measured: MeasuredSet) -> tuple[MeasuredSet, tuple]:
    """``measured`` with a resonance list for every condition that has a scan and none of
    its own (module notes), and the :class:`ScanPairing` of each such condition.

    Conditions without a scan or mode set, or with their own ``resonances:``, are kept as
    they are.
    """
    conditions, pairings = [], []
    for condition in measured.conditions:
        if not condition.shapes_measured or condition.resonances is not None:
            conditions.append(condition)
            continue
        low, high = condition.band
        pairing = pair_condition(measured, condition)
        correlation, modes = pairing.correlation, pairing.modes
        energy = {mode.test_mode: float(np.sum(np.abs(mode.shape) ** 2)) for mode in modes}
        resonances, energies = [], []
        for pair in correlation.pairs:
            resonance = _resonance(pair)
            if resonance is not None:
                resonances.append(resonance)
                energies.append(energy[pair.test_mode])
        resonances = tuple(sorted(_merge_unresolved(resonances, correlation, energies),
                                  key=lambda r: r.frequency_hz))
        logger.info("%s: %d test modes, %d paired by shape, %d resonances",
                    condition.name, len(modes),
                    sum(1 for pair in correlation.pairs if pair.label), len(resonances))
        pairings.append(dataclasses.replace(pairing, resonances=resonances))
        conditions.append(dataclasses.replace(condition, resonances=resonances or None))
        if not resonances and condition.spectrum is None:
            from copdea_fem.measured import MeasuredDataError
            kind = "modes" if condition.mode_set is not None else "scan"
            raise MeasuredDataError(f"{condition.name}: {kind} {condition.files.get(kind)}: "
                                    "no mode in the band "
                                    f"[{low:g} Hz, {high:g} Hz]; allowed: a {kind} with at "
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
        self.window, self.mac_min = pairing_settings(measured)
        self._cache: dict = {}

    def correlations(self, state) -> dict:
        """``{condition: Correlation}`` of the model ``state`` (FE solved once per state)."""
        from copdea_fem.vibrometer.model_shapes import correlate_identified, fe_shapes

        key = repr(state)
        if key not in self._cache:
            out = {}
            for condition in self.measured.conditions:
                pairing = self.pairings.get(condition.name)
                if pairing is None:
                    continue
                study = scan_fe_study(self.measured, condition, state)
                out[condition.name] = correlate_identified(
                    condition.name, pairing.modes, fe_shapes(study, pairing.scan),
                    window=self.window, mac_min=self.mac_min, warn=False)   # said once
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


__all__ = ["ScanPairing", "ShapeCheck", "base_shape_macs", "condition_test_modes",
           "pair_condition", "pairing_report_lines", "pairing_settings", "resonances_from_scans",
           "scan_fe_study", "step_mac_lines"]
