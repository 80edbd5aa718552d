"""studies/measured_scan_example: a vibrometer export made by the FE, read, identified, paired
by shape with the base model (correlate) and turned into the diagnosis's labelled peaks.

The export's truth is the FE coupled with the air (synth_truth.json holds its frequencies);
the base model is the same device in vacuo, whose modes lie 10-20 % higher: exactly where
pairing by frequency goes wrong and pairing by shape must not.
"""

from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

import pytest

from copdea_fem.cli import main

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "studies" / "measured_scan_example"


def _truth(label: str | None = None) -> dict:
    """The export's true modes (label -> frequency, damping ratio), or one of them."""
    modes = json.loads((EXAMPLE / "synth_truth.json").read_text())["conditions"]["z16_v2"][
        "modes"]
    return modes if label is None else modes[label]


def _truth_label(frequency_hz: float) -> str:
    """The true mode nearest a test frequency (the export's own modes, not the FE's)."""
    truth = _truth()
    return min(truth, key=lambda label: abs(truth[label]["freq_hz"] - frequency_hz))


def _same_unit(first: str, second: str) -> bool:
    from copdea_fem.vibrometer.pairing import unit_key
    return unit_key(first) == unit_key(second)


def test_the_example_is_small():
    assert sum(path.stat().st_size for path in EXAMPLE.iterdir()) < 300_000


