"""File glue of the reduced model: contract files, modes.json, CSV inputs, study keys."""

import csv
import json

import numpy as np
import pytest
from reduced_helpers import DATA, paper_study

import copdea_fem as cf
from copdea_fem.reduced.io import read_modes_json, write_csv
from copdea_fem.reduced.model import build_reduced
from copdea_fem.study import StudyError, load_study, parse_study, reduced_mode_labels


def run_spectrum(study, folder):
    """``copdea-fem spectrum --out folder`` through the API: its summary."""
    spectrum = cf.spectrum(study)
    spectrum.write(folder)
    return spectrum.summary


def fit_material_cli(study, data, folder):
    """``copdea-fem fit-material --out folder`` through the API: the fit and its lines."""
    result = cf.fit_material(study, data, out=folder)
    return {"values": result.values, "lines": result.summary_lines()}


def calibrate_damping_cli(study, spectrum, folder, **options):
    """``copdea-fem calibrate-damping --out folder`` through the API: b/m and the lines."""
    result = cf.calibrate_damping(study, spectrum, out=folder, **options)
    return {"damping_per_mass": result.damping_per_mass, "lines": result.summary_lines()}


def read_rows(path):
    with open(path, newline="") as handle:
        return list(csv.reader(handle))


def test_spectrum_writes_the_contract_files(tmp_path):
    study = load_study(DATA / "g1_z16_2kV.yaml")
    summary = run_spectrum(study, tmp_path)
    average = read_rows(tmp_path / "spectrum_average.csv")
    assert average[0] == ["freq_hz", "v_axial", "v_radial"]
    assert len(average) == 1 + 800
    freqs = np.array([float(row[0]) for row in average[1:]])
    assert np.allclose(np.diff(freqs), 1.25) and freqs[-1] == pytest.approx(1000.0)
    points = read_rows(tmp_path / "spectrum_points.csv")
    assert points[0] == ["freq_hz", "v_axial_q1", "v_radial_q1", "v_axial_q2", "v_radial_q2",
                         "v_axial_q3", "v_radial_q3"]
    modes = read_rows(tmp_path / "reduced_modes.csv")
    assert modes[0] == ["label", "freq_hz", "modal_mass", "added_mass", "damping"]
    assert [row[0] for row in modes[1:]] == ["P1", "(0,1)", "(0,2)"]
    damping_per_mass = [float(row[4]) / float(row[2]) for row in modes[1:]]
    assert np.allclose(damping_per_mass, [45.0, 245.0, 57.0])
    assert (tmp_path / "reduced_study.resolved.yaml").is_file()
    assert not list(tmp_path.glob("*.png"))            # output.plots = false in the study
    assert any("Annex I" in line for line in summary["lines"])


def test_spectrum_plots_when_asked(tmp_path):
    study = load_study(DATA / "g1_z16_2kV.yaml", overrides={"output.plots": True})
    run_spectrum(study, tmp_path)
    for name in ("spectrum_average.png", "spectrum_points.png", "reduced_mode_shapes.png"):
        assert (tmp_path / name).stat().st_size > 1000


def fake_modes_json(path, study, **frequencies):
    """A modes.json in the FE solver's format (hand-made frequencies, for the I/O only)."""
    modes = [{"label": label, "m": 0, "n": 1, "kind": "out-of-plane", "freq_hz": freq,
              "freq_im_hz": 0.0} for label, freq in frequencies.items()]
    path.write_text(json.dumps({"study": study.as_dict(), "modes": modes}))
    return path


def test_added_masses_come_from_modes_json_unless_the_study_gives_them(tmp_path):
    study = paper_study()
    path = fake_modes_json(tmp_path / "modes.json", study, **{"(0,1)": 400.0, "(0,2)": 930.0,
                                                                "(1,1)": 500.0})
    frequencies = read_modes_json(path, study)
    assert frequencies == {"(0,1)": 400.0, "(0,2)": 930.0, "(1,1)": 500.0}
    reduced = build_reduced(study, frequencies).reduced
    assert np.allclose(reduced.frequency_hz[1:], [400.0, 930.0])
    assert reduced.added_mass_source[1:] == ("modes.json", "modes.json")
    override = build_reduced(study.replace({"reduced.coupled_freq_01": 410.0}), frequencies)
    assert override.reduced.frequency_hz[1] == pytest.approx(410.0)
    assert override.reduced.added_mass_source[1] == "reduced.coupled_freq_01"
    summary = run_spectrum(study.replace({"reduced.modes_json": str(path)}), tmp_path / "out")
    assert [row["source"] for row in summary["modes"]][1:] == ["modes.json"] * 2


def test_modes_json_from_another_operating_point_is_refused(tmp_path):
    path = fake_modes_json(tmp_path / "modes.json", paper_study(z=0.011), **{"(0,1)": 400.0})
    with pytest.raises(StudyError, match="load.z = 0.011 differs"):
        read_modes_json(path, paper_study(z=0.016))
    with pytest.raises(StudyError, match="does not exist"):
        read_modes_json(tmp_path / "missing.json")


