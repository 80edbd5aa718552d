"""Close pairs on an FE-made scan: the identification against the FE's own split members
(frequencies and orientations from an independent ``solve``), never against itself."""

from pathlib import Path

import numpy as np
import pytest

import copdea_fem as cf

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "studies/g1_z16_v2_quick.yaml"


@pytest.mark.slow
def test_fe_made_scan_of_an_anisotropic_device_gives_both_members_and_their_axes():
    """synth --format uff of G1 (coupled, coarse, z = 16 mm, 2 kV) with 2 % anisotropy along
    30 deg, 60 dB noise, no frequency scatter, 1.25-1000 Hz (some 45 modes; without ``resolve_pairs`` the weak (1,1)a is missed): with ``resolve_pairs`` the
    identification finds both (1,1) members (2.8 % apart; the weak one 20 dB below its
    partner) within a tenth of their half-power bandwidth (2 zeta f ~ 7 Hz) of the solve's
    frequencies, and each member's antinode line (order-1 part of its axial shape,
    :func:`copdea_fem.diagnosis.imperfections.shape_orientation`) within 10 deg of the
    solve's ``orientation_deg``."""
    from copdea_fem.diagnosis.imperfections import shape_orientation
    from copdea_fem.diagnosis.synth_scan import ScanOptions
    from copdea_fem.vibrometer.identification import identify

    study = cf.load_study(QUICK, {"membrane.prestretch_anisotropy": 0.02,
                                  "membrane.prestretch_axis": "30 deg",
                                  "eigen.f_max": "1000 Hz", "output.plots": False})
    fe = cf.solve(study).modes.set_index("label")
    data = cf.synthesise(study, conditions="load.z=16 mm", file_format="uff",
                         options=ScanOptions(frequency_noise=0.0, seed=1))
    scan = data.conditions[0].scan
    modes = identify(scan, f_min=2.5, f_max=1000.0, resolve_pairs=True)
    axial = np.flatnonzero(np.abs(scan.channel_direction[:, 2]) > 0.9)
    points = scan.positions[scan.channel_point[axial]]
    for label in ("(1,1)a", "(1,1)b"):
        expected = fe.loc[label, "freq_hz"]
        mode = min(modes, key=lambda m: abs(m.freq_hz - expected))
        angle = shape_orientation(mode.shape[axial], points[:, 0], points[:, 1], 1)
        print(f"{label}: FE {expected:.2f} Hz at {fe.loc[label, 'orientation_deg']:.1f} deg; "
              f"identified {mode.freq_hz:.2f} Hz at {angle:.1f} deg (MPC {mode.mpc:.2f})")
        assert abs(mode.freq_hz - expected) < 0.1 * 2 * mode.damping_ratio * expected, label
        error = (angle - fe.loc[label, "orientation_deg"] + 90.0) % 180.0 - 90.0
        assert abs(error) < 10.0, label
