"""The diagnosis with the FE as the model of record (issue 13).

Data made by the FE solver with this suite's own noise (``fe_battery.py``), never
by ``synth``'s ring model; FE solves come from the committed cache
``tests/data/fe_cache`` (refill: ``python tests/diagnosis/fe_battery.py``).
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import fe_battery as battery  # noqa: E402

from copdea_fem.diagnosis import load_measured  # noqa: E402
from copdea_fem.diagnosis.anchored import AnchoredEngine  # noqa: E402
from copdea_fem.diagnosis.compare import MeasuredPeak, gap, match_condition  # noqa: E402
from copdea_fem.diagnosis.fe import FEModel, fe_key, fe_study  # noqa: E402
from copdea_fem.diagnosis.ring_predictor import ModelMode, RingPredictor  # noqa: E402
from copdea_fem.diagnosis.scoring import refusal  # noqa: E402
from copdea_fem.diagnosis.select import Diagnoser  # noqa: E402
from copdea_fem.measured import NoiseModel  # noqa: E402
from copdea_fem.study import parse_study  # noqa: E402

FAST_SEEDS = (1, 2)
ALL_SEEDS = tuple(range(1, 11))


def diagnose(case, seed, folder, **manifest):
    path = battery.write_measured(case, seed, folder)
    if manifest:
        import yaml
        raw = yaml.safe_load(path.read_text())
        raw.update(manifest)
        path.write_text(yaml.safe_dump(raw, sort_keys=False))
    measured = load_measured(path)
    engine = (AnchoredEngine(measured, FEModel(cache_dir=battery.FE_CACHE))
              if measured.model == "fe" else None)
    return Diagnoser(measured, engine=engine).run()


def gaps_never_rise(result) -> bool:
    return all(step.gap_after < step.gap_before for step in result.steps if step.effects)


def check_battery(seeds, folder):
    """Right verdicts, false discoveries, air gap shrink, rising gaps over the cases."""
    right, runs, false, shrink, rises = 0, 0, [], [], []
    for case_name, case in battery.CASES.items():
        for seed in seeds:
            result = diagnose(case_name, seed, folder / f"{case_name}_{seed}")
            runs += 1
            right += battery.right(case_name, result)
            wrong = set(result.missing_effects) - set(case.missing)
            if wrong:
                false.append((case_name, seed, sorted(wrong)))
            if case_name == "air_hidden":
                shrink.append(result.gap_before / result.gap_after)
            if not gaps_never_rise(result):
                rises.append((case_name, seed))
    return right, runs, false, shrink, rises


def test_fe_battery_fast(tmp_path):
    """Two noise seeds of each case: every verdict right, no false discovery, the air gap
    shrinks >= 5x, no accepted step raises the gap."""
    right, runs, false, shrink, rises = check_battery(FAST_SEEDS, tmp_path)
    assert right == runs and not false and not rises
    assert min(shrink) >= 5


@pytest.mark.slow
def test_fe_battery_ten_seeds(tmp_path):
    """The issue's targets over 10 seeds x 5 cases: >= 95 % right, 0 false discoveries,
    gap shrink >= 5x on air in every run, no run whose gap rises at an accepted step."""
    right, runs, false, shrink, rises = check_battery(ALL_SEEDS, tmp_path)
    print(f"FE battery: {right}/{runs} right; air gap shrink min {min(shrink):.1f}x")
    assert right >= 0.95 * runs and not false and not rises
    assert min(shrink) >= 5


# -- the model of record ----------------------------------------------------------------------
def test_at_the_anchor_the_prediction_is_the_fe(tmp_path):
    """(A1): at the base state the anchored prediction is the FE mode by mode; the FE's
    non-axisymmetric modes are there (optional), the ring's 6-ring error is not."""
    measured = load_measured(battery.write_measured("air_hidden", 1, tmp_path))
    fe = FEModel(cache_dir=battery.FE_CACHE)
    engine = AnchoredEngine(measured, fe)
    for condition in measured.conditions:
        modes = {m.label: m for m in engine.predict(condition).modes}
        reference = fe.modes(engine.condition_study(condition),
                             f_max=1.25 * condition.band[1]).frequencies()
        ring = {m.label: m.frequency_hz for m in RingPredictor.predict(engine, condition).modes}
        assert abs(ring["(0,2)"] / reference["(0,2)"] - 1) > 0.02      # what the anchor removes
        for label, frequency in reference.items():
            assert modes[label].frequency_hz == pytest.approx(frequency, rel=1e-12)
        assert modes["(1,1)"].kind == "non-axisymmetric" and modes["(1,1)"].optional


