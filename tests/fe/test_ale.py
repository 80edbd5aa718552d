"""ALE air-mesh motion (copdea_fem.fe.ale): boundary data, no inversion, clear failures."""

from pathlib import Path

import ngsolve as ngs
import numpy as np
import pytest

from copdea_fem.fe import engine_for
from copdea_fem.fe.ale import MIN_JACOBIAN, MeshMotionError, air_mesh_displacement, check_jacobian
from copdea_fem.fe.pipeline import prepare_mesh
from copdea_fem.fe.prestress import solve_prestress
from copdea_fem.study import StudyError, parse_study

R_O, R_I, Z = 0.0355, 0.017, 0.016
COARSE_AIR = {"membrane_size": "9 mm", "order": 2, "pressure_order": 1, "air_size": "35.5 mm"}


@pytest.fixture(scope="module")
def moved():
    study = parse_study({"air": {"enabled": True}, "mesh": dict(COARSE_AIR),
                         "load": {"z": Z, "voltage": "2 kV"}}, name="ale-test")
    mesh = prepare_mesh(study, with_air=True, engine=engine_for(study))
    state = solve_prestress(study, mesh)
    return mesh, state, air_mesh_displacement(state, mesh, study.air.domain_radius)


def _on_plane(mesh, radii, angles=(0.2, 0.8, 1.4)):     # the default air mesh is a quadrant
    xs = [r * np.cos(a) for r in radii for a in angles]
    ys = [r * np.sin(a) for r in radii for a in angles]
    return mesh(np.array(xs), np.array(ys), np.zeros(len(xs)), ngs.BND)


def test_motion_carries_the_boundary_data(moved):
    mesh, state, motion = moved
    disc = np.asarray(motion(_on_plane(mesh, [0.3 * R_I, 0.8 * R_I])))
    np.testing.assert_allclose(disc, np.tile([0, 0, Z], (len(disc), 1)), atol=1e-9 * Z)
    frame = np.asarray(motion(_on_plane(mesh, [1.05 * R_O, 1.1 * R_O])))
    np.testing.assert_allclose(frame, 0, atol=1e-9 * Z)
    on_membrane = _on_plane(mesh, np.linspace(R_I, R_O, 7)[1:-1])
    np.testing.assert_allclose(np.asarray(motion(on_membrane)),
                               np.asarray(state.displacement(on_membrane)), atol=1e-6 * Z)


def test_air_keeps_its_order_along_vertical_lines(moved):
    """zeta -> zeta + D_z is increasing above and below the membrane: no overlap."""
    mesh, _, motion = moved
    for radius in (0.5 * R_I, 0.5 * (R_I + R_O), 0.98 * R_O):
        heights = np.concatenate([np.linspace(-0.06, -1e-4, 40), np.linspace(1e-4, 0.06, 40)])
        points = mesh(np.full(heights.size, radius), np.zeros(heights.size), heights)
        moved_heights = heights + np.asarray(motion(points))[:, 2]
        assert np.all(np.diff(moved_heights[:40]) > 0) and np.all(np.diff(moved_heights[40:]) > 0)
    assert check_jacobian(mesh, motion) > MIN_JACOBIAN


def test_inverting_motion_stops_with_what_to_change(moved):
    mesh, _, motion = moved
    inverted = ngs.GridFunction(motion.space)
    inverted.vec.data = 6.0 * motion.vec      # a 96 mm lift through a 62 mm decay height
    with pytest.raises(MeshMotionError) as caught:
        check_jacobian(mesh, inverted)
    message = str(caught.value)
    assert "inverted" in message and "det(I + Grad D)" in message
    assert "mesh.membrane_size" in message and "load.z" in message


def test_lift_beyond_the_decay_height_is_rejected_before_meshing(tmp_path, capsys):
    from copdea_fem.cli import main
    from copdea_fem.fe.pipeline import coupled_modes
    study = parse_study({"air": {"enabled": True}, "load": {"z": "30 mm"}})
    with pytest.raises(StudyError, match=r"load.z = 0.03 is not allowed \(raise air.domain_radius"):
        coupled_modes(study, mesh=object(), engine=engine_for(study))     # never reaches the mesh
    out = tmp_path / "run"
    quick = Path(__file__).resolve().parents[2] / "studies" / "g1_z16_v2_quick.yaml"
    assert main(["solve", str(quick), "--set", "load.z=30 mm",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "0.45 L for the coupled step" in err and "meshing" not in err and not out.exists()
    # the reduced model does not move the air: the same study is fine there
    from copdea_fem.reduced.model import build_reduced
    setup = build_reduced(study.replace({"disc.motion": "spring"}))
    assert setup.linearisation.equilibrium.disc_position == pytest.approx(0.03)
    assert len(setup.pumping_frequency_hz) == 3 and np.all(setup.pumping_frequency_hz > 0)
