"""What a diagnosis says in words: evidence of a step, goodness of fit, the verdict."""

from __future__ import annotations

import math

import numpy as np
import scipy.stats

from copdea_fem.diagnosis.compare import residual_summary


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


OFF_SIGMAS = 3.0       # a mode is "off" when its mean ln error is this many standard errors out


def remaining_off(matches, noise) -> list[dict]:
    """The modes the model still misses beyond the noise model, worst first.

    Per mode label over the conditions: the mean ln(f_model / f_meas) of its n pairs
    against its standard error sigma_f / sqrt(n) under the noise model; off when
    ``|mean| > OFF_SIGMAS x sigma_f / sqrt(n)`` (a two-sided 3-sigma test: 0.27 % false
    alarms per label when the model is right).  Each: label, n, mean relative error,
    z = mean / (sigma_f / sqrt n).
    """
    sigma = noise.frequency_relative
    by_label: dict = {}
    for m in matches:
        if m is None:
            continue
        for pair in m.pairs:
            by_label.setdefault(pair.model.label, []).append(-pair.log_error)
    out = []
    for label, errors in by_label.items():
        n = len(errors)
        mean = float(np.mean(errors))
        z = mean / (sigma / math.sqrt(n))
        if abs(z) > OFF_SIGMAS:
            out.append({"label": label, "pairs": n, "mean_error": float(math.expm1(mean)),
                        "sigmas": float(z)})
    return sorted(out, key=lambda item: -abs(item["sigmas"]))


def explained(result) -> str:
    """How much of the discrepancy the diagnosis explains: ``"explained"`` (the final
    model within the noise), ``"partly explained"`` (effects added or ambiguous, modes
    still off beyond the noise), ``"unexplained"`` (nothing added, modes off beyond the
    noise) or ``"nothing missing"``."""
    off = bool(result.remaining_off)
    if result.missing_effects or result.ambiguous:
        return "partly explained" if off else "explained"
    return "unexplained" if off else "nothing missing"


def _off_text(items, limit=4) -> str:
    return ", ".join(f"{i['label']} {100 * i['mean_error']:+.1f} % ({abs(i['sigmas']):.0f} "
                     f"sigma, {i['pairs']} pair{'s' if i['pairs'] > 1 else ''})"
                     for i in items[:limit])


def verdict(result) -> str:
    """The headline sentences of a :class:`~copdea_fem.diagnosis.select.DiagnosisResult`."""
    parts = []
    state = explained(result)
    if result.missing_effects:
        parts.append(("Partly explained. " if state == "partly explained" else "")
                     + "Missing: " + ", ".join(result.missing_effects)
                     + f" (in order of importance); gap {100 * result.gap_before:.1f} % -> "
                     f"{100 * result.gap_after:.1f} %.")
    elif state == "partly explained":
        parts.append("Partly explained.")
    for effect_id, text in result.status.items():    # a mounting change
        prefix = "on in the base model: replaced by "
        if text.startswith(prefix) and text[len(prefix):] in result.missing_effects:
            parts.append(f"The base study's mounting ({effect_id}) does not fit the data: "
                         f"{text[len(prefix):]} replaces it.")
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
    if result.remaining_off:
        parts.append("The final model still misses, beyond the noise model (sigma_f = "
                     f"{100 * result.measured.noise.frequency_relative:g} %): "
                     + _off_text(result.remaining_off)
                     + " (mean model error over the conditions): a cause outside the "
                     "catalogue or a parameter of the base study.")
    if result.not_tested:
        parts.append("Not tested: " + ", ".join(result.not_tested) + ".")
    return " ".join(parts)
