"""Automatic modal identification of scans: analytic FRFs, a real beam, the command."""

import csv
import math

import numpy as np
import pytest
from vibrometer_helpers import (
    BASE_STUDY,
    REALDATA,
    mac,
    make_scan,
    membrane_scan,
    membrane_shapes,
    paper_grid,
    pole,
    write_measured,
)

from copdea_fem import api
from copdea_fem.cli import main
from copdea_fem.measured import MeasuredDataError, ScanData, write_scan
from copdea_fem.measured.uff import read_functions
from copdea_fem.study import StudyError
from copdea_fem.vibrometer.identification import identify, identify_scan, modal_phase_collinearity

#: (m, n, orientation) families and their (frequency [Hz], damping ratio): the (1,1) pair
#: split by 1 % with damping 1 % - a half-power width of 2 % - so that the sum of the FRFs
#: has one peak where there are two modes
MODES = [((0, 1, 0.0), (95.0, 0.02)), ((1, 1, 0.0), (300.0, 0.01)),
         ((1, 1, 0.5 * math.pi), (303.0, 0.01)), ((2, 1, 0.3), (455.0, 0.012)),
         ((0, 2, 0.0), (610.0, 0.015)), ((3, 1, 1.0), (820.0, 0.01))]
FREQUENCIES = np.arange(801) * 1.25          # the paper's 0-1000 Hz chirp at 1.25 Hz


def _analytic_scan(noise=0.0, seed=0):
    positions = paper_grid()
    shapes = membrane_shapes(positions, [family for family, _ in MODES])
    poles = [pole(f, zeta) for _, (f, zeta) in MODES]
    scan = make_scan(FREQUENCIES, poles, shapes, positions)
    if noise:
        rng = np.random.default_rng(seed)
        size = noise * np.abs(scan.values).max()
        values = scan.values + size * (rng.normal(size=scan.values.shape)
                                       + 1j * rng.normal(size=scan.values.shape))
        scan = ScanData(**{**scan.__dict__, "values": values})
    return scan, shapes.reshape(len(MODES), -1)


def test_split_pair_is_one_peak_of_the_sum():
    """The premise: a peak search on the summed FRF sees one mode near 300 Hz."""
    scan, _ = _analytic_scan()
    total = np.abs(scan.values).sum(axis=0)
    band = (FREQUENCIES > 280) & (FREQUENCIES < 325)
    inner = total[band]
    peaks = np.flatnonzero((inner[1:-1] > inner[:-2]) & (inner[1:-1] > inner[2:]))
    assert peaks.size == 1


@pytest.mark.parametrize("noise", [0.0, 1e-3])
def test_analytic_modes_identified(noise):
    """Every mode, the split pair too, and nothing else: frequency within a tenth of its
    half-power width (0.1 x 2 zeta f: a tenth of the pair's spacing), damping within 10 %,
    shape MAC >= 0.99 against the true residues, MPC >= 0.99 (normal modes).  The noise is
    60 dB below the largest FRF value (1e-3, complex Gaussian per line); with it the MPC
    bound is 0.95: the split pair's residues are fitted from overlapping resonances, which
    amplifies the noise in their imaginary parts (0.989 seen), still far from the MPC of
    complex modes (spread phases: 0 to 0.5)."""
    scan, shapes = _analytic_scan(noise)
    modes = identify(scan)
    assert len(modes) == len(MODES)
    for mode, (_, (frequency, damping)), shape in zip(modes, MODES, shapes):
        assert abs(mode.freq_hz - frequency) <= 0.1 * 2 * damping * frequency
        assert mode.damping_ratio == pytest.approx(damping, rel=0.1)
        assert mac(mode.shape, shape) >= 0.99
        assert mode.mpc >= (0.99 if noise == 0 else 0.95)
    assert [m.test_mode for m in modes] == list(range(1, len(MODES) + 1))