def test_a_base_written_with_air_is_coupled_in_the_fe_and_carries_air_in_the_ring(tmp_path):
    """A base with air.enabled: true is the coupled FE; its ring surrogate has the air's
    estimate (it used to add no air mass at all)."""
    measured = load_measured(battery.write_measured("air_base", 1, tmp_path))
    condition = measured.conditions[0]
    dry = parse_study(battery.DRY, name="dry").replace(condition.overrides)
    ring = RingPredictor(measured).predict(condition)
    ring_dry = RingPredictor(measured).predict_study(dry, condition)
    assert ring.mode("(0,1)").frequency_hz < 0.85 * ring_dry.mode("(0,1)").frequency_hz
    study = measured.study_of(condition)
    assert fe_study(study).air.enabled and fe_key(study) != fe_key(dry)


def test_frame_reflection_is_tested_with_fe_solves_and_named(tmp_path):
    result = diagnose("frame_hidden", 1, tmp_path)
    assert result.missing_effects == ["frame_reflection"]
    assert result.status["frame_reflection"] == "missing: added"
    assert "frame_reflection" not in result.not_tested
    # with the ring model alone it cannot be tested, and says so
    reduced = diagnose("frame_hidden", 1, tmp_path / "reduced", model="reduced")
    assert "model of record" in reduced.not_tested["frame_reflection"]


def test_report_names_the_model_and_warns_that_six_rings_are_not_converged(tmp_path):
    from copdea_fem.diagnosis.report import write_report
    result = diagnose("air_hidden", 1, tmp_path / "data")
    convergence = result.ring_convergence
    assert not convergence["converged"] and convergence["rings"] == 6
    assert abs(convergence["largest_error"]) > 0.01 and convergence["suggested_rings"] in (
        12, 24, 48)
    (tmp_path / "report").mkdir()
    write_report(result, tmp_path / "report")
    document = json.loads((tmp_path / "report" / "diagnosis.json").read_text())
    assert document["model_of_record"] == "fe"
    assert document["ring_convergence"]["suggested_rings"] == convergence["suggested_rings"]
    text = (tmp_path / "report" / "report.md").read_text()
    assert "not converged" in text and f"reduced.rings: {convergence['suggested_rings']}" in text
    history = [h["gap"] for h in document["history"] if h["action"] != "none"]
    assert len(history) == 2
    assert all(b < a for a, b in zip(history, history[1:]))


# -- acceptance --------------------------------------------------------------------------------
def test_a_fit_at_a_bound_is_reported_and_not_accepted(tmp_path):
    """Air hidden, but only electrostatic softening may be added (base without it): its
    scale runs to the bound 2.5 trying to explain a 20-30 % drop -- never accepted.  Seed 3:
    on the octant-mirrored mesh's data the noise of seeds 1 and 2 leaves the optimum just
    inside the range (2.44, 2.16), seeds 3 and 4 put it at the bound."""
    folder = tmp_path / "data"
    path = battery.write_measured("air_hidden", 3, folder)
    base = dict(battery.DRY, effects={"maxwell_scale": 0.0})
    import yaml
    (folder / "base_study.yaml").write_text(yaml.safe_dump(base))
    raw = yaml.safe_load(path.read_text())
    raw["candidates"] = ["electrostatic_softening"]
    path.write_text(yaml.safe_dump(raw))
    measured = load_measured(path)
    result = Diagnoser(measured, engine=AnchoredEngine(
        measured, FEModel(cache_dir=battery.FE_CACHE))).run()
    score = result.steps[0].candidates[0]
    assert score.at_bound == ("electrostatic_softening.scale",) and not score.significant
    assert result.missing_effects == [] and result.ambiguous == []


