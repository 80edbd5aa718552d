"""File glue of the reduced model: modes.json, CSV in and out, PNG plots, summaries.

The physics lives in the other modules of :mod:`copdea_fem.reduced`; this
module only reads and writes, for the results of :mod:`copdea_fem.api` (each written by
its ``write``):

- ``copdea-fem spectrum``: :func:`write_spectrum_files` and :func:`spectrum_summary`
  (:class:`copdea_fem.api.Spectrum`);
- ``copdea-fem fit-material STUDY.yaml DATA.csv``: :func:`read_force_csv`,
  :func:`fit_force_data`, :func:`write_material_fit` and :func:`material_fit_lines`
  (:class:`copdea_fem.api.MaterialFitResult`);
- ``copdea-fem calibrate-damping STUDY.yaml SPECTRUM.csv``: :func:`calibrate_on_spectrum`,
  :func:`write_damping_calibration` and :func:`damping_calibration_lines`
  (:class:`copdea_fem.api.DampingCalibrationResult`; ``--fit rayleigh|prony`` fits the FE's
  keys: :mod:`copdea_fem.damping_fit`, above the FE pipeline).

Output files (column names are a contract):

- ``spectrum_average.csv``: ``freq_hz, v_axial, v_radial`` [Hz, m/s, m/s]
- ``spectrum_points.csv``: ``freq_hz, v_axial_q1, v_radial_q1, ..., v_radial_q3``
- ``reduced_modes.csv``: ``label, freq_hz, modal_mass, added_mass, damping``
  [-, Hz (in air, eq. 19), kg, kg, kg/s; shapes scaled to a largest nodal
  displacement of 1]
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from copdea_fem.inputs import read_text
from copdea_fem.reduced.chirp_response import calibrate_damping
from copdea_fem.reduced.fit import PARAMETERS, fit_material
from copdea_fem.reduced.modal import mode_profile
from copdea_fem.reduced.model import build_reduced, damping_key, spectra_of
from copdea_fem.reduced.rings import RingModel
from copdea_fem.study import StudyError, dump_resolved

AVERAGE_COLUMNS = ("freq_hz", "v_axial", "v_radial")
POINT_COLUMNS = ("freq_hz",) + tuple(f"v_{component}_q{i}" for i in (1, 2, 3)
                                     for component in ("axial", "radial"))
MODE_COLUMNS = ("label", "freq_hz", "modal_mass", "added_mass", "damping")
CALIBRATION_COLUMNS = ("label", "freq_hz", "measured_peak", "model_peak", "damping_per_mass")
MATERIAL_FIT_COLUMNS = ("parameter", "value_pa", "standard_error_pa")
FORCE_COLUMNS = ("z_m", "force_n")
FORCE_OPTIONAL = ("voltage_v", "prestretch", "inner_radius_m", "force_std_n")
_COMPARED_SECTIONS = ("geometry", "membrane", "load")


# -- readers ---------------------------------------------------------------------------------------
def read_modes_json(path, study=None) -> dict:
    """Coupled frequencies {label: freq_hz} of a FE solve's ``modes.json``.

    Takes the first entry of each label.  With ``study`` given, the
    geometry, membrane and load keys stored in the file's ``"study"`` block
    must match it (relative difference <= 1e-9): added masses from another
    operating point would be wrong.
    """
    path = Path(path)
    if not path.is_file():
        raise StudyError(f"reduced.modes_json = {str(path)!r} does not exist; allowed: the "
                         "modes.json written by a FE solve")
    text = read_text(path, "reduced.modes_json", error=StudyError)
    try:
        data = json.loads(text)
        entries = data["modes"]
    except (json.JSONDecodeError, KeyError, TypeError) as exc:
        raise StudyError(f"reduced.modes_json = {str(path)!r} is not a modes.json ({exc}); "
                         'allowed: {"study": {...}, "modes": [{"label": ..., "freq_hz": ...}]}') \
            from None
    if study is not None and isinstance(data.get("study"), dict):
        values = study.values
        for section in _COMPARED_SECTIONS:
            theirs = data["study"].get(section) or {}
            for key, mine in values[section].items():
                other = theirs.get(key)
                if isinstance(mine, (int, float)) and isinstance(other, (int, float)) and not (
                        math.isclose(mine, other, rel_tol=1e-9, abs_tol=1e-15)):
                    raise StudyError(
                        f"reduced.modes_json = {str(path)!r} is not allowed: its {section}.{key} "
                        f"= {other!r} differs from this study's {mine!r}; allowed: a FE solve at "
                        "the same geometry, membrane and operating point")
    frequencies = {}
    for entry in entries:
        label, freq = entry.get("label"), entry.get("freq_hz")
        if isinstance(label, str) and isinstance(freq, (int, float)) and label not in frequencies:
            frequencies[label] = float(freq)
    return frequencies


def modes_json_air_enabled(path):
    """``air.enabled`` of the study stored in a modes.json (None when absent)."""
    try:
        value = json.loads(Path(path).read_text())["study"]["air"]["enabled"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return value if isinstance(value, bool) else None


def _read_table(path, required, optional=()) -> dict:
    path = Path(path)
    if not path.exists():
        raise StudyError(f"data file {str(path)!r} does not exist")
    lines = read_text(path, "data file", error=StudyError).splitlines()
    rows = list(csv.reader(row for row in lines if row.strip() and not row.startswith("#")))
    if not rows:
        raise StudyError(f"data file {str(path)!r} is empty; allowed: a CSV with header "
                         + ", ".join(required))
    header = [name.strip() for name in rows[0]]
    missing = [name for name in required if name not in header]
    if missing:
        raise StudyError(f"data file {str(path)!r} has columns {header}; allowed: columns "
                         f"{', '.join(required)} (optional: {', '.join(optional) or 'none'})")
    columns = {}
    for name in [*required, *optional]:
        if name in header:
            index = header.index(name)
            try:
                columns[name] = np.array([float(row[index]) for row in rows[1:]])
            except (ValueError, IndexError):
                raise StudyError(f"data file {str(path)!r}: column {name} has a value that is "
                                 "not a number; allowed: numbers in SI units") from None
    return columns


def read_force_csv(path) -> dict:
    """Force-displacement data: columns ``z_m, force_n`` [m, N], optional
    ``voltage_v`` [V], ``prestretch`` [-], ``inner_radius_m`` [m], ``force_std_n`` [N]."""
    return _read_table(path, FORCE_COLUMNS, FORCE_OPTIONAL)


def read_spectrum_csv(path) -> dict:
    """Average spectrum: columns ``freq_hz, v_axial, v_radial`` [Hz, m/s, m/s]."""
    return _read_table(path, AVERAGE_COLUMNS)


# -- writers ---------------------------------------------------------------------------------------
def write_csv(path, header, columns) -> Path:
    """Write equal-length columns under a header; numbers with 10 significant digits."""
    path = Path(path)
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        for row in zip(*columns):
            writer.writerow([f"{value:.10g}" if isinstance(value, (float, np.floating)) else value
                             for value in row])
    return path


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _mark_modes(axis, reduced):
    for label, freq in zip(reduced.labels, reduced.frequency_hz):
        axis.axvline(freq, color="0.8", lw=0.8, zorder=0)
        axis.text(freq, 1.0, label, transform=axis.get_xaxis_transform(), ha="center",
                  va="bottom", fontsize=7, color="0.4")


def plot_average(path, result, reduced, title, measured=None):
    """Average axial/radial velocity spectra in mm/s (style of Figs 12-13)."""
    plt = _pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    for axis, values, name, key in ((axes[0], result.average_axial, "axial", "v_axial"),
                                    (axes[1], result.average_radial, "radial", "v_radial")):
        axis.plot(result.frequency_hz, 1e3 * values, "k-", lw=1, label="model")
        if measured is not None:
            axis.plot(measured["freq_hz"], 1e3 * measured[key], "r--", lw=1, label="measured")
            axis.legend(fontsize=8)
        axis.set_ylabel(f"{name} velocity [mm/s]")
        _mark_modes(axis, reduced)
    axes[-1].set_xlabel("frequency [Hz]")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def plot_points(path, result, reduced, title):
    """Point spectra at Q1-Q3, axial and radial, in mm/s (style of Fig. 14)."""
    plt = _pyplot()
    fig, axes = plt.subplots(3, 2, figsize=(9, 7), sharex=True)
    for i in range(3):
        for j, (values, name) in enumerate(((result.point_axial, "axial"),
                                            (result.point_radial, "radial"))):
            axis = axes[i, j]
            axis.plot(result.frequency_hz, 1e3 * values[:, i], "k-", lw=1)
            axis.set_ylabel(f"Q{i + 1} {name} [mm/s]", fontsize=8)
            _mark_modes(axis, reduced)
    for axis in axes[-1]:
        axis.set_xlabel("frequency [Hz]")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def plot_mode_shapes(path, setup):
    """Equilibrium profile and the kept modes' deformed profiles (style of Fig. 9d)."""
    plt = _pyplot()
    modes = setup.basis.truncate(setup.reduced.labels)
    fig, axes = plt.subplots(len(modes), 1, figsize=(6, 2.2 * len(modes)), squeeze=False)
    width = setup.ring_model.outer_radius - setup.ring_model.inner_radius
    for axis, mode in zip(axes[:, 0], modes):
        profile = mode_profile(setup.ring_model, setup.linearisation, mode)
        amplitude = 0.15 * width
        axis.plot(1e3 * profile["radius"], 1e3 * profile["height"], "k--", lw=1)
        axis.plot(1e3 * (profile["radius"] + amplitude * profile["radial"]),
                  1e3 * (profile["height"] + amplitude * profile["axial"]), "ko-", ms=3, lw=1)
        for q, r in enumerate(setup.reduced.point_radii):
            axis.axvline(1e3 * r, color="0.8", lw=0.8)
            axis.text(1e3 * r, 1.0, f"Q{q + 1}", transform=axis.get_xaxis_transform(),
                      ha="center", va="bottom", fontsize=7)
        axis.set_ylabel("z [mm]")
        axis.set_title(f"{mode.label}, {mode.frequency_hz:.1f} Hz dry", fontsize=8, pad=12)
        axis.set_aspect("equal", adjustable="datalim")
    axes[-1, 0].set_xlabel("r [mm]")
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


