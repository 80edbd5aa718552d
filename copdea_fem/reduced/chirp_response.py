"""Reduced modal model in air (eq. 19) and its forced response to the chirp (Sects 4.2, 5.3).

Each kept mode j obeys (eq. 19, modes uncoupled as in Sect. 5.1)

    (m_j + m_ad,j) a_j'' + b_j a_j' + k_j a_j = f_j V~(t),   f_j = phi_j^T V_b dC/dq,

with m_j, k_j from the dry ring model (eq. 16), m_ad,j from the coupled
frequency, ``m_ad = k / w_c^2 - m`` (the undamped in-air frequency equals
w_c), and ``b_j = (b/m)_j m_j`` with the paper's damping-to-structural-mass
ratios.  Modal quantities here refer to shapes scaled to a largest nodal
displacement of 1 (so masses are in kg, stiffnesses in N/m); the ratios
m_ad/m and b/m do not depend on that choice.

Excitation and spectra (Sect. 4.2-4.3): the periodic chirp
``V~(t) = A sin(2 pi (f0 t + (f1 - f0) t^2 / (2 T)))`` sampled every dt over
one period T.  Its steady-state response is periodic with the same period,
so the FFT line k of any response is exactly H(w_k) times line k of the
input: spectra are computed line by line, with the vibrometer's
normalisation |FFT| / N (N samples per period, "FFT/N"), on the
lines k = 1 .. floor(f1 T) (0.8 s: 1.25 Hz spacing, 800 lines to 1 kHz).
The average spectrum is the mean of |v| over the scan points (a magnitude
average: phases differ across the membrane and a complex average would cancel
the (0,2) peak; the paper does not say which the vibrometer software uses, and
a magnitude average is its usual "average spectrum").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from copdea_fem.reduced.rings import Equilibrium, ReducedModelError
from copdea_fem.study.schema import QUARTER_POINTS  # noqa: F401  (Q1-Q3, Sect. 5.3)



# -- excitation (Sect. 4.2) -------------------------------------------------------------------
@dataclass(frozen=True)
class Chirp:
    """Periodic linear chirp of the vibrometer tests (Sect. 4.2).

    Attributes
    ----------
    amplitude : float
        V~ [V] (100 V).
    f_start, f_end : float
        Swept band [Hz] (0-1000 Hz).
    duration : float
        Period T = FFT window [s] (0.8 s).
    sample_time : float
        dt [s] (0.4 ms).
    """

    amplitude: float = 100.0
    f_start: float = 0.0
    f_end: float = 1000.0
    duration: float = 0.8
    sample_time: float = 0.4e-3

    @classmethod
    def from_study(cls, study) -> "Chirp":
        x = study.excitation
        return cls(amplitude=x.amplitude, f_start=x.f_start, f_end=x.f_end,
                   duration=x.duration, sample_time=x.sample_time)

    @property
    def sample_count(self) -> int:
        return int(round(self.duration / self.sample_time))

    @property
    def line_spacing(self) -> float:
        """1 / T [Hz]."""
        return 1.0 / self.duration

    @property
    def line_count(self) -> int:
        """Lines 1 .. floor(f_end T) (800 for the paper's chirp)."""
        return int(math.floor(self.f_end * self.duration + 1e-9))

    def signal(self) -> tuple[np.ndarray, np.ndarray]:
        """Sample times t [s] and voltage V~(t) [V] over one period."""
        t = np.arange(self.sample_count) * self.sample_time
        sweep_rate = (self.f_end - self.f_start) / self.duration
        phase = 2 * math.pi * (self.f_start * t + 0.5 * sweep_rate * t ** 2)
        return t, self.amplitude * np.sin(phase)

    def lines(self) -> tuple[np.ndarray, np.ndarray]:
        """Line frequencies [Hz] and the input's complex line values |FFT|/N scaling [V]."""
        _, voltage = self.signal()
        spectrum = vibrometer_spectrum(voltage)
        k = np.arange(1, self.line_count + 1)
        return k * self.line_spacing, spectrum[k]


def vibrometer_spectrum(samples) -> np.ndarray:
    """FFT / N of a real signal sampled over one period, lines 0 .. N/2 (Sect. 4.3).

    Same unit as the samples (V for the input, m/s for a velocity).
    """
    samples = np.asarray(samples, dtype=float)
    return np.fft.rfft(samples) / samples.size


# -- observation points ---------------------------------------------------------------------------
def scan_fractions(count: int) -> np.ndarray:
    """Centres of ``count`` equal bands across the width, from the inner edge [-]."""
    return (np.arange(count) + 0.5) / count


def observation_matrix(equilibrium: Equilibrium, fractions) -> tuple[np.ndarray, np.ndarray]:
    """Interpolation from node values to points at projected radii r_i + f (r_o - r_i).

    The vibrometer looks along the axis, so a point is placed by its projected
    radius on the equilibrium profile; displacements are interpolated linearly
    in R inside its ring, as eq. (12) assumes.

    Returns
    -------
    matrix : ndarray, shape (points, n + 1)
    radii : ndarray
        The points' projected radii [m].
    """
    r = equilibrium.radii
    if np.any(np.diff(r) >= 0):
        raise ReducedModelError("the equilibrium profile folds back (node radii not decreasing "
                                "from r_o to r_i); allowed: a profile that the axis sees once")
    inner, outer = r[-1], r[0]
    radii = inner + np.asarray(fractions, float) * (outer - inner)
    ring = np.clip(np.searchsorted(-r, -radii), 1, len(r) - 1)  # r[ring] <= radius <= r[ring-1]
    t = (r[ring - 1] - radii) / (r[ring - 1] - r[ring])
    matrix = np.zeros((len(radii), len(r)))
    matrix[np.arange(len(radii)), ring - 1] = 1 - t
    matrix[np.arange(len(radii)), ring] = t
    return matrix, radii


# -- eq. (19) ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SpectrumResult:
    """Velocity spectra, |FFT|/N per line [m/s].

    Attributes
    ----------
    frequency_hz : ndarray, shape (lines,)
    average_axial, average_radial : ndarray, shape (lines,)
        Mean of |v_z|, |v_r| over the scan points.
    point_axial, point_radial : ndarray, shape (lines, 3)
        |v_z|, |v_r| at Q1, Q2, Q3.
    """

    frequency_hz: np.ndarray
    average_axial: np.ndarray
    average_radial: np.ndarray
    point_axial: np.ndarray
    point_radial: np.ndarray


@dataclass(frozen=True)
class ReducedModel:
    """The truncated modal model in air, eq. (19), with its observation points.

    Attributes
    ----------
    labels : tuple of str
    modal_mass : ndarray
        m_j [kg] (structural, eq. 16; shapes scaled to unit largest displacement).
    modal_stiffness : ndarray
        k_j [N/m] (eq. 16).
    added_mass : ndarray
        m_ad,j [kg] (eq. 19).
    damping : ndarray
        b_j [kg/s] (eq. 19).
    modal_force_per_volt : ndarray
        f_j = phi_j^T V_b dC/dq [N/V] (eqs 14, 18).
    scan_axial, scan_radial : ndarray, shape (scan points, modes)
        u_z, u_r of each mode at the scan points [-] (per unit modal coordinate).
    point_axial, point_radial : ndarray, shape (3, modes)
        The same at Q1-Q3.
    scan_radii, point_radii : ndarray
        Projected radii of the points [m].
    added_mass_source : tuple of str
        Where each added mass came from (for reports).
    elastic_stiffness : ndarray or None
        k_el,j: the part of k_j from the membrane's elastic energy (eq. 13,
        without the spring and the electrostatic term) [N/m]; with
        ``viscoelastic_strength`` > 0 it is stiffened with frequency.
    viscoelastic_strength, viscoelastic_time : float
        Delta [-] and tau [s] of a standard linear solid (quasi-linear
        visco-elasticity: the elastic force increments scale with the storage
        factor g(w) = 1 + Delta (w tau)^2 / (1 + (w tau)^2)), so
        k_j(w) = k_j + (g(w) - 1) k_el,j; Delta = 0: elastic (the default).
        The loss part is left to the calibrated damping b_j (Sect. 5.3).
    """

    labels: tuple
    modal_mass: np.ndarray
    modal_stiffness: np.ndarray
    added_mass: np.ndarray
    damping: np.ndarray
    modal_force_per_volt: np.ndarray
    scan_axial: np.ndarray
    scan_radial: np.ndarray
    point_axial: np.ndarray
    point_radial: np.ndarray
    scan_radii: np.ndarray
    point_radii: np.ndarray
    added_mass_source: tuple = field(default=())
    elastic_stiffness: np.ndarray | None = None
    viscoelastic_strength: float = 0.0
    viscoelastic_time: float = 0.0

    @property
    def dry_frequency_hz(self) -> np.ndarray:
        """sqrt(k/m) / 2 pi [Hz] (eq. 15, static modulus)."""
        return np.sqrt(self.modal_stiffness / self.modal_mass) / (2 * math.pi)

    def stiffness_at(self, angular_frequency) -> np.ndarray:
        """k_j(w) = k_j + (g(w) - 1) k_el,j [N/m]: shape (..., modes) for w [rad/s] (...)."""
        omega = np.asarray(angular_frequency, float)[..., None]
        if self.viscoelastic_strength == 0 or self.elastic_stiffness is None:
            return np.broadcast_to(self.modal_stiffness, omega.shape[:-1] + (len(self.labels),))
        x2 = (omega * self.viscoelastic_time) ** 2
        return self.modal_stiffness + self.viscoelastic_strength * x2 / (1 + x2) * \
            self.elastic_stiffness

    @property
    def frequency_hz(self) -> np.ndarray:
        """Undamped in-air frequencies [Hz]: sqrt(k / (m + m_ad)) / 2 pi (eq. 19); with
        visco-elasticity the root of k_j(w) = w^2 (m_j + m_ad,j), bracketed by the relaxed
        (k_j) and the glassy (k_j + Delta k_el,j) stiffness."""
        mass = self.modal_mass + self.added_mass
        omega = np.sqrt(self.modal_stiffness / mass)
        if self.viscoelastic_strength != 0 and self.elastic_stiffness is not None:
            glassy = self.modal_stiffness + self.viscoelastic_strength * self.elastic_stiffness
            for j in range(omega.size):
                low, high = sorted((self.modal_stiffness[j], glassy[j]))
                if high - low <= 1e-15 * high:
                    continue
                residual = lambda w: self.stiffness_at(w)[j] - w ** 2 * mass[j]  # noqa: E731
                import scipy.optimize  # at use: 0.15 s of import the modal commands skip
                omega[j] = scipy.optimize.brentq(residual, math.sqrt(low / mass[j]),
                                                 math.sqrt(high / mass[j]), xtol=1e-13,
                                                 rtol=1e-14)
        return omega / (2 * math.pi)

    @property
    def damping_per_mass(self) -> np.ndarray:
        """b/m [1/s] (Sect. 5.3)."""
        return self.damping / self.modal_mass

    def with_damping_per_mass(self, values) -> "ReducedModel":
        """A copy with b_j = values_j m_j (values in 1/s)."""
        return replace(self, damping=np.asarray(values, float) * self.modal_mass)

    def modal_response(self, frequency_hz, voltage_lines) -> np.ndarray:
        """Modal coordinates a_j(w) for input lines V~(w) [m], shape (lines, modes) (eq. 19)."""
        omega = 2 * math.pi * np.asarray(frequency_hz, float)[:, None]
        denominator = (self.stiffness_at(omega[:, 0]) - omega ** 2 * (self.modal_mass
                                                                      + self.added_mass)
                       + 1j * omega * self.damping)
        return (self.modal_force_per_volt * np.asarray(voltage_lines)[:, None]) / denominator

    def spectra(self, frequency_hz, voltage_lines) -> SpectrumResult:
        """Velocity spectra for the given input lines (|FFT|/N) [m/s]."""
        frequency_hz = np.asarray(frequency_hz, float)
        velocity = (2j * math.pi * frequency_hz)[:, None] * self.modal_response(frequency_hz,
                                                                                voltage_lines)
        return SpectrumResult(
            frequency_hz=frequency_hz,
            average_axial=np.abs(velocity @ self.scan_axial.T).mean(axis=1),
            average_radial=np.abs(velocity @ self.scan_radial.T).mean(axis=1),
            point_axial=np.abs(velocity @ self.point_axial.T),
            point_radial=np.abs(velocity @ self.point_radial.T))


def assemble_reduced_model(model, linearisation, modes, added_mass_ratio, damping_per_mass,
                           scan_radii: int, sources=None) -> ReducedModel:
    """Eq. (19) from dry ring-model modes.

    Parameters
    ----------
    model : RingModel
    linearisation : Linearisation
    modes : sequence of Mode
        The truncated set (eq. 18).
    added_mass_ratio : sequence of float
        m_ad / m for each mode [-].
    damping_per_mass : sequence of float
        b / m for each mode [1/s].
    scan_radii : int
        Radial positions of the scan grid.
    """
    scale = np.array([mode.largest_displacement for mode in modes])
    omega = np.array([mode.angular_frequency for mode in modes])
    modal_mass = 1.0 / scale ** 2                      # phi^T M phi = 1 for the unscaled shapes
    shapes = np.stack([mode.shape for mode in modes], axis=1) / scale
    radial = np.stack([mode.radial for mode in modes], axis=1) / scale
    axial = np.stack([mode.axial for mode in modes], axis=1) / scale
    eq = linearisation.equilibrium
    scan_matrix, scan_r = observation_matrix(eq, scan_fractions(scan_radii))
    point_matrix, point_r = observation_matrix(eq, QUARTER_POINTS)
    ratio = np.asarray(added_mass_ratio, float)
    return ReducedModel(
        labels=tuple(mode.label for mode in modes), modal_mass=modal_mass,
        modal_stiffness=omega ** 2 * modal_mass, added_mass=ratio * modal_mass,
        damping=np.asarray(damping_per_mass, float) * modal_mass,
        modal_force_per_volt=shapes.T @ linearisation.forcing_per_volt,
        scan_axial=scan_matrix @ axial, scan_radial=scan_matrix @ radial,
        point_axial=point_matrix @ axial, point_radial=point_matrix @ radial,
        scan_radii=scan_r, point_radii=point_r,
        added_mass_source=tuple(sources or ("",) * len(modes)))


def added_mass_ratio_from_frequency(dry_frequency_hz: float, coupled_frequency_hz: float,
                                    label: str = "mode") -> float:
    """m_ad / m = (f_dry / f_coupled)^2 - 1 (eq. 19: k / (m + m_ad) = w_c^2) [-].

    Raises
    ------
    ReducedModelError
        f_coupled > f_dry: air loading only lowers frequencies, so the
        coupled frequency does not belong to this operating point (or the
        rings are too few to be stiffer than the FE model).
    """
    if not coupled_frequency_hz > 0:
        raise ReducedModelError(f"coupled frequency of {label} = {coupled_frequency_hz!r} Hz is "
                                "not allowed; allowed: > 0 Hz")
    if coupled_frequency_hz > dry_frequency_hz:
        raise ReducedModelError(
            f"coupled frequency of {label} = {coupled_frequency_hz:g} Hz is not allowed; allowed: "
            f"(0, {dry_frequency_hz:g}] Hz = the ring model's dry frequency (air loading lowers "
            "frequencies; check the FE solve is at this z and V_b, or raise reduced.rings)")
    return (dry_frequency_hz / coupled_frequency_hz) ** 2 - 1


# -- damping calibration (Sect. 5.3) -------------------------------------------------------------
@dataclass(frozen=True)
class DampingCalibration:
    """Damping ratios b/m matched to measured peak heights (Sect. 5.3).

    Attributes
    ----------
    labels : tuple of str
    damping_per_mass : ndarray
        Calibrated b/m [1/s].
    measured_peak, model_peak : ndarray
        Peak heights, mean of the axial and radial average-spectrum maxima in
        each mode's window [m/s].
    windows : ndarray, shape (modes, 2)
        Frequency windows searched [Hz].
    """

    labels: tuple
    damping_per_mass: np.ndarray
    measured_peak: np.ndarray
    model_peak: np.ndarray
    windows: np.ndarray


def peak_windows(frequency_hz, relative_half_width: float) -> np.ndarray:
    """[f (1 - w), f (1 + w)] around each mode, cut at the midpoints to its neighbours [Hz]."""
    f = np.asarray(frequency_hz, float)
    order = np.argsort(f)
    windows = np.stack([f * (1 - relative_half_width), f * (1 + relative_half_width)], axis=1)
    for position, index in enumerate(order):
        if position > 0:
            windows[index, 0] = max(windows[index, 0], 0.5 * (f[index] + f[order[position - 1]]))
        if position < len(order) - 1:
            windows[index, 1] = min(windows[index, 1], 0.5 * (f[index] + f[order[position + 1]]))
    return windows


def _peak(frequency, axial, radial, window):
    inside = (frequency >= window[0]) & (frequency <= window[1])
    if not np.any(inside):
        return math.nan
    return 0.5 * (np.max(axial[inside]) + np.max(radial[inside]))


def calibrate_damping(model: ReducedModel, chirp: Chirp, measured_frequency_hz, measured_axial,
                      measured_radial, relative_half_width: float = 0.15,
                      sweeps: int = 3) -> DampingCalibration:
    """Choose each b/m so the model's average-spectrum peak matches the measured one (Sect. 5.3).

    For each mode the peak height is the mean of the axial and radial maxima
    of the average spectrum inside the mode's window (:func:`peak_windows`
    around the model's in-air frequency; the default half-width 0.15 exceeds
    the paper's 8 % model-experiment frequency gap).  Peaks are matched one
    mode at a time by a root search on log(b/m) (a peak falls monotonically
    with its own damping); as neighbouring modes add a little to each peak,
    the modes are swept ``sweeps`` times.

    Raises
    ------
    ReducedModelError
        A mode outside the band, no measured line in a window, or a measured
        peak the model cannot reach even undamped on its spectral lines.
    """
    f_meas = np.asarray(measured_frequency_hz, float)
    v_ax, v_rad = np.asarray(measured_axial, float), np.asarray(measured_radial, float)
    freqs, lines = chirp.lines()
    band = (max(freqs[0], f_meas.min()), min(freqs[-1], f_meas.max()))
    for label, f in zip(model.labels, model.frequency_hz):
        if not band[0] <= f <= band[1]:
            raise ReducedModelError(
                f"{label} at {f:.1f} Hz is not allowed for the calibration; allowed: modes inside "
                f"[{band[0]:g}, {band[1]:g}] Hz, the band of both spectra (give its coupled "
                "frequency, e.g. reduced.coupled_freq_02, or leave it out of reduced.modes)")
    windows = peak_windows(model.frequency_hz, relative_half_width)
    targets = np.array([_peak(f_meas, v_ax, v_rad, w) for w in windows])
    for label, target, window in zip(model.labels, targets, windows):
        if not np.isfinite(target) or target <= 0:
            raise ReducedModelError(
                f"measured spectrum has no peak for {label} in [{window[0]:.1f}, "
                f"{window[1]:.1f}] Hz; allowed: a spectrum covering every kept mode")
    ratios = model.damping_per_mass.astype(float).copy()

    def height(j, log_ratio):
        trial = ratios.copy()
        trial[j] = math.exp(log_ratio)
        result = model.with_damping_per_mass(trial).spectra(freqs, lines)
        return _peak(freqs, result.average_axial, result.average_radial, windows[j])

    low, high = math.log(1e-6), math.log(1e6)   # b/m bounds [1/s]: far outside physical values
    for _ in range(sweeps):
        for j, label in enumerate(model.labels):
            top, bottom = height(j, low), height(j, high)
            if not bottom < targets[j] < top:
                raise ReducedModelError(
                    f"measured peak of {label} = {targets[j]:.4g} m/s is not allowed; allowed: "
                    f"({bottom:.4g}, {top:.4g}) m/s, what b/m in [1e-6, 1e6] 1/s gives on the "
                    "model's lines (check the excitation keys match the measurement)")
            import scipy.optimize  # at use: 0.15 s of import the modal commands skip
            ratios[j] = math.exp(scipy.optimize.brentq(lambda s: height(j, s) - targets[j],
                                                       low, high, xtol=1e-10))
    calibrated = model.with_damping_per_mass(ratios)
    result = calibrated.spectra(freqs, lines)
    return DampingCalibration(
        labels=model.labels, damping_per_mass=ratios, measured_peak=targets,
        model_peak=np.array([_peak(freqs, result.average_axial, result.average_radial, w)
                             for w in windows]),
        windows=windows)
