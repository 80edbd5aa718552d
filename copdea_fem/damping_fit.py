"""Fit the membrane's structural damping keys to measured modal damping.

``copdea-fem calibrate-damping STUDY.yaml [SPECTRUM.csv] --fit rayleigh|prony`` fits
``membrane.rayleigh_alpha`` [1/s] and ``membrane.rayleigh_beta`` [s], or one Prony term
(``modulus_ratio`` g [-], ``relaxation_time`` tau [s]), to the damping ratios of measured
modes, with the FE of the study as the model of record:

1. The measured damping ratio of mode k is ``zeta_k = 1 / (2 Q_k)`` (half-power width
   ``f_k / Q_k = 2 |Im f_k|``, ``zeta = -Im f / |f|`` as in ``modes.csv``), read from a CSV
   of quality factors, or ``zeta_k = (b/m)_k / (2 omega_k)`` from the reduced model's b/m
   calibrated on a measured spectrum (eq. 19: ``m q'' + b q' + k q``).
2. An FE solve of the study without damping keys gives each mode's frequency ``omega_k``
   and its radiation damping ratio ``zeta_rad,k`` (0 for a dry study).  Radiation and
   structural damping add at first order (``tests/fe/test_damping.py``), so the structural
   target is ``zeta_k - zeta_rad,k``.
3. The fit (below), then an FE solve with the fitted keys: its damping ratios, not the
   formula's, are the ``fitted`` column, and ``residual = zeta_FE / zeta_measured - 1``
   says how well each mode is fitted.  Where the FE differs from the formula (the Prony
   formula is first order; radiation and structural damping add only at first order),
   the formula of each mode is rescaled by ``zeta_FE,struct / zeta_formula`` and the fit
   repeated (at most ``refinements`` times).

Rayleigh (``C = alpha M + beta K``, exact)
------------------------------------------
The undamped modes ``K x_k = omega_k^2 M x_k`` diagonalise ``C``, so each mode of
``(K - i omega C - omega^2 M) x = 0`` solves ``omega^2 + i c_k omega - omega_k^2 = 0`` with
``c_k = alpha + beta omega_k^2``: ``omega = (-i c_k +- sqrt(4 omega_k^2 - c_k^2)) / 2``.  For an
underdamped mode ``|omega| = omega_k``, so

    zeta_k = -Im omega / |omega| = c_k / (2 omega_k) = alpha / (2 omega_k) + beta omega_k / 2,

exactly, linear in ``(alpha, beta)``.  The fit minimises the relative residuals
``sum_k (zeta_k(alpha, beta) / zetahat_k - 1)^2`` with ``alpha, beta >= 0`` (the keys' range):
a non-negative linear least-squares problem (``scipy.optimize.nnls`` on the rows
``[1 / (2 omega_k zetahat_k), omega_k / (2 zetahat_k)]``, right-hand side 1, columns scaled
to unit norm).  One mode cannot separate ``alpha`` from ``beta``: then ``beta`` alone is fitted.

One Prony term (first order, modal strain energy)
-------------------------------------------------
``T(omega) = K - omega^2 M + g K_mat r(omega)``, ``r = -i omega tau / (1 - i omega tau)
= (omega^2 tau^2 - i omega tau) / (1 + omega^2 tau^2)`` (``copdea_fem.fe.eigen.damped``).
With the undamped mode ``x_k`` the Rayleigh quotient gives, to first order in g,
``omega^2 = omega_k^2 (1 + g s_k r(omega_k))``, ``s_k = x_k^T K_mat x_k / x_k^T K x_k`` the
share of the mode's strain energy that is material (not initial stress, electrostatic or
spring), hence

    zeta_k = g s_k omega_k tau / (2 (1 + omega_k^2 tau^2))        (first order)

(the modal strain-energy method: half the material loss factor ``g omega tau / (1 + omega^2
tau^2)`` times ``s_k``).  ``s_k`` is measured on the FE of record by one probe solve with a
small term ``(g_0, tau_0)``: ``s_k = 2 dzeta_k (1 + omega_k^2 tau_0^2) / (g_0 omega_k tau_0)``,
``dzeta_k`` the change of the mode's damping ratio (dry or with the air, any engine).  For a
fixed tau the fit is linear in g (closed form); tau is found by a scan of log tau and a
bounded refinement.  **Not identifiable**: a mode with ``s_k ~ 0`` (every out-of-plane
mode of a flat membrane, ``load.z = 0``: its first-order strain vanishes, docs/damping.md)
carries no information on (g, tau) and is left out; with fewer than two modes, or a
best tau at the end of the scan (all modes far on one side of ``omega tau = 1``, where
only ``g tau`` or ``g / tau`` is determined), tau must be given (``--relaxation-time``).
"""

