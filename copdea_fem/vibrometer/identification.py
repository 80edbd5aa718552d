"""Modal parameters of a scan: LSCF poles chosen from a stabilisation diagram, LSFD residues.

The FRF model of a scan with one input (the drive voltage) is

    H_c(w) = sum_r [ A_cr / (i w - s_r) + conj(A_cr) / (i w - conj(s_r)) ] (i w)^k
             + lower and upper residual terms,

k = 0, 1, 2 for displacement, velocity and acceleration responses (receptance, mobility,
accelerance), with the pole ``s_r = -zeta_r w_r + i w_r sqrt(1 - zeta_r^2)`` and the residue
``A_cr`` of mode r at channel c (Ewins, *Modal testing*, 2nd ed., Sect. 4.3; Peeters et al.,
"The PolyMAX frequency-domain method", Shock Vib. 11, 2004).  Both steps are sdypy-EMA's:

1. **Poles** (:meth:`sdypy.EMA.Model.get_poles`, method ``lscf``): the least-squares
   complex-frequency estimator fits a common-denominator polynomial of order 2, 4, ...,
   ``max_order`` and returns its roots at every order.  A scan has hundreds of channels;
   LSCF needs only the space they span, so it is fed the scan's principal response
   functions: the first ``components`` right singular vectors of the (channels x lines)
   FRF matrix, scaled by their singular values (the common-denominator poles of a sum of
   modes are those of any set of combinations that keeps every mode's shape; the residues
   are then fitted on every channel).
2. **Choice** (no GUI, no FE): poles are chained over the orders into tracks, each to the
   nearest pole of the previous order (or the one before it) within
   ``frequency_tolerance`` (relative), one to one, those whose damping also lies within
   ``damping_tolerance`` (relative) first; such a link is *stable*, one in frequency only
   *frequency-stable* (it continues the track: at 60 dB noise a weak mode's damping
   scatters past 5 % between orders and broke its track into pieces too short to count).
   A physical mode is a track stable over at least ``min_stable_orders`` orders; its
   pole is the median over the upper half of its stable poles (the higher orders, where
   it has converged).  Two
   poles closer than a peak's half-power width are told apart by this - a split pair
   (m,n)a/b gives two tracks that coexist at the same orders - where a peak search on
   the sum of the FRFs finds one peak.
3. **Refinement** (:mod:`copdea_fem.vibrometer.pole_refinement`): the chosen poles start
   a nonlinear least-squares fit of the FRF model to the principal response functions,
   the residues eliminated (variable projection); modes the diagram missed are added one
   at a time where the residual holds a resonance above the noise, and poles whose
   removal the noise would hide are dropped.  Weakly driven modes among strong ones within
   a half-power width come and go between LSCF's orders; the fit finds them (the dry
   membrane's (0,1), (1,1), (2,1) 2.5 % apart at 1 % damping: all three on 10 of 10
   seeds, against none of 10 with the diagram alone; ``benchmarks/identification_recall``).
   No mode is added where the noise cannot be measured (fewer channels outside the
   principal functions than in them).
4. **Residues** (:func:`sdypy.EMA.EMA.LSFD`): with the chosen poles fixed, the residues
   ``A_cr`` and the residual terms are the linear least-squares fit of every channel
   over the band.  The mode's shape is ``A_:r`` (per channel of the scan); its modal
   phase collinearity ``MPC = ((l1 - l2) / (l1 + l2))^2`` with l1 >= l2 the eigenvalues
   of the 2 x 2 matrix of the real and imaginary parts' inner products (Pappa, Elliott
   & Schenk, J. Guid. Control Dyn. 16, 1993): 1 for a real (normal) mode, 0 for phases
   spread evenly.  A mode with ``MPC < MPC_MIN`` is dropped and the others refitted (the
   least collinear first, one at a time): its residues are no shape, as when two poles
   share one resonance the data do not separate.  The poles the refinement presses
   against a band edge stay in this fit as the tails of modes just outside the band (no
   modes, not reported).  LSFD's residual terms (a constant and a ``1/w^2`` term) stand
   for modes far outside the band; a strongly driven mode just past its edge has a tail
   that changes across the band as ``1/(w_r^2 - w^2)`` does, and without its pole its
   shape goes into the residues of the modes inside, the weak ones most (the FE-made G1
   scan with a 2 % anisotropy, lines to 1000 Hz: an in-plane mode at 1004.5 Hz, the
   largest static response of the band, held 69 % of the energy of the weak (1,1)
   member's residues at its true pole - MAC with the round FE's (1,1) pair 0.27 - and that
   member was not found; with the band-edge poles kept it is found at 449.55 Hz, MAC
   0.98).  Without them the MPC drop cascaded: on FE-made 84-point scans of G1 at
   150-850 Hz, one edge pole more or less (849.7 against 848.4 Hz, a round-off change of
   the data) dropped four modes near the top, 17 against 13 identified.
5. **Close pairs** (``resolve_pairs``, off by default; :mod:`close_pairs`): the noise from
   the median eigenvalue (:func:`noise_variance`), a second refinement on the residual's
   shapes beyond the principal functions, poles whose half-power band holds two shapes
   split in two, and the members of such a pair exempt from the MPC drop.  The band-edge
   poles take part in the second refinement, the residual's shapes and the split too.
"""

