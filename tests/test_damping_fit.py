"""calibrate-damping --fit rayleigh|prony (issue 23, item 4): closed forms, noise, the FE.

Closed forms (copdea_fem/damping_fit.py): Rayleigh zeta_k = alpha / (2 omega_k) +
beta omega_k / 2 (exact); one Prony term zeta_k = g s_k omega_k tau / (2 (1 + omega_k^2
tau^2)) at first order.  The FE tests make "measured" quality factors with the FE itself
and check that the FE solved with the fitted keys reproduces them within the stated fit.
"""

import csv

import numpy as np
import pytest

from copdea_fem.damping_fit import (
    DampingFitError,
    MeasuredDamping,
    fe_modes,
    fit_damping,
    fit_prony,
    fit_rayleigh,
    prony_ratio,
    rayleigh_ratio,
    read_quality_csv,
)
from copdea_fem.fe import engine_for
from copdea_fem.study import StudyError, parse_study

FREQ = np.geomspace(150.0, 1500.0, 6)           # Hz


def coarse_study(**sections):
    """The coarse G1 cone of tests/fe/test_damping.py (z = 8 mm, 2 kV, baffle, m = 0..)."""
    raw = {"mesh": {"membrane_size": "6 mm", "order": 2, "engine": "axisymmetric"},
           "geometry": {"frame": "baffle"}, "load": {"z": "8 mm", "voltage": "2 kV"},
           "eigen": {"f_min": 50, "f_max": 600}}
    for section, values in sections.items():
        raw.setdefault(section, {}).update(values)
    return parse_study(raw, name="test")


def test_rayleigh_fit_recovers_alpha_beta():
    alpha, beta = 40.0, 4e-6
    zeta = rayleigh_ratio(FREQ, alpha, beta)
    assert zeta[0] == pytest.approx(alpha / (2 * 2 * np.pi * 150) + beta * np.pi * 150)
    fitted = fit_rayleigh(FREQ, zeta)
    assert fitted == pytest.approx((alpha, beta), rel=1e-9)
    assert fit_rayleigh(FREQ, rayleigh_ratio(FREQ, 0.0, beta)) == pytest.approx((0, beta),
                                                                                abs=1e-12)
    assert fit_rayleigh(FREQ[:1], zeta[:1])[0] == 0.0          # one mode: beta alone


def test_rayleigh_fit_noise_tolerance():
    """Documented (docs/damping.md): independent relative noise sigma on six quality
    factors -> the fitted zeta within 3 sigma at every mode, median error below sigma."""
    alpha, beta, sigma = 40.0, 4e-6, 0.05
    zeta = rayleigh_ratio(FREQ, alpha, beta)
    errors = []
    for seed in range(20):
        quality = np.exp(np.random.default_rng(seed).normal(0, sigma, FREQ.size)) / (2 * zeta)
        fitted = fit_rayleigh(FREQ, 1 / (2 * quality))
        errors.append(np.max(np.abs(rayleigh_ratio(FREQ, *fitted) / zeta - 1)))
    assert max(errors) <= 3 * sigma and np.median(errors) <= sigma


def test_prony_fit_recovers_first_order_closed_form():
    strain = np.array([0.02, 0.03, 0.5, 0.01, 0.2, 0.05])
    zeta = prony_ratio(FREQ, strain, 0.5, 3e-4)
    wt = 2 * np.pi * FREQ[0] * 3e-4
    assert zeta[0] == pytest.approx(0.5 * 0.02 * wt / (2 * (1 + wt**2)))
    g, tau, identified = fit_prony(FREQ, zeta, strain)
    assert identified and (g, tau) == pytest.approx((0.5, 3e-4), rel=1e-6)
    assert fit_prony(FREQ, zeta, strain, relaxation_time=3e-4)[0] == pytest.approx(0.5)
    # all modes far below omega tau = 1: only g tau is determined
    slow = prony_ratio(FREQ, strain, 0.5, 1e-7)
    assert not fit_prony(FREQ, slow, strain)[2]


def _write_quality(path, labels, zeta):
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["label", "quality_factor"])
        writer.writerows((label, f"{1 / (2 * z):.12g}") for label, z in zip(labels, zeta))
    return path


def test_quality_csv_is_read_and_checked(tmp_path):
    measured = read_quality_csv(_write_quality(tmp_path / "q.csv", ["(0,1)", "(0,2)"],
                                               [0.01, 0.02]))
    assert measured.labels == ["(0,1)", "(0,2)"]
    assert measured.damping_ratio == pytest.approx([0.01, 0.02])
    (tmp_path / "bad.csv").write_text("label,quality_factor\n\"(0,1)\",-3\n")
    with pytest.raises(StudyError, match="quality_factor = -3 is not allowed"):
        read_quality_csv(tmp_path / "bad.csv")
    (tmp_path / "cols.csv").write_text("mode,q\n\"(0,1)\",3\n")
    with pytest.raises(StudyError, match="allowed: columns label, quality_factor"):
        read_quality_csv(tmp_path / "cols.csv")