def test_correlate_labels_the_example_by_shape(tmp_path, capsys):
    out = tmp_path / "correlate"
    assert main(["correlate", str(EXAMPLE / "measured.yaml"), "--out", str(out),
                 "--quiet"]) == 0
    captured = capsys.readouterr()
    assert "test modes paired by shape" in captured.out
    assert "cannot tell the FE's shapes apart" not in captured.err    # 34 points suffice
    with open(out / "pairs.csv", newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert list(rows[0]) == ["condition", "test_mode", "test_freq_hz", "test_damping_ratio",
                             "label", "fe_freq_hz", "freq_error", "mac", "fe_auto_mac"]
    assert len(rows) >= 3
    # a test mode may stay unpaired (below the MAC threshold on this coarse grid); a paired
    # one must be the true mode (measured: 16 of 16 paired, all right)
    paired = [row for row in rows if row["label"]]
    assert len(paired) >= 0.8 * len(rows)
    for row in paired:
        truth = _truth_label(float(row["test_freq_hz"]))
        assert _same_unit(row["label"], truth), (row, truth)
        assert 0.5 <= float(row["mac"]) <= 1.0
        assert 0 < float(row["test_damping_ratio"]) < 0.05
        # the dry base is higher than the truth in air: a positive frequency error (the air
        # barely moves an in-plane mode: its error is either sign)
        if not row["label"].startswith("ip"):
            assert float(row["freq_error"]) > 0
    first = rows[0]
    assert first["label"] == "(0,1)" and float(first["freq_error"]) > 0.1
    for name in ("comac.csv", "mac.png", "report.md"):
        assert (out / name).stat().st_size > 0
    report = (out / "report.md").read_text()
    assert "(differs)" in report          # frequency order alone would have mislabelled
    with open(out / "comac.csv", newline="") as stream:
        comac = list(csv.DictReader(stream))
    assert len(comac) == 3 * 34                 # 34 points, three directions each


def test_the_scan_becomes_labelled_peaks_with_quality_factors():
    from copdea_fem.diagnosis import load_measured
    from copdea_fem.diagnosis.scanned import pairing_report_lines, resonances_from_scans

    measured, pairings = resonances_from_scans(load_measured(EXAMPLE / "measured.yaml"))
    (condition,) = measured.conditions
    assert condition.resonances and len(pairings) == 1
    assert sum(bool(resonance.label) for resonance in condition.resonances) >= 2
    for resonance in condition.resonances:
        truth = _truth_label(resonance.frequency_hz)
        # Q = 1 / (2 zeta) as identified, against the export's truth (the study's modal
        # b/m and the radiation): within 10 % (measured: 4 % at most)
        zeta = _truth(truth)["damping_ratio"]
        assert resonance.quality_factor == pytest.approx(1 / (2 * zeta), rel=0.1)
        if not resonance.label:             # unpaired by shape: an unlabelled peak
            continue
        assert _same_unit(resonance.label, truth)
        assert resonance.kind == ("axisymmetric" if resonance.label.startswith("(0,")
                                  else "non-axisymmetric")
    text = "\n".join(pairing_report_lines(pairings))
    assert "## Shape pairing (vibrometer scans)" in text and "| MAC |" in text


def test_correlate_refuses_a_problem_above_the_size_limit_before_any_work(tmp_path,
                                                                        monkeypatch, capsys):
    """correlate guards the size of each condition's FE problem as solve does (exit 2
    naming --allow-large), before identifying anything."""
    import copdea_fem.fe.engines as engines
    import copdea_fem.vibrometer.identification as identification

    def not_reached(*args, **kwargs):
        raise AssertionError("identified before the size check")
    monkeypatch.setattr(engines, "MAX_UNKNOWNS", 10.0)
    monkeypatch.setattr(identification, "identify", not_reached)
    out = tmp_path / "pairs"
    assert main(["correlate", str(EXAMPLE / "measured.yaml"), "--out", str(out),
                 "--quiet"]) == 2
    assert "more than the limit of 10; allowed:" in capsys.readouterr().err
    assert not out.exists()


def test_a_failed_fe_solve_in_correlate_exits_3_with_one_line(tmp_path, monkeypatch, capsys,
                                                              counted):
    """correlate solves the FE as solve does: an eigen solve that fails is a SolveFailed
    (exit 3, one line: what failed, at which load, which keys to change), nothing written;
    --allow-large reaches the solve; measured.yaml and the scan are read once."""
    import copdea_fem.fe.engines as engines
    import copdea_fem.fe.pipeline as pipeline
    import copdea_fem.vibrometer.identification as identification
    from copdea_fem.fe.eigen.errors import EigenSolverError
    from copdea_fem.measured import manifest

    def fail(study, **options):
        raise EigenSolverError("the Krylov run did not converge")
    monkeypatch.setattr(engines, "MAX_UNKNOWNS", 10.0)
    monkeypatch.setattr(identification, "identify", lambda scan, **options: ())
    monkeypatch.setattr(pipeline, "run_solve", fail)
    counted(manifest, "read_yaml")
    counted(manifest, "read_scan")
    out = tmp_path / "pairs"
    assert main(["correlate", str(EXAMPLE / "measured.yaml"), "--out", str(out), "--quiet",
                 "--allow-large"]) == 3
    assert capsys.readouterr().err.splitlines() == [
        "error: the eigen solve failed at load.z = 16 mm, load.voltage = 2000 V: the Krylov "
        "run did not converge; change the band eigen.f_min..eigen.f_max, "
        "eigen.max_damping_ratio or eigen.backend"]
    assert not out.exists()
    assert counted.calls == {"read_yaml": 1, "read_scan": 1}


@pytest.mark.slow
def test_diagnose_names_air_loading_from_the_example_scan(tmp_path, capsys):
    """The whole path: scan -> identified peaks -> shape labels -> diagnosis (cold FE cache:
    about a minute on two cores)."""
    out = tmp_path / "diagnose"
    assert main(["diagnose", str(EXAMPLE / "measured.yaml"), "--out", str(out), "--quiet",
                 "--fe-cache", str(tmp_path / "cache"), "--fe-workers", "1"]) == 0
    document = json.loads((out / "diagnosis.json").read_text())
    assert document["missing_effects"] == ["air_loading"]
    assert document["gap_before"] > 5 * document["gap_after"]      # measured: 10.1 -> 0.66 %
    report = (out / "report.md").read_text()
    assert "## Shape pairing (vibrometer scans)" in report and "paired RMS error" in report
    assert math.isfinite(document["gap_after"])
    # the gap's paired part: "paired RMS error: 10.11 % -> 0.66 % over the pairs"
    found = re.search(r"paired RMS error: ([\d.]+) % -> ([\d.]+) %", report)
    assert found and float(found[1]) > 5 * float(found[2]), found


def test_the_api_gives_the_pairs_it_writes(tmp_path):
    import copdea_fem as cf

    result = cf.correlate(EXAMPLE / "measured.yaml")
    table = result.pairs
    assert list(table.columns) == ["condition", "test_mode", "test_freq_hz",
                                   "test_damping_ratio", "label", "fe_freq_hz", "freq_error",
                                   "mac", "fe_auto_mac"]
    folder = result.write(tmp_path / "pairs")
    with open(folder / "pairs.csv", newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert [row["label"] for row in rows] == list(table["label"])
    written = [float(row["mac"]) if row["mac"] else math.nan for row in rows]
    assert written == pytest.approx(list(table["mac"]), abs=1e-4, nan_ok=True)


def test_correlate_and_diagnose_pair_the_example_alike(tmp_path):
    """pairs.csv and the diagnosis report's shape-pairing table give every test mode the same
    label and the same FE frequency: one FE study, one pairing (on the 3-D engine under the
    study's square frame the members of a pair split by 0.01 %, on the diagnosis's
    axisymmetric one not at all: two solves swapped a/b and moved FE frequencies by 0.8 %)."""
    import copdea_fem as cf
    from copdea_fem.diagnosis import load_measured
    from copdea_fem.diagnosis.scanned import pairing_report_lines, resonances_from_scans

    measured = load_measured(EXAMPLE / "measured.yaml")
    folder = cf.correlate(measured).write(tmp_path / "pairs")
    with open(folder / "pairs.csv", newline="") as stream:
        written = [(row["label"], row["fe_freq_hz"]) for row in csv.DictReader(stream)]
    _, pairings = resonances_from_scans(measured)
    rows = [line.split("|") for line in pairing_report_lines(pairings)
            if re.match(r"\| \d+ \|", line)]
    reported = [(cells[4].strip(), cells[5].strip()) for cells in rows]
    assert len(written) == len(reported) >= 10
    for (label, fe_freq), (report_label, report_freq) in zip(written, reported):
        assert report_label == (label or "unpaired")
        if label:        # pairs.csv: 6 significant digits; the report: 2 decimals
            assert float(report_freq) == pytest.approx(float(fe_freq), abs=0.006)