def test_diagram_records_the_choice():
    result = identify_scan(_analytic_scan()[0], max_order=40)
    diagram = result.diagram
    assert list(diagram.orders) == list(range(2, 41, 2))
    assert len(diagram.status) == len(diagram.orders) == len(diagram.frequencies)
    assert diagram.chosen.shape == (len(result.modes), 2)


def test_mpc_closed_forms():
    """MPC: 1 for a real vector (any common phase), 0 for components in quadrature of equal
    weight (the 2 x 2 matrix is isotropic)."""
    real = np.array([1.0, -2.0, 0.5])
    assert modal_phase_collinearity(real * np.exp(0.7j)) == pytest.approx(1.0)
    assert modal_phase_collinearity(np.array([1.0, 1j])) == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("options, message", [({"max_order": 3}, "max_order"),
                                              ({"f_min": 2000.0}, "f_min"),
                                              ({"frequency_tolerance": -1.0},
                                               "frequency_tolerance")])
def test_bad_options(options, message):
    with pytest.raises(MeasuredDataError, match=message):
        identify(_analytic_scan()[0], **options)


#: the free-free beam's peaks (the folder's README: maxima of |H| on the 1 Hz grid)
BEAM_PEAKS = [52.0, 142.0, 279.0, 460.0, 687.0, 959.0]


@pytest.mark.skipif(not (REALDATA / "pyuff_meas_frf_3pt").is_dir(),
                    reason="real FRFs not present")
def test_real_beam_frfs():
    """Three measured accelerances of a free-free beam (roving hammer, one accelerometer:
    by reciprocity a three-point scan).  Each peak found within 0.5 % - or half a line,
    where the peak's own bin can lie: the resonance between 51 and 52 Hz has |H| 7.8 and
    8.4 there, so "52" is only known to +-0.5 Hz (1 %)."""
    records = read_functions(REALDATA / "pyuff_meas_frf_3pt" / "measurement_e2089be.uff")
    assert [r.response for r in records] == ["acceleration"] * 3
    scan = ScanData(path=REALDATA, nodes=np.array([r.reference_node for r in records]),
                    positions=np.zeros((3, 3)), channel_point=np.arange(3),
                    channel_direction=np.tile([1.0, 0.0, 0.0], (3, 1)),
                    frequencies=records[0].abscissa,
                    values=np.array([r.values for r in records]), response="acceleration")
    modes = identify(scan)
    assert len(modes) == len(BEAM_PEAKS)
    step = scan.frequencies[1] - scan.frequencies[0]
    for mode, peak in zip(modes, BEAM_PEAKS):
        assert abs(mode.freq_hz - peak) <= max(0.005 * peak, 0.5 * step)
        assert 0 < mode.damping_ratio < 0.01 and mode.mpc > 0.9


# --- the command ----------------------------------------------------------------------------

def _measured(tmp_path, scans=("z16",)):
    scan, _ = _analytic_scan()
    small = ScanData(**{**scan.__dict__, "values": scan.values[:, :401],
                        "frequencies": scan.frequencies[:401]})      # 0-500 Hz: 4 modes
    files = {}
    for name in scans:
        write_scan(tmp_path / f"{name}.uff", small)
        files[name] = (f"{name}.uff", {"load.z": "16 mm", "load.voltage": "2 kV"})
    return write_measured(tmp_path, files)