def test_rayleigh_fit_with_air_reproduces_measured_q():
    """Coupled G1 (radiation damping 2.3e-2 on (0,1)): quality factors made by the FE with
    known alpha, beta; the fit subtracts the FE's radiation, takes the membrane's share of
    each term from probe solves, recovers alpha and beta, and an FE solve
    with the fitted keys gives back every measured Q within the stated residual."""
    alpha, beta = 30.0, 3e-6
    membrane = {"rayleigh_alpha": alpha, "rayleigh_beta": beta}
    truth = fe_modes(coarse_study(air={"enabled": True}, membrane=membrane))
    labels = ["(0,1)", "(1,1)a", "(2,1)a", "(3,1)a"]
    measured = MeasuredDamping(labels, np.array([truth[label][1] for label in labels]))
    fit = fit_damping(coarse_study(air={"enabled": True}), measured, "rayleigh",
                      refinements=1)
    assert fit.verified and np.all(fit.used) and fit.radiation[0] > 0.01   # (0,1) radiates
    keys = fit.keys
    assert keys["membrane.rayleigh_alpha"] == pytest.approx(alpha, rel=0.01)
    assert keys["membrane.rayleigh_beta"] == pytest.approx(beta, rel=0.01)
    assert np.max(np.abs(fit.residual)) < 0.01
    check = fe_modes(coarse_study(air={"enabled": True}, membrane={
        "rayleigh_alpha": float(f"{keys['membrane.rayleigh_alpha']:.6g}"),
        "rayleigh_beta": float(f"{keys['membrane.rayleigh_beta']:.6g}")}))
    quality = np.array([1 / (2 * check[label][1]) for label in labels])
    stated = np.abs(fit.residual) + 1e-4
    assert np.all(np.abs(quality * 2 * measured.damping_ratio - 1) <= stated)


def test_prony_fit_through_the_cli_reproduces_measured_q(tmp_path, capsys):
    """Dry cone: quality factors of the FE with g = 0.5, tau = 1 ms; ``calibrate-damping
    --fit prony --quality-factors`` recovers the term, its table states the residuals and
    the FE with the printed keys reproduces the Q within them."""
    from copdea_fem.cli import main
    dry = {"air": {"enabled": False}}
    truth = fe_modes(coarse_study(**dry, membrane={"prony": [
        {"modulus_ratio": 0.5, "relaxation_time": "1 ms"}]}))
    labels = ["(0,1)", "(1,1)a", "(2,1)a", "(3,1)a", "(4,1)a"]
    zeta = np.array([truth[label][1] for label in labels])
    quality = _write_quality(tmp_path / "q.csv", labels, zeta)
    study = tmp_path / "study.yaml"
    study.write_text("mesh: {membrane_size: 6 mm, order: 2, engine: axisymmetric}\n"
                     "geometry: {frame: baffle}\nload: {z: 8 mm, voltage: 2 kV}\n"
                     "eigen: {f_min: 50, f_max: 600}\nair: {enabled: false}\n")
    code = main(["calibrate-damping", str(study), "--fit", "prony", "--quality-factors",
                 str(quality), "--out", str(tmp_path / "fit"), "--quiet"])
    out = capsys.readouterr().out
    assert code == 0, out
    rows = list(csv.DictReader(open(tmp_path / "fit" / "damping_fit.csv")))
    assert [row["label"] for row in rows] == labels
    residual = np.array([float(row["residual"]) for row in rows])
    assert np.max(np.abs(residual)) < 0.01
    use = next(line for line in out.splitlines() if "use: --set 'membrane.prony=" in line)
    term = use.split("=", 1)[1].strip("'[]{} ")
    values = dict(item.split(":") for item in term.split(","))
    g, tau = float(values["modulus_ratio"]), float(values[" relaxation_time"])
    assert g == pytest.approx(0.5, rel=0.05) and tau == pytest.approx(1e-3, rel=0.05)
    check = fe_modes(coarse_study(**dry, membrane={"prony": [
        {"modulus_ratio": g, "relaxation_time": tau}]}))
    fe_quality = np.array([1 / (2 * check[label][1]) for label in labels])
    assert np.all(np.abs(fe_quality * 2 * zeta - 1) <= np.abs(residual) + 1e-4)


def test_prony_on_a_flat_membrane_is_not_identifiable(tmp_path):
    """z = 0: the out-of-plane modes carry no first-order material strain -> refused."""
    flat = coarse_study(air={"enabled": False}, load={"z": 0.0})
    measured = MeasuredDamping(["(0,1)", "(1,1)a"], np.array([0.01, 0.012]))
    with pytest.raises(DampingFitError, match="not identifiable by a Prony term"):
        fit_damping(flat, measured, "prony")
    with pytest.raises(StudyError, match=r"\(9,9\) are not in the FE band"):   # bad input
        fit_damping(flat, MeasuredDamping(["(9,9)"], np.array([0.01])), "rayleigh")