# -- CLI actions --------------------------------------------------------------------------------
def fe_frequencies(study, modes_json):
    path = modes_json or study.reduced.modes_json
    return (read_modes_json(path, study) if path else {}), path


def _title(study):
    g, load = study.geometry, study.load
    return (f"{study.name}: r_i = {1e3 * g.inner_radius:g} mm, z = {1e3 * load.z:g} mm, "
            f"V_b = {load.voltage / 1e3:g} kV, {study.reduced.rings} rings")


def write_spectrum_files(out, study, setup, result) -> list:
    """The files of ``spectrum`` in ``out`` (a staging folder); their paths."""
    reduced = setup.reduced
    files = [
        write_csv(out / "spectrum_average.csv", AVERAGE_COLUMNS,
                  (result.frequency_hz, result.average_axial, result.average_radial)),
        write_csv(out / "spectrum_points.csv", POINT_COLUMNS,
                  (result.frequency_hz,) + tuple(values[:, i] for i in range(3)
                                                 for values in (result.point_axial,
                                                                result.point_radial))),
        write_csv(out / "reduced_modes.csv", MODE_COLUMNS,
                  (reduced.labels, reduced.frequency_hz, reduced.modal_mass, reduced.added_mass,
                   reduced.damping)),
    ]
    shapes = [mode_profile(setup.ring_model, setup.linearisation, mode)
              for mode in setup.basis.truncate(reduced.labels)]
    files.append(write_csv(
        out / "reduced_mode_shapes.csv",
        ("label", "reference_radius_m", "radius_m", "height_m", "radial", "axial"),
        ([label for label in reduced.labels for _ in shapes[0]["radius"]],
         *(np.concatenate([s[key] for s in shapes])
           for key in ("reference_radius", "radius", "height", "radial", "axial")))))
    dump_resolved(study, out / "reduced_study.resolved.yaml")
    files.append(out / "reduced_study.resolved.yaml")
    if study.output.plots:
        title = _title(study)
        for name, plot in (("spectrum_average.png", plot_average),
                           ("spectrum_points.png", plot_points)):
            plot(out / name, result, reduced, title)
            files.append(out / name)
        plot_mode_shapes(out / "reduced_mode_shapes.png", setup)
        files.append(out / "reduced_mode_shapes.png")
    return files