def test_mode_lists_that_change_with_a_parameter_keep_scores_finite(tmp_path):
    """A mode that comes and goes across the fit range (a cut-off crossing) must not make a
    held-out deviance infinite (the issue's electrostatic misses)."""
    from copdea_fem.diagnosis.scoring import Scorer
    from copdea_fem.diagnosis.tabulation import Tabulation
    measured = load_measured(battery.write_measured("electrostatic_hidden", 1, tmp_path))

    class CutOff(RingPredictor):
        def predict(self, condition, state=(), perturbation=None):
            prediction = super().predict(condition, state, perturbation)
            scale = dict(state).get("electrostatic_softening", (0.0,))[0]
            if scale > 1.0:      # (0,3) leaves the model above a scale of 1
                return replace(prediction, modes=tuple(m for m in prediction.modes
                                                       if m.label != "(0,3)"))
            return prediction

    scorer = Scorer(measured, CutOff(measured))
    from copdea_fem.diagnosis.effects import CATALOGUE
    table = Tabulation(scorer, (), ("electrostatic_softening",),
                       list(CATALOGUE["electrostatic_softening"].parameters))
    names = [c.name for c in measured.conditions]
    values = [table.deviance(names, [u]) for u in np.linspace(0, 1, 21)]
    assert all(math.isfinite(v) for v in values)
    for name in names:
        assert math.isfinite(table.deviance([name], table.fit([n for n in names if n != name])))


def test_labelled_peaks_pair_only_with_their_label():
    """A labelled (0,1) peak 35 % below the model's (0,1) stays with (0,1) (or unexplained),
    never with the nearer (0,2); (1,1) pairs with a split (1,1)a; non-axisymmetric peaks are
    scored when the model has such modes and optional modes cost nothing when unseen."""
    noise = NoiseModel(frequency_relative=0.01)
    band = (20.0, 1000.0)
    modes = [ModelMode("(0,1)", "axisymmetric", 600.0, math.inf, math.nan, True),
             ModelMode("(0,2)", "axisymmetric", 420.0, math.inf, math.nan, True),
             ModelMode("(1,1)a", "non-axisymmetric", 700.0, math.inf, math.nan, True,
                       optional=True),
             ModelMode("(2,1)", "non-axisymmetric", 800.0, math.inf, math.nan, True,
                       optional=True)]
    peaks = [MeasuredPeak(414.0, "(0,1)", "axisymmetric"),
             MeasuredPeak(705.0, "(1,1)", "non-axisymmetric")]
    match = match_condition("c", modes, peaks, band, noise)
    pairs = {(p.model.label, p.peak.label) for p in match.pairs}
    assert pairs == {("(0,1)", "(0,1)"), ("(1,1)a", "(1,1)")}
    assert [m.label for m in match.unseen] == ["(0,2)"]        # (2,1) optional: not counted
    without = match_condition("c", modes[:3], peaks, band, noise)
    assert without.deviance == pytest.approx(match.deviance, rel=1e-12)
    ring_only = match_condition("c", modes[:2], peaks, band, noise)
    assert [p.label for p in ring_only.out_of_scope] == ["(1,1)"]


# -- the FE side --------------------------------------------------------------------------------
def test_the_fe_honours_the_effect_keys_exactly(tmp_path):
    """In vacuo at z = 0: f scales with sqrt(stiffness_scale) (stress and stiffness both scale
    with c10, c20, c01; the mass does not); maxwell_scale s at V_b is V_b sqrt(s) at s = 1."""
    fe = FEModel(cache_dir=False)
    study = parse_study(battery.DRY, name="flat").replace(
        {"load.z": 0.0, "load.voltage": 0.0, "eigen.f_max": 700.0, "mesh.membrane_size": 0.004})
    one = fe.modes(study).frequencies()
    stiff = fe.modes(study.replace({"effects.stiffness_scale": 1.21})).frequencies()
    assert stiff["(0,1)"] / one["(0,1)"] == pytest.approx(1.1, rel=1e-7)
    charged = study.replace({"load.z": 0.011, "load.voltage": 2000.0})
    scaled = fe.modes(charged.replace({"effects.maxwell_scale": 2.25})).frequencies()
    raised = fe.modes(charged.replace({"load.voltage": 3000.0})).frequencies()
    assert scaled["(0,1)"] == pytest.approx(raised["(0,1)"], rel=1e-7)