def test_rayleigh_fit_from_a_spectrum_through_the_cli(tmp_path, capsys):
    """The spectrum path: the reduced model's b/m (245 1/s for (0,1), 45 1/s for P1) give
    zeta = (b/m) / (2 omega); the FE (dry, coarse) fits alpha, beta to both exactly; (0,2)
    lies above the FE band and is left out with a note."""
    from copdea_fem.cli import main
    study = "tests/reduced/data/g1_z16_2kV.yaml"
    coupled = ["--set", "reduced.coupled_freq_01=400 Hz", "--set", "reduced.coupled_freq_02=930 Hz"]
    assert main(["spectrum", study, *coupled, "--out", str(tmp_path / "measured")]) == 0
    coarse = ["--set", "mesh.engine=axisymmetric", "--set", "mesh.membrane_size=6 mm",
              "--set", "mesh.order=2", "--set", "geometry.frame=baffle",
              "--set", "air.enabled=false"]
    capsys.readouterr()
    code = main(["calibrate-damping", study, str(tmp_path / "measured" / "spectrum_average.csv"),
                 *coupled, *coarse, "--fit", "rayleigh", "--out", str(tmp_path / "fit"),
                 "--quiet"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "(0,2) are not in the FE band" in out and "--set membrane.rayleigh_beta=" in out
    rows = {row["label"]: row for row in csv.DictReader(open(tmp_path / "fit" / "damping_fit.csv"))}
    assert set(rows) == {"P1", "(0,1)"}
    # b/m of the calibration round trip (tests/reduced): 245 1/s at the reduced 400 Hz
    assert float(rows["(0,1)"]["measured_damping_ratio"]) == pytest.approx(
        245 / (2 * 2 * np.pi * 400), rel=0.02)
    assert all(abs(float(row["residual"])) < 1e-3 for row in rows.values())
    quality = str(_write_quality(tmp_path / "q.csv", ["(0,1)"], [0.01]))
    for bad in (["--fit", "modal"], ["--fit", "prony"], ["--quality-factors", quality],
                ["--fit", "rayleigh", "--quality-factors", quality, "--relaxation-time", "1 ms"]):
        assert main(["calibrate-damping", study, *bad, "--out", str(tmp_path / "none")]) == 2
        assert "error: --" in capsys.readouterr().err     # refused before any FE work
    assert not (tmp_path / "none").exists()


def test_a_fit_the_fe_cannot_hold_is_an_error_not_nan():
    """A measured zeta = 0.9 (underdamped, allowed): the fitted beta moves (0,1) to
    |Im f| = 0.9 |f|, beyond the band's height eigen.max_damping_ratio * f_max = 30 Hz, so
    the FE with the fitted keys has no (0,1): an error, never a NaN written as the fit."""
    study = coarse_study(air={"enabled": False})
    with pytest.raises(DampingFitError, match=r"leave no FE mode \(0,1\) in the band"):
        fit_damping(study, MeasuredDamping(["(0,1)"], np.array([0.9])), "rayleigh")


def test_overdamped_roots_are_left_out_of_the_modes(caplog):
    """Mass-proportional damping C = alpha M: every root solves omega^2 + i alpha omega -
    omega_k^2 = 0, so Im f = -alpha / (4 pi) for each mode with f_k > alpha / (4 pi) and the
    roots of the slower ones lie on the imaginary axis (overdamped, not modes).  With
    alpha / (4 pi) = 500 Hz the modes table keeps only oscillating roots, each at that
    Im f (closed form, to the eigen residual), and one warning counts the rest.  (The
    undamped (0,1), (1,1)a/b, (2,1)a/b lie at 452 .. 488 Hz here, below 500 Hz:
    overdamped.)"""
    import logging

    from copdea_fem.fe.pipeline import run_solve
    alpha = 4 * np.pi * 500.0
    study = coarse_study(air={"enabled": False}, membrane={"rayleigh_alpha": alpha},
                         eigen={"f_min": 0, "f_max": 600, "max_damping_ratio": 1})
    with caplog.at_level(logging.WARNING, logger="copdea_fem"):
        modes = run_solve(study, engine=engine_for(study)).modes
    dropped = [record.getMessage() for record in caplog.records
               if "overdamped root(s) left out" in record.getMessage()]
    assert len(dropped) == 1 and int(dropped[0].split()[0]) > 0, dropped
    assert modes and all(mode.freq_hz > 1e-3 * abs(mode.freq_im_hz) for mode in modes)
    assert [mode.freq_im_hz for mode in modes] == pytest.approx([-500.0] * len(modes), rel=1e-6)
