"""Report of a diagnosis: ``report.md``, ``diagnosis.json``, PNG figures, ``final_study.yaml``.

``diagnosis.json`` is a contract (other scripts read it): at least
``missing_effects`` (ordered effect identifiers), ``ambiguous`` (list of
groups the data cannot separate), ``gap_before``, ``gap_after`` and
``history`` (one entry per step, the base model first).

Figures: ``gap_history.png`` (the gap before and after each step),
``frequencies.png`` (model vs measured frequency per mode, base and final
model, like Fig. 10), ``spectra_<condition>.png`` (measured vs base and
final model average spectra, like Fig. 12) for every condition with a
spectrum.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import yaml

from copdea_fem.diagnosis.compare import GATE, gap_parts
from copdea_fem.diagnosis.effects import CATALOGUE, catalogue_table
from copdea_fem.diagnosis.evidence import explained
from copdea_fem.diagnosis.peaks import peak_height, peak_width
from copdea_fem.diagnosis.ring_predictor import state_overrides
from copdea_fem.diagnosis.scanned import base_shape_macs, pairing_report_lines, step_mac_lines
from copdea_fem.folders import package_versions


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _pct(value) -> str:
    return "n/a" if value is None or not math.isfinite(value) else f"{100 * value:+.1f} %"


def _state_json(state) -> list:
    return [{"effect": e, "parameters": {p.name: float(v) for p, v in
                                         zip(CATALOGUE[e].parameters, values)}}
            for e, values in state]


def final_study(result):
    """The base study with the final state's effects switched on."""
    base = result.measured.base_study
    return base.replace(state_overrides(base, result.final_state)) if result.final_state \
        else base


def _pair_rows(result, name, which) -> list:
    matches = (result.matches_before if which == "before" else result.matches_after)[name]
    prediction = (result.predictions_before if which == "before"
                  else result.predictions_after)[name]
    condition = next(c for c in result.measured.conditions if c.name == name)
    spectrum = condition.spectrum
    model_spectrum = None
    if spectrum is not None and prediction is not None:
        model_spectrum = prediction.spectra()       # None: the FE evaluated directly
    rows = []
    for pair in matches.pairs:
        row = {"model_label": pair.model.label, "model_hz": pair.model.frequency_hz,
               "measured_hz": pair.peak.frequency_hz, "measured_label": pair.peak.label,
               "by": pair.by, "relative_error": pair.relative_error,
               "model_quality": _finite(pair.model.quality_factor),
               "measured_quality": _finite(pair.peak.quality_factor),
               "amplitude_ratio": None, "width_ratio": None}
        if model_spectrum is not None:
            measured_sum = spectrum.axial + spectrum.radial
            model_sum = model_spectrum.average_axial + model_spectrum.average_radial
            if spectrum.point != "average":
                index = int(spectrum.point[1]) - 1
                model_sum = (model_spectrum.point_axial[:, index]
                             + model_spectrum.point_radial[:, index])
            h_meas = peak_height(spectrum.frequency_hz, measured_sum, pair.peak.frequency_hz)
            h_model = peak_height(model_spectrum.frequency_hz, model_sum, pair.model.frequency_hz)
            w_meas = peak_width(spectrum.frequency_hz, measured_sum, pair.peak.frequency_hz)
            w_model = peak_width(model_spectrum.frequency_hz, model_sum, pair.model.frequency_hz)
            row["amplitude_ratio"] = _finite(h_model / h_meas) if h_meas > 0 else None
            row["width_ratio"] = _finite(w_model / w_meas) if w_meas > 0 else None
        rows.append(row)
    return rows


def _finite(value):
    return float(value) if value is not None and math.isfinite(value) else None


