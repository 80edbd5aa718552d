"""Hidden-effect battery of issue 5: data generated with effects the diagnosed model lacks.

Fast suite: two seeds per scenario.  ``-m slow``: ten seeds per scenario and
the hit-rate table (printed).  A miss may be an honest "ambiguous" (the data
of a seed too weak to separate two explanations); a wrong name may not be:
the slow battery requires no false discovery at all and the hit counts the README
states (10/10, 8/10 for electrostatic softening alone and with air loading).
"""

import pytest
from diagnose_helpers import SCENARIOS, diagnose_scenario, hit, wrong

FAST_SEEDS = (11, 12)


def test_air_loading_hidden_names_it_and_the_gap_shrinks_five_fold(tmp_path):
    for seed in FAST_SEEDS:
        result = diagnose_scenario("air_loading", seed, tmp_path / str(seed))
        assert result.missing_effects == ["air_loading"], result.verdict
        assert result.gap_before >= 5 * result.gap_after, (result.gap_before, result.gap_after)
        # the dry model over-predicts (0,1) by ~30 % (Fig. 10); the step says so
        evidence = " ".join(result.steps[0].evidence)
        assert "(0,1): mean frequency error +" in evidence


def test_spring_mass_hidden_is_named_from_the_extra_pistonic_peaks(tmp_path):
    for seed in FAST_SEEDS:
        result = diagnose_scenario("spring_mass", seed, tmp_path / str(seed))
        assert result.missing_effects == ["spring_mass"], result.verdict
        assert any("pistonic peak" in e for e in result.steps[0].evidence), \
            result.steps[0].evidence
        fitted = result.steps[0].values["spring_mass"]["mass"]
        assert 1.2e-3 < fitted < 2.6e-3          # truth 1.8 g (Table 1)


def test_electrostatic_softening_hidden_is_named_from_data_at_1_2_3_kV(tmp_path):
    for seed in FAST_SEEDS:
        result = diagnose_scenario("electrostatic_softening", seed, tmp_path / str(seed))
        assert result.missing_effects == ["electrostatic_softening"], result.verdict
        assert result.ambiguous == []
        assert result.gap_after < result.gap_before


def test_viscoelastic_stiffening_hidden_is_named_from_an_error_growing_with_frequency(tmp_path):
    for seed in FAST_SEEDS:
        result = diagnose_scenario("viscoelastic_stiffening", seed, tmp_path / str(seed))
        assert result.missing_effects == ["viscoelastic_stiffening"], result.verdict
        evidence = " ".join(result.steps[0].evidence)
        assert "changing with frequency" in evidence, evidence


def test_two_hidden_effects_are_both_named_in_order_of_importance(tmp_path):
    for seed in FAST_SEEDS:
        result = diagnose_scenario("two_effects", seed, tmp_path / str(seed))
        # air loading moves (0,1) by ~30 %, the Maxwell term by <= 5 % at 3 kV
        assert result.missing_effects == ["air_loading", "electrostatic_softening"], \
            result.verdict
        gaps = [result.gap_before] + [s.gap_after for s in result.steps if s.effects]
        assert gaps == sorted(gaps, reverse=True)


def test_modal_damping_hidden_is_named_from_the_quality_factors(tmp_path):
    """Not in the issue's list, but in the catalogue: an undamped model against measured Q."""
    result = diagnose_scenario("modal_damping", FAST_SEEDS[0], tmp_path)
    assert result.missing_effects == ["modal_damping"], result.verdict
    assert 1.2 < result.steps[0].values["modal_damping"]["scale"] < 1.9     # truth 1.5
    assert any("quality factor" in e for e in result.steps[0].evidence)


def test_nothing_hidden_reports_nothing_missing_for_several_noise_seeds(tmp_path):
    for seed in (11, 12, 13):
        result = diagnose_scenario("nothing", seed, tmp_path / str(seed))
        assert result.missing_effects == [] and result.ambiguous == [], result.verdict
        assert result.verdict.startswith("Nothing is missing")
        assert result.gap_after == result.gap_before < 0.03


def test_two_indistinguishable_explanations_are_reported_not_guessed(tmp_path):
    for seed in FAST_SEEDS:
        result = diagnose_scenario("ambiguous", seed, tmp_path / str(seed))
        assert result.missing_effects == [], result.verdict
        assert [set(g) for g in result.ambiguous] == [{"electrostatic_softening",
                                                       "uniform_stiffness"}]
        step = next(s for s in result.steps if s.action == "ambiguous")
        separation = step.separation[0]
        # another bias voltage separates them: the Maxwell term scales with V_b^2
        assert separation["voltage"] != 3000.0 and separation["sigma"] > 3
        assert "cannot tell" in result.verdict


@pytest.mark.slow
def test_battery_hit_rates_over_ten_seeds(tmp_path, figures):
    seeds = range(100, 110)
    rates, false_discoveries = {}, {}
    for name in SCENARIOS:
        results = [diagnose_scenario(name, seed, tmp_path / f"{name}_{seed}") for seed in seeds]
        rates[name] = sum(hit(name, r) for r in results) / len(results)
        false_discoveries[name] = sum(wrong(name, r) for r in results)
    figures("hit rates over seeds 100-109 (false discoveries):",
            [f"{name:26s} {rate:.0%} ({false_discoveries[name]})" for name, rate in rates.items()])
    # the README's table (right verdicts of seeds 100-109), asserted as stated
    claimed = {"air_loading": 10, "spring_mass": 10, "electrostatic_softening": 8,
               "viscoelastic_stiffening": 10, "two_effects": 8, "modal_damping": 10,
               "nothing": 10, "ambiguous": 10}
    assert set(claimed) == set(SCENARIOS)
    assert all(round(10 * rates[name]) >= claimed[name] for name in SCENARIOS), rates
    assert not any(false_discoveries.values()), false_discoveries


def test_spectra_alone_are_enough_peaks_are_picked(tmp_path):
    """The air-loading data with the resonance lists removed: the peaks come from the
    average spectra (no labels, no kinds) and the verdict is the same."""
    import yaml
    from diagnose_helpers import make_data

    from copdea_fem.diagnosis import load_measured
    from copdea_fem.diagnosis.select import Diagnoser
    path = make_data("air_loading", FAST_SEEDS[0], tmp_path)
    manifest = yaml.safe_load(path.read_text())
    for condition in manifest["conditions"]:
        condition.pop("resonances")
    path.write_text(yaml.safe_dump(manifest))
    result = Diagnoser(load_measured(path)).run()
    assert result.missing_effects == ["air_loading"], result.verdict
    assert all(p.peak.source == "spectrum" for m in result.matches_after.values()
               for p in m.pairs)
    assert result.gap_after < 0.03


def test_a_single_condition_falls_back_to_the_in_sample_test(tmp_path):
    """Nothing to hold out with one condition: Wilks' threshold, and the report says so."""
    import yaml
    from diagnose_helpers import make_data

    from copdea_fem.diagnosis import load_measured
    from copdea_fem.diagnosis.select import Diagnoser
    for name, missing in (("air_loading", ["air_loading"]), ("nothing", [])):
        path = make_data(name, FAST_SEEDS[0], tmp_path / name)
        manifest = yaml.safe_load(path.read_text())
        manifest["conditions"] = manifest["conditions"][1:2]
        path.write_text(yaml.safe_dump(manifest))
        result = Diagnoser(load_measured(path)).run()
        assert not result.cross_validated and result.missing_effects == missing, result.verdict