def spectrum_summary(study, setup, fe_path) -> dict:
    """What ``copdea-fem spectrum`` prints of a reduced model ``setup``
    (:func:`copdea_fem.reduced.model.build_reduced`) whose added masses came from the
    modes.json ``fe_path`` (None: none).

    Returns
    -------
    dict with ``modes`` (rows of reduced_modes.csv plus the added-mass source),
    ``pumping_hz`` (Annex I P1-P3) and ``lines`` (a text summary to print).
    """
    reduced = setup.reduced
    lin = setup.linearisation
    lines = [_title(study),
             f"static: disc force {lin.equilibrium.disc_force:.4g} N, k_DE "
             f"{lin.axial_stiffness:.4g} N/m"
             + (f", spring preload l_b {1e3 * lin.spring_preload:.4g} mm"
                if math.isfinite(lin.spring_preload) else ""),
             f"{'mode':>6} {'dry Hz':>9} {'air Hz':>9} {'m_ad/m':>7} {'b/m 1/s':>8}  "
             "added mass from"]
    rows = []
    for j, label in enumerate(reduced.labels):
        ratio = reduced.added_mass[j] / reduced.modal_mass[j]
        lines.append(f"{label:>6} {reduced.dry_frequency_hz[j]:9.2f} {reduced.frequency_hz[j]:9.2f}"
                     f" {ratio:7.3f} {reduced.damping_per_mass[j]:8.1f}  "
                     f"{reduced.added_mass_source[j]}")
        rows.append(dict(label=label, freq_hz=float(reduced.frequency_hz[j]),
                         modal_mass=float(reduced.modal_mass[j]),
                         added_mass=float(reduced.added_mass[j]),
                         damping=float(reduced.damping[j]),
                         source=reduced.added_mass_source[j]))
    if len(setup.pumping_frequency_hz):
        lines.append("Annex I pumping modes (eq. 22): " + ", ".join(
            f"P{k + 1} {f:.2f} Hz" for k, f in enumerate(setup.pumping_frequency_hz)))
    if study.load.voltage == 0:
        lines.append("note: load.voltage = 0: eq. (14) has no forcing (V_b V~ dC/dq = 0; the "
                     "true response is quadratic in V~), so the spectra are zero")
    elif study.excitation.amplitude > 0.1 * study.load.voltage:
        lines.append("note: excitation.amplitude > 10 % of load.voltage: the linearisation of "
                     "Sect. 3.2 assumes |V~| << V_b; expect distortion the model does not show")
    if fe_path:
        lines.append(f"coupled frequencies read from {fe_path}")
        if modes_json_air_enabled(fe_path) is False:
            lines.append("note: that modes.json is a dry solve (air.enabled = false): its "
                         "frequencies only correct the ring discretisation, no air added mass")
    return {"modes": rows, "pumping_hz": [float(f) for f in setup.pumping_frequency_hz], "lines": lines}