def _condition_json(result, name) -> dict:
    out = {}
    for which, matches in (("before", result.matches_before), ("after", result.matches_after)):
        m = matches[name]
        out[which] = {
            "deviance": m.deviance, "pairs": _pair_rows(result, name, which),
            "unseen_model_modes": [{"label": x.label, "model_hz": x.frequency_hz}
                                   for x in m.unseen],
            "unexplained_peaks": [{"measured_hz": p.frequency_hz, "label": p.label,
                                   "kind": p.kind} for p in m.unexplained],
            "out_of_scope_peaks": [{"measured_hz": p.frequency_hz, "label": p.label}
                                   for p in m.out_of_scope]}
    return out


def diagnosis_document(result) -> dict:
    """The content of ``diagnosis.json`` (module notes)."""
    measured = result.measured
    history = [{"step": 0, "action": "base", "effects": [], "parameters": {},
                "gap": result.gap_before, "gap_after": result.gap_before,
                "deviance": result.deviance_before}]
    state_gap = result.gap_before
    for step in result.steps:
        history.append({
            "step": step.index, "action": step.action, "effects": list(step.effects),
            "parameters": step.values, "gap_before": step.gap_before,
            "gap_after": step.gap_after, "gap": step.gap_after,
            "deviance_before": step.deviance_before, "deviance_after": step.deviance_after,
            "delta_cv": _finite(step.score.delta_cv) if step.effects else None,
            "log_evidence": _finite(step.score.log_evidence) if step.effects else None,
            "threshold": step.score.threshold if step.effects else None,
            "evidence": step.evidence, "ambiguous_with": list(step.ambiguous_with),
            "separation": step.separation,
            "candidates": [{"effects": list(c.effects), "values": list(c.values),
                            "described": c.described(), "delta_in": _finite(c.delta_in),
                            "delta_cv": _finite(c.delta_cv),
                            "log_evidence": _finite(c.log_evidence), "threshold": c.threshold,
                            "significant": c.significant, "at_bound": list(c.at_bound)}
                           for c in step.candidates]})
        state_gap = step.gap_after
    return {
        "measured": {"name": measured.name, "path": str(measured.path) if measured.path else None,
                     "conditions": [{"name": c.name, "set": {k: str(v) for k, v in
                                                             c.overrides.items()},
                                     "band_hz": list(c.band)} for c in measured.conditions],
                     "noise": vars(measured.noise)},
        "missing_effects": list(result.missing_effects),
        "ambiguous": [list(g) for g in result.ambiguous],
        "gap_before": result.gap_before, "gap_after": result.gap_after,
        "deviance_before": result.deviance_before, "deviance_after": result.deviance_after,
        "history": history, "final_state": _state_json(result.final_state),
        "final_gap": state_gap, "status": result.status, "not_tested": result.not_tested,
        "base_on": result.base_on, "goodness": result.goodness, "verdict": result.verdict,
        "per_condition": {c.name: _condition_json(result, c.name) for c in measured.conditions},
        "statistics": {"alpha": result.alpha, "cross_validated": result.cross_validated,
                       "gate": GATE, "test": "prequential likelihood ratio U (each condition "
                       "scored with parameters fitted on the conditions before it, mean over "
                       "3 cyclic orderings): accept when ln U >= ln(N/alpha) and Delta_cv = "
                       "sum of leave-one-condition-out improvements > 0; ambiguous when the "
                       "best's prequential likelihood over a rival's full-data maximum "
                       "likelihood is below 1/alpha",
                       "gap": "sqrt((sum r^2 + GATE^2 N_excess) / (N_pairs + N_excess)), r = "
                       "f_model/f_meas - 1, N_excess = unexplained + unseen beyond E + 2 "
                       "sqrt(V) of the noise model"},
        "model_of_record": result.model,
        "fe": {"solves": result.fe_solves, "seconds": result.fe_seconds},
        "engines": result.engines,
        "explained": explained(result), "remaining_off": result.remaining_off,
        "ring_convergence": result.ring_convergence,
        "rejected": result.rejected,
        "acceptance": "an effect that passes the test is accepted only when, evaluated "
                      "exactly (FE re-solved at the fitted values), the gap and the deviance "
                      "both fall; a fit at a bound of its range is never accepted",
        "final_study": "final_study.yaml", "provenance": package_versions(),
        "imperfections": (result.imperfections.document()
                          if result.imperfections is not None else None)}