from __future__ import annotations

import logging
import math
import numbers
import time
from dataclasses import dataclass, field

import numpy as np

from copdea_fem.measured import MeasuredDataError, ScanData
from copdea_fem.measured.scan import RESPONSES
from copdea_fem.vibrometer.close_pairs import close_partners
from copdea_fem.vibrometer.identified import IdentifiedMode

logger = logging.getLogger(__name__)

#: Defaults of the automatic pole choice (see the module notes).
DEFAULTS = {"max_order": 120, "components": 24, "frequency_tolerance": 0.01,
            "damping_tolerance": 0.05, "max_damping": 0.2, "min_stable_orders": None,
            "resolve_pairs": False}

#: A mode's least modal phase collinearity (module notes): below it, its residues are not
#: a shape (0.5: phases spread over half the circle; a normal mode's is 1).
MPC_MIN = 0.5

#: Channels from which on half of them are kept out of the principal response functions to
#: measure the noise (:func:`principal_count`): fewer channels span the modes' shapes alone.
MIN_NOISE_CHANNELS = 8

#: Fewest LSCF orders (2, 4, ..., 2 MIN_ORDERS) a record must allow; a mode is then stable
#: over at least MIN_STABLE_ORDERS of them - half: a majority, not chance.
MIN_ORDERS, MIN_STABLE_ORDERS = 10, 5

#: The power k of (i w)^k of each FRF form (module notes).
FRF_POWERS = {"receptance": 0, "mobility": 1, "accelerance": 2}

#: The options of :func:`identify_scan`.
OPTIONS = ("f_min", "f_max", *DEFAULTS)

class IdentificationFailed(RuntimeError):
    """The fit itself failed (a singular system): not bad input, the data defeat it."""


#: Pole status in the stabilisation diagram.
NEW, FREQUENCY_STABLE, STABLE = 0, 1, 2


@dataclass(frozen=True)
class StabilisationDiagram:
    """The poles of every model order and what the choice made of them.

    Attributes
    ----------
    orders : (K,) int array
        Polynomial orders 2, 4, ..., max_order.
    frequencies, dampings : list of (n_k,) float arrays
        Each order's physical poles: damped frequency [Hz], damping ratio [-].
    status : list of (n_k,) int arrays
        NEW, FREQUENCY_STABLE (frequency only) or STABLE (frequency and damping).
    chosen : (N, 2) float array
        The chosen modes' frequency [Hz] and damping ratio [-].
    band : (float, float)
        The fitted band [Hz].
    mean_magnitude : (F,) float array
        Mean |H| over the channels on ``band_frequencies`` (the diagram's background).
    band_frequencies : (F,) float array
    peaks : (n,) float array
        The peaks of the summed |H| in the band [Hz] (:mod:`peak_check`).
    unexplained_peaks : (m,) float array
        Those with no chosen mode near them [Hz]: modes the identification missed.
    """

    orders: np.ndarray
    frequencies: list
    dampings: list
    status: list
    chosen: np.ndarray
    band: tuple
    mean_magnitude: np.ndarray
    band_frequencies: np.ndarray
    peaks: np.ndarray = field(default_factory=lambda: np.zeros(0))
    unexplained_peaks: np.ndarray = field(default_factory=lambda: np.zeros(0))


@dataclass(frozen=True)
class Identification:
    """The modes of one scan and the stabilisation diagram they were chosen from."""

    modes: tuple
    diagram: StabilisationDiagram


def modal_phase_collinearity(shape: np.ndarray) -> float:
    """MPC of a complex shape in [0, 1] (Pappa et al. 1993; see the module notes)."""
    shape = np.asarray(shape, complex).ravel()
    real, imag = shape.real, shape.imag
    matrix = np.array([[real @ real, real @ imag], [real @ imag, imag @ imag]])
    low, high = np.linalg.eigvalsh(matrix)
    total = high + low
    return float(((high - low) / total) ** 2) if total > 0 else 0.0


def _check(name, value, low, high, integer=False):
    ok = (isinstance(value, numbers.Real) and not isinstance(value, bool)
          and math.isfinite(value) and low <= value <= high
          and (not integer or float(value).is_integer()))
    if not ok:
        raise MeasuredDataError(f"identify {name} = {value!r} is not allowed; allowed: "
                                f"{'an integer' if integer else 'a number'} in "
                                f"[{low:g}, {high:g}]")


def identify(scan: ScanData, *, f_min=None, f_max=None, **options) -> tuple[IdentifiedMode, ...]:
    """The modes of a scan (:func:`identify_scan`'s, without the diagram)."""
    return identify_scan(scan, f_min=f_min, f_max=f_max, **options).modes


