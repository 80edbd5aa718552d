"""``copdea-fem diagnose | synth | effects`` through ``cli.main``: the file contract,
the bundled example, synthetic data, and bad input."""

import json
import math
from pathlib import Path

import pytest
import yaml

from copdea_fem.cli import main
from copdea_fem.diagnosis import load_measured
from copdea_fem.study import load_study

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "studies" / "measured_example" / "measured.yaml"
STUDY = ROOT / "studies" / "g1_z16_pumping.yaml"


def test_diagnose_the_bundled_example_writes_the_contract(tmp_path, capsys):
    out = tmp_path / "report"
    assert main(["diagnose", str(EXAMPLE), "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "missing: spring_mass, air_loading" in printed
    document = json.loads((out / "diagnosis.json").read_text())
    for key in ("missing_effects", "ambiguous", "gap_before", "gap_after", "history"):
        assert key in document
    assert document["missing_effects"] == ["spring_mass", "air_loading"]
    assert document["ambiguous"] == []
    assert document["gap_before"] > 5 * document["gap_after"]
    assert [h["step"] for h in document["history"]][:3] == [0, 1, 2]
    assert document["history"][1]["effects"] == ["spring_mass"]
    assert "frame_reflection" in document["not_tested"]            # never silently skipped
    for name in ("report.md", "gap_history.png", "frequencies.png", "final_study.yaml",
                 "spectra_z16_v2.png"):
        assert (out / name).is_file(), name
    report = (out / "report.md").read_text()
    assert "frame_reflection" in report and "coupled air/PML FE" in report
    # the final model reruns as an ordinary study, with the fitted effects in it
    final = load_study(out / "final_study.yaml")
    assert final.spring.mass == pytest.approx(
        document["final_state"][0]["parameters"]["mass"])
    assert final.effects.air_added_mass == "incompressible"
    assert main(["spectrum", str(out / "final_study.yaml"), "--set", "load.z=11 mm",
                 "--out", str(tmp_path / "rerun")]) == 0


def test_diagnose_reads_each_measured_file_once(tmp_path, monkeypatch, capsys, counted):
    """The command loads measured.yaml once and gives the API the loaded set: the manifest
    and every CSV it names are read once (the run stops where the search would start)."""
    from copdea_fem.diagnosis.select import Diagnoser
    from copdea_fem.measured import manifest
    from copdea_fem.reduced.rings import ReducedModelError

    def stop(self):
        raise ReducedModelError("stopped after loading")
    monkeypatch.setattr(Diagnoser, "run", stop)
    for name in ("read_yaml", "read_resonances", "read_spectrum"):
        counted(manifest, name)
    conditions = yaml.safe_load(EXAMPLE.read_text())["conditions"]
    assert main(["diagnose", str(EXAMPLE), "--out", str(tmp_path / "report"), "--quiet"]) == 3
    assert "stopped after loading" in capsys.readouterr().err
    assert counted.calls == {"read_yaml": 1,
                             "read_resonances": sum("resonances" in c for c in conditions),
                             "read_spectrum": sum("spectrum" in c for c in conditions)}


def test_the_example_files_follow_the_documented_formats():
    measured = load_measured(EXAMPLE)
    assert measured.name == "measured_example" and len(measured.conditions) == 5
    for condition in measured.conditions:
        assert condition.resonances and condition.spectrum is not None
        assert condition.spectrum.frequency_hz[0] == pytest.approx(1.25)


def test_synth_writes_a_ready_measured_set_and_is_reproducible(tmp_path, capsys):
    args = ["synth", str(STUDY), "--set", "spring.mass=0", "--effects", "spring_mass",
            "--param", "spring_mass.mass=2.5 g", "--conditions",
            "load.z=11 mm, load.voltage=2 kV; load.z=16 mm", "--seed", "7", "--no-spectra"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    assert main([*args, "--out", str(tmp_path / "b")]) == 0
    assert "wrote" in capsys.readouterr().out
    first, second = tmp_path / "a", tmp_path / "b"
    for name in ("measured.yaml", "z11_v2_resonances.csv", "z16_resonances.csv"):
        assert (first / name).read_text() == (second / name).read_text()
    truth = json.loads((first / "synth_truth.json").read_text())
    assert truth["effects"] == {"spring_mass": [pytest.approx(2.5e-3)]}
    measured = load_measured(first / "measured.yaml")
    assert measured.base_study.spring.mass == 0.0            # the base lacks the effect
    assert [c.name for c in measured.conditions] == ["z11_v2", "z16"]
    kinds = [r.kind for r in measured.conditions[1].resonances]
    assert kinds.count("pumping") >= 2                              # P2, P3 are in the data


def test_synth_scatter_has_the_requested_size(tmp_path):
    """Frequency noise: ln(f_meas/f_true) over many modes has the requested sigma."""
    from copdea_fem.diagnosis.synth import SynthOptions, synthesise
    from copdea_fem.study import parse_study
    study = parse_study({"disc": {"motion": "spring"}})
    conditions = [{"load.z": f"{z} mm", "load.voltage": f"{v} kV"} for z in (8, 11, 14, 16, 18)
                  for v in (1, 2, 3)]
    items = synthesise(study, {}, conditions, SynthOptions(seed=5, frequency_noise=0.02,
                                                           spurious=0, spectra=False))
    errors = [math.log(item.truth["perturbed"][label] / item.truth["modes"][label])
              for item in items for label in ("(0,1)", "P1")]
    mean = sum(errors) / len(errors)
    sigma = math.sqrt(sum((e - mean) ** 2 for e in errors) / (len(errors) - 1))
    assert 0.014 < sigma < 0.027           # 30 draws: sigma within +-35 % (chi2, 99.9 %)
    dropped = sum(len(item.truth["missing"]) for item in items)
    assert 0 < dropped < 0.3 * sum(len(item.truth["modes"]) for item in items)


@pytest.mark.parametrize("argv, fragment", [
    (["synth", str(STUDY), "--effects", "acoustics"],
     "--effects = 'acoustics' is not allowed (unknown effect); allowed: air_loading"),
    (["synth", str(STUDY), "--effects", "frame_reflection"],
     "needs the coupled FE engine"),
    (["synth", str(STUDY), "--effects", "air_loading", "--param", "air_loading.size=2"],
     "(unknown parameter); allowed: scale of air_loading"),
    (["synth", str(STUDY), "--conditions", "load.z 11 mm"], "SECTION.KEY=VALUE pairs"),
    (["synth", str(STUDY), "--missing", "1.5"], "--missing-probability = 1.5 is not allowed"),
    (["diagnose", "nowhere/measured.yaml"], "measured file = 'nowhere/measured.yaml' is not "
                                            "allowed (does not exist)"),
])
def test_bad_input_exits_2_with_a_message_and_writes_nothing(tmp_path, capsys, argv, fragment):
    out = tmp_path / "out"
    assert main([*argv, "--out", str(out)]) == 2
    assert fragment in capsys.readouterr().err
    assert not out.exists()


def test_effects_command_prints_the_catalogue(capsys):
    assert main(["effects"]) == 0
    printed = capsys.readouterr().out
    for effect_id in ("air_loading", "viscoelastic_stiffening", "uniform_stiffness"):
        assert f"`{effect_id}`" in printed


def test_a_manifest_naming_an_unknown_candidate_fails_before_any_work(tmp_path, capsys):
    manifest = yaml.safe_load(EXAMPLE.read_text())
    manifest["candidates"] = ["air_loading", "spring_wave"]
    manifest["base_study"] = str(EXAMPLE.parent / "base_study.yaml")
    for condition in manifest["conditions"]:
        for key in ("resonances", "spectrum"):
            condition[key] = str(EXAMPLE.parent / condition[key])
    path = tmp_path / "measured.yaml"
    path.write_text(yaml.safe_dump(manifest))
    assert main(["diagnose", str(path), "--out", str(tmp_path / "out")]) == 2
    assert "candidates = 'spring_wave' is not allowed (unknown effect)" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_diagnose_the_fe_made_example_names_air_with_the_fe_as_model_of_record(tmp_path, capsys):
    """studies/measured_fe_example: coupled 3-D FE data, dry base; FE solves from the
    committed cache (the same FE studies as tests/diagnosis/fe_battery.py)."""
    example = ROOT / "studies" / "measured_fe_example" / "measured.yaml"
    cache = ROOT / "tests" / "data" / "fe_cache"
    out = tmp_path / "report"
    assert main(["diagnose", str(example), "--out", str(out), "--quiet",
                 "--fe-cache", str(cache)]) == 0
    printed = capsys.readouterr().out
    assert "missing: air_loading" in printed and "model of record: FE (0 solves" in printed
    document = json.loads((out / "diagnosis.json").read_text())
    assert document["model_of_record"] == "fe" and document["missing_effects"] == ["air_loading"]
    assert document["gap_before"] > 5 * document["gap_after"]
    assert document["status"]["frame_reflection"] == "on in the base model"
    assert "## Model of record" in (out / "report.md").read_text()
