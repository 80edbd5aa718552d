"""Material damping in the diagnosis (issue 23): the FE-evaluated ``viscoelastic_membrane``.

Data made by the FE's damped eigen step with this suite's own noise (``fe_battery.py``:
frequencies AND quality factors), never by the ring model; FE solves from the committed
cache ``tests/data/fe_cache`` (refill: ``python tests/diagnosis/fe_battery.py --refill``).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import fe_battery as battery  # noqa: E402

from copdea_fem.diagnosis import load_measured  # noqa: E402
from copdea_fem.diagnosis.anchored import (
    PROBE,
    STRONG_PROBE,
    Anchor,
    AnchoredEngine,
    Share,
    material_share,
    prony_mode,
)
from copdea_fem.diagnosis.candidates import material_skipped  # noqa: E402
from copdea_fem.diagnosis.effects import CATALOGUE, catalogue_table  # noqa: E402
from copdea_fem.diagnosis.fe import FEMode, FEModel, FEResult, fe_study  # noqa: E402
from copdea_fem.diagnosis.ring_predictor import ModelMode  # noqa: E402
from copdea_fem.diagnosis.select import Diagnoser  # noqa: E402
from copdea_fem.study import PronyTerm, parse_study  # noqa: E402

FAST_SEEDS = (1,)
SLOW_SEEDS = (2, 3, 4, 5)
VISCO = {"modulus_ratio": 2.0, "relaxation_time": "0.3 ms"}
G1 = {"disc": {"motion": "held"}, "load": {"z": 0.016, "voltage": 2000.0},
      "output": {"plots": False}}


def diagnose(case, seed, folder):
    measured = load_measured(battery.write_measured(case, seed, folder))
    engine = AnchoredEngine(measured, FEModel(cache_dir=battery.FE_CACHE))
    return Diagnoser(measured, engine=engine).run()


def quality_errors(result) -> list:
    """|ln(Q_meas / Q_model)| over the final model's pairs with a measured Q (inf: the
    model has no damping there)."""
    return [abs(math.log(p.peak.quality_factor / p.model.quality_factor))
            if math.isfinite(p.model.quality_factor) else math.inf
            for m in result.matches_after.values() for p in m.pairs
            if math.isfinite(p.peak.quality_factor)]


def check_hidden(seed, folder):
    result = diagnose("viscoelastic_hidden", seed, folder)
    assert battery.right("viscoelastic_hidden", result), result.verdict
    assert result.gap_after < result.gap_before
    assert all(step.gap_after < step.gap_before for step in result.steps if step.effects)
    # g and tau themselves are not asserted: with one octave of modes (500-1000 Hz) and
    # 10 % Q scatter the two sides of the loss peak can fit alike (seeds 3, 4: g ~ 7,
    # tau ~ 0.04 ms; truth 2, 0.3 ms); what the data fix -- the FE's Q -- is checked below
    assert result.status["modal_damping"] == ("on in the base model: replaced by "
                                              "viscoelastic_membrane")
    errors = quality_errors(result)          # the FE's Q at the fit: within 3 sigma_Q
    assert len(errors) >= 10 and np.median(errors) < 3 * battery.Q_SCATTER, errors
    return result


def check_null(seed, folder):
    result = diagnose("damping_known", seed, folder)
    assert battery.right("damping_known", result), result.verdict
    assert "viscoelastic_membrane" in {s.effects[-1] for s in result.steps[0].candidates}
    errors = quality_errors(result)          # the base's FE explains the widths
    assert len(errors) >= 10 and np.median(errors) < 2 * battery.Q_SCATTER, errors
    return result


# -- the battery: FE-made data with quality factors ----------------------------------------
def test_a_hidden_prony_term_is_named_from_widths_and_stiffening(tmp_path):
    """Data made by the FE with one Prony term (g = 2, tau = 0.3 ms), dry base with the
    paper's modal b/m: viscoelastic_membrane is named (replacing the b/m), the gap falls."""
    for seed in FAST_SEEDS:
        check_hidden(seed, tmp_path / f"hidden_{seed}")


def test_data_damped_as_the_base_states_names_nothing(tmp_path):
    """Null: the base states the film's damping (Rayleigh alpha, FE) and the data are that
    FE's: the FE's quality factors explain the widths, no material effect is named."""
    for seed in FAST_SEEDS:
        check_null(seed, tmp_path / f"null_{seed}")