def identify_scan(scan: ScanData, *, f_min=None, f_max=None, max_order=None,
                  components=None, frequency_tolerance=None, damping_tolerance=None,
                  max_damping=None, min_stable_orders=None,
                  resolve_pairs=None) -> Identification:
    """Identify a scan's modes automatically (LSCF poles, LSFD residues; module notes).

    Parameters
    ----------
    scan : ScanData
        FRFs (``quantity == "frf"``) on a uniform frequency axis.
    f_min, f_max : float, optional
        The band [Hz]; default: the scan's axis above 0 Hz.
    max_order : int, optional
        Highest even polynomial order of LSCF (default 120: up to 60 modes in the band;
        twice the number of modes or more is the usual over-modelling: 24 modes with
        two split pairs in 120-980 Hz at 60 dB noise were all found at 120, not at 80).
    components : int, optional
        Principal response functions fed to LSCF (default 24, at most the channels).
    frequency_tolerance, damping_tolerance : float, optional
        Relative change of frequency (default 1 %) and damping (5 %) between orders below
        which a pole is stable.
    max_damping : float, optional
        Poles more damped than this (default 0.2) are not physical modes.
    min_stable_orders : int, optional
        Orders over which a track must stay stable (default: a fifth of the orders, at
        least 5).
    resolve_pairs : bool, optional
        Look again for the modes the principal response functions leave out (the residual's
        shapes) and split a pole whose half-power band holds two shapes
        (:mod:`copdea_fem.vibrometer.close_pairs`); default False.

    Returns
    -------
    Identification
        ``modes`` sorted by frequency (``test_mode`` 1, 2, ...), and the diagram.
    """
    from copdea_fem.progress import single_threaded_blas

    options = _options(scan, f_min, f_max, max_order, components, frequency_tolerance,
                       damping_tolerance, max_damping, min_stable_orders, resolve_pairs)
    # BLAS on one thread: the matrices are small (order 120, 252 channels), and BLAS threads
    # fighting for a shared machine's cores made the 84 x 3 x 800 benchmark 15 times slower
    with single_threaded_blas():
        return _identify(scan, options)


