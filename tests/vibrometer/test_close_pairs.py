"""Close pairs told apart by their shapes (copdea_fem.vibrometer.close_pairs): closed-form
FRF sets made here, never by the identification."""

import math

import numpy as np
import pytest
from vibrometer_helpers import mac, membrane_scan, membrane_shapes, paper_grid

from copdea_fem.vibrometer.close_pairs import significant_shapes
from copdea_fem.vibrometer.identification import (
    identify_scan,
    noise_variance,
)

#: 1.25 Hz lines over 200-400 Hz (the paper's line spacing).
AXIS = np.arange(160, 321) * 1.25
#: The pair: 300 Hz and 0.5 % above, damping 1 % (half-power bandwidth 2 zeta = 2 %: the
#: split is a quarter of it, one peak on every channel), a (0,1) mode below as a neighbour.
PAIR = (300.0, 301.5)
DAMPING = 0.01


def _pair_scan(seed, pair=True, snr_db=60.0):
    modes = [((0, 1, 0.0), 240.0, 0.02, 1.0), ((1, 1, 0.0), PAIR[0], DAMPING, 1.0)]
    if pair:                                   # the other member: its shape turned by 90 deg
        modes.append(((1, 1, 0.5 * math.pi), PAIR[1], DAMPING, 0.7))
    return membrane_scan(modes, AXIS, snr_db, np.random.default_rng(seed)), modes


def test_marchenko_pastur_median_against_noise():
    """The noise variance of a pure-noise matrix from its median eigenvalue: within 3 %
    (252 x 800, the size of a paper scan; and 400 x 400, ratio 1)."""
    rng = np.random.default_rng(3)
    for rows, lines in ((252, 800), (400, 400)):
        noise = (rng.normal(size=(rows, lines)) + 1j * rng.normal(size=(rows, lines))) * 0.5
        power = np.linalg.eigvalsh(noise @ noise.conj().T)
        assert noise_variance(power, lines) == pytest.approx(0.5, rel=0.03)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_two_modes_half_a_percent_apart_both_found(seed):
    """Both members, each with its own shape (MAC >= 0.95 with the true one) and its
    frequency within a tenth of the half-power bandwidth, at 60 dB noise."""
    scan, modes = _pair_scan(seed)
    found = identify_scan(scan, resolve_pairs=True).modes
    near = [m for m in found if 290 < m.freq_hz < 310]
    assert len(near) == 2, [round(m.freq_hz, 2) for m in found]
    shapes = membrane_shapes(paper_grid(), [family for family, *_ in modes[1:]])
    for mode, shape, frequency in zip(sorted(near, key=lambda m: m.freq_hz),
                                      shapes.reshape(2, -1), PAIR):
        assert abs(mode.freq_hz - frequency) < 0.1 * 2 * DAMPING * frequency
        assert mac(mode.shape, shape) >= 0.95


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_single_mode_stays_one(seed):
    """The same set without the second member: one mode near 300 Hz (no twin from the
    shapes' test)."""
    scan, _ = _pair_scan(seed, pair=False)
    found = identify_scan(scan, resolve_pairs=True).modes
    assert len([m for m in found if 290 < m.freq_hz < 310]) == 1


def test_significant_shapes_counts_the_pair():
    """The half-power band of the pair holds one shape more above the noise than that of
    the single mode (the criterion of close_pairs, on the FRF matrix itself; the (0,1)
    neighbour's tail is one shape in both)."""
    counts = []
    for pair in (True, False):
        scan, _ = _pair_scan(0, pair=pair)
        band = np.abs(scan.frequencies - 300.75) <= 2 * DAMPING * 300.75
        values = scan.values / np.abs(scan.values).max()
        power = np.linalg.eigvalsh(values @ values.conj().T)
        counts.append(significant_shapes(values[:, band],
                                         noise_variance(power, values.shape[1])))
    assert counts[0] == counts[1] + 1


@pytest.mark.parametrize("resolve_pairs", [True, False])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_weak_member_clean_beside_an_out_of_band_tail(seed, resolve_pairs):
    """A split pair 2.7 % apart (2 zeta = 1.6 %: two peaks), its weak member at 0.15 of the
    strong one's participation, and a strong (0,2) mode 0.45 % past the band's top (1.8 Hz
    above the last line, five times the pair's participation): its tail, which the
    residues' residual terms cannot follow, stays out of the members' shapes (MAC >= 0.95
    with the true ones; without the band-edge poles in the model the weak member's MAC was
    0.11); no mode on the band's last lines (a pole inside the band may still take part
    of the tail: seed 0, 395.9 Hz)."""
    modes = [((0, 1, 0.0), 240.0, 0.02, 1.0), ((1, 1, 0.0), 300.0, 0.008, 1.0),
             ((1, 1, 0.5 * math.pi), 308.1, 0.008, 0.15), ((0, 2, 0.0), 401.8, 0.005, 5.0)]
    scan = membrane_scan(modes, AXIS, 60.0, np.random.default_rng(seed))
    found = identify_scan(scan, resolve_pairs=resolve_pairs).modes
    shapes = membrane_shapes(paper_grid(), [family for family, *_ in modes[1:3]])
    for (low, high), shape in zip(((295, 303), (303, 313)), shapes.reshape(2, -1)):
        near = [m for m in found if low < m.freq_hz < high]
        assert len(near) == 1, [round(m.freq_hz, 2) for m in found]
        assert mac(near[0].shape, shape) >= 0.95
    assert all(m.freq_hz < AXIS[-1] - 1.25 for m in found)