from __future__ import annotations

import csv
import logging
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.optimize

from copdea_fem.inputs import read_text
from copdea_fem.study import StudyError

log = logging.getLogger(__name__)

TWO_PI = 2 * math.pi
FITS = ("rayleigh", "prony")
QUALITY_COLUMNS = ("label", "quality_factor")
#: A mode whose material strain-energy share is below this carries no Prony information.
MIN_STRAIN_FRACTION = 1e-5
#: Probe Prony terms: the strain-energy shares (small g: first order) and their change
#: with the stiffening of the material tangent (g = 0.5).
PROBE_RATIOS = (0.01, 0.5)
#: The FE with the fitted keys agrees with the formula within this: no refinement.
AGREEMENT = 1e-3


class DampingFitError(ValueError):
    """The measured damping cannot be fitted (not identifiable, nothing left to fit)."""


@dataclass
class MeasuredDamping:
    """Measured modes: labels as in ``modes.csv`` and damping ratios zeta = 1/(2Q) [-]."""

    labels: list
    damping_ratio: np.ndarray
    freq_hz: np.ndarray | None = None     # measured frequencies [Hz] (information only)
    source: str = ""


@dataclass
class DampingFit:
    """The fitted keys and, per mode, how well the FE with them matches the measurement."""

    kind: str                                # "rayleigh" or "prony"
    keys: dict                               # {"membrane.rayleigh_alpha": 1/s, ...}
    labels: list
    freq_hz: np.ndarray                      # FE frequency of each mode [Hz]
    measured: np.ndarray                     # measured damping ratio [-]
    radiation: np.ndarray                    # FE radiation damping ratio [-]
    formula: np.ndarray                      # fitted damping ratio by the formula [-]
    fitted: np.ndarray                       # FE damping ratio with the fitted keys [-]
    used: np.ndarray                         # mode entered the fit
    strain_fraction: np.ndarray | None = None
    notes: list = field(default_factory=list)
    verified: bool = True                    # ``fitted`` from an FE solve (else formula)

    @property
    def residual(self) -> np.ndarray:
        """zeta_fitted / zeta_measured - 1 per mode [-]."""
        return self.fitted / self.measured - 1

    @property
    def rms_residual(self) -> float:
        """Root-mean-square relative residual of the modes used in the fit [-]."""
        return float(np.sqrt(np.mean(self.residual[self.used] ** 2)))

    def options(self) -> str:
        """The fitted keys as ``--set`` options (6 significant digits)."""
        parts = []
        for key, value in self.keys.items():
            if key == "membrane.prony":
                term = value[0]
                parts.append(f"--set 'membrane.prony=[{{modulus_ratio: "
                             f"{term['modulus_ratio']:.6g}, relaxation_time: "
                             f"{term['relaxation_time']:.6g}}}]'")
            else:
                parts.append(f"--set {key}={value:.6g}")
        return " ".join(parts)


# -- the closed forms ------------------------------------------------------------------------
def rayleigh_ratio(freq_hz, alpha: float, beta: float) -> np.ndarray:
    """zeta_k = alpha / (2 omega_k) + beta omega_k / 2 [-] (module docstring)."""
    omega = TWO_PI * np.asarray(freq_hz, float)
    return alpha / (2 * omega) + beta * omega / 2


def prony_ratio(freq_hz, strain_fraction, modulus_ratio: float, relaxation_time: float,
                softening=0.0) -> np.ndarray:
    """zeta_k = g s_k(kappa_k) omega_k tau / (2 (1 + omega_k^2 tau^2)) [-] (module docstring),
    ``s_k(kappa) = s_k / (1 + d_k kappa)``, ``kappa = g omega^2 tau^2 / (1 + omega^2 tau^2)``
    the stiffening of the material tangent; ``softening`` d_k = 0: the first order."""
    wt = TWO_PI * np.asarray(freq_hz, float) * relaxation_time
    kappa = modulus_ratio * wt**2 / (1 + wt**2)
    share = np.asarray(strain_fraction, float) / (1 + np.asarray(softening, float) * kappa)
    return modulus_ratio * share * wt / (2 * (1 + wt**2))