@pytest.mark.slow
def test_material_damping_battery_more_seeds(tmp_path, figures):
    """Four more seeds of each: every verdict right, the gap falls when named."""
    shrink = []
    for seed in SLOW_SEEDS:
        result = check_hidden(seed, tmp_path / f"hidden_{seed}")
        shrink.append(result.gap_before / result.gap_after)
        check_null(seed, tmp_path / f"null_{seed}")
    figures(f"material damping battery: {2 * len(SLOW_SEEDS)} runs right; hidden Prony gap "
            f"shrink min {min(shrink):.2f}x")


# -- the modal surrogate (P1) and the FE's damping (A2) ------------------------------------
def test_prony_mode_limits_relaxed_glassy_and_the_loss_peak():
    share = Share(0.02)
    f, zeta = prony_mode(500.0, share, ((2.0, 1e-9),))           # tau -> 0: relaxed
    assert f == pytest.approx(500.0, rel=1e-9) and zeta < 1e-7
    f, zeta = prony_mode(500.0, share, ((2.0, 1e3),))            # tau -> inf: glassy
    assert f == pytest.approx(500.0 * math.sqrt(1 + 0.02 * 2.0), rel=1e-9) and zeta < 1e-7
    times = [10 ** (k / 50) * 1e-5 for k in range(151)]
    zetas = [prony_mode(500.0, share, ((0.1, t),))[1] for t in times]
    peak = times[zetas.index(max(zetas))]
    assert 2 * math.pi * 500.0 * peak == pytest.approx(1.0, rel=0.05)   # Maxwell: w tau = 1


def test_material_shares_invert_the_probes():
    """Probes made by (P1) with a known share law give it back."""
    truth = Share(0.02, 0.6)
    weak = prony_mode(500.0, truth, ((PROBE["modulus_ratio"], PROBE["relaxation_time"]),))
    strong = prony_mode(500.0, truth, ((STRONG_PROBE["modulus_ratio"],
                                        STRONG_PROBE["relaxation_time"]),))
    share = Share.from_probes(weak, strong)
    assert share.relaxed == pytest.approx(0.02, rel=1e-9)
    assert share.slope == pytest.approx(0.6, rel=1e-9)
    assert material_share(500.0, 0.0) == 0.0                     # flat membrane: none


def test_the_fe_damping_ratio_is_the_model_quality_factor_at_the_anchor():
    """(A2): at the anchor Q = 1/(2 zeta_FE); a ring-only damping (modal b/m) adds."""
    fe = FEResult((FEMode("(0,1)", "axisymmetric", 500.0, 0.01),
                   FEMode("(1,1)", "non-axisymmetric", 520.0, 0.008)), "axisymmetric",
                  False, 0.0, "key")
    ring = (ModelMode("(0,1)", "axisymmetric", 510.0, math.inf, 0.0, True),)
    anchor = Anchor(fe, ring, {"(0,1)": 500.0 / 510.0})
    modes = {m.label: m for m in anchor.apply(ring)}
    assert modes["(0,1)"].quality_factor == pytest.approx(50.0, rel=1e-12)
    assert modes["(1,1)"].quality_factor == pytest.approx(62.5, rel=1e-12)
    damped = (ModelMode("(0,1)", "axisymmetric", 510.0, 25.0, 0.0, True),)   # zeta 0.02
    modes = {m.label: m for m in anchor.apply(damped)}
    assert modes["(0,1)"].quality_factor == pytest.approx(1 / (2 * 0.03), rel=1e-12)
    assert modes["(1,1)"].quality_factor == pytest.approx(1 / (2 * 0.028), rel=1e-12)


