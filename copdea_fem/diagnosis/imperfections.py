"""Imperfections of a round device named from split pairs: which one, how large, along
which axis.

A perfect (round) device has degenerate (m,n) pairs: the model of record (axisymmetric)
cannot split them, so the search over effects (:mod:`copdea_fem.diagnosis.select`) never
explains a split.  After that search, this stage reads the pairs of the measurement and
tests the catalogue's imperfections (the effects with a
:attr:`~copdea_fem.diagnosis.effects.Effect.split_signature`: an anisotropic pre-stretch,
an uneven thickness, a point mass).

Observed pairs (:class:`ObservedPair`).  From a resonance list: a ``(m,n)a`` and a
``(m,n)b`` peak of one condition (the relative split ``s = (f_high - f_low) / f_mean``), or
a lone ``(m,n)`` peak (an unresolved pair: ``s = 0``).  From a scan (or a mode set): the two
test modes paired by shape with the pair's FE unit (:mod:`copdea_fem.diagnosis.scanned`),
with their orientations (:func:`shape_orientation`: the angle of the order-m part's antinode
line).  One test mode on the unit (a *lone* member) is a censored observation: the pair is
split by less than the identification resolves, ``s < s_res``, or its other member was
not found (not excited: a drive on its nodal line; too weak in the scan's noise).  Its
resolution ``s_res`` is the member's half-power bandwidth ``2 zeta`` (its identified
damping ratio): two modes split by more give two peaks in the FRFs (Ewins, *Modal
testing*, 2nd ed., Sect. 4.2; docs/vibrometer.md, "Close pairs": with ``resolve_pairs``
pairs split by a tenth of ``2 zeta`` are resolved when their shapes are, and some split by
a twentieth are not, so below ``2 zeta`` a lone member says nothing).  A lone member of
unknown damping (a mode set without it) is left out.

Signatures (perturbation theory).  A perturbation ``cos k (theta - angle)`` joins the
circumferential orders m and m +- k, so the two members of an m pair (orders +-m, 2m apart)
are split at order j = 2m / k in its amplitude where that is an integer: an anisotropy
(k = 2) splits (1,n) linearly and (2,n) quadratically; a thickness term of order 4 the
(2,n) linearly; a point mass joins every order and splits every pair linearly.  The split
of each pair is measured per condition by one trial 3-D FE solve at a trial size along
the angle 0 (:class:`~copdea_fem.diagnosis.effect_record.SplitTrial`, through the
diagnosis's cached FE, :class:`~copdea_fem.diagnosis.fe.FEModel`), and scaled by
``(x / x_trial)^j``.  Rotating the imperfection rotates the modes: the stiffer member's
orientation is ``angle + offset`` (mod 180/m), the offset 0 where the trial's cos member
(``a``) is the stiffer, 90/m where the sin member is.  A mass's splits are interpolated
linearly (their square roots) between the trial radii.

Fit and test.  With ``sigma_s`` = :data:`SPLIT_SIGMA` per split and ``sigma_phi`` =
:data:`ORIENTATION_SIGMA_DEG` per orientation (scans),
each hypothesis's deviance is ``D = sum ((s - s_model) / sigma_s)^2 + sum l(s_model) +
sum c(wrap(phi - phi_model))`` (``c(r) ~ (r / sigma_phi)^2`` for small r, robust to a tenth of outliers:
:func:`orientation_cost`; the orientations of the pairs split past sigma_s; where the
hypothesis's fitted split of a pair is below sigma_s, the members' orientations are
uniform under it, density 1 / P over the pair's period P: each costs
``2 ln(P / (sqrt(2 pi) sigma_phi))`` on the scale where a placed member costs its
``(r / sigma_phi)^2``, so every hypothesis is scored on the same orientations; the
magnitude fitted on a log grid refined by a bounded scalar
search, the angle on a 0.25 deg grid).  A lone member of a scan costs ``l(s_model) =
-2 ln(P(s_model) / P(0))`` (:func:`lone_cost`), ``P(s) = p_miss + (1 - p_miss) Phi((s_res -
s) / sigma_s)`` the probability that a pair the hypothesis splits by s shows one member: a
censored Gaussian split (a split s measured with sigma_s falls below s_res), or the other
member missed, with probability p_miss = :data:`LONE_MISS` whatever the split.  So a
hypothesis that leaves the pair below s_res pays nothing, the perfect device (s = 0)
exactly nothing, and one that splits it past s_res a bounded ``-2 ln p_miss`` (4.6): less
than the ambiguity margin ``2 ln(1 / alpha)`` (6.0 at alpha = 0.05), so one lone pair
alone does not decide between two hypotheses that explain the split pairs alike, two do.
A lone pair that a hypothesis's trial solve does not hold (out of its band, or its
members merged) is predicted unsplit: it contributes nothing to that hypothesis.  The
perfect device (``s = 0``) is kept when its split deviance is within the noise
(chi-square quantile ``1 - alpha`` of the number of measured splits, the lone members
not counted: they cost the perfect device nothing): no FE solve then.  Otherwise the best
hypothesis by ``D + p ln N`` (p fitted parameters, N observations: the measured splits,
the lone members and the measured orientations) is named when its split deviance beats the perfect device's by
``2 ln(H / alpha)`` (H hypotheses tested: a likelihood ratio of H / alpha); the others
within ``2 ln(1 / alpha)`` of it are *ambiguous* with it, and then none is named (the data
cannot tell them apart; the best is reported provisionally).  Without orientations (a
resonance list) the angle is not measured: the fit gives the size only.
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
import math
import re

import numpy as np

from copdea_fem.diagnosis.effects import CATALOGUE, IMPERFECTIONS

logger = logging.getLogger(__name__)

#: 1-sigma scatter of a pair's relative split [-]: both members are identified in one
#: measurement, so the condition-wide errors of ``noise.frequency_relative`` (model error,
#: temperature, pre-stretch drift) cancel in their ratio; half the FE's resolution of a
#: pair (:data:`copdea_fem.diagnosis.fe.PAIR_MERGE`, 2e-3).
SPLIT_SIGMA = 1e-3
#: 1-sigma scatter of a measured member's orientation [deg] (a scan's grid and noise).
ORIENTATION_SIGMA_DEG = 5.0
#: Share of measured orientations that follow no model (:func:`orientation_cost`).
ORIENTATION_OUTLIERS = 0.1
#: Probability that the identification shows one member of a pair split past its
#: resolution (the other not driven, or too weak in the noise): the bounded cost of a lone
#: member, ``-2 ln LONE_MISS`` = 4.6 (:func:`lone_cost`).  A choice, like
#: :data:`ORIENTATION_OUTLIERS`, not a measured rate; it keeps one lone pair below the
#: ambiguity margin ``2 ln(1 / alpha)`` (6.0 at alpha = 0.05).
LONE_MISS = 0.1
LABEL = re.compile(r"^\((?P<m>\d+),(?P<n>\d+)\)(?P<letter>[ab]?)$")


@dataclasses.dataclass(frozen=True)
class ObservedPair:
    """One (m,n) pair of one condition: its members' frequencies [Hz] (equal for an
    unresolved pair) and, from a scan, their orientations [deg, in [0, 180/m)] (NaN: not
    measured); ``resolution`` [-]: for a lone member of a scan, the split ``s_res`` below
    which its pair is not resolved (module notes; NaN: the split is measured)."""

    condition: str
    pair: str
    m: int
    low_hz: float
    high_hz: float
    low_orientation_deg: float = math.nan
    high_orientation_deg: float = math.nan
    resolution: float = math.nan

    @property
    def lone(self) -> bool:
        """A lone member of a scan: a censored observation ``s < resolution``."""
        return math.isfinite(self.resolution)

    @property
    def split(self) -> float:
        """Relative split (f_high - f_low) / f_mean [-]."""
        return (self.high_hz - self.low_hz) / (0.5 * (self.high_hz + self.low_hz))

    @property
    def oriented(self) -> bool:
        """Both members' orientations measured, and the split past sigma_s (below it the
        members are not told apart by their frequencies)."""
        return (self.split > SPLIT_SIGMA and math.isfinite(self.high_orientation_deg)
                and math.isfinite(self.low_orientation_deg))


def _parse(label: str):
    match = LABEL.match(label or "")
    if not match or int(match["m"]) == 0:
        return None
    return f"({match['m']},{match['n']})", int(match["m"]), match["letter"]


def pairs_from_resonances(condition: str, resonances) -> list:
    """:class:`ObservedPair` of a resonance list (module notes): both members labelled, or
    one peak labelled ``(m,n)`` (unresolved)."""
    members: dict = {}
    for resonance in resonances or ():
        parsed = _parse(resonance.label)
        if parsed:
            members.setdefault(parsed[:2], []).append((parsed[2], resonance.frequency_hz))
    out = []
    for (pair, m), found in sorted(members.items()):
        letters = {letter for letter, _ in found}
        freqs = sorted(f for _, f in found)
        if letters == {"a", "b"} and len(found) == 2:
            out.append(ObservedPair(condition, pair, m, freqs[0], freqs[1]))
        elif letters == {""} and len(found) == 1:
            out.append(ObservedPair(condition, pair, m, freqs[0], freqs[0]))
    return out


def shape_orientation(values, x, y, m: int) -> float:
    """Orientation [deg, in [0, 180/m)] of the antinode line of a measured shape's order-m
    part: ``values`` (complex) at the points ``(x, y)`` [m].

    The points are grouped in radial bands (equal counts); in each the order-m part
    ``A cos m theta + B sin m theta`` is fitted by least squares (with a constant); the
    band-summed, radius-weighted 2x2 matrix ``Re [(A, B)^H (A, B)]`` has its principal
    eigenvector along ``(cos m psi, sin m psi)`` for a shape ``cos m (theta - psi)``.
    """
    values, x, y = (np.asarray(a) for a in (values, x, y))
    radius, theta = np.hypot(x, y), np.arctan2(y, x)
    keep = radius > 1e-9 * max(float(radius.max(initial=0.0)), 1e-30)
    values, radius, theta = values[keep], radius[keep], theta[keep]
    per_band = max(4 * m + 3, 8)
    bands = max(1, min(8, len(values) // per_band))
    if len(values) < 3:
        return math.nan
    edges = np.quantile(radius, np.linspace(0, 1, bands + 1))
    matrix = np.zeros((2, 2))
    for band in range(bands):
        inside = (radius >= edges[band]) & ((radius <= edges[band + 1]) if band == bands - 1
                                            else (radius < edges[band + 1]))
        if inside.sum() < 3:
            continue
        basis = np.column_stack([np.ones(inside.sum()), np.cos(m * theta[inside]),
                                 np.sin(m * theta[inside])])
        coefficients = np.linalg.lstsq(basis, values[inside].astype(complex), rcond=None)[0]
        parts = coefficients[1:]
        weight = float(np.mean(radius[inside]))
        matrix += weight * np.real(np.outer(np.conj(parts), parts))
    if not np.any(matrix):
        return math.nan
    _, vectors = np.linalg.eigh(matrix)
    angle = math.degrees(math.atan2(vectors[1, -1], vectors[0, -1])) / m
    period = 180.0 / m
    angle %= period
    return 0.0 if period - angle < 1e-9 * period else angle


def _out_of_plane_channels(scan):
    """Indices of the channels measuring along z (|direction . z| > 0.9) and their points'
    (x, y) [m]."""
    direction = np.asarray(scan.channel_direction, dtype=float)
    chosen = np.flatnonzero(np.abs(direction[:, 2]) > 0.9)
    points = np.asarray(scan.positions, dtype=float)[np.asarray(scan.channel_point)[chosen]]
    return chosen, points[:, 0], points[:, 1]


def pairs_from_scan(pairing) -> list:
    """:class:`ObservedPair` of a scanned condition
    (:class:`~copdea_fem.diagnosis.scanned.ScanPairing`): the two test modes paired with an
    (m,n) unit, with their orientations, or a lone test mode on the unit, censored below
    its half-power bandwidth ``2 zeta`` (module notes; left out where its damping ratio is
    not known)."""
    modes = {mode.test_mode: mode for mode in pairing.modes}
    chosen, x, y = _out_of_plane_channels(pairing.scan)
    members: dict = {}
    for pair in pairing.correlation.pairs:
        parsed = _parse(pair.label)
        if parsed and pair.test_mode in modes:
            members.setdefault(parsed[:2], []).append(modes[pair.test_mode])
    out = []
    for (label, m), found in sorted(members.items()):
        found = sorted(found, key=lambda mode: mode.freq_hz)
        if len(found) == 2:
            low, high = (shape_orientation(mode.shape[chosen], x, y, m) if len(chosen)
                         else math.nan for mode in found)
            out.append(ObservedPair(pairing.condition, label, m, found[0].freq_hz,
                                    found[1].freq_hz, low, high))
        elif len(found) == 1 and found[0].damping_ratio > 0:
            # a lone member: the pair is split below its half-power bandwidth, or the
            # other member was not found (module notes); NaN damping fails the test
            out.append(ObservedPair(pairing.condition, label, m, found[0].freq_hz,
                                    found[0].freq_hz,
                                    resolution=2.0 * float(found[0].damping_ratio)))
    return out


def observed_pairs(measured, pairings=()) -> list:
    """Every condition's :class:`ObservedPair`: from its scan's pairing where it has one,
    else from its resonance list."""
    scanned = {pairing.condition: pairing for pairing in pairings}
    out = []
    for condition in measured.conditions:
        if condition.name in scanned and scanned[condition.name].scan is not None:
            out += pairs_from_scan(scanned[condition.name])
        else:
            out += pairs_from_resonances(condition.name, condition.resonances)
    return out


# -- the model: each trial's splits and orientation offsets --------------------------------
def trial_splits(fe_modes) -> dict:
    """``{pair: (split, offset)}`` of an FE solve's modes at a trial (angle 0): ``fe_modes``
    :class:`~copdea_fem.diagnosis.fe.FEMode` (a merged pair is one mode ``(m,n)``)."""
    by_label = {mode.label: mode.frequency_hz for mode in fe_modes}
    out = {}
    for label in by_label:
        parsed = _parse(label)
        if not parsed:
            continue
        pair, m, letter = parsed
        if letter == "":
            out[pair] = (0.0, math.nan)
        elif letter == "a" and pair + "b" in by_label:
            cos, sin = by_label[pair + "a"], by_label[pair + "b"]
            out[pair] = (abs(cos - sin) / (0.5 * (cos + sin)),
                         0.0 if cos >= sin else 90.0 / m)
    return out


def _wrap(angle, period):
    return (np.asarray(angle) + 0.5 * period) % period - 0.5 * period


@dataclasses.dataclass(frozen=True)
class ImperfectionFit:
    """The best fit of one effect (over its trials): parameter values (the effect's
    parameter order; NaN for an angle not measured), its split and orientation deviances,
    fitted parameters, and the trial that gave it."""

    effect: str
    values: tuple
    split_deviance: float
    orientation_deviance: float
    fitted: int
    trial: str
    angle_measured: bool
    predicted: dict = dataclasses.field(default_factory=dict)   # {(condition, pair): s}

    @property
    def deviance(self) -> float:
        return self.split_deviance + self.orientation_deviance

    def describe(self) -> str:
        entry = CATALOGUE[self.effect]
        shown = []
        for parameter, value in zip(entry.parameters, self.values):
            if parameter.unit == "deg" and not math.isfinite(value):
                shown.append(f"{parameter.name} not measured (no orientations)")
            elif parameter.unit == "m":
                shown.append(f"{parameter.name} = {value * 1e3:.3g} mm")
            elif parameter.unit == "kg":
                shown.append(f"{parameter.name} = {value * 1e6:.3g} mg")
            else:
                shown.append(f"{parameter.name} = {parameter.shown(value)}")
        return ", ".join(shown)


#: Range of the fitted magnitude ratio ``q = x / x_trial`` (further narrowed to the bounds
#: of the parameter it sets: :func:`magnitude_range`).
MAGNITUDE_RATIO_RANGE = (1e-3, 20.0)


def magnitude_range(effect_id: str, trial) -> tuple[float, float]:
    """The range of ``q = x / x_trial`` a fit of ``effect_id`` at ``trial`` may take:
    :data:`MAGNITUDE_RATIO_RANGE` within the bounds of the parameter the magnitude sets
    (:attr:`~copdea_fem.diagnosis.effect_record.SplitSignature.magnitude`), so that a
    fitted size stays in the range its study key allows (unbounded, an order-2 thickness
    term, which splits G1's (1,1) pair by 0.15 % at a = 0.3, would explain a 2.6 % split
    with a = 5.5: a negative thickness)."""
    entry = CATALOGUE[effect_id]
    parameter = entry.parameters[entry.split_signature.magnitude]
    low = max(MAGNITUDE_RATIO_RANGE[0], parameter.lower / trial.amplitude)
    high = min(MAGNITUDE_RATIO_RANGE[1], parameter.upper / trial.amplitude)
    return low, max(high, low)


def lone_cost(model_split, resolution: float):
    """Deviance of a lone member of a scan (module notes) where the hypothesis splits its
    pair by ``model_split`` [-] and the identification resolves splits past
    ``resolution`` ``s_res`` [-]: ``-2 ln(P(s) / P(0))``, ``P(s) = p_miss + (1 - p_miss)
    Phi((s_res - s) / sigma_s)`` (:data:`LONE_MISS`, :data:`SPLIT_SIGMA`): 0 at s = 0,
    about 0 below s_res, rising over a few sigma_s to ``-2 ln(p_miss / P(0))`` past it."""
    from scipy.special import ndtr

    def likelihood(split):
        return LONE_MISS + (1 - LONE_MISS) * ndtr((resolution - np.asarray(split))
                                                  / SPLIT_SIGMA)

    return -2 * np.log(likelihood(model_split) / likelihood(0.0))


def _fit_magnitude(observations, bounds=MAGNITUDE_RATIO_RANGE):
    """The magnitude ratio ``q = x / x_trial`` in ``bounds`` minimising the split deviance,
    and it: ``observations`` ``[(s, power, s_trial, resolution)]`` (module notes: ``s_model
    = s_trial q^j``; ``resolution`` finite: a lone member, :func:`lone_cost`)."""
    from scipy.optimize import minimize_scalar

    def deviance(log_q):
        q = math.exp(log_q)
        return sum(float(lone_cost(c * q ** j, res)) if math.isfinite(res)
                   else ((s - c * q ** j) / SPLIT_SIGMA) ** 2
                   for s, j, c, res in observations)

    grid = np.linspace(math.log(bounds[0]), math.log(bounds[1]), 120)
    values = [deviance(v) for v in grid]
    best = int(np.argmin(values))
    low, high = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
    if high > low:
        result = minimize_scalar(deviance, bounds=(low, high), method="bounded",
                                 options={"xatol": 1e-6})
        if result.fun < values[best]:
            return math.exp(result.x), float(result.fun)
    return math.exp(grid[best]), float(values[best])


def orientation_cost(residual, period: float):
    """Deviance of a member's orientation ``residual`` [deg] from the model's, on the scale
    where an exact one costs 0 and a small one ``(r / sigma_phi)^2``: ``-2 ln((1 - eps)
    exp(-r^2 / (2 sigma_phi^2)) + eps sqrt(2 pi) sigma_phi / P)``, a Gaussian of
    :data:`ORIENTATION_SIGMA_DEG` mixed with a uniform share :data:`ORIENTATION_OUTLIERS`
    over the pair's period P (a member mixed with a near mode of another order -- a mass
    joins every order -- has the orientation of neither)."""
    sigma = ORIENTATION_SIGMA_DEG
    floor = ORIENTATION_OUTLIERS * math.sqrt(2 * math.pi) * sigma / period
    gauss = (1 - ORIENTATION_OUTLIERS) * np.exp(-0.5 * (np.asarray(residual) / sigma) ** 2)
    return -2 * np.log(gauss + floor) + 2 * math.log(1 - ORIENTATION_OUTLIERS + floor)


def _fit_angle(orientations, period):
    """The angle [deg, in [0, period)] minimising the orientation deviance, and it:
    ``orientations`` ``[(phi_measured, offset, pair_period)]`` (``phi = angle + offset`` mod
    the pair's period 180/m)."""
    if not orientations:
        return math.nan, 0.0
    grid = np.arange(0.0, period, 0.25)
    total = np.zeros_like(grid)
    for phi, offset, pair_period in orientations:
        total += orientation_cost(_wrap(phi - offset - grid, pair_period), pair_period)
    best = int(np.argmin(total))
    return float(grid[best]), float(total[best])


def fit_trial(effect_id: str, trial, splits: dict, pairs, choices: int = 1) -> ImperfectionFit:
    """:class:`ImperfectionFit` of one trial's splits ``{(condition, pair): (s, offset)}``
    against the observed ``pairs`` (module notes); ``choices``: the trials the effect
    chose among (more than one: one more fitted parameter, a radius or an order)."""
    observations, keys = [], []
    for pair in pairs:
        s_trial, _ = splits.get((pair.condition, pair.pair), (0.0, math.nan))
        power = trial.power(pair.m)
        if power is None:
            s_trial, power = 0.0, 1.0
        observations.append((pair.split, power, s_trial, pair.resolution))
        keys.append((pair.condition, pair.pair))
    q, split_deviance = _fit_magnitude(observations,
                                       magnitude_range(effect_id, trial))
    orientations, unexplained = [], 0.0
    for pair in pairs:
        if not pair.oriented:
            continue
        s_trial, offset = splits.get((pair.condition, pair.pair), (0.0, math.nan))
        period, power = 180.0 / pair.m, trial.power(pair.m)
        if power is None or not s_trial * q ** power > SPLIT_SIGMA or not math.isfinite(offset):
            # the fit does not split this pair past sigma_s: under it the members'
            # orientations are uniform over the pair's period P (density 1 / P), against
            # the Gaussian density of sigma_phi of a placed one -- the deviance of a member
            # is 2 ln(P / (sqrt(2 pi) sigma_phi)) on the scale where a placed member costs
            # (r / sigma_phi)^2, so every hypothesis is scored on the same orientations
            unexplained += 2 * 2 * math.log(max(period / (math.sqrt(2 * math.pi)
                                                          * ORIENTATION_SIGMA_DEG), 1.0))
            continue
        orientations.append((pair.high_orientation_deg, offset, period))
        orientations.append(((pair.low_orientation_deg - 90.0 / pair.m) % period,
                             offset, period))
    angle, orientation_deviance = _fit_angle(orientations, trial.angle_period)
    orientation_deviance += unexplained
    predicted = {key: c * q ** j for key, (_, j, c, _) in zip(keys, observations)}
    values = CATALOGUE[effect_id].split_signature.values(trial, q * trial.amplitude, angle)
    fitted = 1 + (1 if orientations else 0) + (1 if choices > 1 else 0)
    return ImperfectionFit(effect_id, tuple(float(v) for v in values), split_deviance,
                           orientation_deviance, fitted, trial.name, bool(orientations),
                           predicted)


def interpolated_trials(trials: list) -> list:
    """``[(trial, splits)]`` of consecutive trials that differ in one fixed value (a mass's
    radius) with 7 more between each two, the square roots of their splits interpolated
    linearly (a mass's split goes as phi(r)^2; offsets: the nearer trial's)."""
    out = []
    for (first, a), (second, b) in itertools.pairwise(trials):
        varying = [i for i, (u, v) in enumerate(zip(first.fixed, second.fixed))
                   if u is not None and v is not None and u != v]
        if len(varying) != 1:
            continue
        index = varying[0]
        for t in np.linspace(0, 1, 9)[1:-1]:
            fixed = list(first.fixed)
            fixed[index] = (1 - t) * first.fixed[index] + t * second.fixed[index]
            nearer = a if t < 0.5 else b
            # a mass's split goes as phi(r)^2: its square root is interpolated linearly
            splits = {key: (((1 - t) * math.sqrt(a.get(key, (0.0, math.nan))[0])
                             + t * math.sqrt(b.get(key, (0.0, math.nan))[0])) ** 2,
                            nearer[key][1])
                      for key in set(a) | set(b) if key in nearer}
            out.append((dataclasses.replace(first, fixed=tuple(fixed),
                                            name=f"{first.name} .. {second.name}"), splits))
    return out


# -- the verdict -------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class ImperfectionVerdict:
    """What the split pairs say (module notes): ``named`` (effect ids), ``ambiguous``
    (groups the data cannot tell apart), every effect's best :class:`ImperfectionFit`, the
    pairs, the perfect device's split deviance and the thresholds."""

    pairs: tuple
    named: tuple
    ambiguous: tuple
    fits: dict
    perfect_deviance: float
    perfect_limit: float
    significance: float
    verdict: str
    tested: tuple = ()
    fe_solves: int = 0

    def document(self) -> dict:
        """The ``imperfections`` entry of diagnosis.json."""
        def clean(value):
            return value if math.isfinite(value) else None

        return {
            "named": list(self.named), "ambiguous": [list(g) for g in self.ambiguous],
            "verdict": self.verdict, "tested": list(self.tested),
            "perfect_split_deviance": clean(self.perfect_deviance),
            "perfect_limit": clean(self.perfect_limit),
            "significance": clean(self.significance),
            "split_sigma": SPLIT_SIGMA, "orientation_sigma_deg": ORIENTATION_SIGMA_DEG,
            "lone_miss": LONE_MISS,
            "pairs": [{"condition": p.condition, "pair": p.pair, "low_hz": p.low_hz,
                       "high_hz": p.high_hz, "split": p.split,
                       "low_orientation_deg": clean(p.low_orientation_deg),
                       "high_orientation_deg": clean(p.high_orientation_deg),
                       "lone_resolution": clean(p.resolution)}
                      for p in self.pairs],
            "fits": {e: {"values": {p.name: clean(v) for p, v in
                                    zip(CATALOGUE[e].parameters, f.values)},
                         "split_deviance": f.split_deviance,
                         "orientation_deviance": f.orientation_deviance,
                         "fitted_parameters": f.fitted, "trial": f.trial,
                         "angle_measured": f.angle_measured,
                         "predicted": [{"condition": where, "pair": pair,
                                        "split": float(value)}
                                       for (where, pair), value in f.predicted.items()]}
                     for e, f in self.fits.items()},
        }

    def lines(self) -> list:
        """report.md's section."""
        out = ["## Imperfections (split pairs)", "", self.verdict, ""]
        if self.pairs:
            out += [("| condition | pair | f low [Hz] | f high [Hz] | split | orientation "
                     "low / high [deg] |"), "|---|---|---|---|---|---|"]
            for p in self.pairs:
                angles = ("-" if not math.isfinite(p.high_orientation_deg) else
                          f"{p.low_orientation_deg:.1f} / {p.high_orientation_deg:.1f}")
                split = (f"< {100 * p.resolution:.2f} % (one member)" if p.lone
                         else f"{100 * p.split:.3f} %")
                out.append(f"| {p.condition} | {p.pair} | {p.low_hz:.2f} | {p.high_hz:.2f} | "
                           f"{split} | {angles} |")
            out.append("")
        if self.pairs and self.fits:
            out += self.predicted_lines()
        for effect_id, fit in self.fits.items():
            out.append(f"- {effect_id}: {fit.describe()}; split deviance "
                       f"{fit.split_deviance:.1f}, orientation deviance "
                       f"{fit.orientation_deviance:.1f} ({fit.trial})")
        return out + [""]


    def predicted_lines(self) -> list:
        """report.md's table of each pair's split, measured and as each fit predicts it."""
        fits = list(self.fits)
        out = ["Each pair's split, measured and as each hypothesis's best fit predicts it:", "",
               "| condition | pair | measured | " + " | ".join(fits) + " |",
               "|---|---|---|" + "---|" * len(fits)]
        for p in self.pairs:
            measured = (f"< {100 * p.resolution:.2f} %" if p.lone else f"{100 * p.split:.3f} %")
            predicted = [self.fits[e].predicted.get((p.condition, p.pair)) for e in fits]
            out.append(f"| {p.condition} | {p.pair} | {measured} | " + " | ".join(
                "-" if value is None else f"{100 * value:.3f} %" for value in predicted) + " |")
        return out + [""]


def tested_imperfections(measured) -> tuple:
    """The imperfections ``measured.yaml`` allows: those its ``candidates`` name, or all of
    them when it names none of them and lists the defaults (no ``candidates:``)."""
    from copdea_fem.diagnosis.effects import DEFAULT_CANDIDATES
    named = tuple(e for e in IMPERFECTIONS if e in measured.candidates)
    if named:
        return named
    return IMPERFECTIONS if tuple(measured.candidates) == DEFAULT_CANDIDATES else ()


def untested_verdict(measured, pairings=(), why: str = "") -> ImperfectionVerdict:
    """The verdict where the imperfections cannot be tested (``why``: with ``model:
    reduced`` the trial 3-D FE solves are not run), with the pairs the data hold."""
    pairs = tuple(observed_pairs(measured, pairings))
    perfect = sum((p.split / SPLIT_SIGMA) ** 2 for p in pairs)
    return ImperfectionVerdict(pairs=pairs, named=(), ambiguous=(), fits={},
                               perfect_deviance=perfect, perfect_limit=math.nan,
                               significance=math.nan, verdict=f"imperfections not tested: {why}")


def name_imperfections(measured, fe, pairings=(), alpha: float = 0.05,
                       effects=None, pairs=None, square_frame: bool = False
                       ) -> ImperfectionVerdict:
    """The verdict of the split pairs (module notes).

    Parameters
    ----------
    measured : MeasuredSet
    fe : FEModel
        The diagnosis's FE (trial solves cached there).
    pairings : tuple of ScanPairing
        The scanned conditions' shape pairings (orientations).
    alpha : float
        False-alarm probability.
    effects : tuple of str, optional
        The imperfections tested (default :func:`tested_imperfections`).
    pairs : list of ObservedPair, optional
        The observed pairs (default :func:`observed_pairs`).
    square_frame : bool
        The model states a square frame (the base or the search's final state): in air its
        four-fold symmetry splits the pairs of even m, which are then left out.
    """
    from scipy.stats import chi2

    effects = tested_imperfections(measured) if effects is None else tuple(effects)
    pairs = tuple(observed_pairs(measured, pairings) if pairs is None else pairs)
    left_out = ""
    if square_frame and any(p.m % 2 == 0 for p in pairs):
        pairs = tuple(p for p in pairs if p.m % 2)
        left_out = ("; the pairs of even m are left out (the model's square frame splits "
                    "them)")
    perfect = sum((p.split / SPLIT_SIGMA) ** 2 for p in pairs)
    measured_splits = sum(not p.lone for p in pairs)
    limit = float(chi2.ppf(1 - alpha, max(measured_splits, 1)))
    significance = 2 * math.log(max(len(effects), 1) / alpha)
    common = {"pairs": pairs, "perfect_deviance": perfect, "perfect_limit": limit,
              "significance": significance, "tested": effects}
    verdict = _decide(measured, fe, alpha, effects, pairs, common)
    return dataclasses.replace(verdict, verdict=verdict.verdict + left_out) if left_out \
        else verdict


def _decide(measured, fe, alpha, effects, pairs, common) -> ImperfectionVerdict:
    """:func:`name_imperfections` past its inputs: the round device, the fits, the verdict."""
    from scipy.stats import chi2

    from copdea_fem.diagnosis.fe import BAND_MARGIN

    perfect, limit = common["perfect_deviance"], common["perfect_limit"]
    significance = common["significance"]
    if not effects or not pairs:
        why = ("no imperfection tested (measured.yaml's candidates name none)" if not effects
               else "no (m,n) pair labelled in the data: no imperfection tested")
        return ImperfectionVerdict(named=(), ambiguous=(), fits={}, verdict=why, **common)
    if perfect <= limit:
        lone = sum(p.lone for p in pairs)
        also = f"; {lone} lone members of a scan, unsplit as far as resolved" if lone else ""
        return ImperfectionVerdict(
            named=(), ambiguous=(), fits={}, **common,
            verdict=(f"no pair split beyond the noise (split deviance {perfect:.1f} <= "
                     f"{limit:.1f} for {len(pairs) - lone} measured splits, sigma "
                     f"{SPLIT_SIGMA:g}{also}): the device is round as far as the data tell"))
    conditions = {c.name: c for c in measured.conditions}
    wanted = sorted({p.condition for p in pairs})
    solves_before = fe.solves
    requests, plan = [], []
    for effect_id in effects:
        in_air = CATALOGUE[effect_id].split_signature.in_air
        for name in wanted:
            # in vacuo: the air's added mass loads both members of a pair alike, so a
            # stiffness imperfection's relative split is the same; a mass's is smaller in air
            # by m_modal / (m_modal + m_air) (the fitted mass: a lower bound).  A thickness
            # term changes the film's stiffness and mass together (they cancel in vacuo, the
            # air's added mass does not scale with the film): its trials keep the air
            study = measured.study_of(conditions[name],
                                      None if in_air else {"air.enabled": False})
            for trial in CATALOGUE[effect_id].split_signature.trials(study):
                requests.append((study.replace(trial.overrides),
                                 BAND_MARGIN * conditions[name].band[1], False))
                plan.append((effect_id, name, trial))
    logger.info("imperfections: pairs split beyond the noise (split deviance %.1f > %.1f); "
                "%d trial FE solves (in vacuo; a thickness term's with the conditions' air) "
                "of %s", perfect, limit, len(requests), ", ".join(effects))
    fe.solve_many(requests)
    table: dict = {}
    for (effect_id, name, trial), (study, f_max, _) in zip(plan, requests):
        result = fe.modes(study, f_max, merge_pairs=False)
        splits = table.setdefault(effect_id, {}).setdefault(trial.name, (trial, {}))[1]
        for pair, value in trial_splits(result.modes).items():
            splits[(name, pair)] = value
    for effect_id, trials in table.items():
        unheld = [f"{p.condition} {p.pair}" for p in pairs if p.lone
                  and not any((p.condition, p.pair) in splits for _, splits in trials.values())]
        if unheld:
            logger.info("imperfections: %s's trial solves do not hold the lone pairs %s (out "
                        "of their band): they contribute nothing to it", effect_id,
                        ", ".join(unheld))
    fits = {}
    # N: the measured splits, the lone members (censored) and the measured orientations;
    # the chi-square of the fit counts the Gaussian ones (a lone member's cost is bounded)
    n_gauss = sum(not p.lone for p in pairs) + 2 * sum(p.oriented for p in pairs)
    n_obs = n_gauss + sum(p.lone for p in pairs)
    for effect_id in effects:
        candidates = list(table[effect_id].values())
        if CATALOGUE[effect_id].split_signature.continuous:
            candidates += interpolated_trials(candidates)
        best = None
        for trial, splits in candidates:
            fit = fit_trial(effect_id, trial, splits, pairs, len(candidates))
            if best is None or fit.deviance < best.deviance:
                best = fit
        fits[effect_id] = best
    penalised = {e: f.deviance + f.fitted * math.log(max(n_obs, 2)) for e, f in fits.items()}
    order = sorted(penalised, key=penalised.get)
    top = order[0]
    solves = fe.solves - solves_before
    if perfect - fits[top].split_deviance < significance:
        return ImperfectionVerdict(
            named=(), ambiguous=(), fits=fits, fe_solves=solves, **common,
            verdict=(f"pairs split (split deviance {perfect:.1f} > {limit:.1f}), but no "
                     f"imperfection explains them significantly (best: {top}, improvement "
                     f"{perfect - fits[top].split_deviance:.1f} < {significance:.1f})"))
    rivals = tuple(e for e in order[1:]
                   if penalised[e] - penalised[top] < 2 * math.log(1 / alpha)
                   and perfect - fits[e].split_deviance >= significance)
    dof = max(n_gauss - fits[top].fitted, 1)
    fitness = float(chi2.sf(fits[top].deviance, dof))
    partly = (f"; the split pattern is only partly explained (deviance "
              f"{fits[top].deviance:.1f} for {dof} degrees of freedom)" if fitness < 1e-3
              else "")
    if rivals:
        group = (top,) + rivals
        return ImperfectionVerdict(
            named=(), ambiguous=(group,), fits=fits, fe_solves=solves, **common,
            verdict=(f"the pairs split, and {' / '.join(group)} explain them alike (penalised "
                     f"deviances {', '.join(f'{penalised[e]:.1f}' for e in group)}): the "
                     f"data cannot tell them apart; best provisionally {top} "
                     f"({fits[top].describe()}){partly}"
                     f"{deciding_condition(group, [conditions[n] for n in wanted], measured)}"))
    return ImperfectionVerdict(
        named=(top,), ambiguous=(), fits=fits, fe_solves=solves, **common,
        verdict=(f"imperfection: {top} ({fits[top].describe()}); split deviance "
                 f"{perfect:.1f} -> {fits[top].split_deviance:.1f}{partly}"))


def deciding_condition(group, conditions, measured) -> str:
    """What would decide between imperfections that one bias voltage leaves ambiguous
    (``""`` where the group's splits all move with the bias, or none does, or the
    ``conditions`` differ in bias): a condition at another bias
    (:attr:`~copdea_fem.diagnosis.effect_record.SplitSignature.moves_with_bias`; measured
    on the quick G1 at 16 mm in vacuo, (1,1) split from 2 to 3 kV: an order-2 thickness term
    of amplitude 0.2 -0.03 % -> -1.27 %, e = 2 % -2.60 % -> -2.77 %; docs/imperfections.md)."""
    moving = {CATALOGUE[e].split_signature.moves_with_bias for e in group}
    if moving != {True, False}:
        return ""
    voltages = {float(measured.study_of(condition).load.voltage) for condition in conditions}
    if len(voltages) > 1:
        return ""
    still = " / ".join(e for e in group if not CATALOGUE[e].split_signature.moves_with_bias)
    return (f"; every split pair is at one bias voltage ({voltages.pop():g} V): a scan at "
            "another bias (e.g. 1.5 times it) would decide - the splits of "
            f"{' / '.join(e for e in group if CATALOGUE[e].split_signature.moves_with_bias)} "
            f"move with the electrostatic stress, those of {still} hardly")


__all__ = ["LONE_MISS", "MAGNITUDE_RATIO_RANGE", "ImperfectionFit",
           "ImperfectionVerdict", "ObservedPair", "deciding_condition", "lone_cost", "magnitude_range", "name_imperfections",
           "observed_pairs", "pairs_from_resonances", "pairs_from_scan", "shape_orientation",
           "tested_imperfections", "trial_splits", "untested_verdict"]