def fit_rayleigh(freq_hz, damping_ratio, scale=None, sensitivity=None) -> tuple[float, float]:
    """(alpha [1/s], beta [s]) >= 0 minimising sum (zeta_k / zetahat_k - 1)^2 with
    ``zeta_k = scale_k (a_k alpha / (2 omega_k) + b_k beta omega_k / 2)``.

    ``sensitivity = (a, b)`` (default 1): the FE's share of each term in a mode (with the
    air, ``alpha`` damps only the membrane's part of the kinetic energy); ``scale``
    (default 1): the FE refinement.  One mode: beta alone (alpha = 0).
    """
    omega = TWO_PI * np.asarray(freq_hz, float)
    target = np.asarray(damping_ratio, float)
    scale = np.ones_like(omega) if scale is None else np.asarray(scale, float)
    a, b = (1.0, 1.0) if sensitivity is None else sensitivity
    if np.any(target <= 0):
        raise DampingFitError("a measured damping ratio <= 0 cannot be fitted")
    design = np.column_stack([scale * a / (2 * omega), scale * b * omega / 2]) / target[:, None]
    if omega.size < 2 or np.ptp(omega) <= 1e-9 * omega.max():
        beta = float(np.sum(design[:, 1]) / np.sum(design[:, 1] ** 2))
        return 0.0, beta
    norms = np.linalg.norm(design, axis=0)
    solution, _ = scipy.optimize.nnls(design / norms, np.ones(omega.size))
    alpha, beta = solution / norms
    return float(alpha), float(beta)


def _prony_gain(freq_hz, strain_fraction, target, tau, scale, softening):
    """Best g in [1e-6, 1000] (the key's range) for a fixed tau and its residual norm."""
    def cost(log_g):
        zeta = scale * prony_ratio(freq_hz, strain_fraction, math.exp(log_g), tau, softening)
        return float(np.sum((zeta / target - 1) ** 2))
    a = scale * prony_ratio(freq_hz, strain_fraction, 1.0, tau) / target
    first = math.log(min(max(float(np.sum(a) / np.sum(a * a)), 1e-6), 1e3))  # linear (d = 0)
    if not np.any(softening):
        return math.exp(first), cost(first)
    result = scipy.optimize.minimize_scalar(cost, bounds=(math.log(1e-6), math.log(1e3)),
                                            method="bounded", options={"xatol": 1e-10})
    best = min((first, result.x), key=cost)
    return math.exp(best), cost(best)


def fit_prony(freq_hz, damping_ratio, strain_fraction, relaxation_time=None,
              scale=None, softening=0.0) -> tuple[float, float, bool]:
    """(g, tau [s], tau_identified) of one Prony term minimising the relative residuals
    ``sum_k (scale_k zeta_k(g, tau) / zetahat_k - 1)^2`` (:func:`prony_ratio`).

    ``relaxation_time`` given: only g.  Otherwise tau by a scan of 241 points over
    ``[1e-3, 1e3] / omega`` of the band and a bounded refinement of log tau (g the best for
    each tau); ``tau_identified`` is False when the best tau lies at the end of the scan
    (only g tau or g / tau is determined by these modes) or fewer than two distinct
    frequencies are given.
    """
    freq = np.asarray(freq_hz, float)
    target = np.asarray(damping_ratio, float)
    s = np.asarray(strain_fraction, float)
    scale = np.ones_like(freq) if scale is None else np.asarray(scale, float)
    softening = np.broadcast_to(np.asarray(softening, float), freq.shape)
    if np.any(target <= 0):
        raise DampingFitError("a measured damping ratio <= 0 cannot be fitted")

    def gain(tau):
        return _prony_gain(freq, s, target, tau, scale, softening)

    if relaxation_time is not None:
        return gain(relaxation_time)[0], relaxation_time, True
    omega = TWO_PI * freq
    low, high = math.log(1e-3 / omega.max()), math.log(1e3 / omega.min())
    grid = np.linspace(low, high, 241)
    cost = np.array([gain(math.exp(t))[1] for t in grid])
    best = int(np.argmin(cost))
    if best in (0, grid.size - 1) or freq.size < 2 or np.ptp(freq) <= 1e-9 * freq.max():
        tau = math.exp(grid[best])
        return gain(tau)[0], tau, False
    result = scipy.optimize.minimize_scalar(lambda t: gain(math.exp(t))[1],
                                            bounds=(grid[best - 1], grid[best + 1]),
                                            method="bounded", options={"xatol": 1e-10})
    tau = math.exp(result.x)
    return gain(tau)[0], tau, True


