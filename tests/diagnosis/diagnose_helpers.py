"""Shared helpers of the diagnosis tests: the hidden-effect scenarios of issue 5.

Each scenario generates synthetic data (``copdea-fem synth``'s library call)
with effects the base model lacks, then diagnoses it.  The full model of the
paper's G1 sample: disc on the biasing spring (P1), spring mass 1.8 g (P2,
P3), incompressible-air added mass, Maxwell softening, the paper's damping.
A plain module with a unique name (not conftest.py), imported by the tests.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

from copdea_fem.diagnosis import load_measured
from copdea_fem.diagnosis.select import Diagnoser
from copdea_fem.diagnosis.synth import SynthOptions, synthesise, write_synthetic
from copdea_fem.study import parse_study

FULL = {"disc": {"motion": "spring"}, "effects": {"air_added_mass": "incompressible"},
        "output": {"plots": False}}
G1_Z = [{"load.z": f"{z} mm", "load.voltage": "2 kV"} for z in (11, 16, 18)]
MIXED = G1_Z + [{"load.z": "16 mm", "load.voltage": "1 kV"},
                {"load.z": "16 mm", "load.voltage": "3 kV"}]
VOLTAGES = [{"load.z": f"{z} mm", "load.voltage": f"{v} kV"} for z in (11, 16)
            for v in (1, 2, 3)]
# three z at the two ends of the bias range: the Maxwell term (<= 5 % at 3 kV) beside the air
Z_BY_VOLTAGE = [{"load.z": f"{z} mm", "load.voltage": f"{v} kV"} for z in (11, 16, 18)
                for v in (1, 3)]
# (0,2) stays below the 1 kHz band edge with the visco-elastic truth (+9 %): low z and V_b
LOW_FREQUENCY = [{"load.z": "0 mm", "load.voltage": "2 kV"},
                 {"load.z": "6 mm", "load.voltage": "1 kV"},
                 {"load.z": "6 mm", "load.voltage": "3 kV"},
                 {"load.z": "11 mm", "load.voltage": "3 kV"},
                 {"load.z": "0 mm", "load.voltage": "3 kV"}]
# one bias voltage, disc held: a Maxwell softening and a softer membrane look alike
ONE_VOLTAGE = [{"load.z": f"{z} mm", "load.voltage": "3 kV"} for z in (11, 14, 16, 18)]


def _with(base: dict, **sections) -> dict:
    out = copy.deepcopy(base)
    for section, values in sections.items():
        out.setdefault(section, {}).update(values)
    return out


@dataclass(frozen=True)
class Scenario:
    """Base model (raw study), effects hidden in the data, conditions, and the right verdict."""

    base: dict
    hidden: dict
    conditions: list
    missing: list
    ambiguous: tuple = ()


SCENARIOS = {
    "air_loading": Scenario(_with(FULL, effects={"air_added_mass": "none"}),
                            {"air_loading": None}, MIXED, ["air_loading"]),
    "spring_mass": Scenario(_with(FULL, spring={"mass": 0.0}), {"spring_mass": None}, MIXED,
                            ["spring_mass"]),
    "electrostatic_softening": Scenario(_with(FULL, effects={"maxwell_scale": 0.0}),
                                        {"electrostatic_softening": None}, VOLTAGES,
                                        ["electrostatic_softening"]),
    "viscoelastic_stiffening": Scenario(FULL, {"viscoelastic_stiffening": None}, LOW_FREQUENCY,
                                        ["viscoelastic_stiffening"]),
    "two_effects": Scenario(_with(FULL, effects={"air_added_mass": "none", "maxwell_scale": 0.0}),
                            {"air_loading": None, "electrostatic_softening": None},
                            Z_BY_VOLTAGE,
                            ["air_loading", "electrostatic_softening"]),
    "modal_damping": Scenario(_with(FULL, reduced={"damping_p1": 0.0, "damping_01": 0.0,
                                                   "damping_02": 0.0, "damping_higher": 0.0}),
                              {"modal_damping": (1.5,)}, MIXED, ["modal_damping"]),
    "nothing": Scenario(FULL, {}, MIXED, []),
    "ambiguous": Scenario(_with(FULL, effects={"maxwell_scale": 0.0}, disc={"motion": "held"}),
                          {"electrostatic_softening": None}, ONE_VOLTAGE, [],
                          ("electrostatic_softening", "uniform_stiffness")),
}


def make_data(name: str, seed: int, folder, **options):
    """Write the synthetic measured set of a scenario into ``folder``; its measured.yaml."""
    scenario = SCENARIOS[name]
    base = parse_study(scenario.base, name="base")
    settings = SynthOptions(seed=seed, **options)
    items = synthesise(base, scenario.hidden, scenario.conditions, settings)
    write_synthetic(base, scenario.hidden, items, settings, folder)
    return folder / "measured.yaml"


def diagnose_scenario(name: str, seed: int, folder, **options):
    """Synthetic data of a scenario, diagnosed: the DiagnosisResult."""
    return Diagnoser(load_measured(make_data(name, seed, folder, **options))).run()


def hit(name: str, result) -> bool:
    """Whether a diagnosis gives the scenario's right verdict (and, for air, the 5x gap)."""
    scenario = SCENARIOS[name]
    if scenario.ambiguous:
        return (any(set(group) == set(scenario.ambiguous) for group in result.ambiguous)
                and not set(result.missing_effects) & set(scenario.ambiguous))
    ok = list(result.missing_effects) == scenario.missing and not result.ambiguous
    if name == "air_loading":
        ok = ok and result.gap_before >= 5 * result.gap_after
    return ok


def wrong(name: str, result) -> bool:
    """Whether a diagnosis names an effect that was not hidden (a false discovery)."""
    return bool(set(result.missing_effects) - set(SCENARIOS[name].hidden))