def test_resolve_pairs_must_be_a_bool():
    from copdea_fem.measured import MeasuredDataError

    scan, _ = _pair_scan(0, pair=False)
    with pytest.raises(MeasuredDataError, match="resolve_pairs = 'yes' is not allowed"):
        identify_scan(scan, resolve_pairs="yes")


# --- the commands: --resolve-pairs and the measured.yaml's identification.resolve_pairs ---

def _pair_measured(tmp_path, identification=None):
    import yaml
    from vibrometer_helpers import write_measured

    from copdea_fem.measured import write_scan

    scan, _ = _pair_scan(0)
    write_scan(tmp_path / "pair.uff", scan)
    path = write_measured(tmp_path, {"z16": ("pair.uff", {"load.z": "16 mm",
                                                          "load.voltage": "2 kV"})})
    if identification is not None:
        raw = yaml.safe_load(path.read_text())
        raw["identification"] = identification
        path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def _near_pair(out):
    import csv
    with open(out / "identified.csv", newline="") as handle:
        return [float(r["freq_hz"]) for r in csv.DictReader(handle)
                if 290 < float(r["freq_hz"]) < 310]


@pytest.mark.parametrize("how", ["option", "manifest"])
def test_identify_command_resolve_pairs(tmp_path, how):
    """The closed-form pair 0.5 % apart through the command, with --resolve-pairs or
    identification: {resolve_pairs: true}: both members within a tenth of the half-power
    bandwidth of their frequencies."""
    from copdea_fem.cli import main

    path = _pair_measured(tmp_path, {"resolve_pairs": True} if how == "manifest" else None)
    out = tmp_path / "out"
    argv = ["identify", str(path), "--out", str(out), "--quiet"]
    assert main(argv + (["--resolve-pairs"] if how == "option" else [])) == 0
    found = _near_pair(out)
    assert sorted(found) == pytest.approx(PAIR, abs=0.1 * 2 * DAMPING * PAIR[0])


@pytest.mark.parametrize("manifest, flag, expected", [
    (None, False, False), (None, True, True), ({"resolve_pairs": True}, False, True),
    ({"resolve_pairs": False}, True, True)])
def test_resolve_pairs_reaches_the_identification(tmp_path, monkeypatch, manifest, flag,
                                                  expected):
    """What identify_scan is given, by the command (the flag over the manifest, default
    off) and by the pairing of correlate/diagnose (condition_test_modes, the manifest's)."""
    from copdea_fem.cli import main
    from copdea_fem.diagnosis import scanned
    from copdea_fem.diagnosis.effects import MANIFEST_RULES
    from copdea_fem.measured import load_measured
    from copdea_fem.vibrometer import identification

    seen = []
    original = identification.identify_scan

    def spy(scan, **options):
        seen.append(options.get("resolve_pairs"))
        return original(scan, **{**options, "max_order": 20})

    monkeypatch.setattr(identification, "identify_scan", spy)
    monkeypatch.setattr("copdea_fem.api.measured_results.identify_scan", spy, raising=False)
    path = _pair_measured(tmp_path, manifest)
    argv = ["identify", str(path), "--out", str(tmp_path / "out"), "--quiet"]
    assert main(argv + (["--resolve-pairs"] if flag else [])) == 0
    assert bool(seen[-1]) is expected
    measured = load_measured(path, effects=MANIFEST_RULES)
    scanned.condition_test_modes(measured.conditions[0], resolve_pairs=bool(
        measured.identification.get("resolve_pairs", False)))
    assert bool(seen[-1]) is bool((manifest or {}).get("resolve_pairs", False))


@pytest.mark.parametrize("value, message", [
    ({"resolve_pairs": "yes"}, "identification.resolve_pairs"),
    ({"split": True}, "identification.split"),
    ("on", "identification")])
def test_identification_key_refused(tmp_path, capsys, value, message):
    from copdea_fem.cli import main

    path = _pair_measured(tmp_path, value)
    assert main(["identify", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err and "allowed" in err and len(err.strip().splitlines()) == 1