# -- measured damping ------------------------------------------------------------------------
#: A mode label as the FE writes it in modes.csv (copdea_fem.fe.modes.assign_labels):
#: ``(m,n)`` with an optional letter and repeat suffix, ``ip(m,n)...``, or ``P<k>``.
MODE_LABEL = re.compile(r"(?:ip)?\(\d+,[1-9]\d*\)[a-z]?(?:-\d+)?|P[1-9]\d*")
LABEL_ALLOWED = "a mode label as in modes.csv, e.g. (0,1), (1,1)a, ip(0,1)b or P1"
#: Largest relative difference between damping_ratio and 1/(2 quality_factor) of one row
#: when a file gives both (both rounded to a few digits by whoever wrote them).
COLUMNS_AGREEMENT = 0.01


def mode_label(text: str, where: str) -> str:
    """``text`` as a mode label (spaces dropped: ``(0, 1)`` is ``(0,1)``), else a
    :class:`StudyError` naming ``where``."""
    label = "".join(str(text).split())
    if not MODE_LABEL.fullmatch(label):
        raise StudyError(f"{where}: label = {str(text)!r} is not allowed"
                         f"{' (empty)' if not label else ''}; allowed: {LABEL_ALLOWED}")
    return label


def check_damping_ratio(zeta: float, where: str) -> None:
    """A measured damping ratio the fit can use: finite, in (0, 1); a ratio >= 1 is
    overdamped, a motion without oscillation and so without a resonance to fit."""
    if not (math.isfinite(zeta) and 0 < zeta < 1):
        why = " (overdamped: no oscillation, no resonance to fit)" if zeta >= 1 else ""
        raise StudyError(f"{where}: damping_ratio = {zeta:g} is not allowed{why}; allowed: "
                         "(0, 1)")


def read_quality_csv(path) -> MeasuredDamping:
    """Measured modes: columns ``label`` (as in modes.csv, e.g. ``(0,1)``) and
    ``quality_factor`` [-] (or ``damping_ratio`` [-], or both when they agree within
    :data:`COLUMNS_AGREEMENT`); optional ``freq_hz`` [Hz].  Every value is checked here,
    before any FE solve (a :class:`StudyError` naming the file, line and column)."""
    path = Path(path)
    if not path.is_file():
        raise StudyError(f"--quality-factors {str(path)!r} does not exist; allowed: a CSV with "
                         "columns label, quality_factor [, freq_hz]")
    lines = read_text(path, "--quality-factors", error=StudyError).splitlines()
    rows = list(csv.reader(row for row in lines if row.strip() and not row.startswith("#")))
    header = [name.strip() for name in rows[0]] if rows else []
    given = [name for name in ("quality_factor", "damping_ratio") if name in header]
    duplicated = sorted({name for name in header if header.count(name) > 1})
    if "label" not in header or not given or len(rows) < 2 or duplicated:
        twice = f" ({', '.join(duplicated)} twice)" if duplicated else ""
        raise StudyError(f"--quality-factors {str(path)!r} has columns {header}{twice} and "
                         f"{max(len(rows) - 1, 0)} rows; allowed: columns label, quality_factor "
                         "(or damping_ratio) [, freq_hz], each once, and at least one row")
    labels, values, freqs = [], [], []
    for number, row in enumerate(rows[1:], start=2):
        where = f"--quality-factors {str(path)!r} line {number}"
        cells = dict(zip(header, (cell.strip() for cell in row)))
        ratios = {}
        for column in given:
            try:
                number_value = float(cells[column])
            except (KeyError, ValueError):
                raise StudyError(f"{where}: {column} = {cells.get(column)!r} is not allowed; "
                                 "allowed: a number") from None
            if column == "damping_ratio":
                check_damping_ratio(number_value, where)
                zeta = number_value
            elif not (math.isfinite(number_value) and number_value > 0.5):
                why = " (overdamped: no oscillation, no resonance to fit)" \
                    if 0 < number_value <= 0.5 else ""
                raise StudyError(f"{where}: quality_factor = {number_value:g} is not allowed"
                                 f"{why}; allowed: > 0.5 (damping ratio 1/(2 Q) < 1)")
            else:
                zeta = 1 / (2 * number_value)
            ratios[column] = zeta
        if len(ratios) == 2 and abs(ratios["damping_ratio"] / ratios["quality_factor"] - 1) \
                > COLUMNS_AGREEMENT:
            raise StudyError(
                f"{where}: damping_ratio = {ratios['damping_ratio']:g} and quality_factor = "
                f"{1 / (2 * ratios['quality_factor']):g} disagree (1/(2 Q) = "
                f"{ratios['quality_factor']:g}); allowed: one of the columns, or both with "
                f"damping_ratio = 1/(2 quality_factor) within {COLUMNS_AGREEMENT:.0%}")
        text = cells.get("freq_hz", "")
        try:
            freq = float(text) if text else math.nan
        except ValueError:
            freq = -1.0
        if text and not (math.isfinite(freq) and freq > 0):
            raise StudyError(f"{where}: freq_hz = {text!r} is not allowed; allowed: a frequency "
                             "> 0 Hz, or empty")
        label = mode_label(cells.get("label", ""), where)
        if label in labels:
            raise StudyError(f"{where}: label {label!r} is not allowed twice")
        labels.append(label)
        values.append(ratios.get("damping_ratio", ratios.get("quality_factor")))
        freqs.append(freq)
    return MeasuredDamping(labels, np.array(values), np.array(freqs), source=str(path))


