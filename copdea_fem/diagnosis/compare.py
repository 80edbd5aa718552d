"""Compare model and measurement: matching, the deviance and the headline gap.

Matching (one-to-one, per condition)
------------------------------------
1. Measured peaks of kind ``non-axisymmetric`` (a label ``(m,n)`` with
   m >= 1 or the ``kind`` column) are out of the scope of a model without
   such modes (the ring model alone): listed, never scored.  With the FE as
   the model of record they are scored like the others; the FE's
   non-axisymmetric modes are *optional* (excited only through
   imperfections): they may explain a peak, their absence costs nothing.
2. A labelled peak pairs only with the model mode of that label (``(1,1)``
   also with ``(1,1)a``/``b`` of a split pair and back); a label the model
   does not have (``P2`` without spring mass) leaves it unexplained.
3. Unlabelled peaks pair with the remaining expected model modes by an
   assignment (Hungarian, :func:`scipy.optimize.linear_sum_assignment`)
   minimising ``sum ln(f_meas/f_model)^2`` plus a tie-breaking shape term
   when a spectrum gives the peak's radial/axial ratio rho,
   ``c_u (ln(rho_meas/rho_model) / ln 3)^2 / 4`` capped at ``c_u / 2``
   (c_u below; the measured ratio of a small peak is floor-dominated, so it
   never vetoes a pair); pairs must agree in kind (pumping vs membrane).  A
   peak whose kind is known (its shape was seen) may pair within the gate
   ``|ln(f_meas/f_model)| <= ln(1 + GATE)``, GATE = 50 %: wider than the
   largest air-loading shift, 30 % in the paper (Sect. 5.2) and up to 38 %
   for (0,1) with the incompressible estimate at z = 18 mm, so a model that
   misses the air is still paired mode by mode.  A peak of unknown kind
   (no shape evidence: it may be spurious) pairs only where the pairing is
   more likely than a missed mode plus a spurious peak under the noise model
   below, ``e^2/sigma_f^2 + const <= c_miss + c_spur`` (about 4 sigma_f).
   Leaving a peak or a mode unpaired costs ``c_u = ln(1 + GATE)^2`` each, so
   any admissible pair is taken.
4. Expected model modes inside the band left unpaired are "predicted, not
   seen"; unpaired in-scope peaks are "unexplained".

Deviance (the likelihood the selection works with)
--------------------------------------------------
-2 ln L of a mixture model of an identified peak list, with the noise
model of the manifest (sigma_f, sigma_Q, p_miss, lambda_s):

- a mode is found with probability 1 - p_miss, its ln f with Gaussian
  scatter sigma_f: ``d_f = e^2/sigma_f^2 + 2 ln(sqrt(2 pi) sigma_f)
  - 2 ln(1 - p_miss)``, e = ln(f_meas / f_model);
- a mode not found: ``c_miss = -2 ln(1 - (1 - p_miss) p_in)``, where
  ``p_in = Phi((ln f_high - ln f)/sigma_f) - Phi((ln f_low - ln f)/sigma_f)``
  is the chance that its measured peak falls inside the band (a mode at
  the band edge is seen half the time; p_in = 1 inside: ``-2 ln p_miss``);
- a spurious peak (Poisson, lambda_s per condition, uniform in ln f over the
  band of width W = ln(f_high / f_low)): ``c_spur = -2 ln(lambda_s / W)``;
- a quality factor, if both sides have one: ``d_Q = e_Q^2/sigma_Q^2 +
  2 ln(sqrt(2 pi) sigma_Q)``; a Q no mode explains is uniform over ln Q in
  [0, ln 1e4]: ``c_Q = 2 ln(ln 1e4)``;
- a pair is either that mode and its peak or a miss plus a spurious peak:
  ``-2 ln(exp(-(d_f + d_Q)/2) + exp(-(c_miss + c_spur + c_Q)/2))`` (a
  mixture, so one wrong label or a 30 % error costs a bounded amount).

Gap (the headline number)
-------------------------
``gap = sqrt((sum r^2 + GATE^2 N_excess) / (N_pairs + N_excess))``: the RMS
relative frequency error ``r = f_model/f_meas - 1`` over all pairs, with
every unexplained peak or unseen mode beyond what the noise model explains
counted as an error of GATE, the largest error a pair may have.  The noise
model expects ``E = sum q + sum lambda_s`` of them, q = 1 - (1 - p_miss)
p_in per model mode in the band (p_in >= 1/2) and lambda_s per condition,
with variance ``V = sum q (1 - q) + sum lambda_s`` (binomial + Poisson);
``N_excess = max(0, N_unexplained - E - 2 sqrt(V))``: only a count the
detection noise cannot produce (beyond two standard deviations) counts, so
the gap of a right model stays at the frequency scatter whatever the
random number of missed peaks.  Dimensionless; 0.02 means the model is
2 % off on average.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.optimize

from copdea_fem.measured import NoiseModel

GATE = 0.50
_Q_RANGE = math.log(1e4)
_UNPAIRED = math.log(1 + GATE) ** 2
_SHAPE_WEIGHT = 0.25 * _UNPAIRED / math.log(3.0) ** 2


@dataclass(frozen=True)
class MeasuredPeak:
    """A measured resonance as compared: frequency [Hz], label, kind, Q [-], peak height and
    radial/axial ratio from a spectrum (nan when absent), and where it came from."""

    frequency_hz: float
    label: str = ""
    kind: str = ""
    quality_factor: float = math.nan
    height: float = math.nan
    radial_ratio: float = math.nan
    source: str = "resonances"


@dataclass(frozen=True)
class Pair:
    """A model mode and the peak it explains; ``by`` is ``"label"`` or ``"frequency"``."""

    model: object
    peak: MeasuredPeak
    by: str

    @property
    def relative_error(self) -> float:
        """f_model / f_meas - 1 [-]."""
        return self.model.frequency_hz / self.peak.frequency_hz - 1

    @property
    def log_error(self) -> float:
        """ln(f_meas / f_model) [-]."""
        return math.log(self.peak.frequency_hz / self.model.frequency_hz)


@dataclass(frozen=True)
class ConditionMatch:
    """Matching and deviance of one condition.

    Attributes
    ----------
    condition : str
    pairs : tuple of Pair
    unseen : tuple of ModelMode
        Expected model modes in the band that no peak explains.
    unexplained : tuple of MeasuredPeak
        In-scope peaks no model mode explains.
    out_of_scope : tuple of MeasuredPeak
        Non-axisymmetric peaks (need the FE engine).
    band : tuple of float
        [Hz].
    deviance : float
        -2 ln L (module notes) [-].
    expected_unexplained : float
        E of this condition: sum of q over the model modes in the band + lambda_s [-].
    variance_unexplained : float
        V of this condition [-].
    """

    condition: str
    pairs: tuple
    unseen: tuple
    unexplained: tuple
    out_of_scope: tuple
    band: tuple
    deviance: float
    expected_unexplained: float
    variance_unexplained: float = 0.0


class DevianceTerms:
    """The constants of the deviance for one noise model and band (module notes)."""

    def __init__(self, noise: NoiseModel, band):
        sigma, sigma_q = noise.frequency_relative, noise.quality_relative
        width = math.log(band[1] / band[0])
        self.sigma, self.sigma_q = sigma, sigma_q
        self.match = 2 * math.log(math.sqrt(2 * math.pi) * sigma) - 2 * math.log(
            1 - noise.missing_probability)
        self.q_match = 2 * math.log(math.sqrt(2 * math.pi) * sigma_q)
        self.p_miss = noise.missing_probability
        self.log_band = (math.log(band[0]), math.log(band[1]))
        self.miss = -2 * math.log(noise.missing_probability)
        self.spurious = -2 * math.log(noise.spurious_per_condition / width)
        self.q_uniform = 2 * math.log(_Q_RANGE)
        self._strict = self._strict_gate()

    def pair(self, model, peak) -> float:
        d = math.log(peak.frequency_hz / model.frequency_hz) ** 2 / self.sigma ** 2 + self.match
        outlier = self.miss + self.spurious
        if math.isfinite(peak.quality_factor) and peak.quality_factor > 0:
            if not math.isfinite(model.quality_factor):     # undamped or not modelled
                d += self.q_uniform
            else:
                d += math.log(peak.quality_factor / model.quality_factor) ** 2 / \
                    self.sigma_q ** 2 + self.q_match
            outlier += self.q_uniform
        return _softmin(d, outlier)

    def strict_gate(self) -> float:
        """|ln(f_meas/f_model)| up to which a pair beats a miss plus a spurious peak."""
        return self._strict

    def _strict_gate(self) -> float:
        room = self.miss + self.spurious - self.match
        return self.sigma * math.sqrt(max(room, 0.0))

    def inside(self, frequency_hz: float) -> float:
        """p_in: chance that a mode at this model frequency is measured inside the band."""
        x = math.log(frequency_hz)
        root2 = math.sqrt(2) * self.sigma
        return 0.5 * (math.erf((self.log_band[1] - x) / root2)
                      - math.erf((self.log_band[0] - x) / root2))

    def unseen_probability(self, frequency_hz: float) -> float:
        """q = 1 - (1 - p_miss) p_in: chance that a mode leaves no peak in the band."""
        return 1 - (1 - self.p_miss) * self.inside(frequency_hz)

    def lone_mode(self, mode) -> float:
        return -2 * math.log(self.unseen_probability(mode.frequency_hz))

    def lone_peak(self, peak) -> float:
        q = self.q_uniform if math.isfinite(peak.quality_factor) else 0.0
        return self.spurious + q


def _softmin(a: float, b: float) -> float:
    """-2 ln(exp(-a/2) + exp(-b/2)), stable."""
    low = min(a, b)
    return low - 2 * math.log1p(math.exp(-abs(a - b) / 2))


def match_condition(name, model_modes, peaks, band, noise: NoiseModel,
                    terms: DevianceTerms | None = None, observed=None) -> ConditionMatch:
    """Pair model modes and measured peaks of one condition and score them (module notes).

    ``terms`` (optional) are the condition's :class:`DevianceTerms`, to save rebuilding them.
    ``observed`` (:class:`copdea_fem.measured.ObservedFamilies`, optional): the
    families the measurement can see; a model mode outside them may explain a peak, but
    no peak for it costs nothing (like an optional mode).
    """
    orders = any(m.kind == "non-axisymmetric" for m in model_modes)
    in_scope = [p for p in peaks if orders or p.kind != "non-axisymmetric"]
    out_of_scope = tuple(p for p in peaks if not orders and p.kind == "non-axisymmetric")
    expected = [m for m in model_modes if m.expected]
    by_label = {m.label: m for m in expected}
    pairs, unexplained, used = [], [], set()
    unlabelled = []
    for peak in in_scope:
        if peak.label:
            model = _labelled(peak.label, by_label, used)
            if model is not None:
                pairs.append(Pair(model, peak, "label"))
                used.add(model.label)
            else:
                unexplained.append(peak)
        else:
            unlabelled.append(peak)
    reach = (band[0] / (1 + GATE), band[1] * (1 + GATE))
    free = [m for m in expected if m.label not in used and reach[0] <= m.frequency_hz <= reach[1]]
    terms = terms or DevianceTerms(noise, band)
    if unlabelled and free:
        assigned = _assign(unlabelled, free, terms.strict_gate())
        for i, peak in enumerate(unlabelled):
            j = assigned.get(i)
            if j is None:
                unexplained.append(peak)
            else:
                pairs.append(Pair(free[j], peak, "frequency"))
                used.add(free[j].label)
    else:
        unexplained.extend(unlabelled)
    required = [m for m in expected if not m.optional
                and (observed is None or observed.covers(m.label, m.kind))]
    lonely = [m for m in required if m.label not in used]
    inside = {m.label: terms.inside(m.frequency_hz) for m in required}
    unseen = tuple(m for m in lonely if inside[m.label] >= 0.5)
    deviance = (sum(terms.pair(p.model, p.peak) for p in pairs)
                + sum(terms.lone_mode(m) for m in lonely)
                + sum(terms.lone_peak(p) for p in unexplained))
    q = [terms.unseen_probability(m.frequency_hz) for m in required if inside[m.label] >= 0.5]
    spurious = noise.spurious_per_condition
    pairs.sort(key=lambda p: p.peak.frequency_hz)
    return ConditionMatch(
        condition=name, pairs=tuple(pairs), unseen=unseen,
        unexplained=tuple(sorted(unexplained, key=lambda p: p.frequency_hz)),
        out_of_scope=out_of_scope, band=tuple(band), deviance=float(deviance),
        expected_unexplained=float(sum(q) + spurious),
        variance_unexplained=float(sum(x * (1 - x) for x in q) + spurious))


def _labelled(label: str, by_label: dict, used: set):
    """The free model mode a labelled peak pairs with (rule 2), or None."""
    names = [label] + ([label[:-1]] if label[-1] in "ab" else [label + "a", label + "b"])
    return next((by_label[n] for n in names if n in by_label and n not in used), None)


def _assign(peaks, modes, strict_limit: float) -> dict:
    """Hungarian assignment of peaks to modes with the gates (module notes); {peak: mode}."""
    n_p, n_m = len(peaks), len(modes)
    big = 1e6
    cost = np.full((n_p + n_m, n_m + n_p), big)
    for i, peak in enumerate(peaks):
        limit = math.log(1 + GATE) if peak.kind else min(strict_limit, math.log(1 + GATE))
        for j, mode in enumerate(modes):
            if peak.kind and peak.kind != mode.kind:
                continue
            error = math.log(peak.frequency_hz / mode.frequency_hz)
            if abs(error) > limit:
                continue
            shape = 0.0
            if (peak.radial_ratio > 1e-3 and mode.radial_ratio > 1e-3
                    and math.isfinite(peak.radial_ratio) and math.isfinite(mode.radial_ratio)):
                shape = min(_SHAPE_WEIGHT * math.log(peak.radial_ratio / mode.radial_ratio) ** 2,
                            0.5 * _UNPAIRED)
            cost[i, j] = error ** 2 + shape
        cost[i, n_m + i] = _UNPAIRED
    for j in range(n_m):
        cost[n_p + j, j] = _UNPAIRED
    cost[n_p:, n_m:] = 0.0
    rows, cols = scipy.optimize.linear_sum_assignment(cost)
    return {int(r): int(c) for r, c in zip(rows, cols) if r < n_p and c < n_m
            and cost[r, c] < big}


def gap(matches) -> float:
    """Headline gap over all conditions (module notes) [-]."""
    errors = [p.relative_error for m in matches for p in m.pairs]
    unexplained = sum(len(m.unseen) + len(m.unexplained) for m in matches)
    expected = sum(m.expected_unexplained for m in matches)
    spread = math.sqrt(sum(m.variance_unexplained for m in matches))
    excess = max(0.0, unexplained - expected - 2 * spread)
    count = len(errors) + excess
    if count == 0:
        return 0.0
    return math.sqrt((sum(e * e for e in errors) + GATE ** 2 * excess) / count)


def gap_parts(matches) -> dict:
    """The two parts of :func:`gap`: the RMS relative error over the pairs alone
    (``paired_rms``, [-], NaN without pairs), the pairs' count, and the count penalty
    (``excess``: unexplained peaks and unseen modes beyond the noise model's expectation,
    each counted as an error of GATE)."""
    errors = [p.relative_error for m in matches for p in m.pairs]
    unexplained = sum(len(m.unseen) + len(m.unexplained) for m in matches)
    expected = sum(m.expected_unexplained for m in matches)
    spread = math.sqrt(sum(m.variance_unexplained for m in matches))
    return {"paired_rms": (math.sqrt(sum(e * e for e in errors) / len(errors)) if errors
                           else math.nan),
            "pairs": len(errors), "unexplained": unexplained,
            "excess": max(0.0, unexplained - expected - 2 * spread)}


def total_deviance(matches) -> float:
    return float(sum(m.deviance for m in matches))


def residual_summary(matches, conditions_meta=None) -> dict:
    """Residual patterns over the pairs (the evidence a winner removes).

    Returns a dict with per-label mean relative error; the change of ln(f_meas/f_model)
    across the data's range of ln f (an error growing with frequency), of V_b^2 and of z
    (least-squares slope times range; ``conditions_meta`` maps condition -> {"voltage": V,
    "z": m}); the number of unexplained peaks (and of those pistonic), unseen modes, and
    the median ln Q ratio.
    """
    by_label: dict = {}
    xs, ys, vs, zs = [], [], [], []
    q_ratios = []
    for match in matches:
        meta = (conditions_meta or {}).get(match.condition, {})
        for pair in match.pairs:
            by_label.setdefault(pair.model.label, []).append(pair.relative_error)
            xs.append(math.log(pair.peak.frequency_hz))
            ys.append(pair.log_error)
            vs.append(meta.get("voltage", 0.0) ** 2)
            zs.append(meta.get("z", 0.0))
            q_model, q_meas = pair.model.quality_factor, pair.peak.quality_factor
            if math.isfinite(q_meas) and q_meas > 0 and not math.isnan(q_model):
                q_ratios.append(math.log(q_meas / q_model) if math.isfinite(q_model)
                                else -math.inf)

    def span(x, y):
        """Least-squares slope of y on x times the range of x: the change across the data."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        if x.size < 3 or np.ptp(x) == 0:
            return 0.0
        return float(np.polyfit(x - x.mean(), y, 1)[0] * np.ptp(x))

    return {
        "mean_error_by_label": {label: float(np.mean(v)) for label, v in sorted(by_label.items())},
        "mean_log_error": float(np.mean(ys)) if ys else 0.0,
        "span_vs_log_frequency": span(xs, ys),
        "span_vs_voltage_squared": span(vs, ys),
        "span_vs_z": span(zs, ys),
        "unexplained": sum(len(m.unexplained) for m in matches),
        "unexplained_pumping": sum(1 for m in matches for p in m.unexplained
                                   if p.kind == "pumping" or p.label.startswith("P")),
        "unseen": sum(len(m.unseen) for m in matches),
        "median_log_quality_ratio": (float(np.median(q_ratios)) if q_ratios else math.nan),
        "pairs": len(ys),
    }