# -- figures ---------------------------------------------------------------------------------
def plot_gap_history(path, result):
    plt = _pyplot()
    labels = ["base"] + [f"{s.index}: {'+'.join(s.effects) or 'none'}"
                         + (" (?)" if s.action == "ambiguous" else "")
                         for s in result.steps if s.effects]
    values = [result.gap_before] + [s.gap_after for s in result.steps if s.effects]
    fig, axis = plt.subplots(figsize=(max(4, 1.6 * len(values)), 3.5))
    axis.bar(range(len(values)), [100 * v for v in values], color="0.55")
    for i, v in enumerate(values):
        axis.text(i, 100 * v, f"{100 * v:.1f} %", ha="center", va="bottom", fontsize=8)
    axis.set_xticks(range(len(values)))
    axis.set_xticklabels(labels, fontsize=7, rotation=15, ha="right")
    axis.set_ylabel("gap [%]")
    axis.set_title(f"{result.measured.name}: gap before and after each step", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def plot_frequencies(path, result):
    """Model vs measured natural frequencies per mode (style of Fig. 10)."""
    plt = _pyplot()
    fig, axis = plt.subplots(figsize=(5.5, 5))
    markers = {}
    symbols = "osD^v<>ph*"
    low, high = math.inf, 0.0
    for which, matches, fill in (("base", result.matches_before, False),
                                 ("final", result.matches_after, True)):
        for m in matches.values():
            for pair in m.pairs:
                label = pair.model.label
                marker = markers.setdefault(label, symbols[len(markers) % len(symbols)])
                x, y = pair.peak.frequency_hz, pair.model.frequency_hz
                low, high = min(low, x, y), max(high, x, y)
                axis.plot(x, y, marker, ms=5, mfc=f"C{list(markers).index(label) % 10}"
                          if fill else "none", mec=f"C{list(markers).index(label) % 10}",
                          ls="none")
    if high > 0:
        span = np.array([0.8 * low, 1.25 * high])
        axis.plot(span, span, "k--", lw=0.8)
        axis.plot(span, 1.08 * span, ":", color="0.6", lw=0.8)
        axis.plot(span, span / 1.08, ":", color="0.6", lw=0.8)
        axis.set_xlim(span)
        axis.set_ylim(span)
    axis.set_xscale("log")
    axis.set_yscale("log")
    for label, marker in markers.items():
        axis.plot([], [], marker, color=f"C{list(markers).index(label) % 10}", ls="none",
                  label=label)
    axis.plot([], [], "o", mfc="none", mec="k", ls="none", label="base model")
    axis.plot([], [], "o", color="k", ls="none", label="final model")
    axis.legend(fontsize=7, loc="upper left")
    axis.set_xlabel("measured frequency [Hz]")
    axis.set_ylabel("model frequency [Hz]")
    axis.set_title("model vs measured frequency (dotted: +-8 %)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def plot_spectra(path, result, condition):
    """Measured vs base and final model spectra (style of Fig. 12), mm/s, log scale."""
    plt = _pyplot()
    spectrum = condition.spectrum
    fig, axes = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    models = []
    for which, predictions, style in (("base model", result.predictions_before, "-"),
                                      ("final model", result.predictions_after, "-")):
        prediction = predictions[condition.name]
        if prediction is not None and prediction.spectra() is not None:
            models.append((which, prediction.spectra(), style))
    for axis, name in ((axes[0], "axial"), (axes[1], "radial")):
        measured = spectrum.axial if name == "axial" else spectrum.radial
        axis.plot(spectrum.frequency_hz, 1e3 * measured, "r--", lw=0.8, label="measured")
        for (which, model, style), color in zip(models, ("0.6", "k")):
            if spectrum.point == "average":
                values = model.average_axial if name == "axial" else model.average_radial
            else:
                column = int(spectrum.point[1]) - 1
                values = (model.point_axial if name == "axial" else model.point_radial)[:, column]
            axis.plot(model.frequency_hz, 1e3 * values, style, color=color, lw=0.9, label=which)
        axis.set_yscale("log")
        axis.set_ylabel(f"{name} velocity [mm/s]")
        axis.legend(fontsize=7)
    axes[-1].set_xlabel("frequency [Hz]")
    fig.suptitle(f"{result.measured.name}, {condition.name} ({spectrum.point} spectrum)",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


# -- markdown -------------------------------------------------------------------------------
def _fmt(value, digits=1, unit=""):
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return f"{value:.{digits}f}{unit}"


def model_of_record_lines(result) -> list:
    """The report's section on the model of record, the surrogate's convergence and the
    steps the acceptance rule refused."""
    lines = ["## Model of record", ""]
    if result.model == "fe" and result.engines.get("states") is not None:
        states = "; ".join(f"{k}: {', '.join(v)} engine" for k, v in
                           result.engines["states"].items())
        lines += [f"The FE as the base study is written, evaluated **directly** at every "
                  f"effect state (the ring surrogate cannot represent a membrane without a "
                  f"central disc), solved {result.fe_solves} time(s) in "
                  f"{result.fe_seconds:.0f} s (others from the FE cache); a parameter is "
                  f"tabulated on {result.engines['fitted_grid']} and interpolated.  Effects "
                  f"the FE does not model are not tested.  Engines per state: {states}.", ""]
    elif result.model == "fe":
        lines += [f"The FE as the base study is written (in vacuo where `air.enabled` is "
                  f"false, coupled with the air and its frame where true), solved "
                  f"{result.fe_solves} time(s) in {result.fe_seconds:.0f} s (others from the "
                  "FE cache); the ring model is its surrogate for the fits, anchored to it "
                  "mode by mode at every accepted step (copdea_fem.diagnosis.anchored).  "
                  "Model quality factors: the FE's damping ratios (radiation, and the "
                  "membrane's Rayleigh or Prony damping) plus the ring model's modal b/m, "
                  "Q = 1/(2 zeta).", ""]
    else:
        lines += ["The ring model alone (`model: reduced` in measured.yaml): the FE takes no "
                  "part; right for data the ring model made (`copdea-fem synth`).", ""]
    rc = result.ring_convergence
    if rc:
        error = f"{100 * rc['largest_error']:+.2f} %"
        if rc["converged"]:
            lines += [f"Ring surrogate: `reduced.rings = {rc['rings']}` is within the data's "
                      f"scatter of the FE in vacuo (largest error {error} on {rc['label']}).",
                      ""]
        else:
            advice = (f"set `reduced.rings: {rc['suggested_rings']}` in the base study "
                      f"(error {100 * rc['suggested_error']:+.2f} %)"
                      if rc["suggested_rings"] else "raise `reduced.rings`")
            lines += [f"**Warning: the ring surrogate is not converged for the data's "
                      f"scatter.** With `reduced.rings = {rc['rings']}` it is {error} off the FE "
                      f"in vacuo on {rc['label']} ({rc['condition']}), more than sigma_f = "
                      f"{100 * rc['sigma']:g} %.  The anchor removes this at the anchor "
                      "points, but parameter fits that move modes far from them may be "
                      f"biased: {advice}.", ""]
    if result.rejected:
        lines += ["Significant fits the acceptance rule refused (an accepted step must lower "
                  "the gap and the deviance, evaluated exactly):", ""]
        lines += [f"- step {r['step']}: {r['effect']} ({r['values']}): {r['reason']}"
                  for r in result.rejected]
        lines.append("")
    return lines


def _gap_parts_line(result) -> str:
    """The gap's two parts, base -> final: the paired RMS error and the count penalty."""
    parts = [gap_parts(matches.values()) for matches in (result.matches_before,
                                                         result.matches_after)]
    rms = " -> ".join("-" if math.isnan(p["paired_rms"]) else f"{100 * p['paired_rms']:.2f} %"
                      for p in parts)
    excess = " -> ".join(f"{p['excess']:.1f}" for p in parts)
    observed = (f" (observed families: {', '.join(result.measured.observed.families)}; "
                "model modes outside them cost nothing)"
                if result.measured.observed else "")
    return (f"- paired RMS error: {rms} over the pairs; count penalty: {excess} peaks or "
            f"modes beyond the noise model, each counted as a {100 * GATE:.0f} % error"
            + observed)


def report_markdown(result, document: dict, figures: list) -> str:
    measured = result.measured
    lines = [f"# Diagnosis: {measured.name}", ""]
    if measured.description:
        lines += [measured.description, ""]
    lines += ["**Verdict.** " + result.verdict, "",
              f"- missing effects (in order): {', '.join(result.missing_effects) or 'none'}",
              f"- ambiguous: {'; '.join(' / '.join(g) for g in result.ambiguous) or 'none'}",
              *([f"- imperfections (split pairs): {result.imperfections.verdict}"]
                if result.imperfections is not None else []),
              f"- gap: {100 * result.gap_before:.2f} % (base model) -> "
              f"{100 * result.gap_after:.2f} % (final model)",
              _gap_parts_line(result),
              f"- explained: {explained(result)}"
              + ("; modes still off beyond the noise: "
                 + ", ".join(i["label"] for i in result.remaining_off)
                 if result.remaining_off else ""), ""]
    if result.imperfections is not None:
        lines += result.imperfections.lines()
    lines += pairing_report_lines(result.scan_pairings)
    lines += ["## Data", "",
              "| condition | overrides | peaks in scope | out of scope | spectrum | band [Hz] |",
              "|---|---|---|---|---|---|"]
    for c in measured.conditions:
        m = result.matches_before[c.name]
        in_scope = len(m.pairs) + len(m.unexplained)
        spectrum = f"{c.spectrum.point}" if c.spectrum is not None else "-"
        source = "resonances" if c.resonances is not None else "picked from spectrum"
        overrides = ", ".join(f"`{k}={v}`" for k, v in c.overrides.items()) or "(base)"
        lines.append(f"| {c.name} | {overrides} | {in_scope} ({source}) | "
                     f"{len(m.out_of_scope)} | {spectrum} | {c.band[0]:g}-{c.band[1]:g} |")
    n = measured.noise
    lines += ["", f"Noise model: sigma_f = {100 * n.frequency_relative:g} %, sigma_Q = "
                  f"{100 * n.quality_relative:g} %, p_miss = {n.missing_probability:g}, "
                  f"lambda_s = {n.spurious_per_condition:g} spurious peaks per condition.  "
                  + ("Non-axisymmetric peaks are scored against the FE's (m,n) modes "
                     "(optional: their absence costs nothing)." if result.model == "fe" else
                     "Non-axisymmetric peaks are outside the ring model's scope and not "
                     "scored (model: reduced)."), ""]
    lines += model_of_record_lines(result)
    lines += ["## Gap before and after each step", "",
              "Gap = sqrt((sum r^2 + G^2 N_excess) / (N_pairs + N_excess)): the RMS relative "
              "frequency error r = f_model/f_meas - 1 over the paired modes, each unexplained "
              "peak or unseen mode beyond what the noise model expects counting as an error "
              f"of G = {100 * GATE:g} % (the pairing gate).", "",
              "| step | action | effects | parameters | gap | deviance | Delta_cv | ln U | "
              "threshold |", "|---|---|---|---|---|---|---|---|---|",
              f"| 0 | base | - | - | {100 * result.gap_before:.2f} % | "
              f"{result.deviance_before:.1f} | - | - | - |"]
    for step in result.steps:
        if not step.effects:
            best = step.score
            lines.append(f"| {step.index} | stop: best candidate {best.described()} not "
                         f"significant | - | - | {100 * step.gap_after:.2f} % | "
                         f"{step.deviance_after:.1f} | {_fmt(best.delta_cv)} | "
                         f"{_fmt(best.log_evidence, 2)} | {best.threshold:.2f} |")
            continue
        params = "; ".join(f"{e}: " + ", ".join(f"{k} = {CATALOGUE[e].parameters[i].shown(v)}"
                                                 for i, (k, v) in enumerate(p.items()))
                           for e, p in step.values.items() if p) or "-"
        lines.append(f"| {step.index} | {step.action} | {' + '.join(step.effects)} | {params} | "
                     f"{100 * step.gap_after:.2f} % | {step.deviance_after:.1f} | "
                     f"{_fmt(step.score.delta_cv)} | {_fmt(step.score.log_evidence, 2)} | "
                     f"{step.score.threshold:.2f} |")
    lines += ["", "![gap](gap_history.png)", ""]
    lines += ["## Steps", ""]
    if not result.steps:
        lines += ["No candidate effect could be tested.", ""]
    shape_before = base_shape_macs(result.scan_pairings)
    for step in result.steps:
        if not step.effects:
            lines += [f"### Step {step.index}: stop", "",
                      "No remaining candidate passes the test (ln U >= ln(N / alpha) and "
                      "Delta_cv > 0):", ""]
        else:
            title = "added" if step.action == "added" else "ambiguous (kept provisionally)"
            lines += [f"### Step {step.index}: {title}: {step.score.described()}", ""]
            entry = CATALOGUE[step.effects[-1]]
            lines += [f"*{entry.title}* ({entry.kind}). Expected signature: {entry.signature}.",
                      "", "Evidence, the residual patterns it removed:", ""]
            lines += [f"- {e}" for e in step.evidence] or ["- (no single pattern stands out; "
                                                           "the deviance fell)"]
            lines += ["", f"Test: ln U = {step.score.log_evidence:.2f} >= "
                          f"{step.score.threshold:.2f}, Delta_cv = {step.score.delta_cv:.1f}; "
                          f"gap {100 * step.gap_before:.2f} % -> {100 * step.gap_after:.2f} %.",
                      ""]
            for sep in step.separation:
                lines += [_separation_text(sep, measured.noise.frequency_relative), ""]
            if step.shape_macs:
                lines += step_mac_lines(shape_before, step.shape_macs)
                shape_before = step.shape_macs
        lines += ["| candidate | fitted | Delta_in | Delta_cv | ln U | threshold | "
                  "significant |", "|---|---|---|---|---|---|---|"]
        for c in step.candidates:
            lines.append(f"| {' + '.join(c.effects)} | {c.described()} | {_fmt(c.delta_in)} | "
                         f"{_fmt(c.delta_cv)} | {_fmt(c.log_evidence, 2)} | "
                         f"{c.threshold:.2f} | {'yes' if c.significant else 'no'} |")
        lines.append("")
    if result.ambiguous:
        lines += ["## Ambiguities", ""]
        for group in result.ambiguous:
            lines.append(f"- {' / '.join(group)}: the data cannot separate them; none is named "
                         "missing. Signatures: " + "; ".join(
                             f"{e}: {CATALOGUE[e].signature}" for e in group) + ".")
        lines.append("")
    lines += ["## Effects", "", "| effect | kind | engine | status |", "|---|---|---|---|"]
    for effect_id, entry in CATALOGUE.items():
        lines.append(f"| `{effect_id}` | {entry.kind} | {entry.engine} | "
                     f"{result.status[effect_id]} |")
    lines += [""]
    for effect_id, entry in CATALOGUE.items():
        if entry.not_tested_note and effect_id in result.not_tested:
            lines += [entry.not_tested_note, ""]
    lines += ["## Model vs measured", "", "![frequencies](frequencies.png)", ""]
    for c in measured.conditions:
        lines += [f"### {c.name}", "",
                  "| mode | measured [Hz] | label | base [Hz] | base error | final [Hz] | "
                  "final error | Q model/meas | amplitude ratio | width ratio |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        before = {p["measured_hz"]: p for p in document["per_condition"][c.name]["before"]
                  ["pairs"]}
        after = document["per_condition"][c.name]["after"]
        for p in after["pairs"]:
            b = before.get(p["measured_hz"])
            q = (p["model_quality"] / p["measured_quality"]
                 if p["model_quality"] and p["measured_quality"] else None)
            lines.append(f"| {p['model_label']} | {p['measured_hz']:.1f} | "
                         f"{p['measured_label'] or '-'} | "
                         f"{_fmt(b['model_hz']) if b else '-'} | "
                         f"{_pct(b['relative_error']) if b else '-'} | {p['model_hz']:.1f} | "
                         f"{_pct(p['relative_error'])} | {_fmt(q, 2)} | "
                         f"{_fmt(p['amplitude_ratio'], 2)} | {_fmt(p['width_ratio'], 2)} |")
        for x in after["unseen_model_modes"]:
            lines.append(f"| {x['label']} (predicted, not seen) | - | - | - | - | "
                         f"{x['model_hz']:.1f} | - | - | - | - |")
        for x in after["unexplained_peaks"]:
            lines.append(f"| (unexplained {x['kind'] or 'peak'}) | {x['measured_hz']:.1f} | "
                         f"{x['label'] or '-'} | - | - | - | - | - | - | - |")
        for x in after["out_of_scope_peaks"]:
            lines.append(f"| (non-axisymmetric: FE engine) | {x['measured_hz']:.1f} | "
                         f"{x['label'] or '-'} | - | - | - | - | - | - | - |")
        if f"spectra_{c.name}.png" in figures:
            lines += ["", f"![spectra {c.name}](spectra_{c.name}.png)"]
        lines.append("")
    g = result.goodness
    lines += ["## Goodness of fit (final model)", "",
              f"{g['inliers']} paired modes within 4 sigma_f ({g['outliers']} beyond): rms "
              f"ln(f_meas/f_model) = {_fmt(100 * g['rms_log_error'], 2)} % against sigma_f = "
              f"{100 * g['sigma']:g} %; chi^2 = {g['chi2']:.1f}, p = {_fmt(g['p_value'], 3)}.",
              ""]
    lines += ["## Final model", "",
              "`final_study.yaml` is the base study with the effects switched on (the "
              "conditions' own overrides are not in it); rerun a condition with e.g.", "",
              "```bash", "copdea-fem spectrum final_study.yaml "
              + " ".join(f"--set {k}='{v}'" for k, v in measured.conditions[0].overrides.items()),
              "```", ""]
    lines += ["## Method", "",
              "Engine: the reduced model (Sect. 3.2, Annex I) with the effect keys of the "
              "`effects` section; air loading from the condition's modes.json when given, else "
              "an incompressible-air added mass on both faces.  Matching one-to-one (labels "
              "first, then an assignment on ln f within a 50 % gate, pumping vs membrane kind "
              "respected).  Deviance = -2 ln L of a mixture noise model (Gaussian ln f with "
              "sigma_f, missed modes p_miss, spurious peaks lambda_s).  Each candidate is fitted "
              "by maximum likelihood (with the parameters of the effects added before), ranked "
              "by its leave-one-condition-out improvement Delta_cv, and accepted when its "
              "prequential likelihood ratio U (each condition scored with parameters fitted on "
              f"the conditions before it) satisfies ln U >= ln(N / alpha), alpha = "
              f"{result.alpha:g}: a test martingale, so P(false alarm) <= alpha per step.  Two "
              "significant candidates that the same test cannot separate (the best's "
              "prequential likelihood against the rival's full-data maximum likelihood) are "
              "reported as ambiguous." + ("" if result.cross_validated else
                              "  With a single condition there is nothing to hold out: the "
                              "in-sample likelihood ratio with Wilks' threshold was used."), "",
              "### Catalogue", "", catalogue_table(), ""]
    return "\n".join(lines)


def _separation_text(sep, sigma) -> str:
    vacuo = (f"  A measurement in vacuo separates them: {sep['first']} or {sep['second']} "
             "acts through the air only, the other does not." if sep.get("in_vacuo") else "")
    if sep.get("condition"):                       # the FE evaluated directly: mode by mode
        return (f"To separate {sep['first']} from {sep['second']}: the two fitted models "
                f"differ most on {sep['label']} at {sep['condition']} ({sep['first']} "
                f"{sep['first_hz']:.1f} Hz, {sep['second']} {sep['second_hz']:.1f} Hz: "
                f"{sep['sigma']:.1f} sigma_f, sigma_f = {100 * sigma:g} %): measure that mode "
                "(labelled, several times) and the (0,n) modes." + vacuo)
    if not sep.get("label"):
        return (f"No operating point of the reduced model separates {sep['first']} from "
                f"{sep['second']}: a different observable is needed (e.g. the static force "
                "F(z) at two voltages, Fig. 4b)." + vacuo)
    return (f"To separate {sep['first']} from {sep['second']}: measure at z = "
            f"{1e3 * sep['z']:g} mm, V_b = {sep['voltage'] / 1e3:g} kV, where the two fitted "
            f"models differ by {sep['sigma']:.1f} sigma_f over all modes (sigma_f = "
            f"{100 * sigma:g} %); most in {sep['label']}: {sep['first']} predicts "
            f"{sep['first_hz']:.1f} Hz, {sep['second']} {sep['second_hz']:.1f} Hz." + vacuo)


def write_report(result, directory) -> list[Path]:
    """Write every report file into ``directory`` (which exists); returns the paths."""
    out = Path(directory)
    files = []
    plot_gap_history(out / "gap_history.png", result)
    plot_frequencies(out / "frequencies.png", result)
    files += [out / "gap_history.png", out / "frequencies.png"]
    figures = []
    for c in result.measured.conditions:
        if c.spectrum is not None:
            name = f"spectra_{c.name}.png"
            plot_spectra(out / name, result, c)
            figures.append(name)
            files.append(out / name)
    document = _clean(diagnosis_document(result))
    (out / "diagnosis.json").write_text(json.dumps(document, indent=1, default=_json_default,
                                                   allow_nan=False))
    files.append(out / "diagnosis.json")
    study = final_study(result)
    header = ["# Final model of copdea-fem diagnose " + result.measured.name,
              "# base study + effects: " + (", ".join(
                  f"{e} ({CATALOGUE[e].describe_values(v)})" if v else e
                  for e, v in result.final_state) or "none"),
              "# conditions (use --set): " + "; ".join(
                  f"{c.name}: " + ", ".join(f"{k}={v}" for k, v in c.overrides.items())
                  for c in result.measured.conditions)]
    data = _yaml_plain(study.as_dict())
    data["provenance"] = package_versions()
    (out / "final_study.yaml").write_text("\n".join(header) + "\n"
                                          + yaml.safe_dump(data, sort_keys=False))
    files.append(out / "final_study.yaml")
    (out / "report.md").write_text(report_markdown(result, document, figures))
    files.insert(0, out / "report.md")
    return files


def _json_default(value):
    """What ``json.dumps`` cannot write itself, as a plain type (after :func:`_clean`, a
    last resort: a value of an unknown type becomes its text, never an exception)."""
    plain = _plain(value)
    if plain is not value:
        return plain
    return str(value)


def _plain(value):
    """numpy scalars (bool included) and arrays, paths, sets and mappings as plain Python;
    other values unchanged."""
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.generic):             # numpy integers, floats, strings
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, (set, frozenset)):
        return sorted(value, key=str)
    return value


def _clean(value):
    """Strict JSON: non-finite floats become null, tuples and sets lists, numpy scalars
    (bools included) and arrays Python, paths text, keys text."""
    value = _plain(value)
    if isinstance(value, dict):
        return {str(_plain(k)): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return str(value)                               # anything else: its text, never a crash


def _yaml_plain(value):
    """Like :func:`_clean` for ``final_study.yaml`` (YAML keeps non-finite floats)."""
    value = _plain(value)
    if isinstance(value, dict):
        return {str(_plain(k)): _yaml_plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_yaml_plain(v) for v in value]
    return value
