"""The CLI contract: subcommands, files, columns, exit codes and messages."""

import csv
import json
from pathlib import Path

import meshio
import numpy as np
import pytest
import yaml

from copdea_fem.cli import main
from copdea_fem.fe import engine_for

ROOT = Path(__file__).resolve().parent.parent
COARSE = ["--set", "mesh.membrane_size=6 mm", "--set", "mesh.order=2", "--quiet"]


def test_solve_writes_the_contracted_files(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["solve", str(ROOT / "studies/g1_z16_v2.yaml"), "--out", str(out),
                 "--set", "eigen.f_max=600 Hz", "--set", "air.enabled=false", *COARSE])
    assert code == 0
    printed = capsys.readouterr().out
    assert "(0,1)" in printed and "disc force" in printed
    for name in ("modes.csv", "modes.json", "study.resolved.yaml", "prestress.vtu",
                 "modes.pvd", "modes.png"):
        assert (out / name).is_file(), name
    rows = list(csv.DictReader(open(out / "modes.csv")))
    assert {"label", "m", "n", "kind", "freq_hz", "freq_im_hz", "dry_freq_hz",
            "added_mass_ratio"} <= set(rows[0])
    assert rows[0]["label"] == "(0,1)" and rows[0]["kind"] == "out-of-plane"
    assert [float(r["freq_hz"]) for r in rows] == sorted(float(r["freq_hz"]) for r in rows)
    document = json.loads((out / "modes.json").read_text())
    assert document["study"]["load"]["z"] == pytest.approx(0.016)
    assert document["prestress"]["disc_force_n"] > 0
    resolved = yaml.safe_load((out / "study.resolved.yaml").read_text())
    assert resolved["mesh"]["order"] == 2 and "ngsolve" in resolved["provenance"]
    vtus = sorted(out.glob("mode_*.vtu"))
    assert len(vtus) == len(rows)
    assert all(v.name in (out / "modes.pvd").read_text() for v in vtus)
    assert not list(tmp_path.glob(".run.*")), "staging directory left behind"


def test_vtu_round_trip_matches_what_was_written(tmp_path):
    import ngsolve as ngs

    from copdea_fem.fe.pipeline import prepare_mesh
    from copdea_fem.fe.quadrant.fields import MembraneSampler
    from copdea_fem.study import parse_study
    from copdea_fem.vtu import write_membrane_vtu

    study = parse_study({"mesh": {"membrane_size": "6 mm"}})
    mesh = prepare_mesh(study, with_air=False, engine=engine_for(study))
    sampler = MembraneSampler(mesh, subdivision=2)
    radial = ngs.sqrt(ngs.x**2 + ngs.y**2)
    path = write_membrane_vtu(tmp_path / "f", sampler,
                              {"radius": radial, "vector": ngs.CF((ngs.x, 2 * ngs.y, 0))})
    back = meshio.read(path)
    np.testing.assert_allclose(back.point_data["radius"], np.hypot(*back.points[:, :2].T),
                               rtol=1e-12)
    np.testing.assert_allclose(back.point_data["vector"][:, 1], 2 * back.points[:, 1], atol=1e-15)
    radii = np.hypot(*back.points[:, :2].T)
    # the order-3 curved rims approximate the circles to ~1e-4 on a 6 mm mesh
    assert radii.min() == pytest.approx(0.017, rel=1e-3)
    assert radii.max() == pytest.approx(0.0355, rel=1e-3)


@pytest.mark.parametrize("argv, fragment", [
    (["--set", "load.voltage=3 m"], "load.voltage = '3 m' is not allowed (wrong unit"),
    (["--set", "geometry.inner_radius=40 mm"], "geometry.inner_radius = 0.04 is not allowed"),
    (["--set", "load.volts=3"], "load.volts = 3 is not allowed (unknown key)"),
    (["--set", "load.voltage"], "SECTION.KEY=VALUE"),
])
def test_bad_input_exits_2_with_message_and_writes_nothing(tmp_path, capsys, argv, fragment):
    out = tmp_path / "run"
    code = main(["solve", str(ROOT / "studies/g1_z16_v2.yaml"), "--out", str(out), *argv])
    assert code == 2
    assert fragment in capsys.readouterr().err
    assert not out.exists() and not list(tmp_path.iterdir())


def test_failed_solve_exits_3_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["solve", str(ROOT / "studies/g1_z00_v2.yaml"), "--out", str(out),
                 "--set", "load.voltage=9 kV", *COARSE])
    assert code == 3
    assert "loss of tension" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_check_and_schema(capsys):
    assert main(["check", str(ROOT / "studies/g2_z16_v2.yaml")]) == 0
    assert "valid study" in capsys.readouterr().out
    assert main(["schema"]) == 0
    assert "`load.voltage`" in capsys.readouterr().out


def test_force_writes_curves(tmp_path, capsys):
    out = tmp_path / "force"
    code = main(["force", str(ROOT / "studies/g1_z16_v2.yaml"), "--out", str(out),
                 "--voltages", "0 kV, 3 kV", "--z-max", "12 mm", "--points", "4", *COARSE])
    assert code == 0
    rows = list(csv.DictReader(open(out / "force_displacement.csv")))
    assert len(rows) == 6 and set(rows[0]) == {"voltage_v", "z_m", "force_n"}
    assert (out / "force_displacement.png").is_file()
    assert main(["force", str(ROOT / "studies/g1_z16_v2.yaml"), "--voltages", "3 parsecs"]) == 2


COARSE_AIR = ["--set", "mesh.membrane_size=9 mm", "--set", "mesh.pressure_order=1",
              "--set", "mesh.air_size=35.5 mm"]


@pytest.mark.parametrize("path", sorted((ROOT / "studies").glob("*.yaml")), ids=lambda p: p.name)
def test_every_bundled_study_solves_on_a_coarse_mesh(path, tmp_path):
    from copdea_fem.study import load_study
    coarse = COARSE_AIR if load_study(path).air.enabled else []
    code = main(["solve", str(path), "--out", str(tmp_path / "r"), "--set", "eigen.f_max=450 Hz",
                 "--set", "output.paraview=false", "--set", "output.plots=false", *COARSE,
                 *coarse])
    assert code == 0
    assert (tmp_path / "r" / "modes.csv").is_file()