def check_measured(measured: MeasuredDamping) -> None:
    """Refuse measured damping the fit cannot use, before any FE solve: empty, a label
    that is not a mode label, a damping ratio not in (0, 1) (:func:`check_damping_ratio`)."""
    where = f"measured damping from {measured.source or 'the spectrum'}"
    if not len(measured.labels):
        raise StudyError(f"{where}: no mode is allowed; allowed: at least one measured mode")
    for label, zeta in zip(measured.labels, measured.damping_ratio):
        mode_label(label, where)
        check_damping_ratio(float(zeta), f"{where}, mode {label}")


def measured_from_spectrum(labels, damping_per_mass, freq_hz, source="") -> MeasuredDamping:
    """zeta_k = (b/m)_k / (2 omega_k) from the reduced model's calibrated b/m [1/s] (eq. 19)."""
    ratio = np.asarray(damping_per_mass, float) / (2 * TWO_PI * np.asarray(freq_hz, float))
    return MeasuredDamping(list(labels), ratio, np.asarray(freq_hz, float), source=source)


# -- the FE of record ------------------------------------------------------------------------
def _undamped(study):
    keys = {"membrane.rayleigh_alpha": 0.0, "membrane.rayleigh_beta": 0.0, "membrane.prony": []}
    return study.replace(keys)


def fe_modes(study) -> dict:
    """``{label: (freq_hz, damping_ratio)}`` of an FE solve of ``study`` (first of a label).

    :func:`copdea_fem.fe.run_solve` on the study's engine (resolved here: each fitted study
    is solved once), nothing written (not :mod:`copdea_fem.api`, which imports this module:
    :func:`copdea_fem.api.calibrate_damping` wraps the fit in :func:`copdea_fem.api.solving`).
    """
    from copdea_fem.fe import engine_for, run_solve
    result = run_solve(study, engine=engine_for(study))
    modes = {}
    for mode in result.modes:
        modes.setdefault(mode.label, (float(np.hypot(mode.freq_hz, mode.freq_im_hz)),
                                      float(mode.damping_ratio)))
    return modes


def _with_keys(study, keys: dict, lowest_hz: float):
    """The study with the fitted keys; ``eigen.f_min`` raised where the Prony relaxation
    spectrum would reach the band (None when that would cut a fitted mode)."""
    try:
        return study.replace(keys)
    except StudyError as error:
        prony = keys.get("membrane.prony")
        if not prony or "eigen.f_min" not in str(error):
            raise
        term = prony[0]
        lowest = 1 / (TWO_PI * term["relaxation_time"] * (1 + term["modulus_ratio"]))
        f_min = 0.5 * lowest * 1.001
        if f_min >= 0.9 * lowest_hz:
            return None
        return study.replace({**keys, "eigen.f_min": f_min})


def _probe_time(study, freq_hz) -> float:
    """tau_0 of the probe: near omega tau = 1 in the band, its relaxation spectrum
    (|Im f| >= 1 / (2 pi tau_0 (1 + g_0))) kept above the band's height (study check)."""
    eigen = study.eigen
    height = eigen.max_damping_ratio * eigen.f_max
    centre = math.exp(np.mean(np.log(freq_hz)))
    return min(1 / (TWO_PI * centre), 1 / (TWO_PI * 2.2 * height * (1 + max(PROBE_RATIOS))))