def test_a_mode_the_ring_lacks_takes_its_own_modal_damping_not_its_proxys():
    """A (m,1) mode's b/m is ``reduced.damping_higher`` (eq. 19), not the (0,1)'s 245 1/s
    that its proxy carries: the proxy's zeta change scaled by (b/m)_L w_p / ((b/m)_p w_L)."""
    fe = FEResult((FEMode("(0,1)", "axisymmetric", 500.0, 0.001),
                   FEMode("(3,1)", "non-axisymmetric", 560.0, 0.0005)), "3d", True, 0.0,
                  "key")
    ring = (ModelMode("(0,1)", "axisymmetric", 510.0, math.inf, 0.0, True),)
    anchor = Anchor(fe, ring, {"(0,1)": 500.0 / 510.0})
    proxy_zeta = 0.03                                   # the (0,1)'s b/m, share 0.8 say
    damped = (ModelMode("(0,1)", "axisymmetric", 510.0, 1 / (2 * proxy_zeta), 0.0, True),)
    bm = {"(0,1)": 245.0, "(3,1)": 57.0}
    modes = {m.label: m for m in anchor.apply(damped, bm.get)}
    zeta = 0.0005 + proxy_zeta * 57.0 * 510.0 / (245.0 * 560.0)
    assert modes["(3,1)"].quality_factor == pytest.approx(1 / (2 * zeta), rel=1e-12)
    assert modes["(0,1)"].quality_factor == pytest.approx(1 / (2 * 0.031), rel=1e-12)
    # a proxy without modal damping passes none on
    modes = {m.label: m for m in anchor.apply(damped, {"(0,1)": 0.0, "(3,1)": 57.0}.get)}
    assert modes["(3,1)"].quality_factor == pytest.approx(1 / (2 * 0.0005), rel=1e-12)


# -- the effect and its competition ---------------------------------------------------------
def test_the_effect_sets_one_prony_term_replaces_modal_damping_and_keeps_the_band_clear():
    effect = CATALOGUE["viscoelastic_membrane"]
    study = parse_study(G1)
    on = study.replace(effect.on(study, (2.0, 3e-4)))
    assert on.membrane.prony == (PronyTerm(2.0, 3e-4),)
    assert not CATALOGUE["modal_damping"].is_on(on) and effect.is_on(on)
    slow = effect.on(study, (3.0, 2e-3))        # relaxation at 20 Hz: reaches |Im f| <= 62 Hz
    assert slow["eigen.f_min"] == pytest.approx(0.5 / (2 * math.pi * 2e-3 * 4.0))
    study.replace(slow)                                           # valid
    wide = fe_study(on.replace({"membrane.prony": [{"modulus_ratio": 0.5,
                                                     "relaxation_time": 1e-3}]}), 1250.0)
    assert wide.eigen.f_min > 0                            # the diagnosis's wider band
    row = next(line for line in catalogue_table().splitlines() if "`viscoelastic_membrane`"
               in line)
    assert "fe (FE solves; needs model: fe)" in row and "ratio `membrane.prony[0]" in row


def test_one_material_damping_cause_at_a_time():
    skipped = material_skipped
    base = parse_study(G1)                                        # modal b/m on (Sect. 5.3)
    assert skipped("viscoelastic_membrane", (), base) is None     # replaces the b/m
    assert "viscoelastic_stiffening" in skipped(
        "viscoelastic_membrane", (("viscoelastic_stiffening", (0.3, 2e-4)),), base)
    assert "modal_damping" in skipped("viscoelastic_membrane", (("modal_damping", (1.0,)),),
                                      base)
    for other in ("viscoelastic_stiffening", "modal_damping"):
        assert "viscoelastic_membrane" in skipped(
            other, (("viscoelastic_membrane", (2.0, 3e-4)),), base)
        visco_base = base.replace(CATALOGUE["viscoelastic_membrane"].on(base, (2.0, 3e-4)))
        assert "viscoelastic_membrane" in skipped(other, (), visco_base)
    stiff_base = base.replace({"effects.viscoelastic_strength": 0.3})
    assert "viscoelastic_stiffening" in skipped("viscoelastic_membrane", (), stiff_base)


def test_a_condition_may_not_set_the_prony_series(tmp_path):
    """membrane.prony is the effect's key: a condition setting it is refused by name."""
    import yaml

    from copdea_fem.measured import MeasuredDataError
    path = battery.write_measured("damping_known", 1, tmp_path)
    manifest = yaml.safe_load(path.read_text())
    manifest["conditions"][0]["set"]["membrane.prony"] = [VISCO]
    path.write_text(yaml.safe_dump(manifest, sort_keys=False))
    with pytest.raises(MeasuredDataError, match=r"set\.membrane\.prony .*switched by effect "
                                                r"viscoelastic_membrane"):
        load_measured(path)