def fit_force_data(study, data: dict):
    """Fit c10, c20, c01 to force-displacement data (Sect. 5.1; :func:`read_force_csv`'s
    columns).

    Missing ``voltage_v``/``prestretch``/``inner_radius_m`` columns default
    to the study's load.voltage, membrane.prestretch, geometry.inner_radius.
    The study's c10, c20, c01 are the start values.

    Returns
    -------
    (RingModel, MaterialFit, numpy.ndarray)
        The ring model of the study, the fit, and each row's voltage [V].
    """
    model = RingModel.from_study(study)
    count = data["z_m"].size
    voltage = data.get("voltage_v", np.full(count, study.load.voltage))
    fit = fit_material(model, data["z_m"], data["force_n"], voltage,
                       prestretch=data.get("prestretch"), inner_radius=data.get("inner_radius_m"),
                       force_std=data.get("force_std_n"))
    return model, fit, voltage


def write_material_fit(out, study, model, fit, data, voltage) -> list:
    """The files of ``fit-material`` in ``out`` (a staging folder): material_fit.csv
    (``parameter, value_pa, standard_error_pa``) and, with ``output.plots``, the fitted
    curves over the data (material_fit.png); their paths."""
    files = [write_csv(out / "material_fit.csv", MATERIAL_FIT_COLUMNS,
                       (PARAMETERS, fit.values, fit.standard_error))]
    if study.output.plots:
        files.append(_plot_force_fit(out / "material_fit.png", study, model, fit, data, voltage))
    return files