def test_identify_command_writes_its_files(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["identify", str(_measured(tmp_path)), "--out", str(out), "--quiet"]) == 0
    with open(out / "identified.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert list(rows[0]) == ["condition", "test_mode", "freq_hz", "damping_ratio", "mpc"]
    expected = [f for _, (f, _) in MODES if f < 500]
    assert [float(r["freq_hz"]) for r in rows] == pytest.approx(expected, rel=1e-3)
    assert (out / "stabilisation_z16.png").stat().st_size > 10_000
    files = sorted((out / "shapes_z16").glob("*.vtu"))
    assert len(files) == len(expected) and (out / "shapes_z16" / "shapes.pvd").exists()
    import meshio
    mesh = meshio.read(files[0])
    assert mesh.points.shape == (84, 3) and mesh.cells[0].type == "triangle"
    assert mesh.point_data["shape_real"].shape == (84, 3)
    assert "z16: 4 modes" in capsys.readouterr().out


def test_identify_command_bad_file_exit_2(tmp_path, capsys):
    path = _measured(tmp_path)
    (tmp_path / "z16.uff").write_text("not a UFF file\n")
    out = tmp_path / "out"
    assert main(["identify", str(path), "--out", str(out), "--quiet"]) == 2
    error = capsys.readouterr().err
    assert "z16.uff" in error and "dataset" in error and "Traceback" not in error
    assert not out.exists()


def test_identify_command_without_scan_exit_2(tmp_path, capsys):
    path = tmp_path / "measured.yaml"
    (tmp_path / "r.csv").write_text("freq_hz\n100\n")
    path.write_text(f"base_study: {BASE_STUDY}\nconditions:\n- name: a\n  resonances: r.csv\n")
    assert main(["identify", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "no condition has a scan" in capsys.readouterr().err


def test_identify_reads_the_manifest_and_each_scan_once(tmp_path, counted):
    """The command loads measured.yaml once and gives the API the loaded set: no file is
    read twice (the manifest once, each condition's scan once)."""
    from copdea_fem.measured import manifest
    path = _measured(tmp_path, ("a", "b"))
    counted(manifest, "read_yaml")
    counted(manifest, "read_scan")
    assert main(["identify", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    assert counted.calls == {"read_yaml": 1, "read_scan": 2}
    counted.calls.clear()
    loaded = api.load_measured(path)
    assert list(api.identify(loaded).table["condition"].unique()) == ["a", "b"]
    assert counted.calls == {"read_yaml": 1, "read_scan": 2}       # by load_measured alone


def test_api_identify(tmp_path):
    result = api.identify(_measured(tmp_path, ("a", "b")))
    assert list(result.table["condition"].unique()) == ["a", "b"]
    with pytest.raises(StudyError, match="identify option 'order'"):
        api.identify(_measured(tmp_path), order=3)


def test_dense_spectrum_with_two_split_pairs():
    """22 modes spread over 120-980 Hz plus two split pairs (0.8 % and 0.6 % apart, at
    1-2 % damping), random shapes, 60 dB noise: every mode found, none extra, each within
    0.2 % (a tenth of the smallest half-power width, 2 %)."""
    rng = np.random.default_rng(2)
    frequencies = np.sort(rng.uniform(120, 980, 22))
    frequencies = np.sort(np.concatenate([frequencies, [frequencies[5] * 1.008,
                                                        frequencies[12] * 1.006]]))
    poles = [pole(f, 0.01 + 0.01 * rng.random()) for f in frequencies]
    scan = make_scan(FREQUENCIES, poles, rng.normal(size=(len(poles), 84, 3)), paper_grid())
    size = 1e-3 * np.abs(scan.values).max()
    noisy = scan.values + size * (rng.normal(size=scan.values.shape)
                                  + 1j * rng.normal(size=scan.values.shape))
    modes = identify(ScanData(**{**scan.__dict__, "values": noisy}))
    found = np.array([m.freq_hz for m in modes])
    assert found.size == frequencies.size
    assert np.all(np.abs(found - frequencies) <= 0.002 * frequencies)


def test_identify_command_bad_option_exit_2(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["identify", str(_measured(tmp_path)), "--out", str(out),
                 "--max-order", "2"]) == 2
    assert "identify max_order = 2 is not allowed" in capsys.readouterr().err
    assert not out.exists()


def test_condition_band_is_the_identification_band(tmp_path):
    """band: [200 Hz, 500 Hz] leaves out the 95 Hz mode."""
    path = _measured(tmp_path)
    text = path.read_text().replace("scan: z16.uff", "scan: z16.uff\n  band: [200 Hz, 500 Hz]")
    path.write_text(text)
    frequencies = [m.freq_hz for m in api.identify(path).sets[0].modes]
    assert frequencies == pytest.approx([300.0, 303.0, 455.0], rel=1e-3)


def test_short_scan_limits_the_order():
    """41 lines (0-50 Hz) cannot carry order 120 (LSCF needs order <= lines - 2): the order
    is limited and the mode still found."""
    positions = paper_grid()
    scan = make_scan(np.arange(41) * 1.25, [pole(20.0, 0.05)],
                     membrane_shapes(positions, [(0, 1, 0.0)]), positions)
    (mode,) = identify(scan)
    assert mode.freq_hz == pytest.approx(20.0, rel=0.01)


def test_noise_alone_gives_no_mode():
    """Complex Gaussian noise on 252 channels x 801 lines: no pole stays stable over the
    orders, so no mode is reported (the choice does not invent modes)."""
    rng = np.random.default_rng(0)
    scan, _ = _analytic_scan()
    noise = rng.normal(size=scan.values.shape) + 1j * rng.normal(size=scan.values.shape)
    assert identify(ScanData(**{**scan.__dict__, "values": noise})) == ()


def _dry_cluster(seed, snr_db=60.0):
    """The dry membrane's dense family: (0,1), (1,1), (2,1) 2.5 % apart (5 % in all) at 1 %
    damping - each gap 1.25 half-power widths - the m >= 1 modes driven by imperfections
    only (participation 0.3 x LogNormal(0, 1/2) of the axisymmetric mode's, as
    synth_scan's exports), at random orientations, among two isolated modes; 150-850 Hz
    at 2.5 Hz lines (the battery's exports)."""
    rng = np.random.default_rng(seed)
    base = rng.uniform(380, 420)
    modes = [((0, 2, 0.0), 200.0, 0.015, 1.0), ((1, 2, 0.4), 650.0, 0.01, 0.5)]
    modes += [((m, 1, rng.uniform(0, 2 * math.pi)), base * (1 + 0.025 * m), 0.01,
               1.0 if m == 0 else 0.3 * math.exp(rng.normal(0, 0.5))) for m in range(3)]
    modes.sort(key=lambda mode: mode[1])
    scan = membrane_scan(modes, np.arange(150, 850.1, 2.5), snr_db, rng)
    return scan, np.array([mode[1] for mode in modes]), np.array([mode[2] for mode in modes])


def test_dense_cluster_every_mode_found():
    """Every mode of the dry cluster found on at least 9 of 10 seeds (before the pole
    refinement: on none, the (1,1) in the middle missed), within a quarter of a line
    (0.625 Hz, 0.15 % - a tenth of the 2.5 % gaps) and its damping within 20 %; and not
    one mode more."""
    complete = 0
    for seed in range(10):
        scan, frequencies, dampings = _dry_cluster(seed)
        modes = identify(scan)
        found = np.array([m.freq_hz for m in modes])
        if found.size != frequencies.size:
            continue
        damping = np.array([m.damping_ratio for m in modes])
        complete += bool(np.all(np.abs(found - frequencies) <= 0.25 * 2.5)
                         and np.all(np.abs(damping / dampings - 1) <= 0.2))
    assert complete >= 9


def test_dense_cluster_clean_exact():
    """Without noise the fit is exact: the cluster's poles to 1e-6, nothing spurious (the
    modes added are bounded by the data's energy, not by round-off)."""
    scan, frequencies, dampings = _dry_cluster(0, snr_db=math.inf)
    modes = identify(scan)
    assert [m.freq_hz for m in modes] == pytest.approx(frequencies, rel=1e-6)
    assert [m.damping_ratio for m in modes] == pytest.approx(dampings, rel=1e-4)