def fit_damping(study, measured: MeasuredDamping, kind: str, relaxation_time=None,
                refinements: int = 2) -> DampingFit:
    """Fit ``kind`` (``rayleigh`` or ``prony``) to ``measured`` with the study's FE.

    FE solves (module docstring): the undamped study (frequencies, radiation); Rayleigh
    with the air: one probe per term (its share in each mode); Prony: two probes (the
    strain-energy shares and their change with the stiffening); then one with the fitted
    keys per attempt (1 + ``refinements`` at most).  Modes the FE band does not hold are
    left out with a note (an error when none is left).
    """
    if kind not in FITS:
        raise StudyError(f"--fit = {kind!r} is not allowed; allowed: modal, "
                         + ", ".join(FITS))
    if relaxation_time is not None and not relaxation_time > 0:
        raise StudyError(f"--relaxation-time = {relaxation_time!r} is not allowed; allowed: "
                         "a time > 0 s")
    base = _undamped(study)
    log.info("calibrate-damping: FE solve without damping keys (frequencies, radiation) ...")
    undamped = fe_modes(base)
    missing = [label for label in measured.labels if label not in undamped]
    notes = []
    if missing and len(missing) < len(measured.labels):
        notes.append(f"measured mode(s) {', '.join(missing)} are not in the FE band "
                     f"[eigen.f_min, eigen.f_max] = [{study.eigen.f_min:g}, "
                     f"{study.eigen.f_max:g}] Hz: left out")
        kept = [j for j, label in enumerate(measured.labels) if label in undamped]
        measured = MeasuredDamping([measured.labels[j] for j in kept],
                                   measured.damping_ratio[kept], None, measured.source)
    elif missing:
        raise StudyError(
            f"measured mode(s) {', '.join(missing)} are not in the FE band of the study "
            f"(its modes: {', '.join(undamped)}); allowed: labels of the FE modes in "
            f"[eigen.f_min, eigen.f_max] = [{study.eigen.f_min:g}, "
            f"{study.eigen.f_max:g}] Hz")
    labels = list(measured.labels)
    freq = np.array([undamped[label][0] for label in labels])
    radiation = np.maximum([undamped[label][1] for label in labels], 0.0)   # dry: -0.0
    target = measured.damping_ratio - radiation
    used = target > 0
    for label, zeta, rad in zip(labels, measured.damping_ratio, radiation):
        if zeta <= rad:
            notes.append(f"{label}: measured damping ratio {zeta:.4g} <= its FE radiation "
                         f"damping {rad:.4g}: no structural damping to fit (left out)")
    strain = softening = None
    sensitivity = (np.ones(len(labels)), np.ones(len(labels)))
    if kind == "rayleigh" and study.air.enabled:
        # with the air the closed form holds for the membrane's share only: each term's
        # share per mode from one probe solve each (zeta ~ 1e-3, first order)
        centre = TWO_PI * math.exp(np.mean(np.log(freq)))
        shares = []
        for key, value, unit in (("membrane.rayleigh_alpha", 2e-3 * centre, (1, 0)),
                                 ("membrane.rayleigh_beta", 2e-3 / centre, (0, 1))):
            log.info(f"calibrate-damping: FE probe solve ({key} = {value:.4g}) ...")
            probe = fe_modes(base.replace({key: value}))
            change = np.array([probe.get(label, (0, rad))[1] - rad
                               for label, rad in zip(labels, radiation)])
            shares.append(change / rayleigh_ratio(freq, value * unit[0], value * unit[1]))
        sensitivity = tuple(shares)
    if kind == "prony":
        tau0 = _probe_time(base, freq)
        shares = []
        for ratio in PROBE_RATIOS:
            log.info(f"calibrate-damping: FE probe solve (Prony g = {ratio:g}, tau = "
                     f"{tau0:.4g} s) for the material strain-energy shares ...")
            probe = fe_modes(base.replace({"membrane.prony": [
                {"modulus_ratio": ratio, "relaxation_time": tau0}]}))
            # a mode that left the probe's band (stiffened above eigen.f_max): nan
            change = np.array([probe[label][1] - rad if label in probe else math.nan
                               for label, rad in zip(labels, radiation)])
            shares.append(change / prony_ratio(freq, 1.0, ratio, tau0))
        lost = np.isnan(shares[0])
        for label in np.array(labels)[lost & used]:
            notes.append(f"{label}: left the band in the probe solve (left out)")
        used &= ~lost
        strain = np.nan_to_num(shares[0])
        flat = ~lost & (strain < MIN_STRAIN_FRACTION)
        # s(kappa) = s / (1 + d kappa) through the second probe (kappa = g Re r(omega tau0));
        # d = 0 (first order) where the second probe lost the mode
        wt = TWO_PI * freq * tau0
        kappa = PROBE_RATIOS[1] * wt**2 / (1 + wt**2)
        second = shares[1]
        valid = ~flat & ~lost & np.isfinite(second) & (second > 0)
        softening = np.zeros(len(labels))
        softening[valid] = (strain[valid] / second[valid] - 1) / kappa[valid]
        softening = np.clip(softening, -0.9 / kappa, None)
        for label in np.array(labels)[flat & used]:
            notes.append(f"{label}: not identifiable by a Prony term (material strain-energy "
                         f"share < {MIN_STRAIN_FRACTION:g}: an out-of-plane mode of a flat "
                         "membrane is not strained at first order, docs/damping.md; left out)")
        used &= ~flat
    if not np.any(used):
        raise DampingFitError(
            f"no measured mode can be fitted by {kind} damping: "
            + "; ".join(notes or ["no mode"]))
    scale = np.ones(len(labels))
    result = None
    for attempt in range(refinements + 1):
        if kind == "rayleigh":
            if np.count_nonzero(used) < 2 and attempt == 0:
                notes.append("one mode cannot separate alpha from beta: beta alone fitted")
            alpha, beta = fit_rayleigh(freq[used], target[used], scale[used],
                                       (sensitivity[0][used], sensitivity[1][used]))
            keys = {"membrane.rayleigh_alpha": alpha, "membrane.rayleigh_beta": beta}
            formula = radiation + scale * (rayleigh_ratio(freq, alpha * sensitivity[0], 0.0)
                                           + rayleigh_ratio(freq, 0.0, beta * sensitivity[1]))
        else:
            g, tau, identified = fit_prony(freq[used], target[used], strain[used],
                                           relaxation_time, scale[used], softening[used])
            if not identified:
                raise DampingFitError(
                    "the relaxation time is not identifiable from these modes (fewer than two "
                    "usable modes, or all of them far on one side of omega tau = 1, where only "
                    "g tau or g / tau is determined); give it: --relaxation-time")
            keys = {"membrane.prony": [{"modulus_ratio": g, "relaxation_time": tau}]}
            formula = radiation + scale * prony_ratio(freq, np.maximum(strain, 0), g, tau,
                                                      softening)
        fitted_study = _with_keys(base, keys, float(freq[used].min()))
        if fitted_study is None:
            notes.append("the fitted relaxation spectrum reaches the band of the fitted modes: "
                         "the fitted column is the formula's, not an FE solve's")
            return DampingFit(kind, keys, labels, freq, measured.damping_ratio, radiation,
                              formula, formula, used, strain, notes, verified=False)
        log.info(f"calibrate-damping: FE solve with the fitted keys ({attempt + 1}) ...")
        solved = fe_modes(fitted_study)
        fe = np.array([solved.get(label, (math.nan, math.nan))[1] for label in labels])
        lost = [label for label, zeta, use in zip(labels, fe, used)
                if use and not math.isfinite(zeta)]
        if lost or not all(math.isfinite(value) for value in _key_values(keys)):
            raise DampingFitError(
                f"the fitted keys {keys} leave no FE mode {', '.join(lost) or ''} in the band "
                "(overdamped or moved out of [eigen.f_min, eigen.f_max]): the measured "
                "damping cannot be fitted by " + kind + " damping")
        result = DampingFit(kind, keys, labels, freq, measured.damping_ratio, radiation,
                            formula, fe, used, strain, notes)
        structural = fe - radiation
        off = np.abs(structural[used] / (formula - radiation)[used] - 1)
        if not np.all(np.isfinite(off)) or np.max(off) <= AGREEMENT:
            break
        scale = np.where(used, structural / np.maximum(formula - radiation, 1e-300) * scale,
                         scale)
    return result