def material_fit_lines(fit) -> list[str]:
    """What ``copdea-fem fit-material`` prints of a fit: the values, their 1-sigma errors,
    a note when c10 and c01 are not separated, the ``--set`` options to reuse."""
    lines = [f"fitted eq. (20) on {fit.point_count} points, rms residual "
             f"{fit.residual_rms:.4g} N"]
    for name, value, error in zip(PARAMETERS, fit.values, fit.standard_error):
        lines.append(f"  {name} = {value / 1e3:10.3f} kPa  +/- {error / 1e3:.3f} kPa (1 sigma)")
    corr = fit.correlation[0, 2]
    if abs(corr) > 0.99:
        lines.append(f"  note: c10 and c01 correlate at {corr:+.3f}: the data fix mostly "
                     "c10 + lambda_p^2 c01; add a sample at another pre-stretch to separate them")
    lines.append("  use: " + " ".join(f"--set membrane.{name}='{value / 1e3:.4g} kPa'"
                                      for name, value in zip(PARAMETERS, fit.values)))
    return lines


def _plot_force_fit(path, study, model, fit, data, voltage):
    plt = _pyplot()
    fitted = model.with_membrane(fit.membrane(model.membrane))
    fig, axis = plt.subplots(figsize=(6, 4))
    count = data["z_m"].size
    lam = data.get("prestretch", np.full(count, model.membrane.prestretch))
    r_in = data.get("inner_radius_m", np.full(count, model.inner_radius))
    for sample in sorted(set(zip(lam.tolist(), r_in.tolist(), voltage.tolist()))):
        rows = (lam == sample[0]) & (r_in == sample[1]) & (voltage == sample[2])
        from dataclasses import replace
        sample_model = replace(fitted, inner_radius=sample[1],
                               membrane=replace(fitted.membrane, prestretch=sample[0]))
        z = np.linspace(0, np.max(data["z_m"][rows]), 60)
        line, = axis.plot(1e3 * z, sample_model.force_displacement(z, sample[2]), "-",
                          label=f"lambda_p {sample[0]:g}, r_i {1e3 * sample[1]:g} mm, "
                                f"{sample[2] / 1e3:g} kV")
        axis.plot(1e3 * data["z_m"][rows], data["force_n"][rows], "o", ms=3,
                  color=line.get_color())
    axis.set_xlabel("disc displacement z [mm]")
    axis.set_ylabel("force F [N]")
    axis.legend(fontsize=7)
    axis.set_title(f"{study.name}: eq. (20) fitted (Fig. 4b)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return path


def damping_calibration_columns(calibration, setup) -> tuple:
    """The columns of ``damping_calibration.csv`` (:data:`CALIBRATION_COLUMNS`: label, the
    mode's frequency in air [Hz], the measured and model peaks [m/s], b/m [1/s])."""
    return (calibration.labels, setup.reduced.frequency_hz, calibration.measured_peak,
            calibration.model_peak, calibration.damping_per_mass)


def write_damping_calibration(out, study, calibration, setup, measured) -> list:
    """The files of ``calibrate-damping`` (``--fit modal``) in ``out`` (a staging folder):
    ``damping_calibration.csv`` (:func:`damping_calibration_columns`) and, with
    ``output.plots``, the calibrated model's average spectrum over the measured one
    (damping_calibration.png); their paths."""
    files = [write_csv(out / "damping_calibration.csv", CALIBRATION_COLUMNS,
                       damping_calibration_columns(calibration, setup))]
    if study.output.plots:
        calibrated = setup.reduced.with_damping_per_mass(calibration.damping_per_mass)
        plot_average(out / "damping_calibration.png", spectra_of(setup, calibrated),
                     calibrated, _title(study) + " (damping calibrated)", measured=measured)
        files.append(out / "damping_calibration.png")
    return files


def damping_calibration_lines(calibration, setup) -> list[str]:
    """What ``copdea-fem calibrate-damping`` (``--fit modal``) prints: per mode the measured
    and model peaks and b/m, and the ``--set`` options to reuse."""
    lines = [f"{'mode':>6} {'air Hz':>9} {'measured':>10} {'model':>10} {'b/m 1/s':>9}"]
    options, shared = {}, []
    for j, label in enumerate(calibration.labels):
        lines.append(f"{label:>6} {setup.reduced.frequency_hz[j]:9.2f} "
                     f"{1e3 * calibration.measured_peak[j]:8.4f}mm/s "
                     f"{1e3 * calibration.model_peak[j]:8.4f}mm/s "
                     f"{calibration.damping_per_mass[j]:9.2f}")
        key = damping_key(label)
        if key in options:
            shared.append(label)
        options.setdefault(key, calibration.damping_per_mass[j])
    lines.append("  use: " + " ".join(f"--set {key}={value:.4g}" for key, value in options.items()))
    if shared:
        lines.append(f"  note: {', '.join(shared)} share reduced.damping_higher with a lower mode; "
                     "the value above is the lowest one's")
    return lines


def check_window(window: float) -> None:
    """The relative half-width of the peak search around each mode: in (0, 1), else a
    :class:`StudyError` naming ``--window``."""
    if not 0 < window < 1:
        raise StudyError(f"--window = {window!r} is not allowed; allowed: (0, 1), a relative "
                         "half-width around each mode")


def calibrate_on_spectrum(study, spectrum_csv, modes_json, window):
    """b/m of each kept mode calibrated on a measured average spectrum (Sect. 5.3):
    (calibration, reduced setup, measured columns).

    The CSV has the columns of ``spectrum_average.csv``; it must come from the same chirp
    as the study's ``excitation`` keys.  ``modes_json`` (default ``reduced.modes_json``)
    sets the added masses; ``window`` is the relative half-width of the peak search around
    each mode."""
    check_window(window)
    measured = read_spectrum_csv(spectrum_csv)
    fe, _ = fe_frequencies(study, modes_json)
    setup = build_reduced(study, fe)
    calibration = calibrate_damping(setup.reduced, setup.chirp, measured["freq_hz"],
                                    measured["v_axial"], measured["v_radial"], window)
    return calibration, setup, measured