def _identify(scan: ScanData, options: dict) -> Identification:
    from sdypy.EMA import Model
    from sdypy.EMA.EMA import LSFD

    started = time.perf_counter()
    f_low, f_high = options["band"]
    frequencies = np.asarray(scan.frequencies, float)
    in_band = (frequencies >= f_low) & (frequencies <= f_high)
    band_frequencies = frequencies[in_band]
    values = np.asarray(scan.values, complex)
    scale = float(np.abs(values[:, in_band]).max()) or 1.0
    values = values / scale
    # principal response functions: LSCF sees the space the channels span
    # (the eigenvectors of the channels' Gram matrix: the left singular vectors, at a
    # fraction of an SVD's cost for 252 channels x 800 lines)
    power, left = np.linalg.eigh(values[:, in_band] @ values[:, in_band].conj().T)
    power, left = power[::-1], left[:, ::-1]
    keep = principal_count(options["components"], int(np.sum(power > 1e-18 * power[0])),
                           scan.n_channels)
    if keep == 0 or not power[0] > 0:
        raise MeasuredDataError(f"scan file {scan.path}: every FRF is zero in "
                                f"{f_low:g}-{f_high:g} Hz; allowed: a measured response")
    principal = left[:, :keep].conj().T @ values[:, frequencies <= f_high]
    frf_form = RESPONSES.get(scan.response, "mobility")
    # LSCF on every line from the first above 0 Hz up to f_high; f_low only bounds the poles
    # kept (a fit that leaves out the lines below f_low, sdypy's ``lower``, turns poles
    # unstable at the higher orders: a 200-500 Hz band kept 1 of 3 modes)
    # LSCF's highest order is bounded by the lines it fits (its normal equations hold the
    # correlations of lags -n..n of a spectrum of F lines: n <= F - 2)
    lines = int(np.sum(frequencies <= f_high))
    half_order = min(options["max_order"] // 2, (lines - 2) // 2)
    if half_order < options["max_order"] // 2:
        logger.info("LSCF order limited to %d by the %d lines", 2 * half_order, lines)
        options = {**options, "min_stable_orders": min(options["min_stable_orders"],
                                                        max(MIN_STABLE_ORDERS,
                                                            round(0.2 * half_order)))}
    model = Model(frf=principal, freq=frequencies[frequencies <= f_high],
                  lower=float(frequencies[frequencies > 0][0]), upper=f_high,
                  pol_order_high=half_order, frf_form=frf_form)
    try:
        model.get_poles(method="lscf", show_progress=False)
    except (ValueError, IndexError, np.linalg.LinAlgError) as error:
        raise IdentificationFailed(f"scan file {scan.path}: LSCF failed ({error}); try "
                                   "another band or max_order") from None
    logger.info("LSCF: %d orders on %d principal functions of %d channels (%.1f s)",
                len(model.all_poles), keep, scan.n_channels, time.perf_counter() - started)
    diagram_poles = _physical_poles(model.all_poles, options)
    chosen, status = choose_poles(diagram_poles, options)
    # the noise per complex value, measured where as many channels lie outside the
    # principal functions as in them (:func:`principal_count`)
    # (with resolve_pairs, from the median eigenvalue: :func:`noise_variance`; else the
    # power outside the principal functions, noise only while the modes' shapes span fewer
    # than ``keep`` directions - 34 channels of the example scan hold more than half
    # of them in shapes, where the median is a shape's)
    noise = None
    if scan.n_channels - keep >= keep:
        noise = (noise_variance(power, band_frequencies.size) if options["resolve_pairs"]
                 else float(np.sum(power[keep:])) / (band_frequencies.size
                                                     * (scan.n_channels - keep)))
    principal_band = principal[:, frequencies[frequencies <= f_high] >= f_low].T
    chosen, tails = _refined(chosen, principal_band, band_frequencies, noise, frf_form,
                             options)
    resolve = noise is not None and options["resolve_pairs"]
    if resolve:
        # a second look: the shapes the principal functions left out (weak members of
        # split pairs among strong modes), where the residual still holds them; the
        # band-edge poles model the out-of-band tails (module notes, steps 4 and 5)
        extra = _residual_directions(np.concatenate([chosen, tails]), values[:, in_band],
                                     band_frequencies, left[:, :keep], noise, frf_form,
                                     options)
        if extra.shape[1]:
            logger.info("%d response functions of the residual's shapes added to the %d "
                        "principal ones", extra.shape[1], keep)
            data = np.hstack([principal_band, values[:, in_band].T @ extra.conj()])
            chosen, tails = _refined(chosen, data, band_frequencies, noise, frf_form,
                                     options, tails)
    if resolve and chosen.size:
        both = _split_close(np.concatenate([chosen, tails]), values[:, in_band],
                            band_frequencies, noise, frf_form, options)
        inside = _inside_band(both, band_frequencies, options["band"])
        chosen, tails = both[inside], both[~inside]
    if tails.size:
        logger.info("%d band-edge poles kept in the residues' fit (out-of-band tails, no "
                    "modes): %s", tails.size, ", ".join(f"{abs(p.imag) / (2 * math.pi):.1f} "
                                                        "Hz" for p in tails))
    constants = np.zeros((scan.n_channels, 0), complex)
    while chosen.size:
        try:
            constants, *_ = LSFD(np.concatenate([chosen, tails]), values[:, in_band],
                                 band_frequencies, True, True, 0, band_frequencies.size,
                                 frf_form)
        except (ValueError, np.linalg.LinAlgError) as error:
            raise IdentificationFailed(f"scan file {scan.path}: LSFD failed ({error})") \
                from None
        constants = constants[:, :chosen.size] * scale
        # a mode whose residues scatter in phase is not determined by the data (two poles
        # sharing one resonance): the least collinear one dropped, the rest refitted
        collinearity = [modal_phase_collinearity(constants[:, r]) for r in range(chosen.size)]
        if options["resolve_pairs"]:
            # the members of a pair split by the shapes' test (close_pairs) share their
            # resonance by construction: their MPC measures how ill-conditioned the split
            # of their residues is, not a complex mode; their split was tested already
            collinearity = [1.0 if paired else value for value, paired in
                            zip(collinearity, close_partners(chosen))]
        worst = int(np.argmin(collinearity))
        if collinearity[worst] >= MPC_MIN:
            break
        logger.info("mode at %.1f Hz dropped: MPC %.2f", chosen[worst].imag / (2 * math.pi),
                    collinearity[worst])
        chosen = np.delete(chosen, worst)
        constants = np.zeros((scan.n_channels, 0), complex)
    modes = []
    for index in np.argsort(np.abs(chosen.imag)):
        pole = chosen[index]
        shape = constants[:, index]
        modes.append(IdentifiedMode(
            test_mode=len(modes) + 1, freq_hz=float(abs(pole.imag) / (2 * math.pi)),
            damping_ratio=float(-pole.real / abs(pole)), shape=shape,
            mpc=modal_phase_collinearity(shape)))
    orders = np.arange(2, 2 * len(model.all_poles) + 1, 2)
    diagram = StabilisationDiagram(
        orders=orders, frequencies=[p[0] for p in diagram_poles],
        dampings=[p[1] for p in diagram_poles], status=status,
        chosen=np.array([[m.freq_hz, m.damping_ratio] for m in modes]).reshape(-1, 2),
        band=(f_low, f_high), mean_magnitude=np.mean(np.abs(values[:, in_band]), axis=0)
        * scale, band_frequencies=band_frequencies,
        **_peak_check(scan, modes, band_frequencies, values[:, in_band]))
    logger.info("identified %d modes in %.1f s", len(modes), time.perf_counter() - started)
    _warn_unresolved(scan, modes, float(frequencies[1] - frequencies[0]))
    return Identification(tuple(modes), diagram)


def principal_count(components: int, rank: int, n_channels: int) -> int:
    """How many principal response functions LSCF and the refinement are fed.

    At most ``components`` and the FRF matrix's rank; and, with
    :data:`MIN_NOISE_CHANNELS` channels or more, at most half the channels, so that as many
    channels lie outside the principal functions as in them: their power is the noise the
    refinement weighs a missed mode against (:mod:`pole_refinement`).  Without that
    estimate no missed mode is added, and with few channels the diagram alone misses most:
    the example scan's 34 out-of-plane records, 24 functions of 34 channels, gave 2 of its
    ~17 modes in 150-850 Hz; 17 functions give all of them.  Fewer channels (a beam's
    three) leave no room for noise beside the modes: all are kept and nothing is added.
    """
    keep = min(components, rank)
    if n_channels >= MIN_NOISE_CHANNELS:
        keep = min(keep, n_channels // 2)
    return max(keep, 1) if rank else 0


def marchenko_pastur_median(ratio: float) -> float:
    """Median of the Marchenko-Pastur law of aspect ratio ``ratio`` in (0, 1] [-]: the
    median eigenvalue of ``N N^H / n`` for an (r x n) matrix ``N`` of independent unit-variance
    entries, r / n = ratio, as both grow (Marchenko & Pastur, Math. USSR Sb. 1, 1967; density
    ``sqrt((b - x)(x - a)) / (2 pi ratio x)`` on ``[a, b] = [(1 -+ sqrt ratio)^2]``)."""
    from scipy import integrate, optimize

    low, high = (1 - math.sqrt(ratio)) ** 2, (1 + math.sqrt(ratio)) ** 2

    def density(x):
        return math.sqrt(max((high - x) * (x - low), 0.0)) / (2 * math.pi * ratio * x)

    def below(x):
        return integrate.quad(density, low, x, limit=200)[0] - 0.5

    return float(optimize.brentq(below, low, high, xtol=1e-10))


def noise_variance(channel_power, n_lines: int) -> float:
    """The noise variance per complex FRF value [data unit^2] from the eigenvalues
    ``channel_power`` of the (channels x lines) FRF matrix's Gram matrix ``H H^H``.

    Noise alone gives eigenvalues ``sigma^2 n`` times the Marchenko-Pastur law (n the longer
    side, r the shorter, ratio r / n); the modes add a few large ones.  The median of the
    r nonzero eigenvalues is a noise eigenvalue while the modes' shapes span fewer than half
    of them (the median-based estimate of Gavish & Donoho, IEEE Trans. Inf. Theory 60, 2014):
    ``sigma^2 = median / (n mu(r / n))``, ``mu`` :func:`marchenko_pastur_median`.  The sum
    outside the first ``q`` eigenvalues over ``(C - q) F`` counts the modes past the q-th as
    noise: the FE-made G1 scan (252 channels, 800 lines, some 40 modes with three
    components) has some 36 shapes above the noise, and that sum over-estimated sigma^2 by 11
    times at q = 24 (the median: within 3 %), hiding the weak member of each split pair.
    """
    power = np.sort(np.asarray(channel_power, float))[::-1]
    rank = min(power.size, int(n_lines))
    longer = max(power.size, int(n_lines))
    median = float(np.median(np.maximum(power[:rank], 0.0)))
    return median / (longer * marchenko_pastur_median(rank / longer))


def _peak_check(scan, modes, band_frequencies, band_values) -> dict:
    """The summed |H|'s peaks and those no mode explains (:mod:`peak_check`), with a
    warning naming them: the modes there could not be found."""
    from copdea_fem.vibrometer.peak_check import summed_peaks, unexplained_peaks

    peaks = summed_peaks(band_frequencies, band_values)
    missed = unexplained_peaks(peaks, [m.freq_hz for m in modes],
                               float(band_frequencies[1] - band_frequencies[0]))
    if missed.size:
        logger.warning(
            "scan file %s: %d modes identified, but the summed |H| of its %d channels has %d "
            "peaks, %d of them with no mode near: %s Hz; the modes there could not be "
            "found (too few channels, lines or modes too close?): check the stabilisation "
            "diagram", scan.path, len(modes), scan.n_channels, peaks.size, missed.size,
            ", ".join(f"{f:.1f}" for f in missed))
    return {"peaks": peaks, "unexplained_peaks": missed}


def _warn_unresolved(scan, modes, line_spacing: float) -> None:
    """A warning naming the modes whose half-power width ``2 zeta f`` [Hz] is narrower than
    the line spacing ``df`` [Hz]: the lines do not resolve their damping (a resonance falls
    between two lines), so the damping ratio is a guess of the fit."""
    narrow = [m for m in modes if 2 * m.damping_ratio * m.freq_hz < line_spacing]
    if narrow:
        logger.warning(
            "scan file %s: the damping of %d modes is narrower than the line spacing "
            "(2 zeta f < df = %.4g Hz), not resolved by the lines: %s", scan.path,
            len(narrow), line_spacing, ", ".join(f"{m.freq_hz:.1f} Hz (zeta {m.damping_ratio:.2g})"
                                                 for m in narrow))


def condition_band(condition) -> tuple[float, float]:
    """A measured condition's ``band:`` [Hz] within its scan's lines.

    A band reaching past the scan's first line above 0 Hz or its last line is clipped to
    them, with a warning naming the condition's ``band:``; a band that misses the lines
    altogether is refused naming it.

    Parameters
    ----------
    condition : copdea_fem.measured.Condition
        With ``scan`` and ``band`` [Hz].

    Returns
    -------
    (float, float)
        f_min, f_max [Hz].
    """
    from copdea_fem.measured.errors import refusal

    frequencies = np.asarray(condition.scan.frequencies, float)
    first, last = float(frequencies[frequencies > 0][0]), float(frequencies[-1])
    low, high = max(condition.band[0], first), min(condition.band[1], last)
    if not low < high:
        raise refusal(f"condition {condition.name!r} band", f"[{condition.band[0]:g} Hz, "
                      f"{condition.band[1]:g} Hz]", f"a band overlapping the scan's lines "
                      f"{first:g}..{last:g} Hz ({condition.scan.path})")
    if (low, high) != tuple(condition.band):
        logger.warning("condition %r: band: [%g Hz, %g Hz] reaches past the scan's lines "
                       "%g..%g Hz (%s): identified in [%g Hz, %g Hz]", condition.name,
                       condition.band[0], condition.band[1], first, last, condition.scan.path,
                       low, high)
    return low, high


def _residual_directions(chosen, values, band_frequencies, principal_directions, noise,
                         frf_form, options) -> np.ndarray:
    """(C, q2) orthonormal channel directions of the shapes the model of ``chosen`` leaves
    in ``values`` (C, F): the residual's left singular vectors above :data:`close_pairs.
    EDGE_MARGIN` times the noise's largest singular value, made orthogonal to the principal
    directions (C, q) already fitted; at most ``components`` of them."""
    from copdea_fem.vibrometer.close_pairs import EDGE_MARGIN
    from copdea_fem.vibrometer.pole_refinement import model_residual

    f_high = options["band"][1]
    omega = band_frequencies / f_high
    residual = model_residual(omega, values.T, chosen / (2 * math.pi * f_high),
                              FRF_POWERS[frf_form]).T
    residual = residual - principal_directions @ (principal_directions.conj().T @ residual)
    left, singular, _ = np.linalg.svd(residual, full_matrices=False)
    channels, lines = values.shape
    edge = math.sqrt(noise) * (math.sqrt(channels) + math.sqrt(lines))
    count = min(int(np.sum(singular > EDGE_MARGIN * edge)), options["components"])
    return left[:, :count]


def _split_close(chosen, values, band_frequencies, noise, frf_form, options):
    """The chosen poles with those whose half-power band holds two shapes split in two
    (:mod:`close_pairs`)."""
    from copdea_fem.vibrometer.close_pairs import split_close_poles

    f_low, f_high = options["band"]
    scale = 2 * math.pi * f_high
    poles, split = split_close_poles(band_frequencies / f_high, values, chosen / scale,
                                     FRF_POWERS[frf_form], (f_low / f_high, 1.0),
                                     options["max_damping"], noise, hz_per_unit=f_high)
    if split:
        logger.info("%d poles split by their shapes (close pairs)", split)
    return poles * scale


def _refined(chosen, data, band_frequencies, noise, frf_form, options, tails=None):
    """The chosen poles refined and the missed ones added (:mod:`pole_refinement`);
    ``noise`` the noise variance per complex value (None: not measured, nothing added).

    Returns ``(poles, tails)``: the poles inside the band, and those the fit pressed
    against a band edge (an out-of-band mode's tail, module notes step 5), which are no
    modes.  With ``tails`` (the previous call's) they start the fit with the chosen ones."""
    from copdea_fem.vibrometer.pole_refinement import LEAST_DAMPING, add_missing

    f_low, f_high = options["band"]
    scale = 2 * math.pi * f_high
    start = chosen if tails is None else np.concatenate([chosen, tails])
    poles, added = add_missing(band_frequencies / f_high, data, start / scale,
                               FRF_POWERS[frf_form],
                               (f_low / f_high, 1.0), options["max_damping"], noise,
                               hz_per_unit=f_high)
    poles = poles * scale
    zeta = -poles.real / np.abs(poles)
    frequency = poles.imag / (2 * math.pi)
    # a pole pressed against the fit's least damping is a spike between two lines fitted to
    # model error, not a resonance the lines resolve
    resolved = zeta > 2 * LEAST_DAMPING
    inside = _inside_band(poles, band_frequencies, options["band"])
    logger.info("poles refined, %d added, %d on a band edge's line (not modes)%s", added,
                int(np.sum(~inside)), "".join(f" ({f:.1f} Hz)" for f in frequency[~inside]
                                              if f_low <= f <= f_high))
    if np.any(~resolved):
        logger.info("%d poles at the fit's least damping dropped: %s", int(np.sum(~resolved)),
                    ", ".join(f"{f:.1f} Hz" for f in frequency[~resolved]))
    physical = resolved & (zeta <= options["max_damping"])
    return poles[physical & inside], poles[physical & ~inside]


def _inside_band(poles, band_frequencies, band) -> np.ndarray:
    """Whether each pole [rad/s] is a mode of the band: not pressed by the fit against a
    band edge nor on the band's first or last line, where no line beyond it resolves it
    (an out-of-band mode's tail)."""
    f_low, f_high = band
    frequency = np.asarray(poles).imag / (2 * math.pi)
    half_line = 0.5 * float(band_frequencies[1] - band_frequencies[0])
    return ((frequency > max(f_low * (1 + 1e-6), band_frequencies[0] + half_line))
            & (frequency < min(f_high * (1 - 1e-6), band_frequencies[-1] - half_line)))


def _options(scan, f_min, f_max, max_order, components, frequency_tolerance,
             damping_tolerance, max_damping, min_stable_orders, resolve_pairs=None) -> dict:
    if scan.quantity != "frf":
        raise MeasuredDataError(f"scan file {scan.path}: quantity = {scan.quantity!r} is not "
                                "allowed for identification; allowed: 'frf' (UFF function "
                                "type 4: a spectrum has no reference to fit residues to)")
    frequencies = np.asarray(scan.frequencies, float)
    steps = np.diff(frequencies)
    if frequencies.size < 8 or np.any(steps <= 0) or not np.allclose(steps, steps[0],
                                                                      rtol=1e-6):
        raise MeasuredDataError(f"scan file {scan.path}: frequency axis of {frequencies.size} "
                                "lines is not allowed; allowed: at least 8 evenly spaced lines")
    positive = frequencies[frequencies > 0]
    low = float(positive[0]) if f_min is None else f_min
    high = float(frequencies[-1]) if f_max is None else f_max
    _check("f_min", low, 0.0, float(frequencies[-1]))
    _check("f_max", high, 0.0, float(frequencies[-1]))
    count = int(np.sum((frequencies >= low) & (frequencies <= high)))
    if low <= 0 or count < 8:
        raise MeasuredDataError(f"identify band = [{low:g}, {high:g}] Hz is not allowed; "
                                f"allowed: 0 < f_min < f_max within the scan's "
                                f"{frequencies[0]:g}..{frequencies[-1]:g} Hz holding >= 8 lines")
    options = check_options({"max_order": max_order, "components": components,
                             "frequency_tolerance": frequency_tolerance,
                             "damping_tolerance": damping_tolerance, "max_damping": max_damping,
                             "min_stable_orders": min_stable_orders,
                             "resolve_pairs": resolve_pairs})
    options["band"] = (low, high)
    # a short record leaves too few orders for a pole's stability to be evidence (15 lines:
    # 6 orders, stable over 2 of them, gave 5 modes, two where there is none): refused
    lines = int(np.sum((frequencies > 0) & (frequencies <= high)))
    if min(options["max_order"] // 2, (lines - 2) // 2) < MIN_ORDERS:
        raise MeasuredDataError(
            f"scan file {scan.path}: {lines} lines up to {high:g} Hz are not allowed for "
            f"identification (too short a record: LSCF's order is at most the lines - 2, and "
            f"the stabilisation diagram needs {MIN_ORDERS} orders); allowed: at least "
            f"{2 * MIN_ORDERS + 2} lines from the first above 0 Hz to f_max")
    return options


def check_scan(scan: ScanData, *, f_min=None, f_max=None, **options) -> None:
    """Refuse, before any work, a scan or band :func:`identify_scan` would refuse (its
    parameters): a :class:`MeasuredDataError` naming the file and what is allowed."""
    _options(scan, f_min, f_max, *(options.get(name) for name in DEFAULTS))


def check_options(values: dict) -> dict:
    """The options of the pole choice (:data:`DEFAULTS`'s keys; None: the default) checked
    and completed; :class:`MeasuredDataError` naming a bad one."""
    options = {**DEFAULTS, **{k: v for k, v in values.items() if v is not None}}
    _check("max_order", options["max_order"], 4, 400, integer=True)
    _check("components", options["components"], 1, 1000, integer=True)
    _check("frequency_tolerance", options["frequency_tolerance"], 1e-6, 0.2)
    _check("damping_tolerance", options["damping_tolerance"], 1e-6, 1.0)
    _check("max_damping", options["max_damping"], 1e-4, 1.0)
    n_orders = int(options["max_order"]) // 2
    if options["min_stable_orders"] is None:
        options["min_stable_orders"] = max(5, round(0.2 * n_orders))
    _check("min_stable_orders", options["min_stable_orders"], 2, n_orders, integer=True)
    if not isinstance(options["resolve_pairs"], bool):
        raise MeasuredDataError(f"identify resolve_pairs = {options['resolve_pairs']!r} is not "
                                "allowed; allowed: true or false")
    options["max_order"] = int(options["max_order"])
    options["components"] = int(options["components"])
    return options


def _physical_poles(all_poles, options) -> list:
    """Per order: (frequency [Hz], damping [-], pole) of the poles in the band, Im s > 0,
    0 < damping <= max_damping."""
    low, high = options["band"]
    out = []
    for poles in all_poles:
        poles = np.asarray(poles, complex)
        poles = poles[np.isfinite(poles) & (poles.imag > 0)]
        frequency = np.abs(poles.imag) / (2 * math.pi)
        damping = -poles.real / np.maximum(np.abs(poles), 1e-300)
        keep = ((frequency >= low) & (frequency <= high) & (damping > 0)
                & (damping <= options["max_damping"]))
        order = np.argsort(frequency[keep])
        out.append((frequency[keep][order], damping[keep][order], poles[keep][order]))
    return out


def choose_poles(diagram_poles, options) -> tuple[np.ndarray, list]:
    """The automatic choice (module notes, step 2).

    Parameters
    ----------
    diagram_poles : list of (frequency, damping, pole) arrays
        Per model order: the damped frequencies [Hz], damping ratios [-] and the poles
        [rad/s] of the physical poles, ascending in frequency.
    options : dict
        :func:`check_options`'s (``frequency_tolerance``, ``damping_tolerance``,
        ``min_stable_orders``).

    Returns
    -------
    chosen : (N,) complex array
        The chosen modes' poles [rad/s].
    status : list of (n_k,) int arrays
        Each pole's NEW, FREQUENCY_STABLE or STABLE.
    """
    tracks, status = _tracks(diagram_poles, options)
    return _choose(tracks, options), status


def _tracks(diagram_poles, options):
    """Chain poles over the orders by frequency (module notes); returns the tracks (lists of
    (order index, frequency, damping, pole, stable)) and every pole's status."""
    f_tol, d_tol = options["frequency_tolerance"], options["damping_tolerance"]
    tracks, active, status = [], [], []
    for k, (frequency, damping, poles) in enumerate(diagram_poles):
        state = np.full(frequency.size, NEW, int)
        pairs = []
        for t, track in enumerate(active):
            last_f, last_d = track[-1][1], track[-1][2]
            df = np.abs(frequency - last_f) / last_f
            for i in np.flatnonzero(df < f_tol):
                damping_ok = abs(damping[i] - last_d) / last_d < d_tol
                pairs.append((not damping_ok, df[i], t, i, damping_ok))
        used_tracks, used_poles = set(), set()
        for *_, t, i, damping_ok in sorted(pairs, key=lambda p: p[:2]):
            if t in used_tracks or i in used_poles:
                continue
            used_tracks.add(t)
            used_poles.add(i)
            state[i] = STABLE if damping_ok else FREQUENCY_STABLE
            active[t].append((k, frequency[i], damping[i], poles[i], damping_ok))
        for i in range(frequency.size):
            if i not in used_poles:
                track = [(k, frequency[i], damping[i], poles[i], False)]
                active.append(track)
                tracks.append(track)
        active = [track for track in active if track[-1][0] >= k - 1]
        status.append(state)
    return tracks, status


def _choose(tracks, options) -> np.ndarray:
    """The poles of the tracks stable over ``min_stable_orders`` orders (module notes)."""
    chosen = []
    stable_tracks = [[p for p in track if p[4]] for track in tracks]
    for track in sorted(stable_tracks, key=len, reverse=True):
        if len(track) < options["min_stable_orders"]:
            break
        upper = track[len(track) // 2:]
        frequency = float(np.median([p[1] for p in upper]))
        damping = float(np.median([p[2] for p in upper]))
        orders = {p[0] for p in track}
        duplicate = any(not (orders & other_orders)
                        and abs(frequency - other_f) < options["frequency_tolerance"] * other_f
                        for _, other_f, other_orders in chosen)
        if duplicate:
            continue
        omega = 2 * math.pi * frequency / math.sqrt(1 - damping ** 2)
        chosen.append((complex(-damping * omega, omega * math.sqrt(1 - damping ** 2)),
                       frequency, orders))
    return np.array([c[0] for c in chosen], complex)


__all__ = [
    "DEFAULTS",
    "MIN_NOISE_CHANNELS",
    "OPTIONS",
    "Identification",
    "StabilisationDiagram",
    "check_scan",
    "choose_poles",
    "condition_band",
    "identify",
    "identify_scan",
    "marchenko_pastur_median",
    "modal_phase_collinearity",
    "noise_variance",
    "principal_count",
]