def test_fe_cache_round_trip_and_a_damaged_entry_is_solved_again(tmp_path):
    study = parse_study(battery.DRY, name="flat").replace(
        {"load.z": 0.0, "load.voltage": 0.0, "eigen.f_max": 600.0, "mesh.membrane_size": 0.004})
    first = FEModel(cache_dir=tmp_path)
    solved = first.modes(study)
    assert first.solves == 1 and (tmp_path / f"{solved.key}.json").is_file()
    again = FEModel(cache_dir=tmp_path)
    assert again.modes(study).modes == solved.modes and again.solves == 0
    (tmp_path / f"{solved.key}.json").write_text("{not json")
    repaired = FEModel(cache_dir=tmp_path)
    assert repaired.modes(study).frequencies() == pytest.approx(solved.frequencies())
    assert repaired.solves == 1


def test_a_batch_of_fe_solves_runs_side_by_side_sharing_the_cache(tmp_path):
    """FEModel.solve_many (issue 24, item 5): the studies a cache lacks are solved in worker
    processes on the shared folder -- the same modes as one solve at a time in memory, each
    entry written once; a second run finds them all (nothing solved) and a serial model
    reads them."""
    study = parse_study(battery.DRY, name="flat").replace(
        {"load.z": 0.0, "load.voltage": 0.0, "eigen.f_max": 600.0, "mesh.membrane_size": 0.004})
    studies = [study.replace({"effects.stiffness_scale": s}) for s in (0.9, 1.1)]
    requests = [(s, None) for s in studies] * 2                      # duplicates solved once
    parallel = FEModel(cache_dir=tmp_path, workers=2)
    assert parallel.solve_many(requests) == 2 and parallel.solves == 2
    assert len(list(tmp_path.glob("*.json"))) == 2 and not list(tmp_path.glob("*.lock"))
    serial = FEModel(cache_dir=False, workers=1)
    for s in studies:
        assert parallel.modes(s).modes == serial.modes(s).modes
    assert parallel.solves == 2                                      # memory hits
    again = FEModel(cache_dir=tmp_path, workers=2)
    assert again.solve_many(requests) == 0 and again.solves == 0
    assert FEModel(cache_dir=tmp_path, workers=1).solve_many(requests) == 0


def test_fe_worker_counts_are_checked_before_any_work(monkeypatch, capsys):
    from copdea_fem.diagnosis.fe import WORKERS_VARIABLE, default_workers
    from copdea_fem.study import StudyError
    for bad in (0, -1, "two", 1.5, True):
        with pytest.raises(StudyError, match="is not allowed; allowed: an integer >= 1"):
            FEModel(cache_dir=False, workers=bad)
    from copdea_fem.cli import main
    assert main(["diagnose", "absent.yaml", "--fe-workers", "0"]) == 2     # before reading
    assert capsys.readouterr().err.strip() == ("error: --fe-workers = '0' is not allowed; "
                                               "allowed: an integer >= 1 (processes solving "
                                               "FE studies side by side)")
    import os
    monkeypatch.setattr(os, "cpu_count", lambda: 8)
    monkeypatch.setenv(WORKERS_VARIABLE, "3")
    assert default_workers() == 3
    monkeypatch.setattr(os, "cpu_count", lambda: 2)               # capped at the cores
    assert default_workers() == 2
    monkeypatch.setenv(WORKERS_VARIABLE, "0")
    with pytest.raises(StudyError, match=WORKERS_VARIABLE):
        default_workers()


def test_ring_only_physics_of_the_base_acts_through_the_ring_ratio(tmp_path):
    """A base with the spring's mass on (ring-only physics: the FE's spring is massless):
    the anchored P1 is the FE's P1 times ring(with mass)/ring(without), not the FE's P1."""
    from copdea_fem.diagnosis.effects import MANIFEST_RULES
    from copdea_fem.measured import parse_measured
    (tmp_path / "r.csv").write_text("freq_hz,label\n40,P1\n380,(0,1)\n")
    base = dict(battery.DRY, disc={"mass": "3.0 g", "motion": "spring"},
                spring={"stiffness": "52 N/m", "mass": "1.8 g", "length": "30 mm"})
    import yaml
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(base))
    measured = parse_measured({"base_study": "base.yaml", "conditions": [
        {"name": "z16", "set": {"load.z": "16 mm", "load.voltage": "2 kV"},
         "resonances": "r.csv", "band": ["20 Hz", "1000 Hz"]}]}, tmp_path,
        effects=MANIFEST_RULES)
    condition = measured.conditions[0]
    engine = AnchoredEngine(measured, FEModel(cache_dir=tmp_path / "fe"))
    anchored = engine.predict(condition).mode("P1").frequency_hz
    fe = engine.anchor(condition).fe.frequencies()["P1"]
    study = engine.condition_study(condition)
    with_mass = RingPredictor.predict(engine, condition).mode("P1").frequency_hz
    without = engine.ring_predict_study(study.replace({"spring.mass": 0.0}),
                                        condition).mode("P1").frequency_hz
    assert with_mass < 0.97 * without                      # the mass matters
    assert anchored == pytest.approx(fe * with_mass / without, rel=1e-9)