def _key_values(keys: dict) -> list:
    """The numbers of fitted keys (a Prony term's two included)."""
    values = []
    for value in keys.values():
        values.extend([number for term in value for number in term.values()]
                      if isinstance(value, list) else [value])
    return values


# -- the command -----------------------------------------------------------------------------
FIT_COLUMNS = ("label", "freq_hz", "measured_quality_factor", "measured_damping_ratio",
               "radiation_damping_ratio", "fitted_damping_ratio", "fitted_quality_factor",
               "residual", "strain_energy_fraction", "used")


def measured_damping(study, spectrum_csv=None, quality_csv=None, modes_json=None,
                     window: float = 0.15) -> MeasuredDamping:
    """The measured damping a structural fit is made to, checked (:func:`check_measured`).

    ``quality_csv`` (:func:`read_quality_csv`: label, quality_factor [, freq_hz]), else the
    b/m of the reduced model calibrated on ``spectrum_csv``
    (:func:`copdea_fem.reduced.io.calibrate_on_spectrum`; zeta = (b/m) / (2 omega),
    :func:`measured_from_spectrum`).
    """
    from copdea_fem.reduced.io import calibrate_on_spectrum
    if quality_csv is not None:
        measured = read_quality_csv(quality_csv)
    elif spectrum_csv is not None:
        calibration, setup, _ = calibrate_on_spectrum(study, spectrum_csv, modes_json, window)
        measured = measured_from_spectrum(calibration.labels, calibration.damping_per_mass,
                                          setup.reduced.frequency_hz, source=str(spectrum_csv))
    else:
        raise StudyError("measured damping is required; allowed: --quality-factors Q.csv or "
                         "a SPECTRUM.csv")
    check_measured(measured)
    return measured


