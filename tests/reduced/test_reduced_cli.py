"""``copdea-fem spectrum | fit-material | calibrate-damping`` through ``cli.main``."""

import numpy as np
import pytest
from reduced_helpers import DATA

from copdea_fem.cli import main
from copdea_fem.reduced.io import write_csv
from copdea_fem.reduced.model import build_reduced
from copdea_fem.study import load_study

STUDY = str(DATA / "g1_z16_2kV.yaml")


def test_spectrum_command_writes_the_contract_files(tmp_path, capsys):
    code = main(["spectrum", STUDY, "--set", "reduced.coupled_freq_01=400 Hz",
                 "--out", str(tmp_path)])
    assert code == 0
    out = capsys.readouterr().out
    assert "reduced.coupled_freq_01" in out and "Annex I" in out
    for name in ("spectrum_average.csv", "spectrum_points.csv", "reduced_modes.csv"):
        assert (tmp_path / name).is_file()


def test_spectrum_command_reports_bad_keys_with_exit_2(tmp_path, capsys):
    code = main(["spectrum", STUDY, "--set", "reduced.modes=(0,9)", "--out", str(tmp_path)])
    assert code == 2
    assert "reduced.rings = 6 is not allowed" in capsys.readouterr().err


def test_spectrum_command_reports_physics_failures_with_exit_3(tmp_path, capsys):
    code = main(["spectrum", STUDY, "--set", "reduced.coupled_freq_01=900 Hz",
                 "--out", str(tmp_path)])
    assert code == 3
    assert "coupled frequency of (0,1) = 900 Hz is not allowed" in capsys.readouterr().err


def test_calibrate_damping_command(tmp_path, capsys):
    coupled = ["--set", "reduced.coupled_freq_01=400 Hz", "--set", "reduced.coupled_freq_02=930 Hz"]
    assert main(["spectrum", STUDY, *coupled, "--out", str(tmp_path / "measured")]) == 0
    measured = str(tmp_path / "measured" / "spectrum_average.csv")
    code = main(["calibrate-damping", STUDY, measured, *coupled, "--set", "reduced.damping_01=80",
                 "--out", str(tmp_path / "cal")])
    assert code == 0
    assert "--set reduced.damping_01=245" in capsys.readouterr().out
    assert (tmp_path / "cal" / "damping_calibration.csv").is_file()
    # dry (0,2) sits at ~1054 Hz, beyond the 1 kHz band: refused with the reason
    code = main(["calibrate-damping", STUDY, measured, "--out", str(tmp_path / "cal")])
    assert code == 3
    assert "(0,2) at 1054.0 Hz is not allowed" in capsys.readouterr().err


def test_fit_material_command(tmp_path, capsys):
    model = build_reduced(load_study(STUDY)).ring_model
    z = np.tile(np.linspace(0.001, 0.02, 10), 2)
    voltage = np.repeat([0.0, 3000.0], 10)
    force = np.concatenate([model.force_displacement(z[:10], 0.0),
                            model.force_displacement(z[10:], 3000.0)])
    data = write_csv(tmp_path / "force.csv", ("z_m", "force_n", "voltage_v"), (z, force, voltage))
    code = main(["fit-material", STUDY, str(data), "--out", str(tmp_path / "fit")])
    assert code == 0
    assert "c10 =" in capsys.readouterr().out
    assert (tmp_path / "fit" / "material_fit.csv").is_file()
    missing = main(["fit-material", STUDY, str(tmp_path / "none.csv"), "--out", str(tmp_path)])
    assert missing == 2
    assert "does not exist" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["spectrum", "fit-material", "calibrate-damping"])
def test_help_lists_the_reduced_commands(command, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([command, "--help"])
    assert exit_info.value.code == 0
    assert "study" in capsys.readouterr().out
