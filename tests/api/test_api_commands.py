"""The API functions of fit-material, calibrate-damping and synth: results with their
tables, summaries and ``write``; ``out`` claimed after the checks, before any work."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import copdea_fem as cf
from copdea_fem import api
from copdea_fem.study import parse_study

ROOT = Path(__file__).resolve().parents[2]
PUMPING = ROOT / "studies" / "g1_z16_pumping.yaml"


def study_without_plots():
    return parse_study({"output": {"plots": False}}, name="fit")


def force_data(path: Path, study) -> Path:
    """Noise-free force-displacement data of the study's own ring model at 0 and 3 kV."""
    from copdea_fem.reduced.io import write_csv
    from copdea_fem.reduced.model import build_reduced
    model = build_reduced(study).ring_model
    z = np.tile(np.linspace(0.001, 0.02, 10), 2)
    voltage = np.repeat([0.0, 3000.0], 10)
    force = np.concatenate([model.force_displacement(z[:10], 0.0),
                            model.force_displacement(z[10:], 3000.0)])
    return write_csv(path, ("z_m", "force_n", "voltage_v"), (z, force, voltage))


def test_fit_material_returns_the_fit_and_writes_it_into_the_default_folder(tmp_path,
                                                                            monkeypatch):
    monkeypatch.chdir(tmp_path)
    study = study_without_plots()
    data = force_data(tmp_path / "force.csv", study)
    out = api.Output()
    result = cf.fit_material(study, data, out=out)
    assert result.values["c10"] == pytest.approx(study.membrane.c10, rel=1e-6)
    assert list(result.table.columns) == ["parameter", "value_pa", "standard_error_pa"]
    assert list(result.table["parameter"]) == ["c10", "c20", "c01"]
    assert out.path == Path(study.output.directory) and out.claim.written
    written = sorted(p.name for p in (tmp_path / out.path).iterdir())
    assert "material_fit.csv" in written and "material_fit.png" not in written
    assert any("--set membrane.c10=" in line for line in result.summary_lines())


def test_a_bad_input_is_refused_before_the_folder_is_claimed(tmp_path):
    study = study_without_plots()
    with pytest.raises(cf.StudyError, match="data file = .* is not allowed \\(does not exist\\)"):
        cf.fit_material(study, tmp_path / "none.csv", out=tmp_path / "fit")
    with pytest.raises(cf.StudyError, match="--fit modal .* needs SPECTRUM.csv"):
        cf.calibrate_damping(study, None, out=tmp_path / "cal")
    with pytest.raises(cf.StudyError, match="--relaxation-time is not allowed with --fit "
                                            "rayleigh; allowed: with --fit prony"):
        cf.calibrate_damping(study, None, fit="rayleigh", relaxation_time="1 ms",
                             out=tmp_path / "cal")
    with pytest.raises(cf.StudyError, match="--fit = 'viscous' is not allowed; allowed: one "
                                            "of modal, rayleigh, prony"):
        cf.calibrate_damping(study, None, fit="viscous", out=tmp_path / "cal")
    with pytest.raises(cf.StudyError, match="--format = 'wav' is not allowed"):
        cf.synthesise(study, file_format="wav", out=tmp_path / "synth")
    assert not list(tmp_path.iterdir())                     # no folder, no lock file


def test_calibrate_damping_gives_b_over_m_as_keys_and_a_table(tmp_path):
    study = cf.load_study(ROOT / "tests" / "reduced" / "data" / "g1_z16_2kV.yaml", {
        "output.plots": False, "reduced.coupled_freq_01": "400 Hz",
        "reduced.coupled_freq_02": "930 Hz"})
    cf.spectrum(study).write(tmp_path / "measured")
    start = study.replace({"reduced.damping_01": 100.0, "reduced.damping_02": 20.0})
    result = cf.calibrate_damping(start, tmp_path / "measured" / "spectrum_average.csv")
    assert result.fit == "modal" and result.structural is None
    assert result.keys["reduced.damping_01"] == pytest.approx(
        study.reduced.damping_01, rel=1e-5)
    assert list(result.table.columns) == ["label", "freq_hz", "measured_peak", "model_peak",
                                          "damping_per_mass"]
    assert list(result.table["label"]) == list(result.damping_per_mass)
    assert not list(tmp_path.glob("*cal*"))                 # nothing written without out
    result.write(tmp_path / "cal")
    assert (tmp_path / "cal" / "damping_calibration.csv").is_file()
    assert result.summary_lines(tmp_path / "cal") == result.summary_lines()   # names no folder


def test_synthesise_returns_the_set_and_its_write_names_what_it_wrote(tmp_path):
    study = cf.load_study(PUMPING, {"spring.mass": "0 g"})
    synthetic = cf.synthesise(study, "spring_mass", "load.z=11 mm, load.voltage=2 kV; "
                              "load.z=16 mm", ["spring_mass.mass=2.5 g"], seed=7, spectra=False)
    assert synthetic.names == ["z11_v2", "z16"] and synthetic.files == []
    assert synthetic.effects == {"spring_mass": (pytest.approx(2.5e-3),)}
    lines = synthetic.summary_lines()
    assert lines[0].startswith("2 conditions: z11_v2 (") and "seed 7" in lines[1]
    assert len(lines) == 2
    folder = synthetic.write(tmp_path / "set")
    assert sorted(path.name for path in synthetic.files) == sorted(
        path.name for path in folder.iterdir() if not path.name.startswith("."))
    last = synthetic.summary_lines(tmp_path / "set")[-1]
    assert last == (f"wrote {len(synthetic.files)} files to {tmp_path / 'set'}; diagnose "
                    f"with: copdea-fem diagnose {tmp_path / 'set' / 'measured.yaml'}")