def calibrate_structural_damping(study, measured: MeasuredDamping, fit: str,
                                 relaxation_time=None) -> DampingFit:
    """Fit ``membrane.rayleigh_alpha/beta`` or one Prony term (module docstring) to
    ``measured`` with the FE of ``study`` (:func:`fit_damping`); measured damping that
    cannot be fitted is a :class:`~copdea_fem.reduced.rings.ReducedModelError` (the CLI's
    exit 3)."""
    from copdea_fem.reduced.rings import ReducedModelError
    try:
        return fit_damping(study, measured, fit, relaxation_time=relaxation_time)
    except DampingFitError as error:
        raise ReducedModelError(str(error)) from None


def write_damping_fit(out, result: DampingFit) -> list:
    """``damping_fit.csv`` in ``out`` (a staging folder): :data:`FIT_COLUMNS` (FE frequency
    [Hz], measured and fitted damping ratio and quality factor [-], the FE radiation damping
    ratio [-], residual = fitted / measured - 1 [-], the material strain-energy share of a
    Prony fit [-], whether the mode was fitted); its path in a list."""
    from copdea_fem.reduced.io import write_csv
    return [write_csv(out / "damping_fit.csv", FIT_COLUMNS, damping_fit_columns(result))]


def damping_fit_columns(result: DampingFit) -> tuple:
    """The columns of ``damping_fit.csv``, in the order of :data:`FIT_COLUMNS`."""
    strain = result.strain_fraction if result.strain_fraction is not None \
        else np.full(len(result.labels), math.nan)
    return (result.labels, result.freq_hz, 1 / (2 * result.measured), result.measured,
            result.radiation, result.fitted, 1 / (2 * result.fitted), result.residual, strain,
            ["yes" if used else "no" for used in result.used])


def damping_fit_lines(result: DampingFit, source: str) -> list[str]:
    """What ``copdea-fem calibrate-damping --fit rayleigh|prony`` prints: the table of the
    fitted modes, the rms residual, the notes and the ``--set`` options (``source``: where
    the measured damping came from)."""
    verified = "FE with the fitted keys" if result.verified else "formula (not FE-verified)"
    lines = [f"{result.kind} fit to {len(result.labels)} measured mode(s) from {source}; "
             f"fitted = {verified}",
             f"{'mode':>8} {'FE Hz':>9} {'Q meas':>9} {'zeta meas':>10} {'zeta rad':>10} "
             f"{'zeta fit':>10} {'residual':>9}  fitted"]
    for j, label in enumerate(result.labels):
        lines.append(f"{label:>8} {result.freq_hz[j]:9.2f} {1 / (2 * result.measured[j]):9.2f} "
                     f"{result.measured[j]:10.4g} {result.radiation[j]:10.4g} "
                     f"{result.fitted[j]:10.4g} {100 * result.residual[j]:8.2f}%  "
                     f"{'yes' if result.used[j] else 'no'}")
    lines.append(f"  rms residual of the fitted modes: {100 * result.rms_residual:.2f} %")
    lines.extend(f"  note: {note}" for note in result.notes)
    lines.append("  use: " + result.options())
    return lines