def test_the_fe_study_keeps_the_frame_only_where_there_is_air():
    """In vacuo the frame plays no part: one FE study (axisymmetric) for every frame; with
    air the frames none / baffle / square are three FE studies (square on the 3-D quadrant)."""
    from copdea_fem.study import engine_of
    dry = parse_study(battery.DRY, name="dry")
    keys = {fe_key(fe_study(dry.replace({"geometry.frame": f}))) for f in
            ("none", "baffle", "square")}
    assert len(keys) == 1 and engine_of(fe_study(dry)) == "axisymmetric"
    wet = dry.replace({"air.enabled": True})
    studies = {f: fe_study(wet.replace({"geometry.frame": f})) for f in ("none", "baffle",
                                                                         "square")}
    assert len({fe_key(s) for s in studies.values()}) == 3
    assert engine_of(studies["square"]) == "3d" and engine_of(studies["baffle"]) == \
        "axisymmetric"
    # ring-only keys do not change the FE study
    assert fe_key(wet) == fe_key(wet.replace({"effects.air_mass_scale": 2.0,
                                              "effects.viscoelastic_strength": 0.5,
                                              "reduced.rings": 24}))


def test_a_passing_candidate_is_refused_when_the_exact_gap_or_deviance_does_not_fall():
    """The acceptance rule on exact matches: gap and deviance must both fall (a width-only
    effect: the gap must not rise); an unevaluable fitted model is refused too."""
    peaks = [MeasuredPeak(400.0, "(0,1)"), MeasuredPeak(900.0, "(0,2)")]
    noise, band = NoiseModel(frequency_relative=0.01), (20.0, 1000.0)

    def matches(f01, f02):
        modes = [ModelMode("(0,1)", "axisymmetric", f01, math.inf, math.nan, True),
                 ModelMode("(0,2)", "axisymmetric", f02, math.inf, math.nan, True)]
        return {"c": match_condition("c", modes, peaks, band, noise)}

    far, near = matches(440.0, 950.0), matches(402.0, 905.0)
    assert refusal(far, near, ("air_loading",)) is None
    assert "gap does not fall" in refusal(near, far, ("air_loading",))
    assert "gap does not fall" in refusal(near, near, ("air_loading",))
    assert refusal(near, near, ("modal_damping",)).startswith("the deviance")
    assert "cannot be evaluated at c" in refusal(near, {"c": None}, ("air_loading",))


def test_the_acceptance_rule_refuses_a_step_that_raises_the_gap_by_one_per_cent():
    """The boundary of the acceptance rule (issue 24): a step whose exact gap is 1 % above
    the current one is refused even when its deviance falls, and one 1 % below is accepted
    -- a rule that let the gap grow by up to 50 % would pass the 20-fold test above."""
    peaks = [MeasuredPeak(400.0, "(0,1)"), MeasuredPeak(900.0, "(0,2)")]
    noise, band = NoiseModel(frequency_relative=0.01), (20.0, 1000.0)

    def matches(e01, e02):
        modes = [ModelMode("(0,1)", "axisymmetric", 400.0 * (1 + e01), math.inf, math.nan,
                           True),
                 ModelMode("(0,2)", "axisymmetric", 900.0 * (1 + e02), math.inf, math.nan,
                           True)]
        return {"c": match_condition("c", modes, peaks, band, noise)}

    current = matches(0.03, 0.0)
    rising = matches(0.0, 0.0303)          # the error moved to (0,2), 1 % larger
    before, after = gap(current.values()), gap(rising.values())
    assert 1.005 < after / before < 1.015
    assert "gap does not fall" in refusal(current, rising, ("uniform_stiffness",))
    falling = matches(0.0, 0.0297)
    assert gap(falling.values()) < before
    assert refusal(current, falling, ("uniform_stiffness",)) is None