def test_fit_material_cli_reads_the_csv_and_prints_set_options(tmp_path):
    study = paper_study()
    model = build_reduced(study).ring_model
    z = np.linspace(0.001, 0.02, 12)
    rows_z, rows_f, rows_v, rows_l = [], [], [], []
    from dataclasses import replace
    for stretch in (1.2, 1.6):
        sample = replace(model, membrane=replace(model.membrane, prestretch=stretch))
        for voltage in (0.0, 2000.0):
            rows_z.append(z)
            rows_f.append(sample.force_displacement(z, voltage))
            rows_v.append(np.full(z.size, voltage))
            rows_l.append(np.full(z.size, stretch))
    data = write_csv(tmp_path / "force.csv", ("z_m", "force_n", "voltage_v", "prestretch"),
                     [np.concatenate(c) for c in (rows_z, rows_f, rows_v, rows_l)])
    summary = fit_material_cli(study, data, tmp_path / "fit")
    assert summary["values"]["c10"] == pytest.approx(228.5e3, rel=1e-6)   # noise-free data
    assert any("--set membrane.c10=" in line for line in summary["lines"])
    assert read_rows(tmp_path / "fit" / "material_fit.csv")[0] == [
        "parameter", "value_pa", "standard_error_pa"]
    bad = tmp_path / "bad.csv"
    bad.write_text("z,F\n0.001,0.2\n")
    with pytest.raises(StudyError, match="allowed: columns z_m, force_n"):
        fit_material_cli(study, bad, tmp_path / "fit")


def test_calibrate_damping_cli_round_trip(tmp_path):
    study = paper_study(reduced__coupled_freq_01=400.0, reduced__coupled_freq_02=930.0)
    run_spectrum(study, tmp_path / "measured")
    start = study.replace({"reduced.damping_01": 100.0, "reduced.damping_02": 20.0})
    summary = calibrate_damping_cli(start, tmp_path / "measured" / "spectrum_average.csv",
                                    tmp_path / "cal")
    assert summary["damping_per_mass"]["(0,1)"] == pytest.approx(245.0, rel=1e-5)
    assert summary["damping_per_mass"]["(0,2)"] == pytest.approx(57.0, rel=1e-5)
    assert any("--set reduced.damping_01=245" in line for line in summary["lines"])
    with pytest.raises(StudyError, match="--window = 1.5"):
        calibrate_damping_cli(start, tmp_path / "measured" / "spectrum_average.csv",
                              tmp_path / "cal", window=1.5)


def test_calibrate_damping_fe_fits_need_measured_damping_before_any_work(tmp_path):
    """The reduced model sits below the FE pipeline (issue 21): ``--fit rayleigh|prony``
    runs FE solves, from :mod:`copdea_fem.damping_fit` (the API's ``calibrate_damping``);
    without measured damping it is refused before any work, naming what is allowed."""
    with pytest.raises(StudyError, match=r"--fit rayleigh needs measured damping; allowed: "
                                         r"--quality-factors Q\.csv or a SPECTRUM\.csv"):
        calibrate_damping_cli(paper_study(), None, tmp_path / "cal", fit="rayleigh")
    assert not (tmp_path / "cal").exists()


# -- study keys of the reduced model --------------------------------------------------------------
def test_reduced_and_excitation_defaults_are_the_papers():
    study = parse_study({})
    assert study.reduced.rings == 6
    assert (study.reduced.damping_p1, study.reduced.damping_01,
            study.reduced.damping_02) == (45.0, 245.0, 57.0)
    x = study.excitation
    assert (x.amplitude, x.f_start, x.f_end, x.duration, x.sample_time) == (
        100.0, 0.0, 1000.0, 0.8, 0.4e-3)
    assert reduced_mode_labels("auto", "spring") == ("P1", "(0,1)", "(0,2)")
    assert reduced_mode_labels("auto", "held") == ("(0,1)", "(0,2)")
    assert reduced_mode_labels(" p1,(0, 3)", "spring") == ("P1", "(0,3)")


@pytest.mark.parametrize("overrides, message", [
    ({"reduced.modes": "P1, (0,1)"}, "reduced.modes = 'P1, \\(0,1\\)'.*disc.motion = held"),
    ({"reduced.modes": "P2"}, "reduced.modes = 'P2'.*cannot read 'P2'"),
    ({"reduced.modes": "(0,6)"}, "reduced.rings = 6 .*allowed: >= 7"),
    ({"reduced.rings": 1}, "reduced.rings = 1 .*allowed: \\[2, 400\\]"),
    ({"reduced.damping_01": -1}, "reduced.damping_01 = -1 .*allowed: \\[0, 1e\\+06\\] 1/s"),
    ({"reduced.coupled_freq_01": "0 Hz"},
     "reduced.coupled_freq_01 = '0 Hz.*allowed: \\(0, 1e\\+06\\] Hz"),
    ({"excitation.f_end": "2 kHz"}, "excitation.f_end = 2000.0 .*Nyquist"),
    ({"excitation.duration": "801 ms"}, "excitation.duration = 0.801 .*integer multiple"),
    ({"excitation.f_start": "1 kHz"}, "excitation.f_end = 1000.0 .*> excitation.f_start"),
])
def test_bad_reduced_keys_name_key_value_and_range(overrides, message):
    with pytest.raises(StudyError, match=message):
        parse_study({}, overrides=overrides)


def test_reduced_model_needs_a_disc():
    with pytest.raises(StudyError, match="geometry.inner_radius = 0 is not allowed for the "
                                         "reduced model"):
        build_reduced(paper_study(inner=0.0, z=0.0, motion="held"))
